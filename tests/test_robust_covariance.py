"""The updating's stated uncertainty holds on a structured residual (``_objective.robust_covariance``).

A straight regression whose errors are correlated in time (AR(1), phi 0.8):
the plain posterior understates the spread of the estimates about three
times ((1 + phi) / (1 - phi) = 9 in variance, for regressors that vary
slowly); the sandwich with blocks as long as the residual's correlation
states it, judged against the spread over 300 independent draws. With white
errors it is the plain posterior.
"""

from __future__ import annotations

import numpy as np
import pytest

from dragline.compare.diagnose._objective import robust_covariance

N = 3000
DRAWS = 300


def _design():
    t = np.linspace(0.0, 1.0, N)
    return np.column_stack([np.sin(2 * np.pi * 3 * t), t - 0.5])  # slow next to the errors' correlation


def _errors(rng, phi):
    e = np.empty(N)
    e[0] = rng.normal()
    innovation = rng.normal(size=N) * np.sqrt(1.0 - phi**2)  # unit variance, as the stated noise
    for i in range(1, N):
        e[i] = phi * e[i - 1] + innovation[i]
    return e


def _fits(phi, seed):
    rng = np.random.default_rng(seed)
    X = _design()
    prior = np.full(2, 1e-9)
    H_inv = np.linalg.inv(X.T @ X + np.diag(prior))
    estimates, robust_sd = [], []
    for _ in range(DRAWS):
        y = X @ np.array([0.3, -0.2]) + _errors(rng, phi)
        beta = H_inv @ (X.T @ y)
        z = (y - X @ beta)[:, None]
        estimates.append(beta)
        robust_sd.append(np.sqrt(np.diag(robust_covariance(X, z, H_inv, prior))))
    return np.array(estimates), np.median(robust_sd, axis=0), np.sqrt(np.diag(H_inv))


def test_on_correlated_errors_the_robust_spread_is_the_estimates_own_and_the_plain_one_is_not():
    estimates, robust, plain = _fits(0.8, seed=11)
    spread = estimates.std(axis=0)
    np.testing.assert_allclose(robust, spread, rtol=0.15)
    assert np.all(plain < 0.5 * spread)  # the plain posterior: about a third


def test_on_white_errors_the_robust_spread_is_the_plain_posterior():
    estimates, robust, plain = _fits(0.0, seed=12)
    np.testing.assert_allclose(robust, plain, rtol=0.1)
    np.testing.assert_allclose(estimates.std(axis=0), plain, rtol=0.15)


def test_the_prior_alone_is_its_own_spread():
    X = np.zeros((50, 1))
    prior = np.array([4.0])
    H_inv = np.linalg.inv(X.T @ X + np.diag(prior))
    assert robust_covariance(X, np.zeros((50, 1)), H_inv, prior)[0, 0] == pytest.approx(0.25)
