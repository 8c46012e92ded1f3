"""A law's sites: joined where the recording cannot tell them apart, twins of the law dropped, screened (issue 39).

A law tried at each of a rig's sites (``LAW@*``) may have sites whose
effects on the recording have one shape: the dragline's left and right
drag chains move the bucket alike in its plane. Fitted apart, two such
candidates would tie, and no verdict could name either. So before the fits
each site's linearized signature - its candidate simulated at the bottom
of its plausible range, less the model without it - is weighted as chi2
weighs the residual, each channel's mean removed (the offsets are free),
and sites of one law whose signatures' cosines all reach ``SITES_ALIKE``
are joined (complete linkage: every pair in a set alike) into one
candidate acting at all of them, ``LAW@A+B``. One simulation per site.
A site candidate that is then its law everywhere (every ring of a crane,
joined) is dropped when the law itself is a candidate (``drop_law_twins``).

Then the sites are screened (``screen_sites``) before any nonlinear fit:
each joined candidate's signature added to the rig parameters'
sensitivities as one more column of the linearized least-squares problem
on the updated model's residual, its improvement is what it explains that
no parameter change does. Sites below ``SCREEN_SHARE`` of the best are not
fitted; their signatures still enter the null test, whose threshold is the
largest improvement over every candidate tried (the multiple-testing cost
of many sites).

A joined set is fitted with one coefficient at all its members, and the
law everywhere with one at every site: friction at one sheave of three
alike ones is then stood in for by friction spread over the three, by
whichever law spreads it best. Once the fits have found a lead acting at
several sites, ``sets_to_split`` lists it, and the laws whose fitted
signatures it shares, each at every member alone (one nonlinear fit per
member): sites alike at the bottom of a law's range may differ at the
size the recording asks for.
"""

from __future__ import annotations

import numpy as np

from ...simulate import assemble, make_mechanism, mechanism_sites, mechanism_type
from ._hypotheses import REFINE_FRACTION, _grid_job, _pool, _weighted_signal
from ._trials import first_maneuver

__all__ = ["join_alike_sites", "alike_groups", "drop_law_twins", "screen_sites", "sets_to_split", "SITES_ALIKE",
           "SCREEN_SHARE", "SPLIT_MAX_SITES"]

# Issue 39's definition: two sites whose signatures' cosine is below this are told apart.
SITES_ALIKE = 0.9
# A site is fitted when its linearized improvement reaches this share of the best site's: the share below
# which a candidate's grid fit is not refined either (a cost rule; the site benchmark reports how often the
# true site passed it).
SCREEN_SHARE = REFINE_FRACTION
# A set is split into its members when it has at most this many: each member costs a candidate's fit (a grid
# and a refinement, about 13 simulations), and the laws a dragline or crane asks where have 2-6 sites of a kind.
SPLIT_MAX_SITES = 6


def _shape(problem, signature):
    """The signature as chi2 weighs it, each channel's mean over its measured samples removed (a channel with a
    free offset), flattened."""
    w = _weighted_signal(problem, signature)
    valid = problem.valid
    means = np.array([w[valid[:, j], j].mean() if valid[:, j].any() and problem.offset_free[j] else 0.0
                      for j in range(w.shape[1])])
    return np.where(valid, w - means, 0.0).ravel()


def alike_groups(shapes, alike=SITES_ALIKE):
    """Indices grouped so that every pair in a group has cosine >= ``alike`` (complete linkage, the most alike
    pair joined first); a site with no signature stands alone.

    Returns
    -------
    groups : list of list of int
        Each sorted, in the order of their first member.
    cosines : ndarray (k, k)
    """
    k = len(shapes)
    norms = [float(np.linalg.norm(s)) if s is not None else 0.0 for s in shapes]
    cos = np.eye(k)
    for i in range(k):
        for j in range(i + 1, k):
            if norms[i] > 0 and norms[j] > 0:
                cos[i, j] = cos[j, i] = float(shapes[i] @ shapes[j]) / (norms[i] * norms[j])
    groups = [[i] for i in range(k)]
    while True:
        pairs = [(min(cos[i, j] for i in a for j in b), x, y) for x, a in enumerate(groups)
                 for y, b in enumerate(groups) if x < y]
        best = max(pairs, default=None)
        if best is None or best[0] < alike:
            break
        _, x, y = best
        groups[x] = sorted(groups[x] + groups[y])
        del groups[y]
    return sorted(groups, key=lambda g: g[0]), cos


