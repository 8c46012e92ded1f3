"""Candidate mechanisms: fit each through the simulator, score it on held-out data.

Steps 2-4 of the diagnosis (``_diagnose``); the verdict's rules are
``_decide``, the objective and the held-out scoring ``_problem``'s, what
noise alone gives ``_null``'s.

Fitting
-------
Each candidate's main parameter ``p`` is searched on ``ln p`` over its
plausible range (``MECHANISMS[name].range``): a grid of
``N_GRID`` values (step 2's signature ranking: how well the best grid value
reduces the mismatch), then, for candidates that reduce it at all, a
bounded Brent search in the grid cell around the best value. The nominal
model (``p = 0``) is always one of the evaluated points. Simulations start
from the nominal equilibrium (a mechanism that acts only on motion leaves
the rest pose unchanged) and run in ``workers`` processes.

Parameter uncertainty
---------------------
From the curvature of ``chi2(ln p)`` at the optimum (parabola through the
best evaluated points): ``sigma_ln_p = sqrt(kappa / a)``, ``kappa`` the
residual's dispersion (``chi2_min / N``, at least 1) times its integrated
autocorrelation time; reported with the two folds' estimates. The stated
uncertainty (``_summary.stated_uncertainty``) is the largest of this
profile, the fold spread, the search's resolution and the marginal with
the rig's parameters free (``_confounding.marginal_uncertainty``), with the
model's own error along the signature in quadrature.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar

from .._executor import as_executor
from ...simulate import (
    MECHANISMS,
    SimulationError,
    StaticsError,
    assemble,
    make_mechanism,
    matrix_from_angles,
    mechanism_sites,
    mechanism_type,
    simulate,
    stable_time_step,
)
from ._trials import first_maneuver, split_channel, stack_trials, trial_contexts

__all__ = [
    "candidate_list",
    "fit_candidates",
]

N_GRID = 6
# Friction and bending damping stiffen the equations: the stable step falls
# with the parameter (200x at pulley friction mu = 0.5). A value whose step
# is more than MAX_COST times smaller than the nominal model's is not
# simulated; the searched range ends there and says so.
MAX_COST = 6.0
REFINE_EVALS = 6
# Only candidates whose best grid value reduces chi2 by at least this fraction
# of the best candidate's reduction are refined (the rest keep their grid fit).
REFINE_FRACTION = 0.2
REFINE_XATOL = 0.02  # in ln p: 2 %
# A fitted value in the outermost part of its range is "at the bound".
BOUND_TOLERANCE = 0.05  # in ln p


def candidate_list(names=None, rig=None):
    """The candidate mechanisms: every one in ``MECHANISMS`` marked a candidate (or those named).

    A name may be a law at one site, ``LAW@SITE`` (``pulley_friction@boom``),
    at several together (``LAW@A+B``), or ``LAW@*``: the law at each of
    ``rig``'s sites in turn (``mechanism_sites``), each a candidate of its own.
    ``default`` stands for the default list, ``*@*`` for every law that has
    sites (a candidate everywhere or not) at each of them.

    Returns
    -------
    list of dict
        ``name``, ``main`` (main parameter), ``range`` (lo, hi), ``doc``.

    Raises
    ------
    ValueError
        A name that is not a mechanism, a site the law has not, or (with
        ``rig``) a site the rig has not.
    """
    default = sorted(n for n in MECHANISMS if MECHANISMS[n].candidate)
    names = default if names is None else list(names)
    names = [m for n in names for m in (default if n == "default" else [n])]
    names = [m for n in names for m in ([f"{law}@*" for law in sorted(MECHANISMS) if MECHANISMS[law].site]
                                        if n == "*@*" else [n])]
    out = []
    for name in dict.fromkeys(names):
        entry = mechanism_type(name)  # unknown laws and sites on a law without them say so
        law, _, site = name.partition("@")
        sites = mechanism_sites(rig, law) if rig is not None and site else None
        if site == "*":
            if sites is None:
                raise ValueError(f"{name!r}: the sites of a law are the rig's; no rig given")
            expanded = [f"{law}@{s}" for s in sites]
        else:
            unknown = [part for part in site.split("+") if part not in sites] if sites is not None else []
            if unknown:
                raise ValueError(f"{law} has no site {unknown[0]!r} on this rig "
                                 f"(its sites: {', '.join(sites) or 'none'})")
            expanded = [name]
        lo, hi = entry.range  # the one table of plausible ranges: the mechanism registry
        out += [{"name": n, "main": entry.main, "range": (float(lo), float(hi)), "doc": entry.doc} for n in expanded]
    return out


def cost_ratio(candidate, value, rig, maneuver, discretization, nominal_step):
    """How many times smaller the stable step is with the mechanism at ``value`` (>= 1)."""
    model = assemble(rig, maneuver, discretization,
                     physics=[make_mechanism(candidate["name"], **{candidate["main"]: value})])
    return max(1.0, nominal_step / stable_time_step(model))


def affordable_range(candidate, rig, maneuver, discretization, max_cost=MAX_COST):
    """The part of a candidate's range whose simulations cost at most ``max_cost`` nominal ones.

    Returns
    -------
    (lo, hi) : tuple of float
        ``hi`` is the range's own upper end when affordable, else where the
        cost reaches ``max_cost`` (bisection on ln p, to 1 %).
    """
    lo, hi = candidate["range"]
    nominal_step = stable_time_step(assemble(rig, maneuver, discretization))
    if cost_ratio(candidate, hi, rig, maneuver, discretization, nominal_step) <= max_cost:
        return lo, hi
    a, b = math.log(lo), math.log(hi)
    if cost_ratio(candidate, lo, rig, maneuver, discretization, nominal_step) > max_cost:
        return lo, lo
    while b - a > 0.01:
        m = 0.5 * (a + b)
        if cost_ratio(candidate, math.exp(m), rig, maneuver, discretization, nominal_step) <= max_cost:
            a = m
        else:
            b = m
    return lo, float(math.exp(a))


def unavailable_reason(candidate, rig, maneuver, discretization):
    """None when the simulator can run the candidate, else why not (one line)."""
    try:
        assemble(rig, maneuver, discretization,
                 physics=[make_mechanism(candidate["name"], **{candidate["main"]: candidate["range"][1]})])
    except (ValueError, NotImplementedError) as exc:
        return " ".join(str(exc).split())
    return None


# ---------------------------------------------------------------- simulation workers

_CTX = {}


def _init(ctx):
    _CTX.clear()
    _CTX.update(ctx)


def simulate_channels(name, main, value, ctx=None, discretization=None):
    """One candidate simulation's dynamic channels on the problem's time base.

    ``discretization``: another than the context's, each trial then from its
    own equilibrium there (the context's initial states are of its level).

    Returns
    -------
    ndarray (n, c), or None when the simulation blows up.
    """
    c = _CTX if ctx is None else ctx
    physics = list(c.get("base_physics", ()))  # a mechanism already named (second round)
    if value != 0.0 and name is not None:
        physics.append(make_mechanism(name, **{main: value}))
    sims = []
    for trial in trial_contexts(c):
        start = {"initial_state": trial["initial_state"]} if discretization is None else {}
        try:
            level = c["discretization"] if discretization is None else discretization
            res = simulate(c["rig"], trial["maneuver"], level, physics,
                           duration=trial["duration"], rate_hz=c["rate_hz"], **start)
        except (SimulationError, StaticsError, FloatingPointError):
            return None
        sims.append(channels_on(res, trial))
    return stack_trials(c, sims)


def channels_on(result, ctx):
    """A simulation's dynamic channels as the recording reports them, on the problem's time base, (n, c).

    A recording is reconstructed with the rig file (``ctx["reported_rig"]``):
    a body's position is its mass centre placed from the markers with the
    file's mass-centre offset, a marker-fixed point; a rope's length is
    measured from the file's fixed point (the boom pulley for the hoist
    rope, plus the fixed path from its reel). A simulated rig whose mass
    centre or fixed points moved (model updating) is read the same way, not
    at its own mass centre and pulley: else a 5 mm change of the bucket's
    mass centre shows as 4 mm of bucket.x swinging with the pitch, and a
    moved boom pulley as a hoist rope 17 mm long, that no parameter fits.
    """
    t = np.asarray(result.time, float)
    table = result.motion_table()
    if any(ch not in table for ch in ctx["channels"]):
        table = result.table
    reported = ctx.get("reported_rig")
    columns = []
    for ch in ctx["channels"]:
        values = np.asarray(table[ch], float)
        if reported is not None:
            values = values + _reading_shift(result, table, reported, ch)
        columns.append(np.interp(ctx["time"], t, values))
    return np.column_stack(columns)


def _reading_shift(result, table, reported, channel):
    """What reading a simulated channel with the ``reported`` rig's geometry adds to it (SI, per record)."""
    rig = result.model.rig
    name, _, quantity = split_channel(channel)[1].partition(".")
    if name in rig.bodies and quantity in ("x", "y", "z") and name in reported.bodies:
        moved = np.asarray(reported.bodies[name].cg_body, float) - np.asarray(rig.bodies[name].cg_body, float)
        if not np.any(moved):
            return 0.0
        T = matrix_from_angles(*(np.asarray(table[f"{name}.{a}"], float) for a in ("roll", "pitch", "yaw")),
                               rig.bodies[name].euler_sequence)
        return (T @ moved)[:, "xyz".index(quantity)]
    if quantity == "length" and name in rig.ropes and name in reported.ropes:
        spec = rig.ropes[name]
        # the fixed path: the rope's start and the fixed rings it passes before its measured span
        path = [ref.partition(".") for ref in (spec.start, *spec.rings)]
        if any(kind != "fixed" or point not in rig.fixed_points for kind, _, point in path):
            return 0.0
        sim, rep = ([np.asarray(r.fixed_points[point], float) for _, _, point in path] for r in (rig, reported))
        if all(np.array_equal(a, b) for a, b in zip(sim, rep)):
            return 0.0
        f_sim, f_rep = sim[-1], rep[-1]
        nodes = result.rope_nodes(name)
        # The first node past the span's start: the rope leaves the ring (or the reel) towards it.
        k = int(np.argmin(np.linalg.norm(nodes[0] - f_sim, axis=1))) + 1
        moved = sum(np.linalg.norm(b - a) for a, b in zip(rep[:-1], rep[1:])) - sum(
            np.linalg.norm(b - a) for a, b in zip(sim[:-1], sim[1:]))
        return moved + np.linalg.norm(nodes[:, k] - f_rep, axis=1) - np.linalg.norm(nodes[:, k] - f_sim, axis=1)
    return 0.0


