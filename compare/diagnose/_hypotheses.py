"""Candidate mechanisms: fit each through the simulator, score it on held-out data.

Steps 2-4 of the diagnosis (``_diagnose``); the verdict's rules are ``_decide``.

Objective
---------
``chi2 = sum_t sum_c w_t ((m_tc - s_tc - b_c - delta ds_tc/dt) / sigma_c)^2``
over the dynamic channels ``c``: measured ``m`` minus simulated ``s``, each
channel scaled by its own noise level ``sigma_c`` (``_locate.noise_level``),
free-decay samples weighted ``DECAY_WEIGHT`` (the swing after the reels
stop is where the mechanisms act alone, without the reel table's own
errors). Nuisance parameters, fitted by linear least squares for every
simulation: a constant offset ``b_c`` per channel (calibration origin,
marker placement) and one clock shift ``delta`` (the rope-length alignment
is good to a fraction of a millisecond, but at 1 m/s that is already a
noise level), bounded by ``MAX_SHIFT`` about the updated model's own shift.

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

Held-out scoring (2-fold cross-validation)
------------------------------------------
Samples fall in alternating ``BLOCK_S`` blocks, fold A and fold B. For each
fold, the evaluated point (and nuisance) that fits it best is chosen, and
scored on the other fold; the held-out improvement ``D`` is the drop in
held-out chi2 against the nominal model scored the same way. Measurement
noise is independent between the folds, so noise that a fit absorbs on one
fold is not rewarded on the other.

What noise alone gives (null test)
----------------------------------
Surrogate residuals with the same spectrum (hence autocorrelation) and
cross-channel correlation as the best model's residual are drawn as
Gaussian noise from its smoothed cross-spectral matrix; for each, every candidate's signature (fitted minus nominal
simulation) is fitted with a non-negative amplitude on one fold and scored
on the other exactly as above. The threshold is the ``NULL_QUANTILE``
quantile of the largest improvement over candidates (a family-wise test),
and never below ``MIN_IMPROVEMENT`` (twenty times ln N, ln N the BIC
penalty of one parameter: an allowance for the reconstruction's systematic
errors, measured on blind sessions, see the constant). A candidate is
significant when ``D`` exceeds it; ``score`` is ``D / threshold``.

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
    "Problem",
    "fit_candidates",
    "null_threshold",
]

DECAY_WEIGHT = 2.0
MAX_SHIFT = 0.01  # s
BLOCK_S = 0.5
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
NULL_SURROGATES = 400
SPECTRUM_SMOOTH = 8  # frequency bins either side (0.8 Hz for a 10 s record)
NULL_QUANTILE = 0.99
# Floor of the threshold, in chi2 units (a signature of 14 noise sigmas in
# quadrature). The surrogates model what is left as stationary Gaussian
# noise; the reconstruction's systematic errors are not (the cubic fit of a
# rope's markers errs by a few tenths of a millimetre, smoothly, with the
# rope's shape), and a one-parameter fit absorbs some of them. They weigh
# more as the lab's noise falls: with the wide-angle lab (1.6 mm marker
# noise) the best candidate's held-out improvement reached 50 in 9 blind
# no-physics sessions; with the current one (0.9 mm) it reached 86 in 18
# of 19 and 172 in one (where the surrogates' own quantile was 371).
MIN_IMPROVEMENT = 200.0
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


def bounded_solve(A, g, bounds):
    """``A x = g`` (normal equations, ``A`` symmetric positive semi-definite) with ``x`` within ``bounds`` (k, 2).

    The unconstrained solution; then, while any coefficient lies outside its
    bounds, the one furthest outside is held at its bound and the others
    solved again (an active set without release: exact for one bounded
    coefficient, which is how the clock shift was always clipped, and for
    the few here - the shift and the model error's amplitudes - it ends in
    at most that many rounds).
    """
    k = len(g)
    x = np.linalg.lstsq(A, g, rcond=None)[0]
    held = np.zeros(k, bool)
    for _ in range(k):
        low, high = bounds[:, 0], bounds[:, 1]
        excess = np.where(held, 0.0, np.maximum(low - x, x - high))
        worst = int(np.argmax(excess))
        if excess[worst] <= 0.0:
            break
        held[worst] = True
        x[worst] = np.clip(x[worst], low[worst], high[worst])
        free = ~held
        if free.any():
            x[free] = np.linalg.lstsq(A[np.ix_(free, free)], g[free] - A[np.ix_(free, held)] @ x[held],
                                      rcond=None)[0]
    return x


class Problem:
    """Measured data, noise levels, weights and folds: evaluates one simulation.

    Parameters
    ----------
    time : ndarray (n,)
        Uniform time base (s, simulation clock).
    measured : ndarray (n, c)
        Measured channels (SI), NaN where not measured.
    sigma : ndarray (c,)
        Noise level per channel.
    t_stop : float or ndarray (c,)
        When the reels stop (s); per channel for stacked trials (``_trials``).
    regressors : sequence of ndarray (n, c), optional
        Further nuisance directions fitted linearly with every simulation
        (``_updating``: the rig parameters' sensitivities and the model's
        own numerical error), so that a mechanism is credited only with
        what they cannot explain.
    prior_precision, prior_mean : ndarray (k,), optional
        A Gaussian prior on each regressor's coefficient (precision 0: free).
    shift_center : float, optional
        The clock shift (s) the bound ``MAX_SHIFT`` is taken about: the
        updated model's own (``_updating``), so that the clock the rig's
        update settled on is not clipped back (a sheave inertia of 4e-4
        kg m^2 moved the rope-length alignment by 15 ms; clipped at 10 ms,
        the updated model scored 1.9 times the chi2 its update reached).
    offset_free : ndarray (c,) of bool, optional
        Which channels carry a free constant offset (all by default). A
        channel measured in the frame the model is driven in (a tracker's
        body beside the points it moves, ``shared_frame``) has none: its
        mean is the model's to explain.
    """

    def __init__(self, time, measured, sigma, t_stop, regressors=(), prior_precision=None, prior_mean=None,
                 shift_center=0.0, regressor_bounds=None, offset_free=None):
        self.time = np.asarray(time, float)
        self.dt = float(self.time[1] - self.time[0])
        self.measured = np.asarray(measured, float)
        self.sigma = np.asarray(sigma, float)
        self.valid = np.isfinite(self.measured)
        c = self.measured.shape[1]
        self.offset_free = np.ones(c, bool) if offset_free is None else np.asarray(offset_free, bool).reshape(c)
        # Each channel's own stop (stacked trials, ``_trials``), or one for all.
        w = np.where(self.time[:, None] >= np.asarray(t_stop, float), DECAY_WEIGHT, 1.0)
        # Weight of each squared residual: sample weight / sigma^2, 0 if unmeasured.
        self.W = w * self.valid / self.sigma[None, :] ** 2
        fold = (np.floor((self.time - self.time[0]) / BLOCK_S).astype(int) % 2).astype(bool)
        self.folds = {"A": ~fold, "B": fold, "all": np.ones_like(fold)}
        self.n_weighted = float((w * self.valid).sum())
        self.m0 = np.where(self.valid, self.measured, 0.0)
        self.t_stop = t_stop
        self.shift_center = float(shift_center)
        self.regressors = np.array([np.where(self.valid, x, 0.0) for x in regressors], float).reshape(
            len(regressors), *self.measured.shape)
        k = len(self.regressors)
        self.prior_precision = np.zeros(k) if prior_precision is None else np.asarray(prior_precision, float)
        self.prior_mean = np.zeros(k) if prior_mean is None else np.asarray(prior_mean, float)
        # Each regressor's coefficient within (low, high): the model error's amplitude is bounded.
        self.regressor_bounds = (np.tile([-np.inf, np.inf], (k, 1)) if regressor_bounds is None
                                 else np.asarray(regressor_bounds, float).reshape(k, 2))
        # The regressors do not change between simulations: centre them and
        # form their Gram matrix once per fold.
        self._fold_regressors = {}
        for name, mask in self.folds.items():
            if not k:
                break
            W = self.W * mask[:, None]
            sw = np.maximum(W.sum(0), 1e-300)
            xc = self.regressors - self.offset_free * (W * self.regressors).sum(1)[:, None, :] / sw
            gram = np.einsum("inc,jnc->ij", xc * W, xc)
            self._fold_regressors[name] = (xc, gram)

    def with_regressors(self, regressors, prior_precision=None, prior_mean=None, shift_center=None, bounds=None):
        """The same problem with these nuisance regressors (a new object); the shift's centre kept unless given;
        ``bounds`` (k, 2) on their coefficients (none by default)."""
        centre = self.shift_center if shift_center is None else shift_center
        return Problem(self.time, self.measured, self.sigma, self.t_stop, regressors, prior_precision, prior_mean,
                       centre, bounds, self.offset_free)

    def nuisance(self, sim, rate, fold):
        """Least-squares offsets b (c,), clock shift delta (s) and regressor coefficients a (k,) on one fold;
        a channel without a free offset keeps b = 0."""
        W = self.W * self.folds[fold][:, None]
        r = self.m0 - sim
        # Dividing by infinity where the offset is not free: the channel's "mean" is 0 and nothing is centred.
        sw = np.where(self.offset_free, np.maximum(W.sum(0), 1e-300), np.inf)
        rc = r - (W * r).sum(0) / sw
        dc = rate - (W * rate).sum(0) / sw
        if len(self.regressors):
            return self._joint_nuisance(W, sw, r, rc, rate, dc, fold)
        den = float((W * dc * dc).sum())
        delta = float((W * rc * dc).sum()) / den if den > 0 else 0.0
        c = self.shift_center
        delta = float(np.clip(delta, c - MAX_SHIFT, c + MAX_SHIFT))
        b = ((W * r).sum(0) - delta * (W * rate).sum(0)) / sw
        return b, delta, np.zeros(0)

    def _joint_nuisance(self, W, sw, r, rc, rate, dc, fold):
        """Shift and regressors together (normal equations with the priors); offsets eliminated."""
        xc, gram = self._fold_regressors[fold]
        k = len(self.regressors)
        A = np.empty((k + 1, k + 1))
        A[0, 0] = float((W * dc * dc).sum())
        A[0, 1:] = A[1:, 0] = np.einsum("inc,nc->i", xc, W * dc)
        A[1:, 1:] = gram + np.diag(self.prior_precision)
        g = np.empty(k + 1)
        g[0] = float((W * rc * dc).sum())
        g[1:] = np.einsum("inc,nc->i", xc, W * rc) + self.prior_precision * self.prior_mean
        A[0, 0] = max(A[0, 0], 1e-300)
        c = self.shift_center
        bounds = np.vstack([[c - MAX_SHIFT, c + MAX_SHIFT], self.regressor_bounds])
        coef = bounded_solve(A, g, bounds)
        delta, a = float(coef[0]), coef[1:]
        fitted = delta * rate + np.einsum("i,inc->nc", a, self.regressors)
        b = (W * (r - fitted)).sum(0) / sw
        return b, delta, a

    def _nuisance_part(self, rate, nuisance):
        b, delta, a = nuisance
        part = b[None, :] + delta * rate
        if len(a):
            part = part + np.einsum("i,inc->nc", a, self.regressors)
        return part

    def residual(self, sim, nuisance=None, rate=None):
        """Measured minus simulated minus nuisance (SI), NaN where unmeasured."""
        sim = np.asarray(sim, float)
        rate = np.gradient(sim, self.dt, axis=0) if rate is None else rate
        nuisance = self.nuisance(sim, rate, "all") if nuisance is None else nuisance
        return self.measured - sim - self._nuisance_part(rate, nuisance)

    def evaluate(self, sim):
        """chi2 of one simulation (n, c): on all data and fold by fold.

        Returns
        -------
        dict
            ``full`` (nuisance fitted on all), ``nuisance`` ((b, delta, a)
            on all), and ``AA``, ``AB``, ``BB``, ``BA``: chi2 on the second
            fold with the nuisance fitted on the first.
        """
        sim = np.asarray(sim, float)
        rate = np.gradient(sim, self.dt, axis=0)
        out = {}
        for fit in ("all", "A", "B"):
            nuisance = self.nuisance(sim, rate, fit)
            r = self.m0 - sim - self._nuisance_part(rate, nuisance)
            sq = self.W * r * r
            if fit == "all":
                out["full"] = float(sq.sum())
                out["nuisance"] = nuisance
                continue
            for ev in ("A", "B"):
                out[fit + ev] = float(sq[self.folds[ev]].sum())
        return out

    def held_out_residual(self, sim_a, sim_b):
        """Each sample's held-out residual (n, c, SI; 0 where unmeasured): fold B's with the fit on A (``sim_a``),
        fold A's with the fit on B. ``sum W r^2`` of it is ``evaluate``'s ``AB`` of ``sim_a`` plus ``BA`` of
        ``sim_b``: a candidate's held-out score."""
        out = np.zeros(self.measured.shape)
        for sim, fit, held in ((sim_a, "A", "B"), (sim_b, "B", "A")):
            sim = np.asarray(sim, float)
            rate = np.gradient(sim, self.dt, axis=0)
            r = self.m0 - sim - self._nuisance_part(rate, self.nuisance(sim, rate, fit))
            mask = self.folds[held]
            out[mask] = np.where(self.valid, r, 0.0)[mask]
        return out


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


