"""Combinations of parameters a recording sees only together (``compare.diagnose._unresolved``)."""

from __future__ import annotations

from pathlib import Path

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
    from dragline.compare.diagnose._differences import ROUGH, one_sided_disagreement

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


def test_a_shared_length_is_said_with_each_trials_cable_end_it_trades_with_and_never_with_a_start():
    # two flights of the three-drone box: lengthening the first cable by d and raising its end under the drone by
    # d on both flights moves nothing (the rows of each flight see the length and that flight's end alike); each
    # flight's start and the box's mass centre are seen on their own
    import dataclasses

    from dragline.compare.diagnose._trials import each_trials_own
    from dragline.compare.diagnose._unresolved import combination_columns
    from dragline.simulate import load_rig

    box = load_rig(Path(__file__).resolve().parents[1] / "benchmarks" / "real" / "hmer101.toml")
    wanted = ("ropes.c1.length", "bodies.box.cg_x", "tracks.drone1.z")
    chosen = [p for p in box.tolerances if p.name in wanted]
    params = list(each_trials_own(chosen, ["A", "B"]))
    length = next(p for p in params if p.name == "ropes.c1.length")
    params.append(dataclasses.replace(length, name="start.A.box.x", kind="start", trial="A"))
    names = [p.name for p in params]
    columns = combination_columns(params)
    assert [names[k] for k in columns] == [n for n in names if not n.startswith("start.")]

    rng = np.random.default_rng(5)
    rows = 300
    f_a, f_b, g, s = rng.normal(size=(4, rows))
    X = np.zeros((2 * rows, len(params) + 1))  # the last column a nuisance offset
    col = {n: k for k, n in enumerate(names)}
    X[:rows, col["ropes.c1.length"]], X[rows:, col["ropes.c1.length"]] = 40 * f_a, 40 * f_b
    X[:rows, col["tracks.A.drone1.z"]], X[rows:, col["tracks.B.drone1.z"]] = 40 * f_a, 40 * f_b
    X[:, col["bodies.box.cg_x"]] = 40 * np.r_[g, g[::-1]]
    X[:rows, col["start.A.box.x"]] = 40 * s
    X[:, -1] = 1.0
    tol = np.array([p.tolerance for p in params])
    prior_var = np.r_[tol**2, 1.0]
    (combo,) = unresolved_combinations(X, prior_var, columns, tol[columns], [names[k] for k in columns])
    loading = combo["parameters"]
    assert set(loading) == {"ropes.c1.length", "tracks.A.drone1.z", "tracks.B.drone1.z"}
    # the length up by d, both ends by -d: the direction that moves nothing, in metres
    assert loading["tracks.A.drone1.z"] == pytest.approx(-loading["ropes.c1.length"])
    assert loading["tracks.B.drone1.z"] == pytest.approx(-loading["ropes.c1.length"])
    assert combo["information"] == pytest.approx(0.0, abs=1e-6)
    # asked among the shared parameters alone (the ends projected out with their prior) it is not said
    shared = [k for k in columns if not params[k].of_a_trial]
    assert unresolved_combinations(X, prior_var, shared, tol[shared], [names[k] for k in shared]) == []