def join_alike_sites(problem, ctx, candidates, base_sim, workers=2, alike=SITES_ALIKE):
    """``candidates`` with each law's alike sites joined into one candidate, and what was found.

    Parameters
    ----------
    problem : Problem
    ctx : dict
        The simulations' context (``_hypotheses.fit_candidates``).
    candidates : list of dict
        ``candidate_list`` entries; those named ``LAW@SITE`` are grouped per law.
    base_sim : ndarray (n, c)
        The model without any of them.

    Returns
    -------
    candidates : list of dict
        The same order, a joined group in its first member's place, named ``LAW@A+B``.
    report : list of dict
        Per law with two sites or more: ``law``, ``sites``, ``cosines`` (site x site) and ``groups``.
    signatures : dict
        Each site candidate's name (a joined one's too) -> its signature (n, c), the simulation at the bottom
        of its range less ``base_sim`` (a joined group's the sum of its members'); None where it did not run.
    """
    by_law = {}
    for c in candidates:
        law, _, site = c["name"].partition("@")
        if site:
            by_law.setdefault(law, []).append(c)
    if not by_law:
        return list(candidates), [], {}
    jobs = [(c["name"], c["main"], c["range"][0]) for cs in by_law.values() for c in cs]
    pool = _pool(workers, ctx)
    try:
        signatures = {name: None if sim is None else sim - base_sim for name, _, sim in pool.map(_grid_job, jobs)}
    finally:
        pool.close()
    joined, report = {}, []
    for law, cs in by_law.items():
        if len(cs) < 2:
            continue
        shapes = [None if signatures[c["name"]] is None else _shape(problem, signatures[c["name"]]) for c in cs]
        groups, cos = alike_groups(shapes, alike)
        sites = [c["name"].partition("@")[2] for c in cs]
        report.append({"law": law, "sites": sites, "cosines": np.round(cos, 4).tolist(),
                       "groups": [[sites[i] for i in g] for g in groups]})
        for g in groups:
            if len(g) > 1:
                first = cs[g[0]]
                name = f"{law}@{'+'.join(sites[i] for i in g)}"
                joined[first["name"]] = dict(first, name=name)
                joined.update({cs[i]["name"]: None for i in g[1:]})
                parts = [signatures[cs[i]["name"]] for i in g]
                signatures[name] = None if any(p is None for p in parts) else sum(parts)
    out = [joined.get(c["name"], c) for c in candidates]
    return [c for c in out if c is not None], report, signatures


def drop_law_twins(candidates, ctx):
    """``candidates`` less each site candidate that is its law everywhere, when that law is a candidate too.

    A law at every one of its sites can be the law everywhere - friction at
    all three sheaves of a crane's block and trolley is friction at every
    ring - and two identical candidates tie, so that neither could be named.
    Whether the two are one model is asked of the kernel: the same
    coefficients at the same value (air drag at every body is not air drag
    everywhere, which acts on the ropes too).

    Returns
    -------
    kept : list of dict
    dropped : list of str
        The site candidates dropped, each its law's twin.
    """
    names = {c["name"] for c in candidates}
    rig = ctx["rig"]
    dropped = []
    for c in candidates:
        law, at, sites = c["name"].partition("@")
        if at and law in names and set(sites.split("+")) == set(mechanism_sites(rig, law)):
            value = c["range"][0]
            if _arrays_equal(_arrays(c["name"], c["main"], value, ctx), _arrays(law, c["main"], value, ctx)):
                dropped.append(c["name"])
    return [c for c in candidates if c["name"] not in dropped], dropped


def _arrays(name, main, value, ctx):
    model = assemble(ctx["rig"], first_maneuver(ctx), ctx["discretization"],
                     physics=[make_mechanism(name, **{main: value})])
    return model.arrays


def _arrays_equal(a, b):
    return a.keys() == b.keys() and all(np.array_equal(np.asarray(a[k]), np.asarray(b[k])) for k in a)


