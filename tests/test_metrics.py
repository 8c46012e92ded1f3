"""Comparison metrics against analytic values (dragline.compare._metrics)."""

import json
import math

import numpy as np
import pytest

from dragline.compare import (
    channel_metrics,
    iso18571,
    peak,
    peak_error,
    rms_error,
    sprague_geers,
    theil_u,
)

DT = 0.005
TIME = np.arange(0.0, 10.0, DT)


def _transient(t=TIME):
    """A non-periodic test curve: decaying oscillation on a smooth step."""
    return np.exp(-0.3 * t) * np.sin(2 * np.pi * 0.8 * t) + 0.3 * np.tanh(t - 3.0)


def _pulse(t=TIME):
    """A single smooth pulse, zero at both ends of the interval."""
    return np.exp(-0.5 * ((t - 3.0) / 0.4) ** 2) - 0.4 * np.exp(-0.5 * ((t - 4.2) / 0.3) ** 2)


# -- RMS, peak error, peak -------------------------------------------------


def test_rms_and_peak_error_by_hand():
    m = np.zeros(4)
    s = np.array([3.0, -4.0, 0.0, 0.0])
    assert rms_error(m, s) == pytest.approx(math.sqrt(25.0 / 4.0))
    assert peak_error(m, s) == pytest.approx(4.0)


def test_nan_samples_are_excluded_pairwise():
    m = np.array([0.0, np.nan, 0.0, 0.0, 1.0])
    s = np.array([3.0, 5.0, -4.0, 0.0, np.nan])
    # Only pairs (0, 3), (0, -4), (0, 0) remain.
    assert rms_error(m, s) == pytest.approx(math.sqrt(25.0 / 3.0))
    assert peak_error(m, s) == pytest.approx(4.0)


def test_constant_offset_gives_offset_as_rms_and_peak_error():
    m = _transient()
    assert rms_error(m, m + 0.1) == pytest.approx(0.1)
    assert peak_error(m, m - 0.1) == pytest.approx(0.1)


def test_peak_is_signed_extreme_and_its_time():
    values = np.array([1.0, np.nan, -3.0, 2.5, 0.0])
    time = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    assert peak(values, time) == (-3.0, pytest.approx(0.2))
    # Analytic: exp(-t) sin(t) peaks at t = pi/4.
    t = np.linspace(0.0, 5.0, 50001)
    value, when = peak(np.exp(-t) * np.sin(t), t)
    assert when == pytest.approx(math.pi / 4, abs=2e-4)
    assert value == pytest.approx(math.exp(-math.pi / 4) * math.sqrt(0.5), rel=1e-7)


def test_bad_input_raises_value_error():
    with pytest.raises(ValueError):
        rms_error(np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError):
        rms_error(np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ValueError):
        peak(np.full(3, np.nan), np.arange(3.0))
    with pytest.raises(ValueError):
        channel_metrics(TIME[:3], np.array([1.0, np.nan, 2.0]), np.ones(3))


# -- Sprague-Geers ---------------------------------------------------------


def test_sprague_geers_identical_signals():
    m = _transient()
    mag, phase, comb = sprague_geers(TIME, m, m)
    assert abs(mag) < 1e-12
    assert phase < 1e-6
    assert comb < 1e-6


@pytest.mark.parametrize("a", [0.5, 1.3, 2.0])
def test_sprague_geers_pure_scaling(a):
    m = _transient()
    mag, phase, comb = sprague_geers(TIME, m, a * m)
    assert mag == pytest.approx(a - 1.0, abs=1e-12)
    assert phase < 1e-6
    assert comb == pytest.approx(abs(a - 1.0), abs=1e-6)


def test_sprague_geers_negation_is_full_phase_error():
    m = _transient()
    mag, phase, _ = sprague_geers(TIME, m, -m)
    assert mag == pytest.approx(0.0, abs=1e-12)
    assert phase == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("fraction", [1 / 8, 1 / 4, 1 / 3, 1 / 2])
