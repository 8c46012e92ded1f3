"""The rig parameters' sensitivities by finite differences, and which of them are smooth enough to fit on.

One simulation per parameter, a forward difference over ``FD_FRACTION`` of
its tolerance from the equilibrium of the point it differentiates, in
parallel; at the updating's start each is taken backward too, and a
parameter whose two differences disagree (``ROUGH``) is differenced again
over ``WIDE_STEP`` times the step, and held where it disagrees at both.
``SCREEN`` leaves nominal a parameter the recording hardly sees. The
rig's scale of mass and force is probed once (``_scale_gauge``,
``_mass_scale``).
"""

from __future__ import annotations

import math

import numpy as np

from ._mass_scale import PROBE, is_pure_rescaling, scale_direction
from ._rig_runs import _rig_job

__all__ = ["FD_FRACTION", "SCREEN", "SCATTER_SHARE", "ROUGH", "WIDE_STEP", "one_sided_disagreement"]

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
