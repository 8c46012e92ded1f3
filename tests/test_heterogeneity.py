"""DerSimonian-Laird between-trial variance against values worked by hand (issue 36)."""

from __future__ import annotations

import numpy as np
import pytest

from dragline.compare.diagnose._heterogeneity import between_trials, dersimonian_laird, widened


def test_estimates_that_scatter_as_their_variances_say_have_no_between_trial_variance():
    # y 0, 1, 2 with unit variances: mean 1, Q = 2 = k - 1.
    tau2, q = dersimonian_laird([0.0, 1.0, 2.0], [1.0, 1.0, 1.0])
    assert q == pytest.approx(2.0) and tau2 == 0.0


def test_with_equal_variances_the_between_trial_variance_is_the_sample_variance_less_theirs():
    # y 0, 2, 4: sample variance 4, each trial's variance 1, so tau^2 = 3 (Q = 8, S1 = 3, S2 = 3).
    tau2, q = dersimonian_laird([0.0, 2.0, 4.0], [1.0, 1.0, 1.0])
    assert q == pytest.approx(8.0) and tau2 == pytest.approx(3.0)


def test_unequal_variances_against_the_formula_worked_out():
    y, v = np.array([1.0, 3.0]), np.array([1.0, 4.0])
    # w 1, 1/4: mean (1 + 3/4) / (5/4) = 1.4; Q = 0.16 + 0.64 = 0.8 < 1: no excess.
    assert dersimonian_laird(y, v) == (0.0, pytest.approx(0.8))
    y = np.array([0.0, 5.0])
    # mean 1; Q = 1 + 16/4 = 5; S1 = 1.25, S2 = 1.0625, denominator 1.25 - 0.85 = 0.4: tau^2 = 4 / 0.4 = 10.
    tau2, q = dersimonian_laird(y, v)
    assert q == pytest.approx(5.0) and tau2 == pytest.approx(10.0)


def test_widening_raises_only_the_narrower_standard_deviations_and_keeps_correlations():
    cov = np.array([[4.0, 1.2], [1.2, 1.0]])  # sd 2 and 1, correlation 0.6
    out = widened(cov, [1.0, 3.0])
    assert np.sqrt(np.diag(out)) == pytest.approx([2.0, 3.0])
    assert out[0, 1] / 6.0 == pytest.approx(0.6)


def test_no_standard_deviation_is_stated_wider_than_the_prior():
    cov = np.array([[9.0, 0.6], [0.6, 1.0]])  # sd 3 and 1, correlation 0.2
    out = widened(cov, [0.0, 0.0], prior_sd=[1.5, 2.0])
    assert np.sqrt(np.diag(out)) == pytest.approx([1.5, 1.0])
    assert out[0, 1] / 1.5 == pytest.approx(0.2)


def test_a_trials_own_estimate_stays_within_the_bounds_a_one_trial_fit_would_have():
    # One parameter (prior sd 1, shared value 0), two trials of 50 rows, every row's column 1: a trial's
    # one-step estimate is sum(z) / (50 + 1). Trial a's residual, 10 on every row, pulls it to 500/51 = 9.8
    # tolerances, which the updating would never reach; held at 3. Trial b's, 1, gives 50/51, as unbounded.
    n = 50
    X = np.ones((n * 2, 1))
    z = np.column_stack([np.full(n, 10.0), np.ones(n)])
    args = (X, z, np.zeros(1), np.ones(1), ["a/x", "b/x"], 1, lambda Xi, zi, H_inv, prior: H_inv)
    free = between_trials(*args)
    assert free["estimates"][:, 0] == pytest.approx([500 / 51, 50 / 51])
    held = between_trials(*args, bound=np.array([3.0]))
    assert held["estimates"][:, 0] == pytest.approx([3.0, 50 / 51])
    assert held["at_bound"][:, 0].tolist() == [True, False]
    assert not free["at_bound"].any()