def _grid_job(name, main, value):
    return name, value, simulate_channels(name, main, value)


def _refine_job(name, main, lo, hi):
    """Bounded Brent search on ln p in [lo, hi] in this process; every evaluated point comes back."""
    return name, _brent_points(lambda value: simulate_channels(name, main, value), _CTX["problem"], lo, hi)


def _brent_points(simulate_at, problem, lo, hi):
    """The points (value, sim or None) a bounded Brent search on ln p in [lo, hi] evaluates."""
    points = []

    def f(x):
        value = float(math.exp(x))
        sim = simulate_at(value)
        if sim is None:
            points.append((value, None))
            return 1e300
        points.append((value, sim))
        return problem.evaluate(sim)["full"]

    minimize_scalar(f, bounds=(math.log(lo), math.log(hi)), method="bounded",
                    options={"xatol": REFINE_XATOL, "maxiter": REFINE_EVALS})
    return points


def _refine_searches(pool, problem, refine):
    """Every candidate's refining search: ``[(name, points)]`` in the order of ``refine``.

    A search is sequential (each point depends on the last), so one search
    per worker left a worker idle whenever the searches did not divide
    evenly among them (three searches on two workers: a third of the time).
    With more than one slot, each search runs in a thread of this process
    that hands its simulations to the pool one at a time, so a free worker
    takes the next simulation of any search: the same searches and points.
    """
    if getattr(pool, "slots", 1) <= 1 or len(refine) <= 1:
        return pool.map(_refine_job, refine)
    from concurrent.futures import ThreadPoolExecutor  # noqa: PLC0415

    def search(job):
        name, main, lo, hi = job
        return name, _brent_points(lambda value: pool.map(_grid_job, [(name, main, value)])[0][2], problem, lo, hi)

    with ThreadPoolExecutor(max_workers=len(refine)) as threads:
        return list(threads.map(search, refine))