def test_sprague_geers_time_shift_over_whole_periods(fraction):
    # m = sin(w t), s = sin(w (t - tau)) over 3 whole periods:
    # psi_mm = psi_ss = 3T/2 and psi_ms = (3T/2) cos(w tau), so M = 0 and
    # P = arccos(cos(w tau)) / pi = w tau / pi = 2 * fraction.
    period = 1.6
    t = np.linspace(0.0, 3 * period, 3 * 400 + 1)
    w = 2 * np.pi / period
    tau = fraction * period
    mag, phase, comb = sprague_geers(t, np.sin(w * t), np.sin(w * (t - tau)))
    assert mag == pytest.approx(0.0, abs=1e-12)
    # arccos near +-1 turns rounding eps into sqrt(eps): allow 1e-7.
    assert phase == pytest.approx(w * tau / np.pi, abs=1e-7)
    assert comb == pytest.approx(w * tau / np.pi, abs=1e-7)


# -- Theil's U -------------------------------------------------------------


def test_theil_u_reference_cases():
    m = _transient()
    assert theil_u(m, m) == pytest.approx(0.0, abs=1e-15)
    assert theil_u(m, -m) == pytest.approx(1.0)
    assert theil_u(m, np.zeros_like(m)) == pytest.approx(1.0)
    # s = 2m: rms(m) / (rms(m) + 2 rms(m)) = 1/3.
    assert theil_u(m, 2 * m) == pytest.approx(1.0 / 3.0)


# -- ISO/TS 18571 ----------------------------------------------------------


def test_iso_identical_is_one_everywhere():
    m = _transient()
    r = iso18571(TIME, m, m)
    for key in ("corridor", "phase", "magnitude", "slope", "rating"):
        assert r[key] == pytest.approx(1.0, abs=1e-12), key
    assert r["shift"] == 0.0


def test_iso_corridor_inside_inner_corridor_is_one():
    m = _transient()
    norm = np.max(np.abs(m))
    assert iso18571(TIME, m, m + 0.049 * norm)["corridor"] == 1.0
    assert iso18571(TIME, m, 1.04 * m)["corridor"] == 1.0  # |0.04 m| < 0.05 max|m|


@pytest.mark.parametrize("offset", [0.2, 0.35])
def test_iso_corridor_constant_offset_between_corridors(offset):
    # |C - T| = d everywhere, inner 0.05, outer 0.5 (fractions of max|C|):
    # Z = ((0.5 - d) / (0.5 - 0.05))^2 at every sample.
    m = _transient()
    norm = np.max(np.abs(m))
    expected = ((0.5 - offset) / 0.45) ** 2
    r = iso18571(TIME, m, m + offset * norm)
    assert r["corridor"] == pytest.approx(expected, rel=1e-9)
    assert iso18571(TIME, m, m + 0.6 * norm)["corridor"] == 0.0


@pytest.mark.parametrize("a", [1.1, 1.5, 0.7])
def test_iso_slope_score_of_scaled_curve(a):
    # Derivatives scale by a, so the EEARTH slope error is |a - 1| exactly
    # and the slope score is 1 - |a - 1| / 2.0.
    m = _transient()
    r = iso18571(TIME, m, a * m)
    assert r["slope_error"] == pytest.approx(abs(a - 1.0), rel=1e-9)
    assert r["slope"] == pytest.approx(1.0 - abs(a - 1.0) / 2.0, rel=1e-9)
    assert r["phase"] == 1.0


def test_iso_scores_fall_monotonically_with_scaling_error():
    m = _transient()
    results = [iso18571(TIME, m, a * m) for a in (1.0, 1.03, 1.1, 1.2, 1.4, 1.8)]
    ratings = [r["rating"] for r in results]
    magnitudes = [r["magnitude"] for r in results]
    assert all(x > y for x, y in zip(ratings, ratings[1:])), ratings
    assert all(x > y for x, y in zip(magnitudes, magnitudes[1:])), magnitudes


