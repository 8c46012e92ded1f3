"""A mechanism's stated uncertainty with the rig's parameters free (``_confounding.marginal_uncertainty``).

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

from dragline.compare.diagnose._problem import Problem
from dragline.compare.diagnose._confounding import marginal_uncertainty
from dragline.simulate import load_rig


def _case(rho, tolerance, seed=3, finer_shift=None):
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
    finer = None if finer_shift is None else sim + finer_shift * signature
    return marginal_uncertainty(problem, ctx, update, signature, sim, residual, finer=finer)


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


def test_the_finer_discretizations_shift_of_the_value_joins_the_interval_twice_over():
    """A finer model whose whole difference is the signature times 0.1 moves ln p by 0.1; the truth, about
    twice as far as the next level (Richardson), widens the standard deviation by 0.2 in quadrature."""
    plain = _case(0.8, tolerance=0.05)
    shifted = _case(0.8, tolerance=0.05, finer_shift=0.1)
    assert shifted["discretization_shift"] == pytest.approx(0.1, rel=1e-9)
    assert shifted["sd"] ** 2 == pytest.approx(plain["sd"] ** 2 + 0.2**2, rel=1e-9)
    assert plain["discretization_shift"] is None


def test_the_signatures_slope_is_the_secant_across_the_optimum_over_a_slope_not_a_rounding():
    from dragline.compare.diagnose._steps import _signature_slope

    shape = np.array([[1.0, -2.0], [0.5, 3.0]])

    def sim(v):  # channels quadratic in ln p: a secant across the optimum is its slope there to the gap squared
        x = math.log(v) - math.log(0.02)
        return shape * (x + 0.5 * x * x)

    points = [(0.0, sim(1.0) * 0, None)] + [(v, sim(v), None) for v in (0.005, 0.0199, 0.0201, 0.019, 0.021, 0.08)]
    slope = _signature_slope(points, 0.02, refitted=False)
    # 0.0199 and 0.0201 lie closer than a slope's worth (0.04 in ln p); of the pairs across 0.02 far enough apart
    # the nearest is 0.0199 and 0.021 (0.054 in ln p from it in all, against 0.056 for 0.019 and 0.0201)
    xa, xb = math.log(0.0199 / 0.02), math.log(0.021 / 0.02)
    assert slope == pytest.approx(shape * (1.0 + (xa + xb) / 2), rel=1e-9)
    # a joint refit's point, on another rig, is never one of the pair
    refitted = [*points, (0.0202, sim(0.0202) + 5.0, None)]
    assert _signature_slope(refitted, 0.02, refitted=True) == pytest.approx(slope, rel=1e-12)
    assert _signature_slope(points[:2], 0.02, refitted=False) is None


def _scored(value=0.02, curvature=4.0e4, improvement=1.0e5):
    """A candidate's fit whose chi2(ln p) is a parabola of the given curvature about ``value``."""
    xs = math.log(value) + np.array([-0.2, -0.1, 0.0, 0.1, 0.2])
    profile = [(math.exp(x), 1.0e6 + curvature * (x - math.log(value)) ** 2) for x in xs]
    return {"value": value, "profile": profile, "fold_values": [value, value], "at_bound": None,
            "improvement": improvement}


def test_the_model_errors_part_along_the_signature_moves_a_linear_fit_as_the_interval_states():
    """Linear least squares: a signature g (its chi2 D = |g|^2 the improvement it brings) and a model error e
    of chi2 E whose share s^2 lies along g move the fitted amplitude by s sqrt(E / D); with s the calibrated
    ERROR_ALONG_SIGNATURE that shift is the stated term, and it joins the rest in quadrature."""
    from dragline.compare.diagnose._summary import ERROR_ALONG_SIGNATURE, stated_uncertainty

    rng = np.random.default_rng(7)
    n, D, E = 5000, 4.0e5, 5.0e4
    g = rng.normal(size=n)
    g *= math.sqrt(D) / np.linalg.norm(g)
    other = rng.normal(size=n)
    other -= (other @ g) / D * g
    s = ERROR_ALONG_SIGNATURE
    e = math.sqrt(E) * (s * g / math.sqrt(D) + math.sqrt(1 - s * s) * other / np.linalg.norm(other))
    shift = ((g + e) @ g) / D - 1.0  # the truth's amplitude is 1; d ln p = d p / p there
    base = stated_uncertainty(_scored(improvement=D), "mu", kappa=1.0)
    with_error = stated_uncertainty(_scored(improvement=D), "mu", kappa=1.0, own_error=E)
    assert with_error["model_error_relative"] == pytest.approx(shift, rel=0.01)
    assert with_error["relative"] ** 2 == pytest.approx(base["relative"] ** 2 + shift**2, rel=0.02)
    assert base["model_error_relative"] is None


def test_a_fit_that_improves_no_held_out_data_states_no_interval():
    from dragline.compare.diagnose._summary import stated_uncertainty

    out = stated_uncertainty(_scored(improvement=-10.0), "mu", kappa=1.0, own_error=5.0e4)
    assert out["relative"] is None and out["interval_68"] is None and out["interval_95"] is None
