"""The site-resolved cases (``benchmarks/_site_cases.py``): what they hide, and how a verdict is scored."""

from __future__ import annotations

import pytest

from dragline.benchmarks._site_cases import SITE_CASES, SITE_THRESHOLDS, _screened, beyond_range, site_cases, site_right
from dragline.simulate import load_rig, mechanism_sites, mechanism_type


def test_each_law_sits_at_a_site_of_its_machine_at_its_multiples_of_the_threshold():
    for machine, names in SITE_CASES.items():
        rig = load_rig(machine)
        for name in names:
            law, _, site = name.partition("@")
            assert site in mechanism_sites(rig, law), name
    cases, left = site_cases(seed=9), beyond_range()
    thresholds = SITE_THRESHOLDS["dragline"]
    assert len(cases) + len(left) == 3 * len(SITE_CASES["dragline"])
    by_truth = {}
    for name, value, _ in cases:
        by_truth.setdefault(name, []).append(value / thresholds[name])
        assert value <= mechanism_type(name).range[1]
    for name, value, top in left:
        by_truth.setdefault(name, []).append(value / thresholds[name])
        assert value > top == mechanism_type(name).range[1]
    for name, multiples in by_truth.items():
        assert sorted(multiples) == pytest.approx([2, 5, 20], rel=5e-3), name
    assert len({c[2] for c in cases}) == len(cases) and all(9500 <= c[2] < 9600 for c in cases)
    # the crane: its hoist rope's damping has no threshold within its law's range, so no case of it
    crane = [c[0] for c in site_cases(seed=9, rig_name="hook_block_crane")]
    assert "rope_damping_excess@hoist_rope" not in crane and len(crane) == 8
    with pytest.raises(ValueError, match="no site cases for 'pendulum'"):
        site_cases(seed=9, rig_name="pendulum")


def test_the_right_site_is_the_true_one_or_a_small_set_holding_it():
    cos = {"boom": 1.0, "hoist_cluster": -0.2}
    name = "pulley_friction@boom"
    assert site_right(name, "pulley_friction@boom", cos) == (True, True)
    assert site_right(name, "pulley_friction@boom+hoist_cluster", cos) == (True, True)  # two sites at most
    assert site_right(name, "pulley_friction@hoist_cluster", cos) == (True, False)
    assert site_right(name, "pulley_friction", cos) == (True, True)  # everywhere: both sites, two at most
    three = {"a": 1.0, "b": 0.95, "c": 0.2}
    assert site_right("pulley_friction@a", "pulley_friction", three) == (True, False)  # not all alike
    assert site_right("pulley_friction@a", "pulley_friction", {"a": 1.0, "b": 0.95, "c": 0.92}) == (True, True)
    assert site_right(name, "pulley_inertia@boom", cos) == (False, False)
    assert site_right(name, "unexplained", cos) == (False, False)
    chains = {"a": 1.0, "b": 0.95, "c": 0.93, "d": 0.5}
    assert site_right("chain_link_friction@a", "chain_link_friction@a+b+c", chains) == (True, True)  # all alike
    assert site_right("chain_link_friction@a", "chain_link_friction@a+b+d", chains) == (True, False)


def test_a_law_named_among_those_the_recording_could_not_tell_apart_is_right_with_its_own_sites():
    cos = {"boom": 1.0, "hoist_cluster": -0.2}
    name = "sheave_bearing_friction@boom"
    # named beside the capstan it could not be told from: the law right, its site from its own candidate
    assert site_right(name, "pulley_friction@hoist_cluster", cos,
                      alike_laws=["sheave_bearing_friction@boom"]) == (True, True)
    assert site_right(name, "pulley_friction@boom", cos,
                      alike_laws=["sheave_bearing_friction@hoist_cluster"]) == (True, False)
    # three laws are no answer, as three sites are not
    assert site_right(name, "pulley_friction@boom", cos,
                      alike_laws=["sheave_bearing_friction@boom", "pulley_inertia@boom"]) == (False, False)
    # an alike law that is not the truth's does not make the verdict's law right
    assert site_right(name, "pulley_friction@boom", cos, alike_laws=["pulley_inertia@boom"]) == (False, False)


def test_the_screen_is_read_for_the_candidate_holding_the_true_site():
    doc = {"site_screen": [{"name": "aero_drag@spreader_bar+hoist_cluster", "improvement": 5.0, "fitted": True},
                           {"name": "aero_drag@bucket", "improvement": 0.5, "fitted": False},
                           {"name": "pulley_friction@hoist_cluster", "improvement": 0.1, "fitted": True}]}
    assert _screened(doc, "aero_drag@hoist_cluster") is True
    assert _screened(doc, "aero_drag@bucket") is False
    assert _screened(doc, "pulley_inertia@boom") is None


