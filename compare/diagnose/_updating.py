"""Model updating before blame, and the model's own error budget.

A real rig is never its nominal model. Before any mechanism is blamed, the
diagnosis updates the nominal parameters a lab knows only approximately
(the rig file's ``[tolerances]``, ``simulate._tolerances``) to the
recording, and measures how far the nominal model is from its own
converged solution on the recording's maneuver (``docs/diagnosis.md``).

Updating
--------
Each parameter ``k`` moves by a coordinate ``x_k`` (ln p for masses,
stiffness and damping; metres for positions), with the lab's belief
``x_k ~ N(0, tau_k^2)`` as prior. Sensitivities come first: one simulation
per parameter, a finite difference over ``FD_FRACTION`` of its tolerance,
in parallel; a parameter whose one-tolerance change moves the weighted
residual by less than ``SCREEN`` stays nominal and is reported not
identifiable, and so does one whose difference taken the other way
disagrees with it (``ROUGH``: the column is the integration's scatter, not
a derivative). The active coordinates are then fitted by scipy's bounded
trust-region least squares (``trf``, scaled by the tolerances, no parameter
beyond ``BOUND_TOLERANCES``) on the chi2 of ``_hypotheses`` plus the
priors, with our own parallel finite-difference Jacobian renewed at every
step. The nuisance - one constant offset per channel (marker placement and
calibration: prior ``OFFSET_PRIOR``, so a static offset goes to the
parameters when they can make it within tolerance), the clock shift and the
model-error amplitudes (below) - is linear and is projected out at every
evaluation (variable projection). It stops when the next Gauss-Newton
step promises less than the number of parameters it moves times the
residual's dispersion (what they would gain on the residual's own
scatter), or after ``MAX_JACOBIANS``. Uncertainties come from the
posterior covariance taken robustly (``robust_covariance``: a sandwich
whose middle is the residual's own scatter, summed over blocks as long as
its autocorrelation time), so that a residual the model leaves structured
- a real rig the model does not describe - widens them where a white one at
the noise level leaves the plain posterior; a parameter is *identifiable*
when the recording at least halves its prior standard deviation.

Step schedule
-------------
The integration's step follows the rig (``simulate._tracked``): it is cut
as ropes shorten, and a record interval where a rope element turns slack
or taut is done again at a third of the step. Two runs a small parameter
change apart then step differently wherever an element hangs at the slack
point (the hook-block crane's slings), and their difference holds those
two step sequences' scatter beside the parameter's effect. So every run
of a fit steps on one schedule (``simulate``'s ``schedule``): a finite
difference on the schedule of the point it differentiates, a trial point
on the best point's - run again on its own where a rope turned slack at a
step the schedule had not refined, so that no point a fit may move to is
integrated less carefully than a plain run - except where the rig
stiffens beyond the schedule's margin. (The real slung-load flights'
differences disagreed for another reason: the drone's track, the model's
input, kicked the rope slack at every sample until it was smoothed,
``reconstruct.smoothed_track``.)

Model error
-----------
The nominal model is simulated once more at the next finer discretization
and once with half the time step. Their differences from the model are
the directions in which its numerical error lies on this maneuver; they
are reported (RMS per channel in noise units) and fitted as nuisance
regressors with every candidate, each amplitude within what Richardson
extrapolation allows (``ErrorDirections``), so a mismatch the finer model
also shows is never credited to missing physics, nor a parameter's change
to the model's error; a located mismatch within
``MODEL_ERROR_FACTOR`` times their size in its channel and window is
marked as the model's own error (``mark_model_error``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ...simulate import (
    DISCRETIZATION_LEVELS,
    SimulationError,
    StaticsError,
    make_mechanism,
    simulate,
)
from .._compare import channel_kind
from ._heterogeneity import between_trials, widened
from ._mass_scale import PROBE, gauge_covariance, is_pure_rescaling, scale_block, scale_direction
from ._hypotheses import _init, _pool, bounded_solve, channels_on
from ._scale import REFERENCE
from ._trials import apply_to_trials, joined_states, stack_trials, trial_contexts
from ._unresolved import combination_columns, unresolved_combinations

__all__ = ["OFFSET_PRIOR", "BOUND_TOLERANCES", "ErrorDirections", "update_model", "robust_covariance", "joint_refit",
           "rig_alone_channels", "resume_update",
           "model_error", "finer_discretization", "nuisance_correlation", "mark_model_error", "marginal_uncertainty"]

# What a constant offset between a recorded channel and the model may
# honestly be, with no parameter wrong (one standard deviation): marker
# placement on a body and the calibration's origin (m, rad, m).
OFFSET_PRIOR = {"position": 0.005, "angle": math.radians(1.0), "rope_length": 0.003}
# Offsets left after updating beyond these are a finding: no parameter
# within tolerance explains them (the old 10 mm / 2 deg gate, now applied
# after updating).
OFFSET_FINDING = {"position": 0.010, "angle": math.radians(2.0), "rope_length": 0.010}
# At most this many Jacobians (each one simulation per active parameter) per fit.
MAX_JACOBIANS = 8
# Updating stops (or does not start) once the Gauss-Newton step it would take
# next is predicted to lower chi2 by less than the number of parameters it
# moves times the residual's dispersion (chi2 / N, at least 1): what fitting
# that many parameters to the residual's own scatter gains on average. It
# replaced two stops on chi2's scale, not the candidates': at 5 % above
# chi2's noise expectation, and when a step gained under 1 % of the
# objective. On a recording of N = 15,000 samples either left several
# hundred chi2 - a candidate's threshold - for a mechanism to take up:
# bending damping named on no-physics pendulum recordings whose truth had
# the ball's mass centre a tolerance off (seed 81: 5 of 14).
# Finite-difference step, in tolerances. A simulation is a smooth function of
# the parameters (fixed step; statics from any guess agree to 1e-14 m), so a
# small step costs no accuracy; at 0.1 tolerance the forward difference's
# own error slowed the fit to a crawl along the valley where masses and the
# wire rope's stiffness trade (1.3 times the noise after 8 Jacobians on a
# recording of the model itself, masses at their bounds); at 0.01 it reached
# the noise in 7, every identifiable parameter within 0.2 tolerance.
FD_FRACTION = 0.01
# A parameter whose one-tolerance change moves the weighted residual by less
# than this (sqrt chi2: three noise-level sigmas in quadrature) is not updated.
SCREEN = 3.0
# A parameter's first finite difference is taken both ways too, over +h and -h (``one_sided_disagreement``:
# 2 |J+ - J-| / |J+ + J-|). For a smooth response the two differ by h times its curvature: 0.000-0.014 for the
# dragline's sixteen parameters on the dig, reels' stop and slack chains included. Where the integration's step
# count and slack refinements jump as the parameter moves, the column is scatter over h: two independent
# scatters read about 2, and a derivative under scatter of rho times its size 2 sqrt(2) rho / sqrt(4 + 2 rho^2).
# A column is used when the scatter's share of its information, rho^2, is at most SCATTER_SHARE: 0.1, ROUGH
# 0.44. (ROUGH was 1, rho 0.8, until the real slung-load flights' rope weight, 0.90 at 0.1 tolerance, was fitted
# to its bound there; the share was set after that, so it is judged on flights not seen with it.) The load's mass
# and the rope's material read 2.0-3.9 there at 0.01 and 0.1 tolerance alike, the rope's length 0.21 and 0.06 -
# through the drone's raw polyline track, which kicked the rope slack; smoothed, 0.011-0.27 (docs/real-recordings.md).
# A parameter whose column is rough at both steps is not fitted - its "information" would be that scatter - and
# is reported not identifiable.
SCATTER_SHARE = 0.1
ROUGH = 2.0 * math.sqrt(2.0 * SCATTER_SHARE) / math.sqrt(4.0 + 2.0 * SCATTER_SHARE)
# A parameter rough at FD_FRACTION is differenced again over this many times the step (0.1 tolerance, where the
# flights' rope length read 0.06 and the load's mass centre 0.08): a jump in the step count is the same size
# whatever the step, the parameter's own change ten times larger. It keeps that step in every later Jacobian.
WIDE_STEP = 10.0
MAX_SHIFT_PRIOR = 0.01  # s
# Two parameters whose posterior correlation exceeds this are reported as a
# pair the recording can move only together.
DEGENERATE = 0.9
# The model error's amplitude has a wide prior (its size is set by its
# bounds, ``ErrorDirections``; the prior only keeps the normal equations
# regular): the finer model's difference is its direction, and Richardson's
# factor depends on the order of convergence.
ERROR_AMPLITUDE_SD = 10.0
# A located mismatch no larger than this many times the finer model's
# difference there is the model's own error: the next finer level is not
# converged either, and with counts up by 1.3-2x the nominal model's distance
# from the converged solution is about twice its distance from the next
# level (Richardson, second order).
MODEL_ERROR_FACTOR = 2.0
# No parameter moves further than this many tolerances from nominal.
BOUND_TOLERANCES = 3.0
# Identifiable: the recording shrinks the prior standard deviation at least this much.
IDENTIFIABLE_RATIO = 0.5
# A batch's length in the residual's autocorrelation times (``robust_covariance``). Batch means read a
# correlated residual's variance low by about one correlation length per batch: on AR(1) errors (phi 0.8,
# integrated time 9 samples, tests/test_robust_covariance.py) batches of one time read the spread of the
# estimates over 300 draws 25-28 % low, of four 9-13 % low; the plain posterior reads it a third.
BATCH_TIMES = 4.0


class _Run(NamedTuple):
    """What ``_rig_job`` returns: the channels (n, c), the trials' equilibria and step schedules (None: failed)."""

    sim: np.ndarray | None
    state: object
    schedules: tuple | None


