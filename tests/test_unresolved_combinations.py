"""Combinations of parameters a recording sees only together (``compare.diagnose._unresolved``)."""

from __future__ import annotations

import numpy as np
import pytest

from dragline.compare.diagnose._unresolved import SEEN, unresolved_combinations


def _design(seed, scale_pair=1.0, leak=0.0):
    """Columns: a, b (b = -a: a rise of both moves nothing), c (its own), and an offset nuisance."""
    rng = np.random.default_rng(seed)
    f, g, h = rng.normal(size=(3, 400))
    offset = np.ones(400)
    return np.column_stack([scale_pair * f, -scale_pair * f + leak * h, g, offset])


def test_two_parameters_moving_nothing_together_are_one_combination_with_no_information():
    X = _design(1, scale_pair=50.0)
    names = ["bodies.load.mass", "ropes.rope.static_stiffness", "bodies.load.cg_z"]
    (combo,) = unresolved_combinations(X, np.array([0.02**2, 1.1**2, 0.03**2, 0.005**2]), [0, 1, 2],
                                       np.array([0.02, 1.1, 0.03]), names)
    assert set(combo["parameters"]) == {"bodies.load.mass", "ropes.rope.static_stiffness"}
    # the direction is the one that moves nothing, (1, 1) in the coordinates, whatever the tolerances
    assert combo["parameters"]["bodies.load.mass"] == pytest.approx(combo["parameters"]["ropes.rope.static_stiffness"])
    assert combo["information"] == pytest.approx(0.0, abs=1e-9)


def test_a_combination_the_data_sees_well_enough_to_halve_its_prior_is_not_reported():
    # the leak gives the direction (1, 1) information leak^2 |h|^2 per unit coordinate: at tolerances 1 that is
    # about 400 leak^2 - below SEEN at leak 0.05 (about 1), above at 0.2 (about 16)
    tol = np.array([1.0, 1.0, 1.0])
    prior = np.array([1.0, 1.0, 1.0, 0.005**2])
    faint = unresolved_combinations(_design(2, leak=0.05), prior, [0, 1, 2], tol, ["a", "b", "c"])
    assert len(faint) == 1 and 0.0 < faint[0]["information"] < SEEN
    assert unresolved_combinations(_design(2, leak=0.2), prior, [0, 1, 2], tol, ["a", "b", "c"]) == []


def test_a_nuisance_that_takes_up_a_parameters_whole_effect_leaves_it_unseen_alone_and_unreported():
    # c's column is the offset's: projected out it carries nothing; a lone parameter is its own "not identifiable"
    X = _design(3)
    X[:, 2] = X[:, 3]
    assert unresolved_combinations(X, np.array([1.0, 1.0, 1.0, 1e6]), [0, 1, 2], np.ones(3), ["a", "b", "c"]) == [
        {"parameters": {"a": pytest.approx(1.0), "b": pytest.approx(1.0)}, "information": pytest.approx(0.0, abs=1e-9)}]


def test_differences_either_way_agree_on_a_smooth_response_and_not_on_scatter():
    from dragline.compare.diagnose._updating import ROUGH, one_sided_disagreement

    rng = np.random.default_rng(7)
    b, c = rng.normal(size=(2, 500)) + np.array([[3.0], [0.0]])
    h = 0.01
    # f(x) = b x + c x^2: the forward difference b + c h, the backward b - c h, apart by 2 |c| h / |b| exactly
    assert one_sided_disagreement(b + c * h, b - c * h) == pytest.approx(2 * h * np.linalg.norm(c) / np.linalg.norm(b))
    # two independent scatters: about 2; a derivative under scatter rho times its size (each way its own):
    # 2 sqrt(2) rho / sqrt(4 + 2 rho^2)
    s1, s2 = rng.normal(size=(2, 20000))
    assert one_sided_disagreement(s1, s2) == pytest.approx(2.0, rel=0.05)
    f = rng.normal(size=20000)
    for rho in (0.2, 1.0):
        expected = 2 * np.sqrt(2) * rho / np.sqrt(4 + 2 * rho**2)
        assert one_sided_disagreement(f + rho * s1, f + rho * s2) == pytest.approx(expected, rel=0.05)
    assert one_sided_disagreement(f + 0.2 * s1, f + 0.2 * s2) < ROUGH < one_sided_disagreement(f + s1, f + s2)
    assert one_sided_disagreement(np.zeros(3), np.zeros(3)) == 0.0
