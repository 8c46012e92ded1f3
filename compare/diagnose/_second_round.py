"""A second mechanism on top of the named one.

The candidates are one mechanism each, so a recording with two effects
gets the stronger one named and the other absorbed or left over. After a
verdict names a mechanism, every other candidate is fitted again with the
named one (at its fitted value) in every simulation, scored on held-out
data against that model, and tested against its own null threshold (the
same surrogates, made from the two-mechanism model's residual). The
verdict stays the named mechanism (docs/interfaces.md: one name); a
significant second one is reported beside it.
"""

from __future__ import annotations

from ...simulate import make_mechanism
from ._band import band_improvement, significance
from ._hypotheses import fit_candidates, score_candidate
from ._null import null_threshold

__all__ = ["second_round", "is_second", "seconds_of_document"]


def is_second(improvement, resolved, value, at_bound, threshold):
    """Whether a candidate fitted on top of the named one counts: beyond ``threshold`` (chi2), inside its
    range, and beyond ``_band.RESOLVED_MIN`` of the threshold below ``_band.RESOLVED_HZ``."""
    return significance(improvement, resolved, value, threshold)[0] and not at_bound


def seconds_of_document(document, share):
    """The second mechanisms a diagnosis document's second round names when a second must explain ``share``
    of the named model's excess chi2 (``_steps.SECOND_EXCESS_SHARE`` in force): names, best first.

    A document written before ``named_excess`` was kept gives it as its allowance over the share then in
    force, 0.4.
    """
    second = document.get("second_mechanism") or {}
    if not second.get("candidates"):
        return []
    excess = second.get("named_excess")
    if excess is None:
        excess = second["allowance"] / 0.4
    threshold = max(second["noise_threshold"], share * max(0.0, excess))
    return [h["name"] for h in second["candidates"]
            if is_second(h["improvement"], h["resolved_improvement"], next(iter(h["parameters"].values())),
                         h["at_bound"], threshold)]


def second_round(problem, ctx, candidates, named, base_sim, workers=2, seed=0, progress=None, allowance=0.0):
    """Fit each other candidate on top of the named mechanism.

    Parameters
    ----------
    problem : Problem
    ctx : dict
        The simulations' context (``_hypotheses.fit_candidates``).
    candidates : list of dict
        Every runnable candidate (``candidate_list`` entries, ``searched`` set).
    named : dict
        The verdict's hypothesis entry (``name``, ``main_parameter``, ``parameters``).
    base_sim : ndarray (n, c)
        The named mechanism's fitted simulation.
    workers, seed : int
        Processes; the null test's seed.
    progress : callable, optional
    allowance : float
        The least improvement (chi2) that counts whatever the null test
        says: the share of the named model's own excess over noise a second
        mechanism must explain (``diagnose``).

    Returns
    -------
    dict
        ``given`` (the named mechanism and its parameters), ``threshold``
        (chi2: the larger of ``noise_threshold`` and ``allowance``), ``candidates`` (best first: ``name``, ``parameters``,
        ``improvement``, ``score``, ``resolved_improvement``, ``significant``: beyond the threshold,
        inside its range and beyond ``_band.RESOLVED_MIN`` of it below ``_band.RESOLVED_HZ``),
        ``n_simulations``.
    """
    main = named["main_parameter"]
    value = named["parameters"][main]
    base = [make_mechanism(named["name"], **{main: value})]
    others = [c for c in candidates if c["name"] != named["name"]]
    given = {"name": named["name"], "parameters": {main: value}}
    if not others:
        return {"given": given, "threshold": None, "noise_threshold": None, "allowance": allowance, "candidates": [],
                "n_simulations": 0}
    points = fit_candidates(problem, dict(ctx, base_physics=base), others, base_sim, workers=workers,
                            progress=progress)
    scored = {c["name"]: score_candidate(problem, c, points[c["name"]]) for c in others}
    best = min(scored.values(), key=lambda s: s["evaluation"]["full"])
    best_sim = best["sim"] if best["value"] > 0 else base_sim
    residual = problem.residual(best_sim, problem.evaluate(best_sim)["nuisance"])
    signatures = [s["signature_sim"] - base_sim for s in scored.values() if s["signature_sim"] is not None]
    noise_threshold, _ = null_threshold(problem, residual, signatures, seed=seed + 1)
    threshold = max(noise_threshold, allowance)
    base_residual = problem.residual(base_sim)
    found = []
    for c in others:
        s = scored[c["name"]]
        resolved = (band_improvement(problem, base_residual, problem.residual(s["sim"], s["evaluation"]["nuisance"]))
                    ["resolved"] if s["value"] > 0 else 0.0)
        found.append({
            "name": c["name"],
            "parameters": {c["main"]: s["value"]},
            "improvement": s["improvement"],
            "score": s["improvement"] / threshold,
            "resolved_improvement": resolved,
            "significant": is_second(s["improvement"], resolved, s["value"], s["at_bound"], threshold),
            "at_bound": s["at_bound"],
        })
    found.sort(key=lambda h: -h["improvement"])
    return {"given": given, "threshold": threshold, "noise_threshold": noise_threshold, "allowance": allowance,
            "candidates": found,
            "n_simulations": sum(s["n_simulations"] for s in scored.values())}
