"""``dragline bench discovery``'s scoring: case list and summary on hand-built results."""

import math

import numpy as np
import pytest

from dragline.benchmarks._discovery import MAGNITUDES, REALISTIC_MAGNITUDES, _summarise, default_cases
from dragline.compare.diagnose._hypotheses import N_GRID
from dragline.simulate import MECHANISMS


@pytest.mark.parametrize("table", [MAGNITUDES, REALISTIC_MAGNITUDES], ids=["nominal", "realistic"])
def test_case_magnitudes_sit_inside_the_range_and_off_the_fit_grid(table):
    # A truth at a bound or on a grid point is "found" exactly by construction.
    for name, values in table.items():
        lo, hi = MECHANISMS[name].range
        grid = [math.log(lo) + k * (math.log(hi) - math.log(lo)) / (N_GRID - 1) for k in range(N_GRID)]
        for v in values:
            assert lo < v < hi, (name, v)
            assert min(abs(math.log(v) - g) for g in grid) > 0.1, (name, v)


def test_default_cases_hold_enough_no_physics_cases_with_distinct_seeds():
    cases = default_cases()
    n_none = sum(name is None for name, _, _ in cases)
    assert n_none / len(cases) >= 0.2
    assert len({seed for _, _, seed in cases}) == len(cases)
    assert {name for name, _, _ in cases} - {None} == {n for n in MECHANISMS if MECHANISMS[n].candidate}


def test_realistic_cases_hold_no_mechanism_and_out_of_menu_shares():
    from dragline.benchmarks._discovery import realistic_cases

    for quick in (False, True):
        cases = realistic_cases(quick=quick)
        names = [name for name, _, _, _ in cases]
        assert all(world == "realistic" for *_, world in cases)
        assert names.count(None) / len(cases) >= 0.2
        out_of_menu = [n for n in names if n is not None and not (n in MECHANISMS and MECHANISMS[n].candidate)]
        assert len(out_of_menu) / len(cases) >= 0.15
        assert "sheave_bearing_damping" in out_of_menu  # a mechanism the simulator has, kept off the menu
        assert len({seed for _, _, seed, _ in cases}) == len(cases)


def _case(truth, value, verdict, rel=None, also=()):
    return {"truth": truth, "value": value, "verdict": verdict, "relative_error": rel,
            "covered": rel is not None and abs(rel) < 0.1, "diagnosis_seconds": 60.0, "also": list(also)}


def test_summary_counts_verdicts_false_positives_and_the_reliable_threshold():
    results = [
        _case("aero_drag", 0.15, "none"),
        _case("aero_drag", 0.5, "aero_drag", 0.4, also=["pulley_inertia"]),
        _case("aero_drag", 1.6, "aero_drag", -0.1),
        _case("aero_drag", 5.5, "aero_drag", 0.05),
        _case("pulley_inertia", 1e-5, "pulley_inertia", 0.9),  # found, but not at every larger value
        _case("pulley_inertia", 1e-4, "unexplained"),
        _case("pulley_inertia", 1e-3, "pulley_inertia", 0.02),
        _case("none", 0.0, "none"),
        _case("none", 0.0, "aero_drag"),
        _case("none", 0.0, "unexplained"),
    ]
    report = _summarise(results, wall=1.0, workers=2)
    assert report["accuracy"] == pytest.approx(6 / 10)
    assert report["false_positive_rate"] == pytest.approx(1 / 3)  # "unexplained" names nothing
    assert report["confusion"]["none"]["aero_drag"] == 1
    assert report["smallest_found"] == {"aero_drag": 0.5, "pulley_inertia": 1e-3}
    assert report["parameter_error"]["aero_drag"]["median_abs_relative_error"] == pytest.approx(0.1)
    # reliable: aero 0.4, 0.1, 0.05 and inertia 0.02 -> median 0.075
    assert report["median_abs_relative_error_reliable"] == pytest.approx(0.075)
    assert report["second_mechanism_false_rate"] == pytest.approx(1 / 6)  # 6 verdicts name a mechanism