def _rig_job(coords, discretization=None, dt_factor=None, guess=None, schedules=None, accurate=False):
    """The rig with its parameters at ``coords``: a ``_Run``, its channels None when the simulation fails.

    ``schedules``: each trial's step schedule (``SimulationResult.schedule``)
    to step on, at the model's own discretization and step (the module's
    *Step schedule*). ``accurate``: a trial whose rope turned slack where
    the schedule had not refined is run again on its own schedule (a point
    a fit may move to, not a finite difference). The ``_Run``'s schedules
    are those its runs took: what a finite difference at it steps on.
    """
    from ._hypotheses import _CTX as ctx

    physics = list(ctx.get("base_physics", ()))
    joint = ctx.get("joint_mechanism")
    if joint is not None:
        # The last coordinate is the mechanism's ln value about its first fit (``joint_refit``).
        name, main, value0 = joint
        physics.append(make_mechanism(name, **{main: value0 * math.exp(coords[-1])}))
        coords = coords[:-1]
    rig, maneuvers = apply_to_trials(ctx, ctx["parameters"], coords)
    dt = None
    if dt_factor is not None:
        dt = ctx["nominal_dt"] * dt_factor
    trials = trial_contexts(dict(ctx, maneuver=maneuvers), guess)
    if schedules is None or discretization is not None or dt is not None:
        schedules = [None] * len(trials)
    sims, states, taken = [], [], []
    for trial, schedule in zip(trials, schedules):
        def run(steps):
            return simulate(rig, trial["maneuver"], discretization or ctx["discretization"],
                            physics, duration=trial["duration"], rate_hz=ctx["rate_hz"],
                            dt=dt, statics_guess=trial["initial_state"] if discretization is None else None,
                            schedule=steps)

        try:
            res = run(schedule)
            if accurate and res.unrefined_slack:
                res = run(None)
        except (SimulationError, StaticsError, FloatingPointError):
            return _Run(None, None, None)
        sims.append(channels_on(res, trial))
        states.append(res.states[0])
        taken.append(res.schedule)
    return _Run(stack_trials(ctx, sims), joined_states(ctx, states), tuple(taken))


class ErrorDirections(list):
    """The model's own numerical error directions (``model_error``), each with the most its amplitude can be.

    ``bounds[i]``: direction ``i`` is the next finer model minus the
    nominal one; the nominal model's distance from the converged solution
    is ``R`` times that, ``R = 1 / (1 - (h' / h)^p)`` (Richardson) for a
    step ``h`` refined to ``h'`` at convergence order ``p``. At first order,
    the slowest any of the model's schemes converges, ``R`` is largest:
    ``n' / (n' - n)`` for a rope's particle count ``n`` raised to ``n'``
    (the largest over the ropes), 2 for the halved time step. The
    amplitude lies in ``[0, R]`` - towards the finer model, since the
    levels converge one way. Unbounded, a direction that looks like a
    parameter's change absorbs any amount of it: on a pendulum whose
    discretization error is a shift of its frequency, as the ball's mass
    centre is, amplitude 23 took up four fifths of a tolerance's change,
    which the updating then missed.
    """

    def __init__(self, directions=(), bounds=()):
        super().__init__(directions)
        self.bounds = [float(b) for b in bounds]

    def amplitude_bounds(self):
        """(k, 2): each amplitude's low and high."""
        return np.array([[0.0, b] for b in self.bounds]).reshape(len(self), 2)


def richardson_bound(rig, discretization, finer):
    """First-order Richardson factor of a refinement from ``discretization`` to ``finer`` (see
    ``ErrorDirections``); 1 when no count changes."""
    coarse, fine = rig.particle_counts(discretization), rig.particle_counts(finer)
    ratios = [fine[name] / (fine[name] - n) for name, n in coarse.items() if fine.get(name, n) > n]
    return max(ratios, default=1.0)


def finer_discretization(rig, discretization):
    """The next finer named level, or every count up by half for a custom one."""
    if isinstance(discretization, str) and discretization in DISCRETIZATION_LEVELS:
        i = DISCRETIZATION_LEVELS.index(discretization)
        if i + 1 < len(DISCRETIZATION_LEVELS):
            return DISCRETIZATION_LEVELS[i + 1]
    counts = rig.particle_counts(discretization)
    return {name: int(math.ceil(1.5 * n)) for name, n in counts.items()}


def model_error(problem, ctx, nominal_sim, workers=2):
    """The nominal model's numerical error on this maneuver.

    Parameters
    ----------
    problem : Problem
    ctx : dict
        Simulation context (``rig``, ``maneuver``, ``discretization``,
        ``duration``, ``rate_hz``, ``time``, ``channels``, ``nominal_dt``).
    nominal_sim : ndarray (n, c)

    Returns
    -------
    directions : list of ndarray (n, c)
        Finer minus nominal simulation, for each estimate that ran.
    block : dict
        JSON-ready: per source (``discretization``, ``time_step``), what it
        compared, its RMS per channel (SI and in noise units) and its chi2
        weight (sum of weighted squares: what a candidate could gain by
        absorbing it).
    """
    _init(ctx)
    finer = finer_discretization(ctx["rig"], ctx["discretization"])
    jobs = [(np.zeros(len(ctx["parameters"])), finer, None), (np.zeros(len(ctx["parameters"])), None, 0.5)]
    pool = _pool(workers, ctx, at_most=len(jobs))
    try:
        results = pool.map(_rig_job, jobs)
    finally:
        pool.close()
    directions, bounds, block = [], [], {}
    described = {"discretization": {"compared": [_level_name(ctx["discretization"]), _level_name(finer)],
                                    "amplitude_bound": richardson_bound(ctx["rig"], ctx["discretization"], finer)},
                 "time_step": {"compared": [f"{ctx['nominal_dt']:.3g} s", f"{0.5 * ctx['nominal_dt']:.3g} s"],
                               "amplitude_bound": 2.0}}
    for (name, entry), (sim, _, _) in zip(described.items(), results):
        if sim is None:
            entry["status"] = "failed"
            block[name] = entry
            continue
        d = sim - nominal_sim
        weighted = np.where(problem.valid, d, 0.0) ** 2 * problem.W
        entry.update(status="ok", chi2=float(weighted.sum()), channels={
            ch: {"rms": float(np.sqrt(np.mean(d[:, j] ** 2))),
                 "rms_noise": float(np.sqrt(np.mean(d[:, j] ** 2)) / problem.sigma[j])}
            for j, ch in enumerate(ctx["channels"])})
        directions.append(d)
        bounds.append(entry["amplitude_bound"])
        block[name] = entry
    block["method"] = ("the nominal model against itself at the next finer discretization and at half the time "
                       "step, on the recording's maneuver; both differences are fitted as nuisance directions with "
                       "every candidate, each amplitude between 0 and its first-order Richardson factor")
    return ErrorDirections(directions, bounds), block


def _offset_prior(ctx):
    """Each channel's offset prior (SI) at the machine's scale (``ctx["scale"]``; default the dragline's)."""
    scale = ctx.get("scale", REFERENCE)
    return np.array([scale.floor(OFFSET_PRIOR, channel_kind(ch), 0.005) for ch in ctx["channels"]])


