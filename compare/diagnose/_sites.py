"""Sites the recording cannot tell apart, joined into one candidate (issue 39's "a set of sites").

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
"""

from __future__ import annotations

import numpy as np

from ._hypotheses import _grid_job, _pool, _weighted_signal

__all__ = ["join_alike_sites", "alike_groups", "SITES_ALIKE"]

# Issue 39's definition: two sites whose signatures' cosine is below this are told apart.
SITES_ALIKE = 0.9


def _shape(problem, signature):
    """The signature as chi2 weighs it, each channel's mean over its measured samples removed, flattened."""
    w = _weighted_signal(problem, signature)
    valid = problem.valid
    means = np.array([w[valid[:, j], j].mean() if valid[:, j].any() else 0.0 for j in range(w.shape[1])])
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
    """
    by_law = {}
    for c in candidates:
        law, _, site = c["name"].partition("@")
        if site:
            by_law.setdefault(law, []).append(c)
    tried = {law: cs for law, cs in by_law.items() if len(cs) > 1}
    if not tried:
        return list(candidates), []
    jobs = [(c["name"], c["main"], c["range"][0]) for cs in tried.values() for c in cs]
    pool = _pool(workers, ctx)
    try:
        sims = {name: sim for name, _, sim in pool.map(_grid_job, jobs)}
    finally:
        pool.close()
    joined, report = {}, []
    for law, cs in tried.items():
        shapes = [None if sims[c["name"]] is None else _shape(problem, sims[c["name"]] - base_sim) for c in cs]
        groups, cos = alike_groups(shapes, alike)
        sites = [c["name"].partition("@")[2] for c in cs]
        report.append({"law": law, "sites": sites, "cosines": np.round(cos, 4).tolist(),
                       "groups": [[sites[i] for i in g] for g in groups]})
        for g in groups:
            if len(g) > 1:
                first = cs[g[0]]
                joined[first["name"]] = dict(first, name=f"{law}@{'+'.join(sites[i] for i in g)}")
                joined.update({cs[i]["name"]: None for i in g[1:]})
    out = [joined.get(c["name"], c) for c in candidates]
    return [c for c in out if c is not None], report
