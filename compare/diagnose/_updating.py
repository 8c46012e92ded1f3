"""Model updating before blame.

A real rig is never its nominal model. Before any mechanism is blamed, the
diagnosis updates the nominal parameters a lab knows only approximately
(the rig file's ``[tolerances]``, ``simulate._tolerances``) to the
recording (``docs/diagnosis.md``), beside the model's own numerical error
(``_model_error``). This module holds the fits; the objective and its
linear algebra are ``_objective``'s, the finite differences
``_differences``', the JSON block ``_calibration_block``'s, and how far a
mechanism's signature looks like a parameter change ``_confounding``'s.

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
model-error amplitudes, ``_model_error`` - is linear and is projected out at every
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...simulate import make_mechanism
from ._calibration_block import _calibration_block, _spread_block
from ._differences import SCREEN, _difference_job, _scale_gauge, _sensitivities, _smooth, _smooth_differences, _strength
from ._heterogeneity import between_trials, widened
from ._hypotheses import _init, _pool
from ._mass_scale import gauge_covariance, scale_block
from ._model_error import ERROR_AMPLITUDE_SD, ErrorDirections, model_error
from ._objective import (
    BOUND_TOLERANCES,
    MAX_SHIFT_PRIOR,
    _design,
    _fit_residual,
    _objective_at,
    _offset_prior,
    _prior_rows,
    _projected_jacobian,
    _solve,
    predicted_gain,
    robust_covariance,
)
from ._rig_runs import _Run, _rig_job
from ._trials import apply_to_trials
from ._unresolved import combination_columns, unresolved_combinations

__all__ = ["MAX_JACOBIANS", "update_model", "joint_refit", "rig_alone_channels", "resume_update",
           "joint_value_bounds"]

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
    X = _design(problem, sim, [sens[i] for i in active] + errs, nuis[-1])
    prior_var = np.r_[tol[active] ** 2, err_var, offset_sd**2, MAX_SHIFT_PRIOR**2]
    _, H_inv = _solve(problem, X, prior_var, np.zeros(len(active) + len(errs) + c + 1), problem.measured - sim)
    # The residual the fit leaves, its nuisance fitted: the sandwich's middle.
    z = np.where(problem.valid, _fit_residual(problem, sim, nuis, errs), 0.0) * np.sqrt(problem.W)
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
        z = (np.where(problem.valid, _fit_residual(problem, sim, nuis, errs), 0.0) * np.sqrt(problem.W)).ravel()
        r = np.r_[z, _prior_rows(nuis, coords, tol, offset_sd, errs)]
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