def mark_model_error(entries, time, directions, channels, factor=MODEL_ERROR_FACTOR, scale=REFERENCE):
    """Mark the located mismatch entries that the model's own numerical error could make.

    Parameters
    ----------
    entries : list of dict
        ``_locate.locate_mismatch`` entries (``channel``, ``t_start``,
        ``t_end``, ``rms``) of a residual.
    time : ndarray (n,)
    directions : sequence of ndarray (n, c)
        ``model_error``'s differences.
    channels : sequence of str
        The columns' names.
    factor : float
    scale : MachineScale
        The machine's: its low-pass (default: the dragline's).

    Returns
    -------
    list of dict
        Copies with ``model_error_rms`` (the largest direction's low-passed
        RMS in that channel and window, its mean over the record removed as
        the offsets remove it) and ``within_model_error`` (the entry's RMS
        is at most ``factor`` times it).
    """
    from ._locate import LOWPASS_S, low_pass

    t = np.asarray(time, float)
    width = scale.lowpass_width(LOWPASS_S, float(t[1] - t[0]))
    smooth = [low_pass(d - np.nanmean(d, axis=0), width) for d in directions]
    out = []
    for e in entries:
        sel = (t >= e["t_start"] - 1e-9) & (t <= e["t_end"] + 1e-9)
        j = list(channels).index(e["channel"])
        budget = max((float(np.sqrt(np.nanmean(s[sel, j] ** 2))) for s in smooth), default=0.0)
        out.append(dict(e, model_error_rms=budget, within_model_error=bool(e["rms"] <= factor * budget)))
    return out


def _level_name(discretization):
    return discretization if isinstance(discretization, str) else ",".join(f"{k}={v}" for k, v in discretization.items())


def _design(problem, sim, sensitivities):
    """Weighted design matrix: the sensitivities' columns, one offset per channel, the clock shift.

    A channel without a free offset (``Problem.offset_free``) keeps its
    column, all zeros: its offset stays at its prior's mean, 0, and the
    nuisance vector's layout is the same for every recording.
    """
    sw = np.sqrt(problem.W)
    n, c = sim.shape
    rate = np.gradient(sim, problem.dt, axis=0)
    cols = [np.where(problem.valid, s, 0.0) * sw for s in sensitivities]
    for j in range(c):
        e = np.zeros((n, c))
        if problem.offset_free[j]:
            e[:, j] = sw[:, j]
        cols.append(e)
    cols.append(np.where(problem.valid, rate, 0.0) * sw)
    return np.stack([col.ravel() for col in cols], axis=1)


def _solve(problem, X, prior_var, prior_mean, residual, bounds=None):
    """Least squares X a = r with the prior N(prior_mean, prior_var), ``a`` within ``bounds`` (p, 2) if given.

    Returns
    -------
    a : ndarray
    H_inv : ndarray
        The inverse of the posterior's Hessian.
    """
    z = (np.where(problem.valid, residual, 0.0) * np.sqrt(problem.W)).ravel()
    H = X.T @ X + np.diag(1.0 / prior_var)
    g = X.T @ z + prior_mean / prior_var
    H_inv = np.linalg.inv(H)
    return (H_inv @ g if bounds is None else bounded_solve(H, g, bounds)), H_inv


def _nuisance_bounds(errs, c):
    """(e + c + 1, 2): the model error's amplitudes bounded (``ErrorDirections``), offsets and shift free."""
    free = np.tile([-np.inf, np.inf], (c + 1, 1))
    own = errs.amplitude_bounds() if isinstance(errs, ErrorDirections) else np.tile([-np.inf, np.inf], (len(errs), 1))
    return np.vstack([own.reshape(len(errs), 2), free])


def update_model(problem, ctx, nominal_sim, error_directions=(), workers=2, progress=None, start=None):
    """Update the rig's uncertain parameters to the recording, within their tolerances.

    Parameters
    ----------
    problem : Problem
        The recording (without regressors).
    ctx : dict
        Simulation context with ``parameters`` (the rig's ``tolerances``).
    nominal_sim : ndarray (n, c)
        The nominal model's channels.
    error_directions : sequence of ndarray (n, c)
        The model's own numerical error (``model_error``), fitted with free
        amplitudes beside the parameters so that no parameter is moved to
        mimic it.
    workers : int
    progress : callable, optional
    start : dict, optional
        An earlier result to resume from (its coordinates, sensitivities and
        screening), for instance with the model error estimated again at
        the rig it found.

    Returns
    -------
    dict
        ``coords`` (k,), ``sim`` (n, c) the updated model's channels,
        ``initial_state`` its equilibrium, ``rig`` and ``maneuver`` updated,
        ``sensitivities`` (list of (n, c) per unit coordinate, at the
        updated point for the active parameters), ``covariance`` (k, k) of
        the coordinates, ``offsets`` (c,) left, ``shift`` (s) the clock shift
        fitted with them, ``block`` (the JSON
        ``calibration`` block), ``n_simulations``.
    """
    note = progress or (lambda msg: None)
    params = list(ctx["parameters"])
    k, c = len(params), len(ctx["channels"])
    tol = np.array([p.tolerance for p in params])
    _init(ctx)
    pool = _pool(workers, ctx)
    try:
        if start is None:
            coords, sim, state, schedules = np.zeros(k), nominal_sim, ctx["initial_state"], ctx.get("schedules")
            sens, failed = _sensitivities(pool, coords, np.arange(k), tol, sim, state, [None] * k, schedules=schedules)
            n_sims = k
            # Sensitivities first: a parameter whose one-tolerance change moves
            # the weighted residual by less than SCREEN (chi2) is left nominal.
            strength = _strength(problem, sens, tol)
            moving = np.flatnonzero(strength >= SCREEN)
            rough, fd_scale, more = _smooth_differences(problem, pool, coords, moving, tol, sim, state, sens, schedules)
            n_sims += more
            strength = _strength(problem, sens, tol)  # a widened difference's column is its own
            active = np.array([i for i in moving if _smooth(rough, int(i))], int)
            note(f"sensitivities of {k} rig parameters done; {len(moving)} move the recording, "
                 f"{len(moving) - len(active)} of them not smoothly")
            scale, more = _scale_gauge(problem, pool, coords, params, tol, sim, state, sens, schedules)
            n_sims += more
            if scale is not None:
                active = active[active != scale["held"]]
                note(f"the rig's scale of mass and force is not observable: {params[scale['held']].name} held")
        else:
            coords, sim, state, sens = start["coords"], start["sim"], start["initial_state"], start["sensitivities"]
            schedules, scale = start.get("schedules"), start.get("scale")
            strength, active, failed = start["strength"], start["active"], start["failed"]
            rough, fd_scale = start.get("rough", {}), start.get("fd_scale", tol)
            n_sims = start["n_simulations"]
        offset_sd = _offset_prior(ctx)
        errs = error_directions if isinstance(error_directions, ErrorDirections) else list(error_directions)
        err_var = np.full(len(errs), ERROR_AMPLITUDE_SD**2)
        fit = _trust_region(problem, pool, _Fit(coords, sim, state, sens, schedules), active, tol, offset_sd, errs,
                            MAX_JACOBIANS, lambda m: note(f"updating: {m}"), fd_scale=fd_scale)
        coords, sim, state, sens, nuis = fit.coords, fit.sim, fit.state, fit.sens, fit.nuisance
        schedules = fit.schedules
        history = (start["block"]["iterations"] if start is not None else []) + fit.history
        failed = sorted(set(failed) | set(fit.failed))
        n_sims += fit.n_sims
    finally:
        pool.close()
    failed_names = [params[i].name for i in failed]
    X = _design(problem, sim, [sens[i] for i in active] + errs)
    prior_var = np.r_[tol[active] ** 2, err_var, offset_sd**2, MAX_SHIFT_PRIOR**2]
    _, H_inv = _solve(problem, X, prior_var, np.zeros(len(active) + len(errs) + c + 1), problem.measured - sim)
    # The residual the fit leaves, its nuisance fitted: the sandwich's middle.
    z = np.where(problem.valid, problem.measured - sim - _apply(_design(problem, sim, errs), nuis, problem, sim.shape),
                 0.0) * np.sqrt(problem.W)
    robust = robust_covariance(X, z, H_inv, 1.0 / prior_var)
    spread = between_trials(X, z, np.r_[coords[active], nuis], 1.0 / prior_var, ctx["channels"], len(active),
                            robust_covariance, bound=BOUND_TOLERANCES * tol[active])
    p_act = len(active)
    # A trial's own coordinates (its start) are not shared: the trials' disagreement does not widen them.
    shared = np.array([not params[i].of_a_trial for i in active], bool)
    pooled = np.where(shared, spread["pooled_sd"], 0.0) if spread is not None else 0.0
    robust[:p_act, :p_act] = widened(robust[:p_act, :p_act], pooled, prior_sd=tol[active])
    cov = np.diag(tol**2).astype(float)  # a screened-out parameter keeps its prior
    idx = np.ix_(active, active)
    cov[idx] = robust[: len(active), : len(active)]
    if scale is not None:
        cov = gauge_covariance(cov, scale["direction"], scale["held"], tol)
    information = np.ones(k)  # posterior / prior sd
    information[active] = np.sqrt(np.clip(np.diag(cov)[active], 0.0, None)) / tol[active]
    rig, maneuver = apply_to_trials(ctx, params, coords)
    offsets = nuis[len(errs):len(errs) + c]
    block = _calibration_block(params, coords, cov, information, strength, offsets, ctx, history,
                               failed_names, rough, fd_scale / tol)
    if spread is not None:
        block["between_trials"] = _spread_block(params, coords, active, spread)
    block["unobservable_scale"] = None if scale is None else scale_block(params, scale["direction"], scale["held"],
                                                                          scale["response_ratio"])
    geometry = np.asarray(combination_columns([params[i] for i in active]), int)
    block["unresolved_combinations"] = unresolved_combinations(
        X, prior_var, geometry, tol[active][geometry], [params[active[j]].name for j in geometry])
    return {"coords": coords, "sim": sim, "initial_state": state, "schedules": schedules, "rig": rig,
            "maneuver": maneuver,
            "sensitivities": sens, "covariance": cov, "offsets": offsets, "shift": float(nuis[-1]), "block": block,
            "n_simulations": n_sims,
            "active": active, "strength": strength, "failed": failed, "rough": rough, "fd_scale": fd_scale,
            "scale": scale}


