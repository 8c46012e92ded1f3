"""Is the model wrong the same way on every trial? Between-trial spread of the rig's parameters.

Several trials fitted together give one estimate of each shared parameter
and a covariance that, even taken robustly (``_objective.robust_covariance``),
says how well the pooled residual pins it - not whether each trial, fitted
on its own, would have said the same. Where the model describes the
machine, the trials agree within their own uncertainties; where it lacks
something that acts differently on each trial (a controller's work, a
disturbance, a wrong clock), each trial pulls a parameter its own way and
the pooled interval is far too narrow. This is the question a
meta-analysis asks of several studies of one effect, and its answer is
the random-effects model of DerSimonian and Laird (1986):

- each trial's own estimate, without a simulation more: one Gauss-Newton
  step from the shared fit on that trial's rows alone, with the lab's
  prior (the rig file's tolerances, the nuisance's priors) and the
  parameters' bounds as a one-trial diagnosis would have them, and its own
  robust covariance. Unbounded, the step follows the linearization as far
  as the trial's residual pulls it: on three real flights a model that
  missed each by fifteen times the noise put one cable at 1.41 m for
  2.42 (ten tolerances), where that flight's own nonlinear fit, bounded,
  found 2.35 m; an estimate held at a bound is said to be;
- for each parameter, Cochran's ``Q`` over the trials and the
  method-of-moments between-trial variance
  ``tau^2 = max(0, (Q - (k - 1)) / (S1 - S2 / S1))`` (``S1``, ``S2`` the
  sums of the inverse variances and of their squares);
- the pooled variance under random effects with the lab's prior on the
  shared value, ``1 / (1 / tol^2 + sum 1 / (v_i + tau^2))`` (never wider
  than the prior), stated where it is wider than the shared fit's own (the
  correlations kept): with ``tau^2 = 0`` nothing changes.

With few trials ``tau^2`` is itself uncertain (two trials give it one
degree of freedom); it is the standard estimate, not a bound, and the
docs say so.
"""

from __future__ import annotations

import numpy as np

from ._problem import bounded_solve
from ._trials import split_channel

__all__ = ["between_trials", "dersimonian_laird", "widened"]


def dersimonian_laird(estimates, variances):
    """DerSimonian-Laird between-trial variance of one quantity.

    Parameters
    ----------
    estimates, variances : ndarray (k,)
        Each trial's estimate and its variance (same units squared).

    Returns
    -------
    tau2 : float
        The between-trial variance (0 when the trials agree within their variances).
    q : float
        Cochran's Q (chi-squared with k - 1 degrees of freedom when they agree).
    """
    y = np.asarray(estimates, float)
    w = 1.0 / np.asarray(variances, float)
    s1 = float(w.sum())
    mean = float((w * y).sum()) / s1
    q = float((w * (y - mean) ** 2).sum())
    denom = s1 - float((w**2).sum()) / s1
    tau2 = max(0.0, (q - (len(y) - 1)) / denom) if denom > 0 else 0.0
    return tau2, q


def between_trials(X, z, theta, prior_precision, channels, n_parameters, covariance_of, bound=None):
    """Each trial's own estimate of the shared parameters, and the covariance widened by their spread.

    Parameters
    ----------
    X : ndarray (n * c, P)
        The fit's weighted design (``_objective._design``): the parameters'
        columns first (``n_parameters`` of them), then the nuisance's.
    z : ndarray (n, c)
        The weighted residual at the shared fit, the nuisance removed.
    theta : ndarray (P,)
        The shared fit's coordinates and nuisance, in ``X``'s column order
        (their priors are centred on 0).
    prior_precision : ndarray (P,)
    channels : sequence of str
        The stacked channels (``trial/channel``), ``z``'s columns.
    n_parameters : int
    covariance_of : callable
        ``covariance_of(X_i, z_i, H_inv_i, prior_precision)``: a trial's
        covariance (``_objective.robust_covariance``).
    bound : ndarray (n_parameters,), optional
        The most each parameter's coordinate may be either way (the
        updating's own bounds); the nuisance is not bounded.

    Returns
    -------
    dict or None
        None for one trial. Else ``trials`` (names), ``estimates`` (k, p)
        each trial's coordinates, ``sd`` (k, p) their standard deviations,
        ``tau`` (p,) the between-trial standard deviation, ``q`` (p,)
        Cochran's Q, and ``pooled_sd`` (p,) the random-effects standard
        deviation of the shared estimate, ``at_bound`` (k, p) where a
        trial's estimate is held at a bound.
    """
    names = [split_channel(ch)[0] for ch in channels]
    trials = list(dict.fromkeys(names))
    if len(trials) < 2 or None in trials:
        return None
    n, c = z.shape
    X3 = X.reshape(n, c, -1)
    p = int(n_parameters)
    prior_precision = np.asarray(prior_precision, float)
    limits = np.tile([-np.inf, np.inf], (X.shape[1], 1))
    if bound is not None:
        limits[:p] = np.asarray(bound, float)[:, None] * np.array([-1.0, 1.0]) - np.asarray(theta, float)[:p, None]
    estimates, sds, held = [], [], []
    for trial in trials:
        mask = np.array([name == trial for name in names])
        Xi = X3[:, mask, :].reshape(-1, X.shape[1])
        zi = z[:, mask]
        A = Xi.T @ Xi + np.diag(prior_precision)
        H_inv = np.linalg.inv(A)
        step = bounded_solve(A, Xi.T @ zi.ravel() - prior_precision * theta, limits)
        held.append((step[:p] <= limits[:p, 0]) | (step[:p] >= limits[:p, 1]))
        # The sandwich's middle from the residual the trial's own fit would leave, not the shared fit's.
        cov = covariance_of(Xi, zi - (Xi @ step).reshape(zi.shape), H_inv, prior_precision)
        estimates.append(theta[:p] + step[:p])
        sds.append(np.sqrt(np.clip(np.diag(cov)[:p], 1e-300, None)))
    estimates, sds = np.array(estimates), np.array(sds)
    tau2 = np.empty(p)
    q = np.empty(p)
    for j in range(p):
        tau2[j], q[j] = dersimonian_laird(estimates[:, j], sds[:, j] ** 2)
    # The lab's prior once (it is in each trial's variance too, which only narrows what max() then discards).
    pooled = 1.0 / np.sqrt(prior_precision[:p] + (1.0 / (sds**2 + tau2[None, :])).sum(axis=0))
    return {"trials": trials, "estimates": estimates, "sd": sds, "tau": np.sqrt(tau2), "q": q, "pooled_sd": pooled,
            "at_bound": np.array(held)}


def widened(covariance, pooled_sd, prior_sd=None):
    """``covariance`` (p, p) with each standard deviation raised to ``pooled_sd`` where that is wider, and
    lowered to ``prior_sd`` where it is wider than that, the correlations kept.

    A sandwich whose middle is a residual far above the noise can state a
    parameter wider than the lab knew it before the recording; what it says
    then is only that the recording does not pin it (not identifiable), and
    the lab's own tolerance is the honest spread to state.
    """
    sd = np.sqrt(np.clip(np.diag(covariance), 1e-300, None))
    target = np.maximum(sd, np.asarray(pooled_sd, float))
    if prior_sd is not None:
        target = np.minimum(target, np.asarray(prior_sd, float))
    factor = target / sd
    return covariance * np.outer(factor, factor)
