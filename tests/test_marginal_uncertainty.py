"""A mechanism's stated uncertainty with the rig's parameters free (``_updating.marginal_uncertainty``).

The truth is linear least squares: with a residual of white noise at the
stated level, a signature whose correlation with a parameter's sensitivity
is rho has, with that parameter free and its prior weak, a marginal
standard deviation 1 / sqrt(1 - rho^2) times the one with the parameter
held, and the two estimates correlate by -rho; a tight prior pins the
parameter and the widening goes.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dragline.compare.diagnose._hypotheses import Problem
from dragline.compare.diagnose._updating import marginal_uncertainty
from dragline.simulate import load_rig


def _case(rho, tolerance, seed=3):
    rng = np.random.default_rng(seed)
    n = 4000
    time = np.arange(n) * 0.005
    channels = ["bucket.x", "bucket.z"]
    sigma = np.array([1e-3, 1e-3])
    # two zero-mean, orthogonal shapes (whole periods), so that the offsets take nothing from either
    a = np.column_stack([np.sin(2 * np.pi * 0.5 * time), np.cos(2 * np.pi * 1.5 * time)])
    b = np.column_stack([np.sin(2 * np.pi * 2.5 * time), np.cos(2 * np.pi * 3.5 * time)])
    a /= np.linalg.norm(a)
    b /= np.linalg.norm(b)
    signature = 0.05 * (rho * a + math.sqrt(1 - rho**2) * b)
    sensitivity = 0.05 * a
    residual = rng.normal(size=(n, 2)) * sigma
    problem = Problem(time, residual, sigma, t_stop=time[-1])
    param = dataclasses.replace(load_rig("dragline").tolerances[0], tolerance=tolerance)
    ctx = {"parameters": [param], "channels": channels}
    update = {"active": np.array([0]), "sensitivities": [sensitivity]}
    sim = np.zeros((n, 2))  # a rest pose: the clock shift's column (the rate) is zero
    return marginal_uncertainty(problem, ctx, update, signature, sim, residual)


@pytest.mark.parametrize("rho", [0.5, 0.8, 0.95])
def test_a_free_parameter_widens_the_interval_as_its_correlation_says(rho):
    out = _case(rho, tolerance=1e3)
    # held: one over the signature's norm in noise units (0.05 / 1e-3 = 50), as white noise at the stated level
    # gives; the residual's own scatter (the sandwich's batches) reads it within its sampling error
    assert out["fixed_rig_sd"] == pytest.approx(1.0 / 50.0, rel=0.15)
    assert out["sd"] / out["fixed_rig_sd"] == pytest.approx(1.0 / math.sqrt(1.0 - rho**2), rel=0.1)
    assert out["correlations"][0]["correlation"] == pytest.approx(-rho, abs=0.05)


def test_a_parameter_its_prior_pins_leaves_the_interval_as_with_the_rig_held():
    out = _case(0.95, tolerance=1e-6)
    assert out["sd"] / out["fixed_rig_sd"] == pytest.approx(1.0, abs=0.02)