def null_threshold(problem, residual, signatures, seed=0, n_surrogates=NULL_SURROGATES):
    """What noise alone gives: the NULL_QUANTILE of the best held-out improvement over candidates.

    Parameters
    ----------
    problem : Problem
    residual : ndarray (n, c)
        The best model's residual (SI), NaN where unmeasured; its spectrum
        and cross-channel correlation make the surrogates.
    signatures : list of ndarray (n, c)
        Each candidate's fitted minus nominal simulation (SI).
    seed : int

    Returns
    -------
    threshold : float
        In chi2 units, at least MIN_IMPROVEMENT.
    quantile : float
        The surrogate quantile itself.
    """
    if not signatures:
        return MIN_IMPROVEMENT, 0.0
    z = _weighted_signal(problem, residual)
    g = np.stack([_weighted_signal(problem, s) for s in signatures])  # (k, n, c)
    A, B = problem.folds["A"], problem.folds["B"]
    gAA = (g[:, A] ** 2).sum(axis=(1, 2))
    gBB = (g[:, B] ** 2).sum(axis=(1, 2))
    rng = np.random.default_rng(seed)
    chol = _spectral_factor(z)
    n_t = z.shape[0]
    best = np.empty(n_surrogates)
    for k in range(n_surrogates):
        n = surrogate(chol, n_t, rng)
        gnA = np.einsum("knc,nc->k", g[:, A], n[A])
        gnB = np.einsum("knc,nc->k", g[:, B], n[B])
        aA = np.maximum(gnA / np.maximum(gAA, 1e-300), 0.0)
        aB = np.maximum(gnB / np.maximum(gBB, 1e-300), 0.0)
        d = (2 * aA * gnB - aA**2 * gBB) + (2 * aB * gnA - aB**2 * gAA)
        best[k] = d.max()
    q = float(np.quantile(best, NULL_QUANTILE))
    return max(q, MIN_IMPROVEMENT), q


