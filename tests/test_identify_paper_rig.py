"""The paper-rig identification's pieces (tools/identify_paper_rig.py): maneuver reading, rig, residuals."""

import importlib.util

import numpy as np
import pytest

from conftest import REPO
from dragline.simulate import dig_maneuver, load_rig, read_maneuver_csv, simulate

_spec = importlib.util.spec_from_file_location("identify_paper_rig", REPO / "tools" / "identify_paper_rig.py")
ip = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ip)
NOMINAL = {name: p[0] for name, p in ip.PARAMETERS.items()}


@pytest.mark.parametrize("ramp_s", [0.0, 0.0567, 0.3])
def test_every_reading_keeps_the_papers_start_and_end_lengths_and_stated_speeds(ramp_s):
    for phase1, phase3 in ((2.5, 0.48), (2.3, 0.36), (2.6, 0.3)):
        man, drag4 = ip.dig_maneuver_at(phase1, phase3, ramp_s)
        assert (man.hoist_length[0], man.drag_length[0]) == (pytest.approx(8.6, abs=1e-9), pytest.approx(4.2, abs=1e-9))
        assert man.hoist_length[-1] == pytest.approx(10.1, abs=1e-9)
        assert man.drag_length[-1] == pytest.approx(1.4, abs=1e-9)
        speed = np.diff(man.drag_length) / np.diff(man.time)
        assert speed.min() == pytest.approx(-max(0.61, phase3, drag4), abs=1e-9)  # no reel faster than asked
        hoist3 = (10.1 - 8.6 - 0.36 * phase1) / 2  # the text's 0.30 m/s at phase1 = 2.5 s
        assert np.abs(np.diff(man.hoist_length) / np.diff(man.time)).max() == pytest.approx(max(0.36, hoist3))


def test_the_landed_reading_is_the_built_in_dig_maneuver():
    man, drag4 = ip.dig_maneuver_at(2.5, 0.48, 0.0)
    dig = dig_maneuver()
    assert drag4 == pytest.approx(0.48)
    for t, hoist, drag in zip(dig.time, dig.hoist_length, dig.drag_length):
        assert np.interp(t, man.time, man.hoist_length) == pytest.approx(hoist, abs=1e-9)
        assert np.interp(t, man.time, man.drag_length) == pytest.approx(drag, abs=2e-3)  # the 5 ms table's edges


def test_the_nominal_parameters_are_the_built_in_rig_and_move_both_sides():
    document = ip.builtin_rig_document()
    rig, built_in = ip.rig_at(NOMINAL, document), load_rig()
    for name in ("left_drag_chain", "right_lower_hoist_chain", "dump_rope"):
        np.testing.assert_array_equal(rig.bodies["bucket"].points[name], built_in.bodies["bucket"].points[name])
    moved = ip.rig_at({**NOMINAL, "bucket.hitch.x": 0.21, "fixed.boom_pulley.z": -4.1}, document)
    for side in ("left", "right"):
        assert moved.bodies["bucket"].points[f"{side}_drag_chain"][0] == 0.21
    assert moved.fixed_points["boom_pulley"][2] == -4.1
    assert document["fixed_points"]["boom_pulley"][2] == built_in.fixed_points["boom_pulley"][2]  # input untouched


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


def test_the_landed_rig_meets_the_poses_and_misses_the_peaks():
    """What the issue reports of the landed rig: poses on target, the predicted peaks far off."""
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


def test_the_committed_identified_rig_meets_the_papers_numbers_it_was_fitted_to():
    """samples/paper_rig, simulated as a user would: poses and peak values on the issue's targets.

    The one published number it misses is the pitch-rate peak's time (0.31 s late for 0.3 s asked).
    """
    folder = REPO / "samples" / "paper_rig"
    rig, man = load_rig(folder / "rig.toml"), read_maneuver_csv(folder / "maneuver.csv")
    table = simulate(rig, man, duration=8.5).table
    assert table["bucket.z"].iloc[0] == pytest.approx(-1.2, abs=0.03)
    assert np.degrees(table["bucket.pitch"].iloc[0]) == pytest.approx(-52.0, abs=3.0)
    assert ip._rest_height(rig, 10.1, 1.4) == pytest.approx(-0.70, abs=0.03)
    for channel, (value, time_s), time_ok in (("bucket.vx", (1.01, 5.95), True), ("bucket.vz", (0.91, 6.27), True),
                                              ("bucket.q", (3.2, 6.77), False)):
        k = int(np.argmax(np.abs(table[channel].to_numpy())))
        assert abs(table[channel].iloc[k]) == pytest.approx(value, rel=0.15), channel
        assert (abs(table["time"].iloc[k] - time_s) <= 0.3) == time_ok, channel