def _pool(workers, ctx, at_most=None):
    """A session of the executor (``workers``: an ``Executor`` or a process count) with ``ctx`` in every task."""
    executor = as_executor(workers)
    return (executor if at_most is None else executor.limited(at_most)).open(_init, (ctx,))


def fit_candidates(problem, ctx, candidates, nominal_sim, workers=2, progress=None):
    """Grid, then refine, every candidate; collect every evaluated point.

    Parameters
    ----------
    problem : Problem
    ctx : dict
        ``rig``, ``maneuver``, ``discretization``, ``duration``, ``rate_hz``,
        ``initial_state``, ``time``, ``channels``: what the simulations need;
        optionally ``base_physics``, mechanisms every simulation includes.
    candidates : list of dict
        From :func:`candidate_list`.
    nominal_sim : ndarray (n, c)
        The nominal model's channels (with ``base_physics``: that model's).
    workers : int
        Processes for the simulations (1: run here).
    progress : callable, optional
        Called with a one-line message as the stages finish.

    Returns
    -------
    dict
        name -> list of ``(value, sim or None, evaluation or None)``, the
        nominal (value 0) first.
    """
    ctx = dict(ctx, problem=problem)
    _init(ctx)
    nominal_eval = problem.evaluate(nominal_sim)
    points = {c["name"]: [(0.0, nominal_sim, nominal_eval)] for c in candidates}
    jobs, costs = [], []
    maneuver = first_maneuver(ctx)
    nominal_step = stable_time_step(assemble(ctx["rig"], maneuver, ctx["discretization"]))
    for c in candidates:
        lo, hi = c.get("searched", c["range"])
        for x in np.linspace(math.log(lo), math.log(hi), N_GRID if hi > lo else 1):
            jobs.append((c["name"], c["main"], float(math.exp(x))))
            costs.append(cost_ratio(c, float(math.exp(x)), ctx["rig"], maneuver, ctx["discretization"],
                                    nominal_step))
    # Longest first: two workers finish together.
    jobs = [jobs[i] for i in np.argsort(-np.array(costs), kind="stable")]
    pool = _pool(workers, ctx)
    try:
        for name, value, sim in pool.map(_grid_job, jobs):
            points[name].append((value, sim, None if sim is None else problem.evaluate(sim)))
        if progress:
            progress(f"grid of {len(jobs)} simulations done")
        refine, gains = [], []
        for c in candidates:
            grid = sorted(points[c["name"]][1:], key=lambda p: p[0])
            chi = np.array([e["full"] if e is not None else np.inf for _, _, e in grid])
            if not np.isfinite(chi).any() or chi.min() >= nominal_eval["full"]:
                continue
            i = int(np.argmin(chi))
            lo = grid[max(i - 1, 0)][0]
            hi = grid[min(i + 1, len(grid) - 1)][0]
            refine.append((c["name"], c["main"], lo, hi))
            gains.append(nominal_eval["full"] - chi[i])
        if refine:
            keep = np.array(gains) >= REFINE_FRACTION * max(gains)
            refine = [job for job, k in zip(refine, keep) if k]
        for name, pts in _refine_searches(pool, problem, refine):
            points[name].extend((v, s, None if s is None else problem.evaluate(s)) for v, s in pts)
        if progress and refine:
            progress(f"refined {len(refine)} candidates")
    finally:
        pool.close()
    return points


