"""The residue of bad input (issue 40): each example found by a fresh fuzz of 1,207 inputs, as a regression.

Possible, not only well-typed: a clock no lab has, a lens no camera has, a
marker kilometres from its machine, a friction no material has, an option
that empties the output. And every refusal names its file; a file cut
short says so.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from conftest import REPO
from dragline.capture import save_cameras, write_c3d, write_vicon_csv
from dragline.lab import default_lab_cameras
from dragline.pipelines.cli import main
from dragline.simulate import marker_positions, simulate, write_trajectory_csv
from test_tracked_tables import BAG_MAPPING, _write_bag

SAMPLE = REPO / "samples" / "dig_sample"


def _refused(capsys, *argv):
    """Exit 2 with one line on stderr and no traceback; the line."""
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


@pytest.fixture(scope="module")
def short_run():
    return simulate(duration=1.0, rate_hz=50.0)


def test_a_table_whose_clock_ticks_faster_than_any_lab_is_refused_naming_it(tmp_path, capsys, short_run):
    table = short_run.table.copy()
    real = tmp_path / "simulated.csv"
    write_trajectory_csv(real, table)
    table["time"] = np.arange(len(table)) * 1e-13  # was an OverflowError traceback in compare
    fast = tmp_path / "fast.csv"
    write_trajectory_csv(fast, table)
    for pair in ((fast, real), (real, fast)):
        line = _refused(capsys, "compare", *pair, "--json", tmp_path / "c.json", "--quiet")
        assert "fast.csv" in line and "time steps 1e-13 s" in line and "1e-05" in line
    assert not (tmp_path / "c.json").exists()


def test_a_lens_no_camera_has_is_refused_naming_the_file(tmp_path, capsys):
    cameras = default_lab_cameras(seed=1)
    path = tmp_path / "cameras.json"
    save_cameras(path, cameras)
    doc = json.loads(path.read_text())
    width = max(doc["cameras"][0]["image_size"])
    doc["cameras"][0]["K"][0][0] = doc["cameras"][0]["K"][1][1] = 14.0  # a 177 deg view on a 1.2 MP sensor
    path.write_text(json.dumps(doc))
    line = _refused(capsys, "reconstruct", SAMPLE, "--calibration", path, "--out", tmp_path / "m.csv", "--quiet")
    assert "cameras.json" in line and "fx = 14" in line and f"{width} px wide" in line
    # a real lens, 1400 px on the same sensor (a 49 deg view), is read
    doc["cameras"][0]["K"][0][0] = doc["cameras"][0]["K"][1][1] = 1400.0
    path.write_text(json.dumps(doc))
    assert main(["inspect", str(path)]) == 0
    capsys.readouterr()


def test_a_marker_kilometres_from_its_machine_is_refused_naming_file_and_marker(tmp_path, capsys, short_run):
    names, points = marker_positions(short_run)
    path = tmp_path / "vicon.csv"
    write_vicon_csv(path, [n.replace(".", ":", 1) for n in names], points, 50.0)
    lines = path.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("Frame")) + 2
    cells = lines[first + 3].split(",")
    cells[2] = "-1e308"  # bucket:alpha's X in mm, frame 4 (was read, exit 0)
    lines[first + 3] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    line = _refused(capsys, "reconstruct", path, "--out", tmp_path / "m.csv", "--quiet")
    assert "vicon.csv" in line and "bucket:alpha at frame 4" in line and "times the rig's reach" in line
    assert not (tmp_path / "m.csv").exists()


def test_a_friction_no_material_has_is_refused_naming_its_bound(tmp_path, capsys):
    line = _refused(capsys, "simulate", "--physics", "pulley_friction:mu=1e300", "--duration", "0.2",
                    "--out", tmp_path / "t.csv", "--quiet")
    assert "--physics" in line and "mu = 1e+300" in line and "at most 10" in line
    assert main(["simulate", "--physics", "pulley_friction:mu=0.5", "--duration", "0.1", "--rate", "50",
                 "--out", str(tmp_path / "t.csv"), "--quiet"]) == 0


def test_an_option_that_would_empty_the_table_is_refused_and_an_empty_reconstruction_is_an_error(
        tmp_path, capsys, short_run):
    line = _refused(capsys, "reconstruct", SAMPLE, "--max-reprojection-px", "1e-300", "--out", tmp_path / "m.csv")
    assert "--max-reprojection-px" in line and "at least 0.01" in line
    # a marker file with no coordinate at all: nothing to write, and said so
    names, points = marker_positions(short_run)
    path = tmp_path / "empty.csv"
    write_vicon_csv(path, [n.replace(".", ":", 1) for n in names], np.full_like(points, np.nan), 50.0)
    line = _refused(capsys, "reconstruct", path, "--out", tmp_path / "m.csv", "--quiet")
    assert "empty.csv" in line and "nothing reconstructed" in line
    assert not (tmp_path / "m.csv").exists()


def test_a_session_whose_info_message_is_cut_short_is_refused_naming_the_file(tmp_path, capsys):
    from test_fuzz_inputs import _fuzzer

    fuzzer = _fuzzer()
    info = json.dumps(fuzzer.session_info(SAMPLE / "capture.mcap")).encode()
    path = tmp_path / "capture.mcap"
    fuzzer.rewrite_session_info(SAMPLE / "capture.mcap", path, info[: len(info) // 2])
    line = _refused(capsys, "inspect", path)
    assert str(path) in line and "session info message" in line and "not JSON" in line


def test_a_cameras_file_in_utf16_is_refused_naming_it(tmp_path, capsys):
    path = tmp_path / "cameras.json"
    save_cameras(path, default_lab_cameras(seed=1))
    path.write_bytes(path.read_text().encode("utf-16"))
    line = _refused(capsys, "reconstruct", SAMPLE, "--calibration", path, "--out", tmp_path / "m.csv", "--quiet")
    assert str(path) in line and "not UTF-8" in line


def test_a_maneuver_that_moves_a_point_the_rig_lacks_is_refused_naming_the_file(tmp_path, capsys):
    maneuver = pd.read_csv(SAMPLE / "maneuver.csv")
    for k in "xyz":
        maneuver[f"tower.{k}"] = 0.0
    path = tmp_path / "moves_tower.csv"
    maneuver.to_csv(path, index=False)
    line = _refused(capsys, "simulate", "--maneuver", path, "--duration", "0.2", "--out", tmp_path / "t.csv")
    assert f"maneuver file {path}" in line and "'tower'" in line


def test_a_c3d_cut_short_is_read_and_said_to_be(tmp_path, capsys, short_run):
    names, points = marker_positions(short_run)
    whole = tmp_path / "whole.c3d"
    write_c3d(whole, [n.replace(".", ":", 1) for n in names], points, 50.0)
    cut = tmp_path / "cut.c3d"
    data = whole.read_bytes()
    cut.write_bytes(data[: len(data) - 8 * 512])  # the last blocks of frames gone
    assert main(["inspect", str(cut)]) == 0
    out = capsys.readouterr().out
    frames = len(points)
    assert f"CUT SHORT: the header promises {frames} frames, the data end after" in out
    assert main(["inspect", str(whole)]) == 0
    assert "CUT SHORT" not in capsys.readouterr().out
    # the real example: ezc3d's Optotrak.c3d declares 1149 frames and holds 29
    assert main(["inspect", str(REPO / "tests" / "data" / "real_exports" / "optotrak_markers.c3d")]) == 0
    assert "the header promises 1149 frames, the data end after 29" in capsys.readouterr().out
    out = tmp_path / "m.csv"
    assert main(["reconstruct", str(cut), "--out", str(out)]) == 0
    assert "cut.c3d is cut short: the header promises" in capsys.readouterr().err
    assert math.isfinite(pd.read_csv(out)["bucket.x"].iloc[0])


def test_every_mechanism_parameter_has_a_door_bound_listed_in_the_docs():
    import re

    from dragline.simulate import MECHANISMS
    from dragline.simulate._physics import limits_markdown

    for name, kind in MECHANISMS.items():
        numeric = {k for k, v in kind.defaults.items() if not isinstance(v, str)}
        assert set(kind.limits) == numeric, name
        # a bound is no plausible range: the diagnosis searches well inside it
        assert kind.range[1] < kind.limits[kind.main], name
    doc = (REPO / "docs" / "schemas.md").read_text()
    block = re.search(r"<!-- generated: mechanism limits -->\n(.*?)<!-- end generated -->", doc, re.S).group(1)
    assert block == limits_markdown()


# Found by the fuzzer's new classes (seeds 91-93), each fixed:

def test_a_release_that_stretches_a_rope_beyond_breaking_is_refused_naming_the_rig(tmp_path, capsys):
    text = (REPO / "tests" / "data" / "double_pendulum_release.toml").read_text()
    at = text.rindex("cg_body = [0.0, 0.0, 0.0]")  # the lower bob's mass centre 1 m off its string's point
    rig = tmp_path / "rig.toml"
    rig.write_text(text[:at] + "cg_body = [-1.0, 0.0, 0.0]" + text[at + len("cg_body = [0.0, 0.0, 0.0]"):])
    (tmp_path / "double_pendulum.csv").write_text((REPO / "tests" / "data" / "double_pendulum.csv").read_text())
    line = _refused(capsys, "simulate", "--rig", rig, "--duration", "0.2", "--out", tmp_path / "t.csv")
    assert str(rig) in line and "rope lower_string is stretched" in line and "25 %" in line


def test_a_principal_point_off_the_sensor_is_refused_naming_the_cameras_file(tmp_path, capsys):
    path = tmp_path / "cameras.json"
    save_cameras(path, default_lab_cameras(seed=1))
    doc = json.loads(path.read_text())
    doc["cameras"][4]["K"][1][2] = 1e9
    path.write_text(json.dumps(doc))
    line = _refused(capsys, "reconstruct", SAMPLE, "--calibration", path, "--out", tmp_path / "m.csv", "--quiet")
    assert "cameras.json" in line and "principal point" in line


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    folder = tmp_path_factory.mktemp("flight")
    table = folder / "flight.csv"
    table.write_text((REPO / "tests" / "data" / "stormlord" / "rosbag_15_rows_0_899.csv").read_text())
    return folder, table, REPO / "benchmarks" / "real" / "stormlord_mapping.toml", REPO / "benchmarks" / "real" / "stormlord.toml"


def test_a_tracked_table_with_an_infinite_position_is_refused_naming_row_and_column(capsys, flight):
    folder, table, mapping, rig = flight
    lines = table.read_text().splitlines()
    cells = lines[5].split(",")
    cells[2] = "inf"  # the drone's z (column 2), row 6: was dropped as a gap
    bad = folder / "inf.csv"
    bad.write_text("\n".join(lines[:5] + [",".join(cells)] + lines[6:]) + "\n")
    line = _refused(capsys, "diagnose", bad, "--rig", rig, "--mapping", mapping, "--json", folder / "d.json")
    assert "inf.csv" in line and "column 2, row 6" in line and "finite" in line


def test_a_mapping_naming_a_column_a_headerless_table_lacks_is_named_as_the_fault(capsys, flight):
    folder, table, mapping, rig = flight
    bad = folder / "mapping.toml"
    bad.write_text(mapping.read_text().replace("position = [14, 15, 16]", 'position = [14, 15, "abc"]'))
    line = _refused(capsys, "diagnose", table, "--rig", rig, "--mapping", bad, "--json", folder / "d.json")
    assert line.startswith(f"dragline: error: {bad}:") and "'abc'" in line and "no header" in line


def test_a_bag_whose_compressed_chunk_is_damaged_is_refused_naming_it(tmp_path, capsys, swing_table):
    bag, mapping = _write_take(tmp_path, swing_table)
    data = bytearray(bag.read_bytes())
    data[len(data) // 2: len(data) // 2 + 4] = b"\x00\xff\x00\xff"  # inside a compressed chunk
    bag.write_bytes(bytes(data))
    line = _refused(capsys, "diagnose", bag, "--rig", "pendulum", "--mapping", mapping, "--json", tmp_path / "d.json")
    assert str(bag) in line


def test_a_comparison_with_nothing_to_compare_names_both_tables(tmp_path, capsys, short_run):
    real = tmp_path / "simulated.csv"
    write_trajectory_csv(real, short_run.table)
    empty = short_run.table.copy()
    empty.loc[:, [c for c in empty.columns if c != "time"]] = np.nan
    blank = tmp_path / "blank.csv"
    write_trajectory_csv(blank, empty)
    line = _refused(capsys, "compare", blank, real, "--json", tmp_path / "c.json", "--quiet")
    assert "blank.csv" in line and "simulated.csv" in line and "no channel has finite samples" in line
    assert not (tmp_path / "c.json").exists()


# Found by the 10,000-case run (seed 97), each fixed:

@pytest.mark.parametrize("old, new, words", [
    ("viscous_damping = 150.0", "viscous_damping = 1e-300", ["ropes.line", "relaxes faster"]),
    ("inertia_diag = [0.000628, 0.000628, 0.000767]", "inertia_diag = [0.000628, 0.000628, 1e-300]",
     ["bodies.load", "no body turns so easily"]),
    ("mass = 0.46", "mass = 1e-300", ["bodies.load.mass"]),
])
def test_a_rig_with_a_body_or_rope_no_lab_has_is_refused_at_the_door(tmp_path, old, new, words):
    from conftest import refused_edit
    from dragline.simulate import load_rig

    message = refused_edit(tmp_path, REPO / "simulate" / "data" / "slung_load.toml", (old, new), load_rig)
    for word in words:
        assert word in message, message


@pytest.fixture(scope="module")
def swing_table():
    from dragline.simulate import load_rig

    return simulate(load_rig("pendulum"), duration=2.0, rate_hz=100.0, discretization="low").table


def _write_take(folder, table, mapping_text=BAG_MAPPING):
    """The pendulum's ball and pivot as a ROS 2 bag the tests write (test_tracked_tables), with its mapping."""
    bag, mapping = folder / "take.mcap", folder / "take.toml"
    _write_bag(bag, table)
    mapping.write_text(mapping_text)
    return bag, mapping


def test_a_mapping_naming_a_topic_the_bag_lacks_is_named_as_the_fault(tmp_path, capsys, swing_table):
    bag, mapping = _write_take(tmp_path, swing_table,
                               BAG_MAPPING.replace("/vrpn_mocap/ball/pose", "/vrpn_mocap/ball/posezz"))
    line = _refused(capsys, "diagnose", bag, "--rig", "pendulum", "--mapping", mapping, "--json", tmp_path / "d.json")
    assert line.startswith(f"dragline: error: {mapping}:") and "'/vrpn_mocap/ball/posezz'" in line


def test_a_bag_whose_timestamp_jumps_ahead_is_refused_not_resampled_into_terabytes(tmp_path, capsys, swing_table):
    from dragline.capture import read_tracked_bag

    # the last ball sample stamped 3 hours late: a clock of a million steps for 402 samples
    late = swing_table.copy()
    late.loc[late.index[-1], "time"] = 3 * 3600.0
    bag, mapping = _write_take(tmp_path, late)
    with pytest.raises(ValueError, match="a timestamp is wrong") as info:
        read_tracked_bag(bag, mapping)
    assert str(bag) in str(info.value)