@pytest.mark.parametrize("shift", [0.05, 0.3, 1.2])
def test_iso_phase_score_of_shifted_pulse(shift):
    # A pure delay is found exactly; the phase score is linear in the delay
    # and reaches 0 at 20 % of the duration; after the shift correction
    # the two curves coincide, so magnitude and slope are perfect.
    k = int(round(shift / DT))
    m = _pulse()
    s = np.concatenate([np.zeros(k), m[: m.size - k]])
    r = iso18571(TIME, m, s)
    duration = TIME[-1] - TIME[0]
    assert r["shift"] == pytest.approx(k * DT)
    assert r["phase"] == pytest.approx(1.0 - k * DT / (0.2 * duration), rel=1e-9)
    assert r["magnitude"] == pytest.approx(1.0)
    assert r["slope"] == pytest.approx(1.0)
    # Published weights: 0.4 corridor, 0.2 each for phase, magnitude, slope.
    assert r["rating"] == pytest.approx(0.4 * r["corridor"] + 0.2 * r["phase"] + 0.4)
    # A lead is a negative shift with the same score.
    lead = iso18571(TIME, m, np.concatenate([m[k:], np.zeros(k)]))
    assert lead["shift"] == pytest.approx(-k * DT)
    assert lead["phase"] == pytest.approx(r["phase"])


def test_iso_scores_fall_monotonically_with_shift():
    m = _pulse()
    ratings, phases = [], []
    for shift in (0.0, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6):
        k = int(round(shift / DT))
        r = iso18571(TIME, m, np.concatenate([np.zeros(k), m[: m.size - k]]))
        ratings.append(r["rating"])
        phases.append(r["phase"])
    assert all(x > y for x, y in zip(ratings, ratings[1:])), ratings
    assert all(x > y for x, y in zip(phases, phases[1:])), phases


def test_iso_needs_uniform_time():
    t = np.sort(np.random.default_rng(0).uniform(0.0, 1.0, 50))
    with pytest.raises(ValueError):
        iso18571(t, np.sin(t), np.sin(t))


# -- channel_metrics -------------------------------------------------------


def test_channel_metrics_scaled_channel_is_json_ready():
    m = _transient()
    s = 1.1 * m
    s[100] = np.nan
    out = channel_metrics(TIME, m, s)
    text = json.dumps(out, allow_nan=False)
    assert json.loads(text) == out
    ok = np.isfinite(s)
    assert out["n_samples"] == TIME.size - 1
    assert out["rms_error"] == pytest.approx(0.1 * np.sqrt(np.mean(m[ok] ** 2)))
    assert out["peak_error"] == pytest.approx(0.1 * np.max(np.abs(m[ok])))
    i = np.argmax(np.abs(m))
    assert out["measured_peak"] == pytest.approx(m[i])
    assert out["simulated_peak"] == pytest.approx(1.1 * m[i])
    assert out["measured_peak_time"] == pytest.approx(TIME[i])
    assert out["peak_time_error"] == pytest.approx(0.0)
    assert out["sg_magnitude"] == pytest.approx(0.1, abs=1e-9)
    assert out["sg_phase"] == pytest.approx(0.0, abs=1e-6)
    assert out["theil_u"] == pytest.approx(0.1 / 2.1)
    assert out["iso_slope"] == pytest.approx(0.95, rel=1e-6)
    assert out["iso_phase"] == 1.0
    assert 0.0 < out["iso_rating"] < 1.0


def test_channel_metrics_undefined_values_are_none():
    m = np.zeros(TIME.size)
    out = channel_metrics(TIME, m, _transient())
    assert out["sg_magnitude"] is None and out["sg_phase"] is None
    json.dumps(out, allow_nan=False)