def joint_refit(problem, ctx, update, mechanism, error_directions=(), workers=2, progress=None, value_range=None):
    """A candidate and the rig parameters refitted together, nonlinearly.

    Updating ran before any mechanism, so with a real mechanism at work the
    parameters took up what they could of its effect (material damping
    absorbs a friction's decay; masses and the boom point drift to their
    bounds). With the mechanism in every simulation, the trust-region fit
    starts again from the nominal rig, the mechanism's main parameter (its
    ln value, no prior, anywhere in ``joint_value_bounds``) one more
    coordinate beside the parameters, the sensitivities recomputed at every
    step; from the updated rig as well when the fit from nominal ends above
    the updated rig's objective (with the mechanism or without it: adding a
    mechanism can only lower it, so that fit has not converged), and the
    lower of the two is kept. From the updated rig alone (the lower start)
    the fit walked back slowly along the valley where the parameters had
    compensated the mechanism: sheave inertias 9-18 % low at 1.0-1.6 times
    the objective the nominal start reached (benchmark seed 96); a spurious
    candidate, which the updated rig already fits, ends lower from there (a
    no-physics recording's bending damping: 64,900 from the updated rig,
    67,400 from nominal). Fitting the value after the parameters instead (a
    Brent search on the rig they reached) left the parameters where they
    had compensated the first fit's value: on a
    gantry crane with air drag cd 0.9, fitted at 0.71 on the updated rig,
    the masses went to their bounds and the fit stayed 1.2 times the
    objective at the truth.

    Parameters
    ----------
    problem : Problem
        The recording (without regressors).
    ctx : dict
        The nominal simulation context (``parameters``: the tolerances).
    update : dict
        ``update_model``'s result.
    mechanism : Mechanism
        The candidate at its fitted value.
    error_directions : sequence of ndarray (n, c)
    workers : int
    progress : callable, optional
    value_range : (float, float), optional
        Where the main parameter may go (the candidate's searched range).

    Returns
    -------
    dict or None
        ``coords``, ``mechanism`` (refitted), ``sim`` (n, c), ``rig``,
        ``maneuver``, ``initial_state``, ``n_simulations``, ``history``,
        ``offsets`` (channel -> the constant offset left, with its prior);
        None when the mechanism's simulation fails.
    """
    note = progress or (lambda msg: None)
    params = list(ctx["parameters"])
    k = len(params)
    main = _main_of(mechanism)
    value0 = float(mechanism.parameters[main])
    tol = np.r_[[p.tolerance for p in params], math.inf]  # the mechanism's coordinate has no prior
    scale = np.r_[tol[:k], 1.0]
    value_lo, value_hi = joint_value_bounds(value0, value_range)
    bounds = (np.r_[-BOUND_TOLERANCES * tol[:k], value_lo - math.log(value0)],
              np.r_[BOUND_TOLERANCES * tol[:k], value_hi - math.log(value0)])
    active = np.r_[update["active"], k].astype(int)
    fd = np.r_[update.get("fd_scale", tol[:k]), 1.0]
    errs = error_directions if isinstance(error_directions, ErrorDirections) else list(error_directions)
    offset_sd = _offset_prior(ctx)
    job_ctx = dict(ctx, joint_mechanism=(mechanism.name, main, value0))
    _init(job_ctx)
    pool = _pool(workers, job_ctx)
    try:
        firsts = (np.zeros(k + 1), np.r_[update["coords"], 0.0])
        plans = (ctx.get("schedules"), update.get("schedules"))
        starts = pool.map(_rig_job, [(firsts[0], None, None, ctx["initial_state"], plans[0], True),
                                     (firsts[1], None, None, update["initial_state"], plans[1], True)])
        n_sims = 2
        options = [(_objective_at(problem, sim, x, tol, offset_sd, errs)[0], x, sim, st, plan, label)
                   for x, (sim, st, plan), label in zip(firsts, starts, ("nominal", "updated"))
                   if sim is not None]
        # Adding a mechanism can only lower the objective: a fit from nominal that ends above the updated rig
        # (with the mechanism or without it) has not converged, and the updated start is fitted too.
        updated_objective = min([o[0] for o in options if o[5] == "updated"] + [_update_objective(update)])
        fits = []
        for _, coords, sim, state, plan, label in options:
            if fits and fits[-1].objective <= updated_objective:
                break
            sens, _ = _sensitivities(pool, coords, active, fd, sim, state, [*update["sensitivities"], None],
                                     schedules=plan)
            n_sims += len(active)
            fit = _trust_region(problem, pool, _Fit(coords, sim, state, sens, plan), active, tol, offset_sd, errs,
                                MAX_JACOBIANS, lambda m: note(f"joint refit with {mechanism.name}: {m}"),
                                final_jacobian=False, scale=scale, bounds=bounds, fd_scale=fd)
            n_sims += fit.n_sims
            if fit.nuisance is not None:  # else the start, moved inside the value's bounds, could not be simulated
                fit.history[0]["start"] = label
                fits.append(fit)
    finally:
        pool.close()
    if not fits:
        return None
    fit = min(fits, key=lambda f: f.objective)
    coords, state = fit.coords[:k], fit.state
    value = value0 * math.exp(float(fit.coords[k]))
    rig, maneuver = apply_to_trials(ctx, params, coords)
    history = fit.history + [{"step": mechanism.name, "value": value, "objective": fit.objective}]
    nuisance = fit.nuisance
    offsets = dict(zip(ctx["channels"], map(float, nuisance[len(errs):len(errs) + len(ctx["channels"])])))
    return {"coords": coords, "mechanism": make_mechanism(mechanism.name, **{main: value}), "sim": fit.sim,
            "rig": rig, "maneuver": maneuver, "initial_state": state, "schedules": fit.schedules,
            "n_simulations": n_sims, "history": history, "offsets": offsets}


def _update_objective(update):
    """The objective (chi2 plus priors) the updating ended at: its last iteration's."""
    iterations = update.get("block", {}).get("iterations") or [{}]
    return float(iterations[-1].get("objective", math.inf))


def rig_alone_channels(ctx, joint):
    """The channels of a joint refit's rig with its mechanism taken out (n, c), or None when that fails.

    The joint refit moves the parameters on from where updating stopped,
    with the mechanism's help; the rig it reaches without the mechanism is
    what the parameters alone explain there (``_steps.credit_at_joint_rig``).
    """
    _init(dict(ctx, joint_mechanism=None))
    return _rig_job(np.asarray(joint["coords"], float), None, None, joint["initial_state"], joint.get("schedules"),
                    True).sim