def test_the_weakest_realistic_magnitudes_move_the_bucket_beyond_the_models_own_error():
    # An effect within twice what the model's own discretization moves the
    # bucket (its distance from the converged solution, docs/diagnosis.md)
    # cannot be told from the model's error: the realistic set starts above
    # it, and the limit cases probe below.
    from dragline.benchmarks._discovery import REALISTIC_LIMIT_CASES, _effect_size, _truth_world
    from dragline.simulate import simulate

    seed = 1503
    rig, maneuver, level, _, _ = _truth_world(None, 0.0, seed)
    without = simulate(rig, maneuver, level, [], duration=10.0, rate_hz=200.0)
    coarse = simulate(rig, maneuver, "baseline", [], duration=10.0, rate_hz=200.0)
    own_error = _effect_size(coarse, without)["bucket_mm"]
    assert 0.02 < own_error < 0.2

    def effect(name, value):
        world = _truth_world(name, value, seed)
        return _effect_size(simulate(*world[:4], duration=10.0, rate_hz=200.0), without)["bucket_mm"]

    for name, values in REALISTIC_MAGNITUDES.items():
        assert effect(name, min(values)) > 2.0 * own_error, name
    below = [(name, value) for name, value, *_ in REALISTIC_LIMIT_CASES
             if name == "rope_bending_damping" and value < min(REALISTIC_MAGNITUDES[name])]
    assert below and all(effect(name, value) < 2.0 * own_error for name, value in below[:1])


def test_every_machine_gets_twenty_cases_with_its_own_candidates_and_no_physics_controls():
    from dragline.benchmarks._machine_cases import DETECTABLE, MIN_CASES, MIN_NONE, machine_cases

    seen, by_rig = set(), {}
    for rig in ("pendulum", "slung_load", "gantry_crane"):
        how = {}
        cases = machine_cases(rig, seed=3, derivation=how)
        # a candidate has cases exactly where its plausible top moves the markers beyond the edge
        for name, h in how.items():
            assert (h["values"] is None) == (h["effect_at_top_mm"] < DETECTABLE * h["model_error_mm"]), (rig, name)
        by_rig[rig] = {c[0] for c in cases}
        assert len(cases) >= MIN_CASES and sum(c[0] is None for c in cases) >= MIN_NONE
        assert all(c[3] == "realistic" and c[4] == rig for c in cases)
        seeds = [c[2] for c in cases]
        assert len(set(seeds)) == len(seeds)
        seen |= {c[0] for c in cases}
        for name, value, *_ in cases:
            if name in MECHANISMS:
                lo, hi = MECHANISMS[name].range
                assert lo < value < hi
    # Chain-link friction only where there are chains (the crane's slings); pulley friction only where there is
    # a ring (the crane's hook block sheave).
    assert {"chain_link_friction", "pulley_friction"} <= by_rig["gantry_crane"]
    assert not {"chain_link_friction", "pulley_friction"} & (by_rig["pendulum"] | by_rig["slung_load"])
    assert "aero_drag" in seen


def test_a_machines_smallest_case_sits_where_the_markers_move_three_times_the_models_own_error():
    # Measured here on its own: the pendulum's aero drag, whose plausible low end (cd 0.45) moves the ball's
    # markers less than three times what the finer discretization moves them.
    from dragline.benchmarks._machine_cases import DETECTABLE, MACHINE_MAGNITUDES, detectable_magnitudes
    from dragline.simulate import body_marker_positions, default_maneuver, load_rig, make_mechanism, simulate

    rig = load_rig("pendulum")
    values, info = detectable_magnitudes(rig, "aero_drag", MACHINE_MAGNITUDES["aero_drag"])
    assert info["edge"] is not None and values[0] == info["edge"] and values[-1] == 3.3

    def markers(level, cd=None):
        physics = [] if cd is None else [make_mechanism("aero_drag", cd=cd)]
        table = simulate(rig, default_maneuver(rig), level, physics, duration=rig.demo["duration"],
                         rate_hz=100.0).motion_table()
        return body_marker_positions(table, rig, "ball")

    base = markers("baseline")
    rms = lambda d: np.sqrt(np.mean(np.sum(d**2, axis=-1)))  # noqa: E731
    own = rms(markers("medium") - base)
    assert rms(markers("baseline", values[0]) - base) >= DETECTABLE * own
    assert rms(markers("baseline", values[0] / 1.05) - base) < DETECTABLE * own


def test_a_machine_case_is_filmed_in_its_own_lab_and_diagnosed_from_its_session_alone():
    from dragline.benchmarks._discovery import _run_case

    out = _run_case("aero_drag", 1.7, 99001, "realistic", None, False, "pendulum")
    assert out["rig"] == "pendulum" and out["verdict"] == "aero_drag", out["reason"]
    assert out["fitted"] == pytest.approx(1.7, rel=0.5)
    assert set(out["calibration"]) <= {p.name for p in __import__("dragline.simulate", fromlist=["load_rig"])
                                        .load_rig("pendulum").tolerances}


