"""The updating's objective and the algebra of its linear part.

A fit of the rig's parameters is judged by chi2 over the recording plus
the priors (the rig file's tolerances on the parameters, ``OFFSET_PRIOR``
on each channel's constant offset, ``MAX_SHIFT_PRIOR`` on the clock
shift). The nuisance - the offsets, the clock shift and the model error's
amplitudes - is solved for at every evaluation (``_objective_at``; linear
but for the shift, which is exact as in ``_problem``: the simulation and
its sensitivities are read on it) and projected out of every Jacobian
(``_projected_jacobian``: variable projection, Kaufman's form). The
posterior covariance is taken robustly (``robust_covariance``).
"""

from __future__ import annotations

import math

import numpy as np

from .._compare import channel_kind
from ._problem import CLOCK_CONVERGED, CLOCK_STEPS, bounded_solve, on_clock
from ._model_error import ERROR_AMPLITUDE_SD, ErrorDirections
from ._scale import REFERENCE

__all__ = ["OFFSET_PRIOR", "MAX_SHIFT_PRIOR", "BOUND_TOLERANCES", "BATCH_TIMES", "predicted_gain",
           "robust_covariance"]

# What a constant offset between a recorded channel and the model may
# honestly be, with no parameter wrong (one standard deviation): marker
# placement on a body and the calibration's origin (m, rad, m).
OFFSET_PRIOR = {"position": 0.005, "angle": math.radians(1.0), "rope_length": 0.003}
MAX_SHIFT_PRIOR = 0.01  # s
# No parameter moves further than this many tolerances from nominal.
BOUND_TOLERANCES = 3.0
# A batch's length in the residual's autocorrelation times (``robust_covariance``). Batch means read a
# correlated residual's variance low by about one correlation length per batch: on AR(1) errors (phi 0.8,
# integrated time 9 samples, tests/test_robust_covariance.py) batches of one time read the spread of the
# estimates over 300 draws 25-28 % low, of four 9-13 % low; the plain posterior reads it a third.
BATCH_TIMES = 4.0


def _offset_prior(ctx):
    """Each channel's offset prior (SI) at the machine's scale (``ctx["scale"]``; default the dragline's)."""
    scale = ctx.get("scale", REFERENCE)
    return np.array([scale.floor(OFFSET_PRIOR, channel_kind(ch), 0.005) for ch in ctx["channels"]])


def _design(problem, sim, sensitivities, shift=0.0):
    """Weighted design matrix: the sensitivities' columns, one offset per channel, the clock shift.

    The simulation and the sensitivities are read on the clock ``shift``
    (s, ``on_clock``): the shift's column is the rate there. A channel
    without a free offset (``Problem.offset_free``) keeps its column, all
    zeros: its offset stays at its prior's mean, 0, and the nuisance
    vector's layout is the same for every recording.
    """
    sw = np.sqrt(problem.W)
    sim = on_clock(sim, problem.dt, shift)
    n, c = sim.shape
    rate = np.gradient(sim, problem.dt, axis=0)
    cols = [np.where(problem.valid, on_clock(s, problem.dt, shift), 0.0) * sw for s in sensitivities]
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


def _objective_at(problem, sim, coords, tol, offset_sd, errs):
    """Objective (chi2 plus priors) at a simulation; error amplitudes, offsets and shift fitted with their priors.

    The shift by Gauss-Newton steps on its linear term, as ``Problem.nuisance``
    does, the prior on the whole shift.

    Returns
    -------
    objective, chi2 : float
    a : ndarray
        Error amplitudes, offsets (c,), shift (s, the whole of it).
    H_inv : ndarray
    """
    c, e = sim.shape[1], len(errs)
    prior_var = np.r_[np.full(e, ERROR_AMPLITUDE_SD**2), offset_sd**2, MAX_SHIFT_PRIOR**2]
    bounds = _nuisance_bounds(errs, c)
    shift = 0.0
    for _ in range(CLOCK_STEPS):
        X = _design(problem, sim, errs, shift)
        step = _solve(problem, X, prior_var, np.r_[np.zeros(e + c), -shift], problem.measured -
                      on_clock(sim, problem.dt, shift), bounds=bounds)[0][-1]
        shift += step
        if abs(step) < CLOCK_CONVERGED:
            break
    X = _design(problem, sim, errs, shift)
    held = bounds.copy()
    held[-1] = 0.0  # the shift found: the rest fitted on the simulation read at it
    r = problem.measured - on_clock(sim, problem.dt, shift)
    a, H_inv = _solve(problem, X, prior_var, np.r_[np.zeros(e + c), -shift], r, bounds=held)
    z = np.where(problem.valid, r - _apply(X, a, problem, sim.shape), 0.0)  # a's shift is 0 here
    a[-1] = shift
    chi2 = float((problem.W * z * z).sum())
    prior = float(((coords / tol) ** 2).sum() + ((a[e:e + c] / offset_sd) ** 2).sum())
    return chi2 + prior, chi2, a, H_inv


def _fit_residual(problem, sim, nuis, errs):
    """Measured minus the simulation read on the fit's clock (``nuis[-1]``) minus the rest of the nuisance
    (n, c; SI, NaN where unmeasured)."""
    read = on_clock(sim, problem.dt, nuis[-1])
    rest = np.r_[nuis[:-1], 0.0]
    return problem.measured - read - _apply(_design(problem, sim, errs, nuis[-1]), rest, problem, sim.shape)


def _prior_rows(nuis, coords, tol, offset_sd, errs):
    """The priors as residual rows: model-error amplitudes, offsets, clock shift, coordinates."""
    e, c = len(errs), len(offset_sd)
    return np.r_[nuis[:e] / ERROR_AMPLITUDE_SD, nuis[e:e + c] / offset_sd, nuis[e + c:] / MAX_SHIFT_PRIOR,
                 coords / tol]


def _apply(X, a, problem, shape):
    """Unweighted fitted part of X a (the columns are weighted by sqrt(W))."""
    sw = np.sqrt(problem.W)
    fitted = (X @ a).reshape(shape)
    return np.where(sw > 0, fitted / np.where(sw > 0, sw, 1.0), 0.0)


def _projected_jacobian(problem, sim, coords, sens, active, tol, offset_sd, errs):
    """The residual's Jacobian in the active coordinates, the linear nuisance projected out (Kaufman), with
    the priors' rows: what ``_trust_region``'s residual vector is differentiated into."""
    k, c, e = len(coords), sim.shape[1], len(errs)
    _, _, nuis, _ = _objective_at(problem, sim, coords, tol, offset_sd, errs)
    X = _design(problem, sim, errs, nuis[-1])
    # A model-error amplitude held at its bound does not follow the parameters: not projected out.
    bounds = _nuisance_bounds(errs, c)
    free = ~((nuis <= bounds[:, 0]) | (nuis >= bounds[:, 1]))
    prior_var = np.r_[np.full(e, ERROR_AMPLITUDE_SD**2), offset_sd**2, MAX_SHIFT_PRIOR**2]
    Xf = X[:, free]
    H_inv = np.linalg.inv(Xf.T @ Xf + np.diag(1.0 / prior_var[free]))
    sw = np.sqrt(problem.W)
    cols = []
    for i in active:
        v = (np.where(problem.valid, on_clock(sens[i], problem.dt, nuis[-1]), 0.0) * sw).ravel()
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