def resume_update(problem, ctx, nominal_sim, update, joint, error_directions=(), workers=2, progress=None):
    """Updating taken up again from a joint refit's rig with its mechanism out, where that rig fits better.

    A joint refit moves the parameters on with the mechanism's help; when
    the rig it reaches fits the recording better without the mechanism than
    the updated rig did, updating had stopped short (its Jacobian cap, or a
    predicted gain below its stop along a valley where masses and
    stiffness trade). From there, as ``update_rig`` does from the nominal
    rig: the model's own error estimated at that rig, its sensitivities
    taken there, and the trust region run again.

    Parameters
    ----------
    problem : Problem
        The recording (without regressors).
    ctx : dict
        The nominal simulation context.
    nominal_sim : ndarray (n, c)
    update : dict
        ``update_model``'s result.
    joint : dict
        ``joint_refit``'s result.
    error_directions : ErrorDirections
        The model's own error at the updated rig: fitted with both rigs when
        they are compared.
    workers : int
    progress : callable, optional

    Returns
    -------
    dict
        ``objective_updated`` and ``objective_joint_rig`` (chi2 with the
        priors), ``update`` (None when the joint rig without its mechanism
        cannot be simulated or fits no better), and with an update its
        ``error_directions`` and ``model_error`` block (two simulations:
        the caller counts them) and its ``n_simulations`` counting on from
        ``update``'s, the comparison's one simulation included.
    """
    note = progress or (lambda msg: None)
    params = list(ctx["parameters"])
    tol = np.array([p.tolerance for p in params])
    coords = np.asarray(joint["coords"], float)
    offset_sd = _offset_prior(ctx)
    _init(ctx)
    sim, state, schedules = _rig_job(coords, None, None, joint["initial_state"], joint.get("schedules"), True)
    here = _objective_at(problem, update["sim"], update["coords"], tol, offset_sd, error_directions)[0]
    there = math.inf if sim is None else _objective_at(problem, sim, coords, tol, offset_sd, error_directions)[0]
    out = {"objective_updated": here, "objective_joint_rig": there, "update": None}
    if not there < here:
        return out
    note(f"updating again from the joint rig (objective {here:.4g} -> {there:.4g} without the mechanism)")
    at_joint = dict(ctx, rig=joint["rig"], maneuver=joint["maneuver"], initial_state=state)
    directions, block = model_error(problem, at_joint, sim, workers=workers)
    block["rig"] = "joint rig without its mechanism"
    _init(ctx)
    pool = _pool(workers, ctx)
    try:
        sens, failed = _sensitivities(pool, coords, update["active"], update.get("fd_scale", tol), sim, state,
                                      update["sensitivities"], schedules=schedules)
    finally:
        pool.close()
    start = dict(update, coords=coords, sim=sim, initial_state=state, sensitivities=sens, schedules=schedules,
                 failed=sorted(set(update["failed"]) | set(failed)),
                 n_simulations=update["n_simulations"] + 1 + len(update["active"]))
    out.update(update=update_model(problem, ctx, nominal_sim, directions, workers=workers, progress=note,
                                   start=start),
               error_directions=directions, model_error=block)
    return out


def joint_value_bounds(value, value_range=None):
    """Search interval in ln p for a joint refit's main parameter: the candidate's searched range.

    No span about the first fit: that fit was made on the updated rig, whose
    parameters had taken up part of the mechanism's effect, so it is biased
    towards no mechanism by as much as the parameters could take up. A span
    of exp(+-0.4) about it held 10 of 18 sheave inertias of three benchmark
    seeds at its edge, 11-41 % under the truth (docs/diagnosis.md). Without
    a range (a caller's own candidate), ln p is free.
    """
    if value_range is None:
        return -math.inf, math.inf
    lo, hi = math.log(value_range[0]), math.log(value_range[1])
    x0 = math.log(value)
    return min(lo, x0), max(hi, x0, lo + 1e-9)


@dataclass
class _Fit:
    """Where a fit of the parameters stands."""

    coords: np.ndarray
    sim: np.ndarray
    state: np.ndarray
    sens: list
    # The trials' step schedules ``sim`` was run on (the module's *Step schedule*); None: each its own.
    schedules: tuple | None = None
    nuisance: np.ndarray | None = None
    objective: float = math.inf
    chi2: float = math.inf
    history: list = field(default_factory=list)
    failed: list = field(default_factory=list)
    n_sims: int = 0


def _trust_region(problem, pool, fit, active, tol, offset_sd, errs, max_jacobians, note, final_jacobian=True,
                  scale=None, bounds=None, fd_scale=None):
    """Bounded trust-region least squares on the active coordinates from ``fit``.

    scipy's ``least_squares`` (``trf``, ``x_scale`` the tolerances, so its
    trust region is measured in tolerances) on the weighted residual with the
    nuisance (model-error amplitudes, per-channel offsets, clock shift)
    projected out at every evaluation, and the priors as extra residual
    rows. Its Jacobian is ours: finite differences over ``FD_FRACTION``
    tolerances simulated in parallel, each from the equilibrium of the point
    it differentiates, projected the same way (the variable-projection
    Jacobian of Kaufman). A Gauss-Newton iteration without a trust region
    took full steps from the nominal rig to the bounds (the masses and the
    wire rope's stiffness move the statics together), where it stalled at
    1.3 times the noise on a recording of the model itself.

    A trial point is one simulation, which leaves the pool's other slots
    idle; they run the first finite differences of the Jacobian at that
    point meanwhile (statics from the best equilibrium so far, which they
    reach to 1e-14 m as from the trial's own), so an accepted step needs
    that many fewer simulations after it and a rejected one costs nothing
    that would not have idled. ``fit.sim`` is taken as the simulation at
    ``fit.coords``, not simulated again.

    The stops are applied here, where scipy's would come one Jacobian late
    (it differentiates at an accepted point before it looks at the gain):
    after ``max_jacobians``, or when the next Gauss-Newton step, predicted
    from the last Jacobian and the residual at the accepted point, would
    gain less than ``enough()`` (the fit does not start when the first one
    would). With ``final_jacobian``
    False (a caller that needs no sensitivities at the end: the joint
    refit), the Jacobian at the point where it stops is not computed.

    ``tol`` is each coordinate's prior standard deviation (inf: no prior);
    ``scale`` its size (finite differences, the trust region's scaling;
    ``tol`` by default) and ``bounds`` (lo, hi) its range, by default
    ``BOUND_TOLERANCES`` scales either side of nominal; ``fd_scale`` what
    the finite differences are a ``FD_FRACTION`` of (``scale`` by default;
    wider for a parameter whose response is rough, ``_smooth_differences``).
    """
    from scipy.optimize import least_squares

    base = fit.coords.copy()
    scale = tol if scale is None else scale
    fd = scale if fd_scale is None else fd_scale
    if bounds is None:
        bounds = (-BOUND_TOLERANCES * scale, BOUND_TOLERANCES * scale)
    lo, hi = bounds[0][active], bounds[1][active]
    cache = {fit.coords.tobytes(): _Run(fit.sim, fit.state, fit.schedules)}
    ahead = {}  # coords -> {parameter: its finite-difference simulation}, run beside the trial point
    spare = max(0, int(getattr(pool, "slots", 1)) - 1)
    best = {"objective": math.inf}
    jacobians = [0]
    # The stop decided at an accepted point (``by``: the gain rule or the cap), the step's predicted gain, trf's last J
    stop = {"by": None, "gain": None, "J": None}

    def full(xa):
        coords = base.copy()
        coords[active] = xa
        return coords

    def simulated(xa):
        coords = full(xa)
        key = coords.tobytes()
        if key not in cache:
            guess = best.get("state", fit.state)
            # Before the first Jacobian the sensitivities are given: nothing to run ahead.
            early = list(active[:spare]) if jacobians[0] > 0 else []
            plan = best.get("schedules", fit.schedules)
            out = pool.map(_rig_job, [(coords, None, None, guess, plan, True)] + [
                _difference_job(coords, i, fd, guess, schedules=plan) for i in early])
            cache[key] = out[0]
            ahead.clear()
            # differences run ahead on the plan are the point's only where it kept the plan
            kept = _same_schedules(out[0].schedules, plan)
            ahead[key] = {i: run.sim for i, run in zip(early, out[1:])} if kept else {}
            fit.n_sims += 1 + len(early)
        return coords, cache[key]

    n_rows = []
    residuals = {}

    def enough():
        """The least gain worth a step: the active parameters' count, in the residual's dispersion."""
        return len(active) * max(1.0, best["chi2"] / problem.n_weighted)

    def fun(xa):
        coords, (sim, state, taken) = simulated(xa)
        if sim is None:
            # A failed simulation: a step the trust region rejects (None only at the start).
            return np.full(n_rows[0], 1e6) if n_rows else None
        obj, chi2, nuis, _ = _objective_at(problem, sim, coords, tol, offset_sd, errs)
        if obj < best["objective"]:
            best.update(objective=obj, chi2=chi2, coords=coords, sim=sim, state=state, nuisance=nuis, schedules=taken)
        X = _design(problem, sim, errs)
        z = (np.where(problem.valid, problem.measured - sim, 0.0) * np.sqrt(problem.W)).ravel()
        r = np.r_[z - X @ nuis, _prior_rows(nuis, coords, tol, offset_sd, errs)]
        n_rows[:] = [len(r)]
        residuals[coords.tobytes()] = r
        return r

    def jac(xa):
        coords, (sim, state, taken) = simulated(xa)
        # trf asks for a Jacobian only at an accepted point: the next step's gain is predicted here from the
        # last Jacobian (the new one would cost its simulations).
        gain = predicted_gain(stop["J"], residuals[coords.tobytes()]) if stop["J"] is not None else None
        stop["gain"] = gain
        low = gain is not None and gain < enough()
        stop["by"] = "gain" if low else ("cap" if jacobians[0] >= max_jacobians - 1 else None)
        if stop["by"] is not None and not final_jacobian and stop["J"] is not None:
            return stop["J"]  # never used: the callback ends the fit before another step
        if jacobians[0] > 0:
            known = ahead.pop(coords.tobytes(), {})
            fit.sens, bad = _sensitivities(pool, coords, active, fd, sim, state, fit.sens, known, taken)
            fit.failed = sorted(set(fit.failed) | set(bad))
            fit.n_sims += len(active) - len(known)
        at_start = jacobians[0] == 0 and coords.tobytes() in start
        jacobians[0] += 1
        stop["J"] = start.pop(coords.tobytes()) if at_start else _projected_jacobian(
            problem, sim, coords, fit.sens, active, tol, offset_sd, errs)
        return stop["J"]

    def callback(intermediate_result):  # noqa: ARG001 (scipy passes the iterate)
        note(f"evaluation {fit.n_sims}, chi2 {best['chi2']:.4g}")
        if stop["by"] is not None:
            raise StopIteration

    # Strictly inside the bounds, as trf starts (a start on a bound would cost one more simulation).
    x0 = np.clip(fit.coords[active], lo + 1e-6 * scale[active], hi - 1e-6 * scale[active])
    if fun(x0) is None:
        return fit
    fit.history = [{"evaluations": fit.n_sims, "objective": best["objective"], "chi2": best["chi2"]}]
    start = {}  # the start's Jacobian (its sensitivities are given), which trf asks for first
    start_gain = 0.0
    if len(active):
        coords0, (sim0, _, _) = simulated(x0)
        start[coords0.tobytes()] = _projected_jacobian(problem, sim0, coords0, fit.sens, active, tol, offset_sd, errs)
        start_gain = predicted_gain(start[coords0.tobytes()], residuals[coords0.tobytes()])
    fit.history[0]["predicted_gain"] = start_gain
    if len(active) and start_gain >= enough():
        ended = least_squares(fun, x0, jac=jac, bounds=(lo, hi), x_scale=scale[active], method="trf",
                              ftol=1e-8, xtol=1e-3, gtol=1e-8, max_nfev=4 * max_jacobians, callback=callback)
        if stop["by"] is None:
            stop["by"] = "evaluations" if ended.status == 0 else "tolerance"  # trf's own stops
    else:
        stop.update(by="gain" if len(active) else "nothing to fit", gain=start_gain)
    fit.coords, fit.sim, fit.state, fit.schedules = best["coords"], best["sim"], best["state"], best["schedules"]
    fit.nuisance, fit.objective, fit.chi2 = best["nuisance"], best["objective"], best["chi2"]
    # Which stop ended the fit: the gain rule, the cap, or trf's own evaluation count ("evaluations") or
    # tolerances ("tolerance"); all but the first leave a fit that had more to gain than its stop asks.
    fit.history.append({"evaluations": fit.n_sims, "jacobians": jacobians[0], "objective": fit.objective,
                        "chi2": fit.chi2, "stopped_by": stop["by"], "predicted_gain": stop["gain"],
                        "least_gain": enough() if len(active) else None})
    return fit


