"""The paper-rig identification (tools/identify_paper_rig.py): its rig, residuals and costs, and its result built in."""

import importlib.util
import json

import numpy as np
import pytest

from conftest import REPO
from dragline.simulate import dig_maneuver, load_rig, simulate

_spec = importlib.util.spec_from_file_location("identify_paper_rig", REPO / "tools" / "identify_paper_rig.py")
ip = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ip)
NOMINAL = {name: p[0] for name, p in ip.PARAMETERS.items()}


def test_the_built_in_rig_is_the_identified_geometry_and_parameters_move_both_sides():
    record = json.loads((REPO / "samples" / "paper_rig" / "identification.json").read_text())
    document = ip.builtin_rig_document()
    rig, built_in = ip.rig_at(record["identified"]["parameters"], document), load_rig()
    for name in ("left_drag_chain", "right_lower_hoist_chain", "dump_rope"):
        np.testing.assert_array_equal(rig.bodies["bucket"].points[name], built_in.bodies["bucket"].points[name])
    for name in ("boom_pulley", "hoist_reel", "drag_reel"):
        np.testing.assert_array_equal(rig.fixed_points[name], built_in.fixed_points[name])
    moved = ip.rig_at({**NOMINAL, "bucket.hitch.x": 0.21, "fixed.boom_pulley.z": -4.1}, document)
    for side in ("left", "right"):
        assert moved.bodies["bucket"].points[f"{side}_drag_chain"][0] == 0.21
    assert moved.fixed_points["boom_pulley"][2] == -4.1
    assert document["fixed_points"]["boom_pulley"][2] == built_in.fixed_points["boom_pulley"][2]  # input untouched


def test_the_second_stage_prices_a_number_outside_its_target_above_a_smaller_sum():
    inside = {"a": 0.85, "b": 0.85}  # sum of squares 1.445, every number on target
    outside = {"a": 1.05, "b": 0.0}  # 1.1025: smaller, one number off target
    assert ip.cost(outside) < ip.cost(inside)
    assert ip.target_cost(inside) == ip.cost(inside)
    assert ip.target_cost(outside) > ip.target_cost(inside)
    box = ip.polish_bounds([p[1] for p in ip.PARAMETERS.values()])  # at every lower bound: clipped there
    for (low, high), (_, lo, hi, _) in zip(box, ip.PARAMETERS.values()):
        assert low == lo and high == pytest.approx(lo + ip.POLISH_BOX * (hi - lo))


def test_residuals_are_misses_over_the_targets_tolerances():
    fig = {"start_z": -1.23, "start_pitch_deg": -55.0, "end_z": -0.70,
           "bucket.vx": {"value": 1.01 * 1.15, "time_s": 5.95 + 0.3},
           "bucket.vz": {"value": -0.91, "time_s": 6.27},
           "bucket.q": {"value": 3.2, "time_s": 6.77 - 0.15}}
    r = ip.residuals(fig)
    assert r["start_z"] == pytest.approx(-1.0) and r["start_pitch"] == pytest.approx(-1.0) and r["end_z"] == 0.0
    assert r["bucket.vx.value"] == pytest.approx(1.0) and r["bucket.vx.time"] == pytest.approx(1.0)
    assert r["bucket.vz.value"] == pytest.approx(0.0)  # the paper's sizes, our signs
    assert r["bucket.q.time"] == pytest.approx(-0.5)


def test_the_rig_before_identification_meets_the_poses_and_misses_the_peaks():
    """What the issue reports of the rig and reading before: poses on target, the predicted peaks far off."""
    fig = ip.figures(NOMINAL, ip.builtin_rig_document())
    r = ip.residuals(fig)
    assert abs(r["start_z"]) < 1 and abs(r["start_pitch"]) < 1
    assert abs(fig["bucket.q"]["value"]) < 1.5  # the paper's simulation: 3.2 rad/s
    assert sum(abs(v) > 1 for v in r.values()) >= 3


def test_the_rig_file_written_is_the_rig_fitted(tmp_path):
    values = {**NOMINAL, "bucket.hitch.x": 0.1423, "bucket.trunnion.z": -0.0778, "fixed.drag_reel.x": -0.2179}
    text = ip.rig_text_at(values, ip.builtin_rig_text())
    (tmp_path / "rig.toml").write_text(text)
    written, fitted = load_rig(tmp_path / "rig.toml"), ip.rig_at(values, ip.builtin_rig_document())
    for body in written.bodies:
        for name, point in written.bodies[body].points.items():
            np.testing.assert_array_equal(point, fitted.bodies[body].points[name])
    for name, point in written.fixed_points.items():
        np.testing.assert_array_equal(point, fitted.fixed_points[name])
    assert "# hitches either side of the nose" in text  # the file's comments kept


def test_the_built_in_rig_and_dig_meet_the_papers_numbers_they_were_fitted_to():
    """The built-in rig and dig maneuver, simulated as a user would: every pose and peak on the issue's targets."""
    rig = load_rig()
    table = simulate(rig, dig_maneuver(), duration=8.5).table
    assert table["bucket.z"].iloc[0] == pytest.approx(-1.2, abs=0.03)
    assert np.degrees(table["bucket.pitch"].iloc[0]) == pytest.approx(-52.0, abs=3.0)
    assert ip._rest_height(rig, 10.1, 1.4) == pytest.approx(-0.70, abs=0.03)
    paper = {"bucket.vx": (1.01, 5.95), "bucket.vz": (0.91, 6.27), "bucket.q": (3.2, 6.77)}  # sizes, seconds
    for channel, (value, time_s) in paper.items():
        k = int(np.argmax(np.abs(table[channel].to_numpy())))
        assert abs(table[channel].iloc[k]) == pytest.approx(value, rel=0.15), channel
        assert table["time"].iloc[k] == pytest.approx(time_s, abs=0.3), channel
