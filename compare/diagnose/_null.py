"""What noise alone gives (the null test): the threshold a candidate's held-out improvement must pass.

Surrogate residuals with the same spectrum (hence autocorrelation) and
cross-channel correlation as the best model's residual are drawn as
Gaussian noise from its smoothed cross-spectral matrix; for each, every candidate's signature (fitted minus nominal
simulation) is fitted with a non-negative amplitude on one fold and scored
on the other exactly as a candidate is (``_problem``). The threshold is the ``NULL_QUANTILE``
quantile of the largest improvement over candidates (a family-wise test),
and never below ``MIN_IMPROVEMENT`` (twenty times ln N, ln N the BIC
penalty of one parameter: an allowance for the reconstruction's systematic
errors, measured on blind sessions, see the constant). A candidate is
significant when ``D`` exceeds it; ``score`` is ``D / threshold``.
"""

from __future__ import annotations

import math

import numpy as np

from ._hypotheses import _weighted_signal

__all__ = ["NULL_SURROGATES", "SPECTRUM_SMOOTH", "NULL_QUANTILE", "MIN_IMPROVEMENT", "null_threshold", "surrogate"]

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