def screen_sites(problem, candidates, signatures, residual, sensitivities, share=SCREEN_SHARE):
    """The site candidates worth a nonlinear fit, from their linearized signatures.

    Each site candidate's signature ``s`` joins the parameters' sensitivities
    ``J`` as one more column (chi2-weighted, each channel's mean removed);
    its linearized improvement is what it adds to the least-squares fit of
    ``residual`` by ``J`` alone, ``(s_perp . r_perp)^2 / |s_perp|^2`` (``perp``:
    out of ``J``'s span), and its amplitude the coefficient of the joint
    fit (only its sign is used: a Coulomb law's signature at the bottom of
    its range is no linear guide to its size). The screen is ranked on the
    rig's span, not on the updated rig alone, because updating runs before
    any mechanism and may have taken up a site's effect at its bounds: the
    true site's column still explains what the parameters cannot
    (Cauchy-Schwarz: in the linear model no other column explains more of
    it). A site with a negative amplitude (the law would have to act
    backwards) or an improvement below ``share`` of the best site's is not
    fitted, unless another law at one of its sites passed: the screen tells
    where better than what. Candidates without a site pass as they are, and
    so does a lone site.

    Parameters
    ----------
    problem : Problem
    candidates : list of dict
    signatures : dict
        ``join_alike_sites``'s.
    residual : ndarray (n, c)
        The updated model's residual (SI), NaN where unmeasured.
    sensitivities : list of ndarray (n, c)
        The rig parameters' (``update_model``'s); [] without tolerances.

    Returns
    -------
    kept : list of dict
        ``candidates`` less the screened-out sites, in order.
    report : list of dict
        Per site candidate, best first: ``name``, ``improvement`` (chi2, linearized), ``fitted`` (bool).
    screened_out : list of ndarray (n, c)
        The signatures of the sites not fitted, for the null test.
    """
    sited = [c for c in candidates if "@" in c["name"] and signatures.get(c["name"]) is not None]
    if len(sited) < 2:  # one site asked for by name is fitted: there is nothing to rank it against
        return list(candidates), [], []
    r = _shape(problem, np.nan_to_num(residual))
    q = _span(np.column_stack([_shape(problem, s) for s in sensitivities]) if sensitivities
              else np.zeros((r.size, 0)))
    r_perp = r - q @ (q.T @ r)
    scores = {}
    for c in sited:
        s = _shape(problem, signatures[c["name"]])
        s_perp = s - q @ (q.T @ s)
        ss = float(s_perp @ s_perp)
        amplitude = float(s_perp @ r_perp) / ss if ss > 0 else 0.0
        scores[c["name"]] = max(amplitude, 0.0) ** 2 * ss
    best = max(scores.values())
    fitted = {n for n, g in scores.items() if g > 0 and g >= share * best}
    # The screen's column is each law at the bottom of its range, and a Coulomb law's is no linear guide to its
    # size: it finds where better than what. So a site through it brings every law at that site that would not
    # act backwards (site seed 205, a viscous bearing at the boom 5x its threshold: bearing friction there led
    # the screen at 91,145, the true law scored 9,928 and was never fitted).
    through = {site for n in fitted for site in _sites_of(n)}
    fitted |= {n for n, g in scores.items() if g > 0 and through & _sites_of(n)}
    kept = [c for c in candidates if c["name"] not in scores or c["name"] in fitted]
    report = sorted(({"name": n, "improvement": g, "fitted": n in fitted} for n, g in scores.items()),
                    key=lambda e: -e["improvement"])
    return kept, report, [signatures[n] for n in scores if n not in fitted]


def _sites_of(name):
    """The sites of a site candidate's name (``LAW@A+B``), as a set of (kind, site): a ring and a body may share
    a name (the dragline's hoist cluster), a ring law and a body law never share a site."""
    kind = mechanism_type(name).site
    return {(kind, site) for site in name.partition("@")[2].split("+")}


def _span(J, rcond=1e-10):
    """An orthonormal basis of ``J``'s column space (directions below ``rcond`` of the largest dropped)."""
    if not J.shape[1]:
        return J
    u, sv, _ = np.linalg.svd(J, full_matrices=False)
    return u[:, sv > rcond * sv[0]] if sv[0] > 0 else u[:, :0]


def sets_to_split(problem, rig, leading, signatures, site_laws, alike=SITES_ALIKE, max_sites=SPLIT_MAX_SITES):
    """The candidates acting at several sites to be fitted at each member alone: the lead and the laws alike to it.

    Parameters
    ----------
    problem : Problem
    rig : Rig
    leading : list of str
        Fitted candidates' names, the lead first.
    signatures : dict
        Name -> its fitted signature (n, c): the fitted simulation less the model without it.
    site_laws : collection of str
        The laws asked where (``LAW@*``): only theirs are split.

    Returns
    -------
    dict
        Each candidate to split (the lead first, then laws whose signature's cosine with the lead's reaches
        ``alike``) -> the names of its members, ``LAW@SITE``. A set with more than ``max_sites`` members, a law
        not asked where and a single site are left out.
    """
    if not leading:
        return {}
    shapes = {n: _shape(problem, signatures[n]) for n in leading}
    lead = shapes[leading[0]]
    out = {}
    for name in leading:
        law, at, sites = name.partition("@")
        if law not in site_laws:
            continue
        members = sites.split("+") if at else list(mechanism_sites(rig, law))
        if not 2 <= len(members) <= max_sites:
            continue
        if name != leading[0] and _cosine(lead, shapes[name]) < alike:
            continue
        out[name] = [f"{law}@{s}" for s in members]
    return out


def _cosine(a, b):
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    return float(a @ b) / (na * nb) if na > 0 and nb > 0 else 0.0