# ---------------------------------------------------------------- scoring

def _weighted_signal(problem, array):
    """sqrt(W) * array, 0 where unmeasured: residual units in which chi2 is a plain sum of squares."""
    return np.where(problem.valid, array, 0.0) * np.sqrt(problem.W)


def autocorrelation_time(z):
    """Integrated autocorrelation time of each column of z, summed until the ACF falls below 0.05."""
    z = np.asarray(z, float)
    n = z.shape[0]
    zc = z - z.mean(0)
    f = np.fft.rfft(zc, 2 * n, axis=0)
    acf = np.fft.irfft(np.abs(f) ** 2, axis=0)[:n]
    acf = acf / np.maximum(acf[0], 1e-300)
    taus = []
    for j in range(z.shape[1]):
        below = np.flatnonzero(acf[1:, j] < 0.05)
        k = int(below[0]) if below.size else n - 1
        taus.append(1.0 + 2.0 * float(acf[1 : k + 1, j].sum()))
    return np.maximum(np.array(taus), 1.0)


def score_candidate(problem, candidate, points):
    """Full-data fit, fold fits, held-out improvement and the profile of one candidate."""
    good = [(v, s, e) for v, s, e in points if e is not None]
    nominal = good[0]
    best = min(good, key=lambda p: p[2]["full"])
    fa = min(good, key=lambda p: p[2]["AA"])
    fb = min(good, key=lambda p: p[2]["BB"])
    held_before = nominal[2]["AB"] + nominal[2]["BA"]
    held_after = fa[2]["AB"] + fb[2]["BA"]
    lo, hi = candidate["range"]
    searched_hi = candidate.get("searched", candidate["range"])[1]
    value = best[0]
    at_bound = None
    if value > 0:
        x = math.log(value)
        if x <= math.log(lo) + BOUND_TOLERANCE:
            at_bound = "lower"
        elif x >= math.log(hi) - BOUND_TOLERANCE:
            at_bound = "upper"
        elif x >= math.log(searched_hi) - BOUND_TOLERANCE:
            at_bound = "search_limit"
    nonzero = [p for p in good if p[0] > 0]
    signature = min(nonzero, key=lambda p: p[2]["full"])[1] if nonzero else None
    evaluated = sorted((v, e["full"]) for v, s, e in good if v > 0)
    return {
        "value": value,
        "sim": best[1],
        "signature_sim": signature,
        "evaluation": best[2],
        "fold_values": [fa[0], fb[0]],
        "heldout_before": held_before,
        "heldout_after": held_after,
        "fold_sims": (fa[1], fb[1]),
        "improvement": held_before - held_after,
        "at_bound": at_bound,
        "profile": evaluated,
        "n_simulations": len(points) - 1,
        "n_failed": sum(1 for _, s, _ in points if s is None),
    }


def profile_uncertainty(profile, value, kappa):
    """Standard deviation of ln p from the curvature of chi2(ln p) at the optimum, or None."""
    if value <= 0:
        return None
    pts = sorted(profile, key=lambda p: p[1])[:5]
    xs = np.array([math.log(v) for v, _ in pts])
    ys = np.array([c for _, c in pts])
    if np.unique(np.round(xs, 9)).size < 3:
        return None
    x0 = math.log(value)
    # Local parabola, the nearest points weigh most.
    w = 1.0 / (0.05 + np.abs(xs - x0))
    a, b, _ = np.polyfit(xs - x0, ys, 2, w=w)
    if not a > 0:
        return None
    return float(math.sqrt(kappa / a))


def signature_match(problem, nominal_residual, signature):
    """Cosine between a candidate's signature and the nominal model's mismatch (weighted)."""
    z = _weighted_signal(problem, nominal_residual)
    g = _weighted_signal(problem, signature)
    den = math.sqrt(float((z * z).sum()) * float((g * g).sum()))
    return float((z * g).sum()) / den if den > 0 else 0.0