def _projected_jacobian(problem, sim, coords, sens, active, tol, offset_sd, errs):
    """The residual's Jacobian in the active coordinates, the linear nuisance projected out (Kaufman), with
    the priors' rows: what ``_trust_region``'s residual vector is differentiated into."""
    k, c, e = len(coords), sim.shape[1], len(errs)
    X = _design(problem, sim, errs)
    _, _, nuis, _ = _objective_at(problem, sim, coords, tol, offset_sd, errs)
    # A model-error amplitude held at its bound does not follow the parameters: not projected out.
    bounds = _nuisance_bounds(errs, c)
    free = ~((nuis <= bounds[:, 0]) | (nuis >= bounds[:, 1]))
    prior_var = np.r_[np.full(e, ERROR_AMPLITUDE_SD**2), offset_sd**2, MAX_SHIFT_PRIOR**2]
    Xf = X[:, free]
    H_inv = np.linalg.inv(Xf.T @ Xf + np.diag(1.0 / prior_var[free]))
    sw = np.sqrt(problem.W)
    cols = []
    for i in active:
        v = (np.where(problem.valid, sens[i], 0.0) * sw).ravel()
        a = np.zeros(len(nuis))
        a[free] = H_inv @ (Xf.T @ v)
        unit = np.zeros(k)
        unit[i] = 1.0
        cols.append(np.r_[-(v - X @ a), _prior_rows(-a, unit, tol, offset_sd, errs)])
    return np.stack(cols, axis=1)


def predicted_gain(J, r):
    """How much a full Gauss-Newton step would lower ``|r|^2`` (the objective): ``r``'s part in ``J``'s span."""
    q, _ = np.linalg.qr(J)
    return float(np.sum((q.T @ r) ** 2))


def robust_covariance(X, z, H_inv, prior_precision, block=None):
    """The posterior covariance of a least-squares fit with its prior, robust to a structured residual.

    ``H_inv (M + P) H_inv`` (a sandwich, Huber-White with blocks: Newey and
    West's batch form), where ``M`` sums, over blocks of ``block``
    consecutive samples, the outer products of each block's score
    ``X_b' z_b``, and ``P`` is the prior's precision (the prior taken as
    stated). Where the residual is white at its stated noise, ``M``
    averages ``X'X`` and the result is the plain posterior ``H_inv``; where
    the model leaves a structure (decimetres against sub-millimetre noise
    on a real flight), ``M`` grows with it and so does the uncertainty, as
    the scatter of estimates over trials says it must.

    Parameters
    ----------
    X : ndarray (n * c, p)
        Weighted design (``_design``), rows in the residual's order.
    z : ndarray (n, c)
        Weighted residual at the fit (noise units; 0 where unmeasured).
    H_inv : ndarray (p, p)
        Inverse of ``X'X + diag(prior_precision)``.
    prior_precision : ndarray (p,)
    block : int, optional
        Samples per block; by default ``BATCH_TIMES`` times the residual's
        integrated autocorrelation time (``_hypotheses.autocorrelation_time``,
        weighted by each channel's share of chi2), rounded up.

    Returns
    -------
    ndarray (p, p)
    """
    from ._hypotheses import autocorrelation_time

    n, c = z.shape
    if block is None:
        tau = autocorrelation_time(z)
        block = int(math.ceil(BATCH_TIMES * float(np.average(tau, weights=(z**2).sum(0) + 1e-300))))
    scores = np.einsum("ncp,nc->np", X.reshape(n, c, -1), z)  # each sample's score, summed over channels
    edges = np.arange(0, n, max(1, int(block)))
    batches = np.add.reduceat(scores, edges, axis=0)
    middle = batches.T @ batches + np.diag(prior_precision)
    return H_inv @ middle @ H_inv


def _prior_rows(nuis, coords, tol, offset_sd, errs):
    """The priors as residual rows: model-error amplitudes, offsets, clock shift, coordinates."""
    e, c = len(errs), len(offset_sd)
    return np.r_[nuis[:e] / ERROR_AMPLITUDE_SD, nuis[e:e + c] / offset_sd, nuis[e + c:] / MAX_SHIFT_PRIOR,
                 coords / tol]


def _main_of(mechanism):
    from ...simulate import mechanism_type

    return mechanism_type(mechanism.name).main


def _same_schedules(a, b):
    """Whether two runs' step schedules (per trial, ``SimulationResult.schedule``) are the same."""
    if a is None or b is None:
        return a is b
    return len(a) == len(b) and all(
        (x is None and y is None) or (x is not None and y is not None and np.array_equal(x[0], y[0])
                                      and np.array_equal(x[1], y[1])) for x, y in zip(a, b))


def _scale_gauge(problem, pool, coords, params, tol, sim, state, sens, schedules):
    """``_mass_scale``'s probe: ``({"direction", "held", "response_ratio"}, 1)`` when the rig's masses and forces
    are all free and scale together unseen, ``(None, simulations run)`` otherwise."""
    direction = scale_direction(params)
    if len(direction) < 2:
        return None, 0
    x = coords.copy()
    x[direction] += PROBE
    probe = pool.map(_rig_job, [(x, None, None, state, schedules)])[0]
    if probe.sim is None:
        return None, 1
    sw = np.where(problem.valid, np.sqrt(problem.W), 0.0)
    response = float(np.linalg.norm(np.nan_to_num((probe.sim - sim) * sw)))
    parts = [PROBE * float(np.linalg.norm(np.nan_to_num(sens[i] * sw))) for i in direction]
    if not is_pure_rescaling(response, parts):
        return None, 1
    held = min(direction, key=lambda i: tol[i])
    return {"direction": direction, "held": int(held), "response_ratio": response / sum(parts)}, 1


def _difference_job(coords, i, tol, guess, sign=1.0, schedules=None):
    """The simulation job of parameter ``i``'s finite difference at ``coords`` (``sign`` -1: the backward one)."""
    x = coords.copy()
    x[i] += sign * FD_FRACTION * tol[i]
    return x, None, None, guess, schedules