def test_a_site_the_rig_has_not_and_a_machine_without_site_cases_exit_2_with_one_line():
    import subprocess
    import sys

    for args, word in ((["detection", "--candidates", "pulley_friction@derrick"], "derrick"),
                       (["discovery", "--realism", "--sites", "--rig", "pendulum"], "no site cases")):
        out = subprocess.run([sys.executable, "-m", "dragline.pipelines.cli", "bench", *args], capture_output=True,
                             text=True)
        assert out.returncode == 2, out.stderr
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and word in lines[0] and "Traceback" not in out.stderr


def _moved(parameter, coordinate, sd=0.1, tolerance=0.6931471805599453):
    return {"parameter": parameter, "coordinate": coordinate, "coordinate_sd": sd, "identifiable": True,
            "shift_in_tolerances": coordinate / tolerance}


def test_a_rig_file_value_beyond_its_tolerance_is_the_updatings_to_report_within_its_bounds():
    import math

    import numpy as np

    from dragline.benchmarks._site_cases import rig_value_right
    from dragline.simulate import load_rig

    parameters = load_rig(None).tolerances
    wire = next(i for i, p in enumerate(parameters) if p.name == "ropes.wire_rope.viscous_damping")
    tol = parameters[wire].tolerance  # ln 2
    drawn = np.zeros(len(parameters))
    drawn[wire] = 0.5 * tol
    name = "rope_damping_excess@wire_rope"
    # The truth 5.84 times the file's value on top of its draw: 2.5 + 0.5 tolerances above it.
    truth = drawn[wire] + math.log(5.84)
    up = _moved("ropes.wire_rope.viscous_damping", truth - 0.1)
    right, site, updated = rig_value_right(name, 4.84, "none", parameters, drawn, [up])
    assert right and site and updated == pytest.approx(math.exp(-0.1))
    # Another verdict, the value moved the wrong way, or not beyond its tolerance: wrong.
    assert rig_value_right(name, 4.84, "unexplained", parameters, drawn, [up])[:2] == (False, False)
    assert rig_value_right(name, 4.84, "none", parameters, drawn, [_moved(up["parameter"], -1.5)])[0] is False
    assert rig_value_right(name, 4.84, "none", parameters, drawn, [_moved(up["parameter"], 0.6)])[0] is False
    # Not told apart: two other rope types' damping moved too (three sites); one other is a set of two.
    others = [_moved("ropes.dump_rope.viscous_damping", 1.2), _moved("ropes.chain.viscous_damping", 1.0)]
    assert rig_value_right(name, 4.84, "none", parameters, drawn, [up, *others])[:2] == (True, False)
    assert rig_value_right(name, 4.84, "none", parameters, drawn, [up, others[0]])[:2] == (True, True)
    # A truth the file's tolerance still holds (drawn 0.3 below, 1.2 times on top): "none" is right.
    drawn[wire] = -0.3 * tol
    assert rig_value_right(name, 0.2, "none", parameters, drawn, []) == (True, True, None)


def test_a_recording_whose_filmed_truth_the_adequacy_rule_would_refuse_is_counted_and_said():
    """The truth's own floor (``recording_floor``) beyond ADEQUATE_RMS squared: not even the motion filmed would
    pass rule 5b's guard there, and the summary says how many such recordings a run had."""
    from dragline.benchmarks._site_cases import summary_lines
    from dragline.compare import DecisionRules

    limit = DecisionRules().adequate_rms ** 2
    case = {"truth": "pulley_friction@boom", "value": 0.01, "verdict": "unexplained", "truth_cosines": {"boom": 1.0},
            "right_law": False, "right_site": False, "screened_in": True, "diagnosis_seconds": 1.0}
    cases = [dict(case, truth_floor={"chi2_per_sample": f, "worst_channel": "bucket.pitch",
                                     "worst_chi2_per_sample": 3 * f, "beyond_adequate": f > limit})
             for f in (0.9 * limit, 1.1 * limit)]
    report = {"n_cases": 2, "seed": 1, "right_law": 0, "right_site": 0, "within": 0, "screened_in": 2,
              "floor_beyond_adequate": sum(c["truth_floor"]["beyond_adequate"] for c in cases), "cases": cases,
              "beyond_range": []}
    lines = summary_lines(report)
    assert "by more than the adequacy rule allows (2.4 sigma): 1 of 2" in lines[1]
    assert f"truth's own floor {1.1 * limit:.2f} per sample, bucket.pitch" in lines[3]
