"""Finite differences, running averages and body rates against analytic truth."""

import numpy as np
import pytest

from dragline.reconstruct import (
    RunningAverage,
    SavitzkyGolay,
    body_rates,
    finite_difference,
    make_smoother,
    running_average,
)
from dragline.simulate import body_rates_from_euler_rates, body_to_inertial


def test_finite_difference_exact_on_quadratics_any_trailing_shape():
    dt = 0.005
    t = np.arange(40) * dt
    coef = np.random.default_rng(0).normal(size=(3, 2, 3))
    x = coef[0] + coef[1] * t[:, None, None] + coef[2] * t[:, None, None] ** 2
    d = finite_difference(x, dt)
    want = coef[1] + 2 * coef[2] * t[:, None, None]
    np.testing.assert_allclose(d, want, atol=1e-11)


def test_finite_difference_is_second_order_everywhere():
    def max_err(dt):
        t = np.arange(0, 1 + dt / 2, dt)
        return np.max(np.abs(finite_difference(np.sin(3 * t), dt) - 3 * np.cos(3 * t)))

    ratio = max_err(0.01) / max_err(0.005)
    assert 3.6 < ratio < 4.4


def test_finite_difference_nan_stays_local():
    x = np.arange(10.0) ** 2
    x[5] = np.nan
    d = finite_difference(x, 1.0)
    assert np.isnan(d[[4, 6]]).all()
    np.testing.assert_allclose(d[[1, 2, 3, 7, 8]], 2 * np.array([1, 2, 3, 7, 8]))


@pytest.mark.parametrize("centred, lag", [(True, -0.5), (False, 5.5)])
def test_running_average_lag_on_a_ramp(centred, lag):
    slope, dt = 0.7, 0.005
    i = np.arange(100)
    x = 2.0 + slope * i * dt
    y = running_average(np.stack([x, -x], axis=1), 12, centred=centred)
    inner = slice(11, 89)
    # On a ramp a running average is the ramp delayed by the window's lag.
    np.testing.assert_allclose(y[inner, 0], 2.0 + slope * (i[inner] - lag) * dt, rtol=1e-14)
    np.testing.assert_allclose(y[:, 1], -y[:, 0], rtol=1e-14)
    # Edges: truncated windows average the samples that exist; on a ramp
    # that is the ramp at the mid-index of the truncated window.
    lo = np.maximum(0, i - (5 if centred else 11))
    hi = np.minimum(99, i + (6 if centred else 0))
    np.testing.assert_allclose(y[:, 0], 2.0 + slope * 0.5 * (lo + hi) * dt, rtol=1e-14)


def test_running_average_odd_window_has_no_lag_and_nan_spreads_by_window():
    x = np.linspace(0, 1, 50)
    np.testing.assert_allclose(running_average(x, 5)[2:-2], x[2:-2], atol=1e-15)
    x[20] = np.nan
    y = running_average(x, 12)
    # Output i uses samples i-5 .. i+6, so sample 20 poisons outputs 14 .. 25.
    assert np.isnan(y[14:26]).all()
    assert np.isfinite(y[:14]).all() and np.isfinite(y[26:]).all()


def _angles(t):
    roll = 0.3 * np.sin(2.0 * t)
    pitch = np.radians(-52) + 0.5 * np.sin(3.0 * t + 0.2)
    yaw = 0.4 * np.cos(1.5 * t)
    rates = (0.6 * np.cos(2.0 * t), 1.5 * np.cos(3.0 * t + 0.2), -0.6 * np.sin(1.5 * t))
    return (roll, pitch, yaw), rates


def test_body_rates_match_euler_rate_kinematics_to_second_order():
    def max_err(dt):
        t = np.arange(0, 2 + dt / 2, dt)
        (roll, pitch, yaw), (droll, dpitch, dyaw) = _angles(t)
        pqr = body_rates(body_to_inertial(roll, pitch, yaw), dt)
        want = np.stack(body_rates_from_euler_rates(roll, yaw, droll, dpitch, dyaw), axis=-1)
        return np.max(np.abs(pqr - want))

    e1, e2 = max_err(2e-3), max_err(1e-3)
    assert e2 < 2e-4
    assert 3.5 < e1 / e2 < 4.5


def test_smoothers():
    t = np.linspace(0, 1, 60)
    cubic = 1 + t - 2 * t**2 + 0.5 * t**3
    np.testing.assert_allclose(SavitzkyGolay(13, 3)(cubic, t[1]), cubic, atol=1e-12)
    ra = make_smoother("running_average", window=12)
    assert isinstance(ra, RunningAverage)
    np.testing.assert_array_equal(ra(cubic, t[1]), running_average(cubic, 12))
    with pytest.raises(ValueError, match="unknown smoother"):
        make_smoother("kalman")


def test_bad_input_raises():
    with pytest.raises(ValueError, match="3 samples"):
        finite_difference(np.zeros(2), 0.1)
    with pytest.raises(ValueError, match="window"):
        running_average(np.zeros(5), 0)
    with pytest.raises(ValueError, match="shape"):
        body_rates(np.zeros((4, 3)), 0.1)