def test_wilsons_interval_matches_its_closed_forms():
    from scipy.stats import norm

    from dragline.benchmarks._discovery import wilson_interval

    z = norm.ppf(0.95)
    # none of n: from 0 to z^2 / (n + z^2); all of n: mirrored
    assert wilson_interval(0, 10) == pytest.approx([0.0, z * z / (10 + z * z)], abs=1e-12)
    assert wilson_interval(10, 10) == pytest.approx([10 / (10 + z * z), 1.0], abs=1e-12)
    # half of n: centred on a half, half-width z / (2 sqrt(n + z^2))
    lo, hi = wilson_interval(20, 40)
    assert (lo + hi) / 2 == pytest.approx(0.5) and (hi - lo) / 2 == pytest.approx(z / (2 * math.sqrt(40 + z * z)))


def test_the_summary_counts_the_intervals_that_hold_the_truth_over_the_correctly_named():
    results = [
        dict(_case("aero_drag", 1.6, "aero_drag", -0.05), covered_95=True, covered_fixed_rig=True),
        dict(_case("aero_drag", 5.5, "aero_drag", 0.3), covered_95=True, covered_fixed_rig=False),
        dict(_case("aero_drag", 0.4, "aero_drag", 0.8), covered_95=False, covered_fixed_rig=False),
        dict(_case("aero_drag", 0.2, "none"), covered_95=False),  # not named: not counted
    ]
    cov = _summarise(results, wall=1.0, workers=2)["coverage"]
    assert cov["n_named"] == 3
    assert [cov[k]["covered"] for k in ("68", "95", "68_fixed_rig")] == [1, 2, 1]
    assert cov["95"]["rate"] == pytest.approx(2 / 3)


def test_the_held_out_trials_figures_count_which_model_predicts_it_best_per_kind_of_verdict():
    from dragline.benchmarks._discovery import _held_out_figures

    def case(verdict, right, nominal, updated, named=None):
        return {"verdict": verdict, "right": right,
                "held_out": {"nominal": nominal, "updated": updated, "named": named}}

    results = [case("aero_drag", True, 9.0, 5.0, 2.0), case("aero_drag", True, 9.0, 5.0, 6.0),
               case("pulley_friction", False, 4.0, 3.0, 3.5), case("none", True, 3.0, 2.0),
               case("unexplained", True, 3.0, 4.0), {"verdict": "none", "right": True}]
    out = _held_out_figures(results)
    assert out["right_named"] == {"n": 2, "named_beats_updated": 1, "updated_beats_nominal": 2,
                                  "median_rms": {"nominal": 9.0, "updated": 5.0, "named": 4.0}}
    assert out["wrong_named"]["n"] == 1 and out["wrong_named"]["named_beats_updated"] == 0
    assert out["none_or_unexplained"]["n"] == 2 and out["none_or_unexplained"]["updated_beats_nominal"] == 1
    assert out["none_or_unexplained"]["median_rms"]["named"] is None
    assert _held_out_figures([{"verdict": "none", "right": True}]) is None


def test_an_out_of_menu_effect_named_as_its_generic_law_is_modeled_and_no_false_name():
    # asked where (default,*@*), a sheave's bearing damping hidden everywhere may be named as that law at its
    # rings, and every rope's material damping as a rope type's damping beyond its tolerance: right, and counted
    # as modeled; any other law named on such a case, or on one with nothing added, is a false name
    from dragline.benchmarks._discovery import _realistic_figures, modeled, verdict_right

    assert modeled("sheave_bearing_damping", "sheave_bearing_damping@boom+hoist_cluster")
    assert modeled("material_damping", "rope_damping_excess@wire_rope")
    assert not modeled("material_damping", "rope_bending_damping@dump_rope")
    assert not modeled("none", "sheave_bearing_damping@boom")
    assert verdict_right("sheave_bearing_damping", 3e-3, True, "sheave_bearing_damping@boom")
    assert not verdict_right("sheave_bearing_damping", 3e-3, True, "pulley_friction@boom")
    results = [
        {"truth": "sheave_bearing_damping", "out_of_menu": True, "verdict": "sheave_bearing_damping@boom",
         "modeled": True, "right": True},
        {"truth": "material_damping", "out_of_menu": True, "verdict": "rope_bending_damping@dump_rope",
         "modeled": False, "right": False},
        {"truth": "material_damping", "out_of_menu": True, "verdict": "none", "modeled": False, "right": True},
        {"truth": "none", "out_of_menu": False, "verdict": "aero_drag@bucket", "right": False},
        {"truth": "none", "out_of_menu": False, "verdict": "none", "right": True},
    ]
    figures = _realistic_figures(results)
    assert figures["false_names"] == 2 and figures["n_false_name_chances"] == 5  # a law at a site is a name
    assert figures["none_named_a_mechanism"] == 1 and figures["out_of_menu_modeled"] == 1
    assert figures["out_of_menu_wrong_name_rate"] == pytest.approx(1 / 3)
