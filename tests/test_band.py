"""The split of a candidate's improvement into the band the model resolves and the band above it."""

import numpy as np
import pytest

from dragline.compare.diagnose._band import RESOLVED_HZ, band_improvement
from dragline.compare.diagnose._problem import Problem

RATE = 200.0
N = 2000


def _problem(sigma=(0.001, 0.002), unmeasured=0):
    time = np.arange(N) / RATE
    measured = np.zeros((N, len(sigma)))
    measured[:unmeasured, 0] = np.nan
    return Problem(time, measured, np.array(sigma), t_stop=time[-1] + 1.0), time


def test_an_improvement_above_the_cutoff_counts_nothing_resolved():
    problem, t = _problem()
    swing = 0.003 * np.sin(2 * np.pi * 0.6 * t)  # a body's swing
    ringing = 0.002 * np.sin(2 * np.pi * 16.0 * t)  # a chain's own mode
    before = np.column_stack([swing + ringing, 2 * (swing + ringing)])
    after = np.column_stack([swing, 2 * swing])  # the candidate removed the ringing only
    out = band_improvement(problem, before, after)
    # Parseval: a whole number of periods of a sine of amplitude A holds A^2 N / 2.
    expected = (0.002**2 * N / 2) / 0.001**2 + (0.004**2 * N / 2) / 0.002**2
    assert out["total"] == pytest.approx(expected, rel=1e-9)
    assert abs(out["resolved"]) < 1e-6 * expected
    assert out["resolved_share"] == pytest.approx(0.0, abs=1e-6)


def test_an_improvement_of_the_swing_is_resolved_whatever_rings_above():
    problem, t = _problem()
    swing = 0.003 * np.sin(2 * np.pi * 0.6 * t)
    ringing = 0.002 * np.sin(2 * np.pi * 16.0 * t)
    before = np.column_stack([swing + ringing, np.zeros(N)])
    after = np.column_stack([ringing, np.zeros(N)])
    out = band_improvement(problem, before, after)
    assert out["resolved"] == pytest.approx((0.003**2 * N / 2) / 0.001**2, rel=1e-9)
    assert out["resolved_share"] == pytest.approx(1.0, rel=1e-9)
    assert out["channels"][1] == 0.0


def test_unmeasured_samples_count_nothing_and_the_cutoff_sits_between_swing_and_ringing():
    problem, t = _problem(unmeasured=100)
    assert 3.0 < RESOLVED_HZ < 10.0
    before = np.column_stack([0.003 * np.sin(2 * np.pi * 0.6 * t), np.zeros(N)])
    before[:100, 0] = np.nan
    out = band_improvement(problem, before, np.where(np.isnan(before), np.nan, 0.0))
    assert np.isfinite(out["total"]) and out["total"] > 0
    assert out["resolved"] == pytest.approx(out["total"], rel=0.02)
