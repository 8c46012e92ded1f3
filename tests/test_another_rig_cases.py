"""The another-rig benchmark's cases and figures (dragline.benchmarks._another_rig)."""

import numpy as np
import pytest

from dragline.benchmarks._another_rig import another_rig_cases, another_rig_figures, beyond_bounds
from dragline.compare import BOUND_TOLERANCES
from dragline.simulate import load_rig


def test_geometry_is_set_beyond_the_updatings_bounds_on_the_drawn_side_and_nothing_else_moves():
    parameters = load_rig(None).tolerances
    drawn = np.array([0.3 * p.tolerance * (-1) ** i for i, p in enumerate(parameters)])
    kept = drawn.copy()
    moved = beyond_bounds(parameters, drawn, "fixed_point", 1.5)
    np.testing.assert_array_equal(drawn, kept)  # the input is not modified
    for p, before, after in zip(parameters, drawn, moved):
        if p.kind == "fixed_point":
            # 1.5 bounds of 3 tolerances of 5 mm: 22.5 mm, on the side the draw put it
            assert after == pytest.approx(np.sign(before) * 1.5 * BOUND_TOLERANCES * p.tolerance)
            assert abs(after) == pytest.approx(0.0225)
        else:
            assert after == before
    with pytest.raises(ValueError, match="no reel_zero parameter"):
        beyond_bounds([p for p in parameters if p.kind != "reel_zero"], drawn[:0], "reel_zero", 3.0)


def test_the_case_list_is_three_kinds_at_three_multiples_beside_cases_within_tolerance():
    cases = another_rig_cases(620)
    another = [c for c in cases if c[0] and c[0].startswith("another_rig:")]
    assert sorted({c[0] for c in another}) == ["another_rig:cg", "another_rig:fixed_point", "another_rig:reel_zero"]
    assert sorted({c[1] for c in another}) == [1.5, 3.0, 6.0] and len(another) == 9
    assert sum(c[0] is None for c in cases) == 5 and len(cases) == 19
    assert len({c[2] for c in cases}) == len(cases) and all(c[3] == "realistic" for c in cases)


def _case(seed, truth, ratio, verdict, without=None):
    out = {"seed": seed, "truth": truth, "value": 1.0, "offset_ratio": ratio, "verdict": verdict,
           "right": verdict in ("none", "unexplained") if truth.startswith("another_rig:") else verdict == truth,
           "offset_rule": without is not None, "reason": "constant offsets beyond ..." if without else ""}
    if without is not None:
        out["verdict_without_offset_rule"] = without
    return out


def test_the_factor_is_bounded_below_by_rigs_within_tolerance_and_above_by_another_rig_that_names_a_mechanism():
    results = [_case(1, "none", 2.0, "none"), _case(2, "pulley_friction", 3.1, "pulley_friction"),
               _case(3, "another_rig:cg", 8.0, "unexplained", without="pulley_friction"),
               _case(4, "another_rig:cg", 4.0, "none"),  # no mechanism named either way: bounds nothing
               _case(5, "another_rig:fixed_point", 12.0, "unexplained", without="aero_drag"),
               _case(6, "another_rig:reel_zero", 4.5, "aero_drag")]  # the rule did not fire: a false name
    f = another_rig_figures(results)
    assert (f["lowest"], f["lowest_set_by"]) == (3.1, 2)
    assert (f["highest"], f["highest_set_by"]) == (4.5, 6)
    assert f["n_another_rig"] == 4 and f["another_rig_right"] == 3 and f["another_rig_named_a_mechanism"] == 1
    assert f["another_rig_rule_fired"] == 2 and f["within_tolerance_rule_fired"] == 0