def surrogate(chol, n_t, rng):
    """One Gaussian surrogate (n_t, c) with the cross-spectrum whose Cholesky factors are ``chol``
    (``_spectral_factor``)."""
    xi = (rng.normal(size=chol.shape[:2]) + 1j * rng.normal(size=chol.shape[:2])) / math.sqrt(2.0)
    xi[0] = rng.normal(size=chol.shape[1])  # the mean and (even n) Nyquist terms are real
    if n_t % 2 == 0:
        xi[-1] = rng.normal(size=chol.shape[1])
    return np.fft.irfft(np.einsum("fij,fj->fi", chol, xi), n_t, axis=0)


def _spectral_factor(z):
    """Cholesky factors of the smoothed cross-spectral matrix of z's columns, (freqs, c, c).

    The raw periodogram of one record scatters like chi^2 with two degrees
    of freedom at every frequency; surrogates that kept it exactly (plain
    phase randomisation) would carry that scatter as spurious correlation
    between the folds. Averaging over ``SPECTRUM_SMOOTH`` neighbouring
    frequencies on either side gives a spectrum estimate to draw Gaussian
    surrogates from.
    """
    from scipy.ndimage import uniform_filter1d

    spec = np.fft.rfft(z, axis=0)
    cross = spec[:, :, None] * spec.conj()[:, None, :]
    size = 2 * SPECTRUM_SMOOTH + 1
    cross = uniform_filter1d(cross.real, size, axis=0, mode="reflect") + 1j * uniform_filter1d(
        cross.imag, size, axis=0, mode="reflect")
    ridge = 1e-9 * max(float(np.mean(np.abs(np.einsum("fii->fi", cross)))), 1e-300)
    cross = cross + ridge * np.eye(z.shape[1])[None]
    return np.linalg.cholesky(cross)


def signature_match(problem, nominal_residual, signature):
    """Cosine between a candidate's signature and the nominal model's mismatch (weighted)."""
    z = _weighted_signal(problem, nominal_residual)
    g = _weighted_signal(problem, signature)
    den = math.sqrt(float((z * z).sum()) * float((g * g).sum()))
    return float((z * g).sum()) / den if den > 0 else 0.0
