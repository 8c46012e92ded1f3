"""How far a mechanism's signature looks like a change of the rig's parameters, and what that does to its value.

Updating runs before any mechanism, so the parameters take up whatever of
a mechanism's effect they can imitate. These measure that, each in the
chi2 metric with the channels' offsets removed: the mechanism's value's
uncertainty with the parameters free (``marginal_uncertainty``), the
parameters whose sensitivities its signature resembles most
(``nuisance_correlation``) and the share of it some change of all of them
together reproduces (``parameter_span_share``).
"""

from __future__ import annotations

import math

import numpy as np

from ._model_error import ERROR_AMPLITUDE_SD, MODEL_ERROR_FACTOR
from ._objective import MAX_SHIFT_PRIOR, _design, _offset_prior, robust_covariance
from ._problem import on_clock

__all__ = ["marginal_uncertainty", "nuisance_correlation", "parameter_span_share"]


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

    # On the clock the updated model settled on: the fits' shifts lie within MAX_SHIFT of it.
    clock = float(update.get("shift", 0.0))

    def design(columns, precision):
        X = _design(problem, sim, [*columns, signature, *errs], clock)
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
        d = (np.where(problem.valid, on_clock(finer - sim, problem.dt, clock), 0.0) * np.sqrt(problem.W)).ravel()
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