def one_sided_disagreement(forward, backward):
    """``2 |J+ - J-| / |J+ + J-|`` of a column differenced forward and backward (weighted, any shape).

    About h times the response's relative curvature where it is smooth,
    about 2 where each is scatter; inf where they cancel, 0 for two zero columns.
    """
    forward, backward = np.asarray(forward, float), np.asarray(backward, float)
    apart, together = np.linalg.norm(forward - backward), np.linalg.norm(forward + backward)
    if apart == 0.0:
        return 0.0
    return float(2.0 * apart / together) if together > 0.0 else math.inf


def _smooth(rough, i):
    """Whether parameter ``i``'s differences agree (unchecked counts as smooth: ``_smooth_differences``)."""
    return not rough.get(i, 0.0) > ROUGH


def _strength(problem, sens, tol):
    """sqrt chi2 of each parameter's one-tolerance change, by its sensitivity."""
    return np.array([math.sqrt(float((problem.W * np.where(problem.valid, s_ * t, 0.0) ** 2).sum()))
                     for s_, t in zip(sens, tol)])


def _smooth_differences(problem, pool, coords, which, tol, sim, state, sens, schedules=None):
    """Each parameter of ``which`` differenced backward too; where the two ways disagree beyond ``ROUGH``, both
    again over ``WIDE_STEP`` times the step. ``sens`` takes the wider forward difference where that one is smooth.

    Returns
    -------
    rough : dict
        Parameter -> the ``one_sided_disagreement`` of the step it keeps
        (beyond ``ROUGH``: not smooth at either step); a parameter whose
        backward run fails is left out.
    fd_scale : ndarray (k,)
        What each parameter's finite differences are a ``FD_FRACTION`` of.
    n_sims : int
    """
    fd_scale = np.asarray(tol, float).copy()
    rough = _disagreement(problem, pool, coords, which, fd_scale, sim, state, {i: sens[i] for i in which}, schedules)
    n_sims = len(which)
    wide = [i for i, d in rough.items() if d > ROUGH]
    if wide:
        trial = fd_scale.copy()
        trial[wide] *= WIDE_STEP
        forward, _ = _sensitivities(pool, coords, wide, trial, sim, state, list(sens), schedules=schedules)
        again = _disagreement(problem, pool, coords, wide, trial, sim, state, {i: forward[i] for i in wide},
                              schedules)
        n_sims += 2 * len(wide)
        for i, d in again.items():
            rough[i] = d
            if d <= ROUGH:
                fd_scale[i], sens[i] = trial[i], forward[i]
    return rough, fd_scale, n_sims


def _disagreement(problem, pool, coords, which, fd_scale, sim, state, forward, schedules=None):
    """Parameter -> ``one_sided_disagreement`` of ``forward[i]`` and a backward difference run here."""
    sw = np.where(problem.valid, np.sqrt(problem.W), 0.0)
    out = {}
    jobs = [_difference_job(coords, i, fd_scale, state, -1.0, schedules) for i in which]
    for i, (s_, _, _) in zip(which, pool.map(_rig_job, jobs) if jobs else []):
        if s_ is not None:
            backward = (sim - s_) / (FD_FRACTION * fd_scale[i])
            out[int(i)] = one_sided_disagreement(np.nan_to_num(forward[i] * sw), np.nan_to_num(backward * sw))
    return out


def _sensitivities(pool, coords, which, tol, sim, state, previous, known=None, schedules=None):
    """Finite differences over FD_FRACTION tolerances, for the parameters ``which``, in parallel.

    ``known`` maps a parameter to its difference's simulation run already
    (``_trust_region`` runs some beside a trial point); the rest are run.
    """
    known = dict(known or {})
    run = [i for i in which if i not in known]
    jobs = [_difference_job(coords, i, tol, state, schedules=schedules) for i in run]
    for i, (s_, _, _) in zip(run, pool.map(_rig_job, jobs)):
        known[i] = s_
    out = list(previous)
    failed = []
    for i in which:
        s_ = known[i]
        if s_ is None:
            failed.append(int(i))
            out[i] = np.zeros_like(sim)
        else:
            out[i] = (s_ - sim) / (FD_FRACTION * tol[i])
    return out, failed


def _objective_at(problem, sim, coords, tol, offset_sd, errs):
    """Objective (chi2 plus priors) at a simulation; error amplitudes, offsets and shift fitted with their priors.

    Returns
    -------
    objective, chi2 : float
    a : ndarray
        Error amplitudes, offsets (c,), shift.
    H_inv : ndarray
    """
    c, e = sim.shape[1], len(errs)
    X = _design(problem, sim, errs)
    a, H_inv = _solve(problem, X, np.r_[np.full(e, ERROR_AMPLITUDE_SD**2), offset_sd**2, MAX_SHIFT_PRIOR**2],
                      np.zeros(e + c + 1), problem.measured - sim, bounds=_nuisance_bounds(errs, c))
    r = problem.measured - sim - _apply(X, a, problem, sim.shape)
    z = np.where(problem.valid, r, 0.0)
    chi2 = float((problem.W * z * z).sum())
    prior = float(((coords / tol) ** 2).sum() + ((a[e:e + c] / offset_sd) ** 2).sum())
    return chi2 + prior, chi2, a, H_inv


def marginal_uncertainty(problem, ctx, update, signature, sim, residual, error_directions=(), finer=None):
    """A mechanism's ln value's standard deviation with the rig's parameters free, and its correlations.

    The profile (``_hypotheses.profile_uncertainty``) holds the updated rig
    fixed, so a mechanism that trades with a parameter (friction's decay
    with material damping, a sheave's inertia with a cluster's mass) is
    stated as sharp as if nothing could imitate it. Here the linearized
    joint fit does not: the design holds the active parameters'
    sensitivities at the updated rig (with their priors), the mechanism's
    ``signature`` d channels / d ln p (no prior), the model error's
    directions and the offsets and clock shift (with theirs), and the
    covariance is ``robust_covariance``'s (the residual's own scatter, in
    blocks of its correlation time). Its mechanism entry is the marginal:
    the profile's variance divided by one minus the squared multiple
    correlation with everything else.

    Parameters
    ----------
    problem : Problem
        The recording without regressors (the updating's).
    ctx : dict
        The nominal context (``channels``, ``parameters``).
    update : dict
        ``update_model``'s result.
    signature : ndarray (n, c)
    sim, residual : ndarray (n, c)
        The candidate's channels and its residual (measured minus fitted, NaN where unmeasured).
    finer : ndarray (n, c), optional
        The candidate at its fitted value simulated at the next finer
        discretization. Its difference from ``sim``, fitted by the same
        design, moves ln p by ``discretization_shift``: what the model's
        own discretization does to this value (a law per element, as
        bending damping, acts differently on finer ropes). The truth is
        about ``MODEL_ERROR_FACTOR`` times as far as the next finer level
        (Richardson), so that many shifts join ``sd`` in quadrature.

    Returns
    -------
    dict or None
        ``sd`` (ln p), ``fixed_rig_sd`` (the same design without the
        parameters: what holding the rig fixed states),
        ``discretization_shift`` (ln p; None without ``finer``) and
        ``correlations`` ([{parameter, correlation}], largest first); None
        when the signature moves nothing (a singular design).
    """
    active = [int(i) for i in update["active"]]
    params = list(ctx["parameters"])
    errs = list(error_directions)
    tol = np.array([p.tolerance for p in params])
    offset_sd = _offset_prior(ctx)
    z = np.where(problem.valid, np.nan_to_num(residual), 0.0) * np.sqrt(problem.W)
    nuisance_precision = np.r_[np.full(len(errs), ERROR_AMPLITUDE_SD**-2.0), offset_sd**-2.0, MAX_SHIFT_PRIOR**-2.0]

    def design(columns, precision):
        X = _design(problem, sim, [*columns, signature, *errs])
        prior = np.r_[precision, 0.0, nuisance_precision]
        return X, prior, np.linalg.inv(X.T @ X + np.diag(prior))

    try:
        X, prior, H_inv = design([update["sensitivities"][i] for i in active], 1.0 / tol[active] ** 2)
        X0, prior0, H0_inv = design([], np.zeros(0))
    except np.linalg.LinAlgError:
        return None  # a signature that moves nothing: no value to state an uncertainty of
    cov = robust_covariance(X, z, H_inv, prior)
    fixed = robust_covariance(X0, z, H0_inv, prior0)
    k = len(active)
    shift = None
    if finer is not None:
        d = (np.where(problem.valid, finer - sim, 0.0) * np.sqrt(problem.W)).ravel()
        shift = float((H_inv @ (X.T @ d))[k])
    sd = math.sqrt(max(float(cov[k, k]), 0.0) + (0.0 if shift is None else (MODEL_ERROR_FACTOR * shift) ** 2))
    corr = [{"parameter": params[i].name, "correlation": float(cov[k, j] / math.sqrt(cov[k, k] * cov[j, j]))}
            for j, i in enumerate(active) if cov[j, j] > 0 and cov[k, k] > 0]
    corr.sort(key=lambda e: -abs(e["correlation"]))
    return {"sd": sd, "fixed_rig_sd": math.sqrt(max(float(fixed[0, 0]), 0.0)), "discretization_shift": shift,
            "correlations": corr}


