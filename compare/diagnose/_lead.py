"""Whether one candidate's held-out lead over another is real: what noise and model error could give it.

Two candidates that both explain a mismatch leave held-out residuals
``r_lead`` and ``r_rival``; the lead is the rival's held-out chi2 minus the
lead's, ``sum W (r_rival^2 - r_lead^2)``. The maneuver is one fixed
excitation, not a sample: what varies between recordings of it is the
residual's random part ``n`` (measurement noise, and the model error the
surrogates treat as noise), which moves both residuals alike. The lead then
changes by ``2 sum W (r_rival - r_lead) n`` - linear in ``n``, so Gaussian
when ``n`` is - and the two candidates are equally close to the recording
when the lead's mean is zero. The test reads the lead against that term's
spread, one-sided at the null test's quantile.

The spread comes from surrogates of the lead's own held-out residual, drawn
as the noise threshold's are (``_null.null_threshold``: its smoothed
cross-spectral matrix), but amplitude-modulated by the residual's local RMS
over ``ENVELOPE_S``: model error is not stationary - a mechanism's
signature, and the error of the rival that imitates it, live in some phases
of a maneuver - and a lead that only a stretch where the residual is large
gives is then read against that stretch's own spread (Priestley's
modulated process). Neglected: how the two folds' fits themselves follow
``n`` (a few coefficients each against thousands of samples).

The model's own discretization is no random part: it moves a lead one
way. A lead of one law over another of the same shape (a sheave's bearing
friction against the capstan, which differ by chord against arc) can be
the discretization's choice rather than the recording's: on the crane at
twenty times its threshold, the capstan at the head sheave was fitted 0.03 %
better by the bearing's law, twice in two fresh seeds, at t = 7.2 and 2.4
against the random part alone. So where both candidates were simulated at
their fits on the next finer discretization too (the marginal
uncertainty's run, no extra simulation), the lead is read where the
converged model would put it. A discretization error that falls as the
level's size to a power ``p >= 1`` puts the converged lead at
``lead + shift 2^p / (2^p - 1)``: between the finer level's lead
(``p`` large) and the Richardson extrapolation ``lead + R shift``
(``p = 1``, ``R = MODEL_ERROR_FACTOR``, as the marginal takes a value's
shift). The test reads the interval from the model's own level to that
extrapolation: its centre ``lead + R shift / 2`` and its half-width
``R |shift| / 2``, the half-width joining the spread in quadrature. A
lead the finer level reverses is then no lead; one it widens is judged
nearer the converged model's. (Until 2026-12-03 the spread held
``R |shift|`` about the model's own level, reading a lead that grows at
the finer level as doubt about it: in six of eight lead-test misses on
three dragline seeds the right law's lead grew there.)

Before this, the lead was judged by Vuong's test (1989) over one-second
batches: a test for losses drawn alike at every sample. A mechanism's
signature is not - its share of the lead varies from batch to batch by the
maneuver's own phases - so the batch spread counted the signature as noise
and the test lost power as the effect grew.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats
from scipy.ndimage import uniform_filter1d

from ._hypotheses import _weighted_signal
from ._model_error import MODEL_ERROR_FACTOR
from ._null import NULL_QUANTILE, NULL_SURROGATES, _spectral_factor, surrogate
from ._problem import BLOCK_S

__all__ = ["lead_tests", "ENVELOPE_S"]

# One block of each fold: the envelope's window holds held-out samples of both fits.
ENVELOPE_S = 2 * BLOCK_S


def lead_tests(problem, residuals, order, seed=0, quantile=NULL_QUANTILE, n_surrogates=NULL_SURROGATES,
               base=None, finer_chi2=None):
    """Each candidate's lead over every one behind it in ``order``, and how alike the two candidates' signatures
    are.

    Parameters
    ----------
    problem : Problem
    residuals : dict
        Name -> held-out residual (n, c) (SI; ``Problem.held_out_residual``).
    order : list of str
        Best first.
    seed : int
    quantile : float
        One-sided level of each test.
    base : ndarray (n, c), optional
        The held-out residual without any candidate: each candidate's
        signature is what it takes off it.
    finer_chi2 : dict, optional
        Name -> (chi2 of the candidate's fit, chi2 of the same fit simulated
        at the next finer discretization). Where both candidates have one,
        the lead's change from the one level to the other, times
        ``MODEL_ERROR_FACTOR``, joins the spread in quadrature.

    Returns
    -------
    dict
        Name -> {rival name -> test}; a test has ``lead`` (the rival's
        held-out chi2 minus the lead's), ``sd`` (the lead's spread under the
        residual's random part), ``t`` (lead / sd), ``critical`` (the normal
        quantile), ``consistent`` (``t`` beyond ``critical``) and, with
        ``base``, ``cosine`` (between the two candidates' weighted signatures:
        what each takes off ``base``); ``sd_noise`` (the spread under the
        random part alone), ``discretization_shift`` (the lead at the
        finer level minus the lead; None without both candidates' finer
        fits) and ``converged_lead`` (the lead the test reads: ``lead``, or
        with a shift the middle of the interval from ``lead`` to its
        Richardson extrapolation); ``t`` is ``converged_lead / sd``.
    """
    finer_chi2 = finer_chi2 or {}
    critical = float(stats.norm.ppf(quantile))
    weighted = {name: _weighted_signal(problem, residuals[name]) for name in order}
    below = None if base is None else _weighted_signal(problem, base)
    out = {}
    for k, name in enumerate(order):
        behind = order[k + 1:]
        if not behind:
            out[name] = {}
            continue
        z = weighted[name]
        differences = np.stack([weighted[o] - z for o in behind])  # sqrt(W) (r_rival - r_lead)
        projections = _surrogate_projections(z, differences, problem.dt, seed, n_surrogates)
        out[name] = {}
        for j, other in enumerate(behind):
            lead = float((weighted[other] ** 2).sum() - (z**2).sum())
            sd_noise = 2.0 * float(np.std(projections[:, j]))
            shift = _discretization_shift(finer_chi2.get(name), finer_chi2.get(other))
            half_span = 0.0 if shift is None else 0.5 * MODEL_ERROR_FACTOR * shift
            converged = lead + half_span
            sd = math.hypot(sd_noise, half_span)
            t = converged / sd if sd > 0 else (math.inf if converged > 0 else 0.0)
            out[name][other] = {"lead": lead, "converged_lead": converged, "sd": sd, "t": float(t),
                                "critical": critical, "consistent": bool(t > critical), "sd_noise": sd_noise,
                                "discretization_shift": shift}
            if below is not None:
                out[name][other]["cosine"] = _cosine(below - z, below - weighted[other])
    return out


def _discretization_shift(lead, rival):
    """The lead's change at the next finer discretization: (rival's chi2 - lead's) there minus here; None
    without both."""
    if lead is None or rival is None:
        return None
    return float((rival[1] - lead[1]) - (rival[0] - lead[0]))


def _cosine(a, b):
    norm = float(np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.sum(a * b) / norm) if norm > 0 else 0.0


def _surrogate_projections(z, directions, dt, seed, n_surrogates):
    """``sum direction * n`` for surrogates ``n`` of the weighted residual z: (n_surrogates, k).

    ``n = envelope * stationary``: the stationary part drawn from the
    smoothed cross-spectrum of ``z / envelope``, the envelope each
    channel's RMS over ``ENVELOPE_S``.
    """
    n_t = z.shape[0]
    envelope = _envelope(z, dt)
    chol = _spectral_factor(z / envelope)
    rng = np.random.default_rng(seed)
    weights = directions * envelope[None]
    out = np.empty((n_surrogates, len(directions)))
    for k in range(n_surrogates):
        out[k] = np.einsum("knc,nc->k", weights, surrogate(chol, n_t, rng))
    return out


def _envelope(z, dt):
    """Each channel's local RMS over ``ENVELOPE_S`` (n, c), floored at a thousandth of its whole RMS."""
    size = max(1, int(round(ENVELOPE_S / dt)))
    local = np.sqrt(uniform_filter1d(z * z, size, axis=0, mode="nearest"))
    whole = np.sqrt(np.mean(z * z, axis=0))
    return np.maximum(local, 1e-3 * whole[None, :] + 1e-300)