def nuisance_correlation(problem, signature, update, most=3, tolerances=None):
    """How far a mechanism's signature looks like a rig parameter's change, and how large a change.

    Parameters
    ----------
    problem : Problem
    signature : ndarray (n, c)
        The mechanism's fitted minus the updated model's simulation.
    update : dict
        ``update_model``'s result.
    tolerances : sequence of float, optional
        Each parameter's tolerance in its coordinate (``RigParameter.tolerance``).

    Returns
    -------
    list of dict
        The ``most`` largest |cosines| between the signature and each
        parameter's sensitivity, in the chi2 metric with per-channel offsets
        removed: ``parameter``, ``correlation`` (1: the recording cannot
        tell the mechanism's shape from that parameter change) and, with
        ``tolerances``, ``tolerances_needed``: how many tolerances of that
        parameter the signature's projection on it would take (a change the
        updating could never make, beyond ``BOUND_TOLERANCES``, is no
        alternative, however alike the shapes).
    """
    g = _centred(problem, signature)
    gn = math.sqrt(float((g * g).sum()))
    out = []
    tol = [None] * len(update["sensitivities"]) if tolerances is None else list(tolerances)
    for p, s, t in zip(update["block"]["parameters"], update["sensitivities"], tol):
        j = _centred(problem, s)
        jn = math.sqrt(float((j * j).sum()))
        if gn > 0 and jn > 0:
            entry = {"parameter": p["parameter"], "correlation": float((g * j).sum()) / (gn * jn)}
            if t is not None and t > 0:
                entry["tolerances_needed"] = abs(float((g * j).sum()) / jn**2) / float(t)
            out.append(entry)
    out.sort(key=lambda e: -abs(e["correlation"]))
    return out[:most]


def _centred(problem, x):
    """``x`` (n, c) in the chi2 metric with each channel's weighted mean (its offset) removed, where the
    channel has a free offset."""
    W = problem.W
    x = np.where(problem.valid, x, 0.0)
    return (x - problem.offset_free * (W * x).sum(0) / np.maximum(W.sum(0), 1e-300)) * np.sqrt(W)


def parameter_span_share(problem, signature, update):
    """Share of a mechanism's signature that some change of the rig parameters reproduces.

    The squared multiple correlation of the signature with all parameters'
    sensitivities together (chi2 metric, per-channel offsets removed): 1
    means a combination of parameter changes looks exactly like the
    mechanism, so updating, which runs before any mechanism, will have
    taken up much of it (a sheave's inertia read as two cluster masses at
    once, where no single parameter's cosine passes 0.85).

    Parameters
    ----------
    problem : Problem
    signature : ndarray (n, c)
        The mechanism's fitted minus the updated model's simulation.
    update : dict
        ``update_model``'s result.

    Returns
    -------
    float
        In [0, 1]; 0 when the signature or every sensitivity is zero.
    """
    g = _centred(problem, signature).ravel()
    gg = float(g @ g)
    if gg == 0.0 or not update["sensitivities"]:
        return 0.0
    J = np.column_stack([_centred(problem, s).ravel() for s in update["sensitivities"]])
    coef, *_ = np.linalg.lstsq(J, g, rcond=1e-10)
    fitted = J @ coef
    return float(min(1.0, max(0.0, (fitted @ fitted) / gg)))


def _apply(X, a, problem, shape):
    """Unweighted fitted part of X a (the columns are weighted by sqrt(W))."""
    sw = np.sqrt(problem.W)
    fitted = (X @ a).reshape(shape)
    return np.where(sw > 0, fitted / np.where(sw > 0, sw, 1.0), 0.0)


def _value_or_none(parameter, coordinate):
    """The parameter's value at a coordinate, None where it overflows."""
    try:
        value = parameter.value(float(coordinate))
    except OverflowError:
        return None
    return value if math.isfinite(value) else None


def _spread_block(params, coords, active, spread):
    """The JSON of ``_heterogeneity.between_trials``: per active parameter, each trial's own estimate and
    standard deviation (the parameter's units), the between-trial standard deviation and Cochran's Q."""
    out = {"trials": spread["trials"], "parameters": {}}
    for j, i in enumerate(active):
        p = params[i]
        if p.of_a_trial:
            continue
        values = [_value_or_none(p, x) for x in spread["estimates"][:, j]]
        scale = (lambda v, sd: v * sd) if p.scale == "log" else (lambda v, sd: sd)
        out["parameters"][p.name] = {
            # None: a trial alone that sets the parameter beyond what a float holds (ln p past 700)
            "trial_estimates": values,
            "trial_at_bound": [bool(b) for b in spread["at_bound"][:, j]],
            "trial_uncertainties": [None if v is None else scale(v, float(sd))
                                    for v, sd in zip(values, spread["sd"][:, j])],
            "between_trials_sd": scale(p.value(float(coords[i])), float(spread["tau"][j])),
            "cochran_q": float(spread["q"][j]),
            "degrees_of_freedom": len(spread["trials"]) - 1,
        }
    return out


def _calibration_block(params, coords, cov, information, strength, offsets, ctx, history, failed, rough=None,
                       fd_widening=None):
    rough = rough or {}
    entries = []
    for i, p in enumerate(params):
        sd = float(math.sqrt(max(cov[i, i], 0.0)))
        x = float(coords[i])
        estimate = p.value(x)
        if p.scale == "log":
            unc = estimate * sd
        else:
            unc = sd
        entries.append({
            "parameter": p.name,
            "kind": p.kind,
            "unit": p.unit,
            "nominal": p.nominal,
            "estimate": estimate,
            "uncertainty": unc,
            "tolerance": p.tolerance if p.scale == "linear" else p.nominal * (math.exp(p.tolerance) - 1.0),
            "coordinate": x,
            "coordinate_sd": sd,
            "coordinate_scale": "ln p" if p.scale == "log" else p.unit,
            "shift_in_tolerances": x / p.tolerance,
            "posterior_over_prior": float(information[i]),
            "sensitivity": float(strength[i]),
            # a rough parameter is never active: its posterior is its prior
            "identifiable": bool(information[i] < IDENTIFIABLE_RATIO and p.name not in failed),
            # null where unchecked, or where the two ways cancel exactly (inf: not smooth)
            "one_sided_disagreement": rough[i] if math.isfinite(rough.get(i, math.inf)) else None,
            "difference_step": FD_FRACTION * (1.0 if fd_widening is None else float(fd_widening[i])),
            "smooth": _smooth(rough, i),
            "at_bound": bool(abs(x) >= BOUND_TOLERANCES * p.tolerance * (1 - 1e-6)),
            "description": p.describe(x),
        })
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(sd, sd)
    pairs = [{"parameters": [params[i].name, params[j].name], "correlation": float(corr[i, j])}
             for i in range(len(params)) for j in range(i + 1, len(params))
             if abs(corr[i, j]) > DEGENERATE and information[i] < 1.0 and information[j] < 1.0]
    left = {}
    findings = []
    scale = ctx.get("scale", REFERENCE)
    for j, ch in enumerate(ctx["channels"]):
        kind = channel_kind(ch)
        left[ch] = float(offsets[j])
        lim = scale.floor(OFFSET_FINDING, kind)
        if lim is not None and abs(offsets[j]) > lim:
            findings.append(ch)
    return {
        "parameters": entries,
        "degenerate_pairs": pairs,
        "offsets_left": left,
        "unexplained_offsets": findings,
        "iterations": history,
        # Only the gain rule says the next step has nothing to gain: stopped by the cap or by trf's own tolerances
        # with more to gain, the estimates are where the fit stopped, not a minimum (docs/diagnosis.md, section 3).
        "converged": history[-1].get("stopped_by") in ("gain", "nothing to fit") if history else None,
        "failed_sensitivities": failed,
        "method": ("bounded trust-region least squares (scipy trf) over the rig file's tolerances, with them as "
                   f"priors: sensitivities by finite differences over {FD_FRACTION:g} tolerance ({WIDE_STEP:g} times "
                   "that where the differences either way disagree, the parameter held where they disagree at both); "
                   "per-channel offsets (prior "
                   f"{scale.floor(OFFSET_PRIOR, 'position') * 1000:.3g} mm, "
                   f"{math.degrees(OFFSET_PRIOR['angle']):g} deg) and the "
                   "clock shift fitted jointly; identifiable when the data at least halve the prior spread"),
    }
