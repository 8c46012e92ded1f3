"""VICON CSV reader/writer, checked against real Nexus exports and variants.

Expected values come from the raw file text by plain string splitting in
this file, never from the reader itself; the variant files are the real
Trajectories section rewritten the way other VICON software writes it.
"""

import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from dragline.capture import (
    marker_trajectories,
    read_vicon_csv,
    summarize_vicon_csv,
    write_vicon_csv,
)


# Real exports from other labs, committed with their origin (tests/data/real_exports/SOURCES.md).
REAL = Path(__file__).parent / "data" / "real_exports"
DEV_TRAJ = REAL / "vicon_nexus_devices_and_trajectories_with_gaps.csv"
MODEL = REAL / "vicon_nexus_model_outputs.csv"
C3D = REAL / "vicon_static_trial.c3d"

# The Trajectories section of vicon_nexus_devices_and_trajectories_with_gaps.csv
# (lines 13-19), verbatim, so the variant tests run even without the fixtures;
# test_embedded_section_is_the_real_one proves it is the real text.
REAL_TRAJ_LINES = [
    "Trajectories" + "," * 121,
    "100" + "," * 121,
    ",,Angelica:HV,,,Angelica:CM_E,,,Angelica:CL_E,,,Angelica:ELAST_DP,,",
    "Frame,Sub Frame,X,Y,Z,X,Y,Z,X,Y,Z,X,Y,Z",
    ",,mm,mm,mm,mm,mm,mm,mm,mm,mm,mm,mm,mm",
    "1,0,209.331,1219.74,1780.67,,,,227.725,1091.81,496.721,,,",
    "2,0,209.475,1219.82,1780.88,,,,227.702,1091.8,496.729,,,",
]
NAMES_LINE, HEADER_LINE, UNITS_LINE = 2, 3, 4
FIRST_DATA_LINE = 5


def raw_markers(lines, delimiter=","):
    """Names and positions (m) of a Nexus Trajectories block by plain splitting."""
    names = [c for c in lines[NAMES_LINE].split(delimiter) if c]
    rows = [line.split(delimiter)[2:2 + 3 * len(names)] for line in lines[FIRST_DATA_LINE:]]
    mm = np.array([[float(c) if c else math.nan for c in row] for row in rows])
    return names, mm.reshape(len(rows), len(names), 3) / 1000.0


EXPECTED_NAMES, EXPECTED_M = raw_markers(REAL_TRAJ_LINES)


def write_text(tmp_path, lines, name="variant.csv", newline="\n", prefix=""):
    path = tmp_path / name
    path.write_bytes((prefix + newline.join(lines) + newline).encode("utf-8"))
    return path


def assert_same_markers(path, names=EXPECTED_NAMES, expected=EXPECTED_M, subject=None):
    got_names, got = marker_trajectories(read_vicon_csv(path), subject=subject)
    assert got_names == names
    np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))
    np.testing.assert_allclose(got, expected, rtol=1e-14, atol=0, equal_nan=True)


def raw_section(path, name):
    """Rate, names, header, units and data rows of one section by plain splitting."""
    lines = [line.split(",") for line in Path(path).read_text().splitlines()]
    start = next(i for i, cells in enumerate(lines) if cells[0] == name)
    rows = []
    for cells in lines[start + 5:]:
        if not any(cells):
            break
        rows.append(cells)
    header = [c for c in lines[start + 3] if c]
    return {"rate": float(lines[start + 1][0]), "names": lines[start + 2],
            "header": header, "units": lines[start + 4][2:len(header)], "rows": rows}


# ---------------------------------------------------------------- real files

def test_embedded_section_is_the_real_one():
    assert DEV_TRAJ.read_text().splitlines()[12:19] == REAL_TRAJ_LINES


def test_real_devices_and_trajectories_sections_rates_and_frames():
    export = read_vicon_csv(DEV_TRAJ)
    assert list(export.sections) == ["devices", "trajectories"]
    assert export.trajectories is export.sections["trajectories"]
    for key, name in (("devices", "Devices"), ("trajectories", "Trajectories")):
        raw = raw_section(DEV_TRAJ, name)
        section = export.sections[key]
        assert section.name == name
        assert section.rate_hz == raw["rate"]
        assert section.frame.tolist() == [int(r[0]) for r in raw["rows"]]
        assert section.sub_frame.tolist() == [int(r[1]) for r in raw["rows"]]
        assert len(section.columns) == len(raw["header"]) - 2
        assert section.units == raw["units"]
    # What SOURCES.md says about this export.
    assert export.sections["devices"].rate_hz == 300.0
    assert export.trajectories.rate_hz == 100.0
    assert export.sections["devices"].sub_frame.tolist() == [0, 1, 2, 0, 1, 2]


PYOMECA_TRAJ = REAL / "pyomeca_nexus_trajectories_with_gaps.csv"
PYOMECA_EMG = REAL / "pyomeca_nexus_devices_emg.csv"


def test_real_export_of_another_lab_reads_every_marker_gap_and_frame():
    # pyomeca's Nexus export: a Trajectories section whose every line is
    # padded with commas to the full width, 51 markers of two subjects.
    raw = PYOMECA_TRAJ.read_text().splitlines()
    cells = [line.split(",") for line in raw]
    names = [c for c in cells[2] if c]
    rows = cells[5:]
    n = len(names)
    expected = np.array([[float(c) if c else math.nan for c in r[2:2 + 3 * n]] for r in rows]) / 1000.0
    export = read_vicon_csv(PYOMECA_TRAJ)
    assert export.trajectories.rate_hz == float(cells[1][0]) == 100.0
    assert export.trajectories.frame.tolist() == [int(r[0]) for r in rows] == list(range(1, 121))
    got_names, got = marker_trajectories(export)
    assert got_names == names and len(names) == 51
    np.testing.assert_array_equal(np.isnan(got), np.isnan(expected.reshape(len(rows), n, 3)))
    np.testing.assert_allclose(got, expected.reshape(len(rows), n, 3), rtol=1e-14, atol=0, equal_nan=True)
    assert np.isnan(got).any()  # the gap SOURCES.md names is kept as NaN, never filled


def test_real_devices_only_export_holds_no_markers_and_says_so():
    export = read_vicon_csv(PYOMECA_EMG)
    devices = export.sections["devices"]
    raw = raw_section(PYOMECA_EMG, "Devices")
    assert devices.rate_hz == raw["rate"] == 2000.0
    assert devices.sub_frame.tolist() == [int(r[1]) for r in raw["rows"]]
    assert max(devices.sub_frame) == 19  # 2000 Hz devices under 100 Hz frames
    assert export.trajectories is None
    summary = summarize_vicon_csv(PYOMECA_EMG)
    assert summary["trajectories"] is None
    assert [(s["name"], s["rate_hz"], s["frames"]) for s in summary["sections"]] == [("Devices", 2000.0, 10)]


def test_real_devices_values_and_column_names():
    devices = read_vicon_csv(DEV_TRAJ).sections["devices"]
    raw = raw_section(DEV_TRAJ, "Devices")
    n = len(raw["header"]) - 2
    expected = np.array([[float(c) if c else math.nan for c in r[2:2 + n]] for r in raw["rows"]])
    np.testing.assert_array_equal(devices.data, expected)
    # EMG channel VL of frame 1 sub frame 1, read straight off line 7.
    line7 = DEV_TRAJ.read_text().splitlines()[6].split(",")
    vl = raw["header"].index("VL")
    assert devices.data[1, vl - 2] == float(line7[vl]) == 0.00463913
    assert devices.columns[0] == "Imported AMTI OR6 Series Force Plate #1 - Force.Fx"
    assert devices.columns[vl - 2] == "EMG2000 - Voltage.VL"
    assert devices.units[0] == "N" and devices.units[vl - 2] == "V"


def test_real_trajectories_positions_in_metres_with_gaps():
    names, pos = marker_trajectories(read_vicon_csv(DEV_TRAJ))
    assert names == ["Angelica:HV", "Angelica:CM_E", "Angelica:CL_E", "Angelica:ELAST_DP"]
    # First row of the file: 1,0,209.331,1219.74,1780.67,,,,227.725,...
    np.testing.assert_allclose(pos[0, 0], [0.209331, 1.21974, 1.78067], rtol=1e-15)
    np.testing.assert_allclose(pos[1, 2], [0.227702, 1.0918, 0.496729], rtol=1e-15)
    # CM_E and ELAST_DP are empty cells in both frames.
    assert np.isnan(pos[:, 1]).all() and np.isnan(pos[:, 3]).all()
    assert not np.isnan(pos[:, [0, 2]]).any()
    assert_same_markers(DEV_TRAJ)


def test_real_model_outputs_crlf_every_value():
    assert b"\r\n" in MODEL.read_bytes()
    export = read_vicon_csv(MODEL)
    assert list(export.sections) == ["model outputs"]
    section = export.sections["model outputs"]
    raw = raw_section(MODEL, "Model Outputs")
    assert section.name == "Model Outputs" and section.rate_hz == raw["rate"] == 120.0
    n = len(raw["header"]) - 2
    expected = np.array([[float(c) if c else math.nan for c in r[2:2 + n]] for r in raw["rows"]])
    assert section.data.shape == expected.shape == (323, 417)
    np.testing.assert_array_equal(section.data, expected)
    assert np.isnan(section.data).sum() == sum(c == "" for r in raw["rows"] for c in r[2:2 + n]) > 0
    assert section.frame.tolist() == [int(r[0]) for r in raw["rows"]]
    assert section.units == raw["units"]
    col = raw["names"].index("Test:HED")
    assert section.columns[col - 2:col + 1] == ["Test:HED.RX", "Test:HED.RY", "Test:HED.RZ"]
    assert section.units[col - 2] == "deg"
    with pytest.raises(ValueError, match="no Trajectories section"):
        marker_trajectories(export)


def test_real_c3d_is_rejected():
    with pytest.raises(ValueError, match=r"vicon_static_trial\.c3d: line 1: binary"):
        read_vicon_csv(C3D)


def test_summary_of_real_export_is_json_and_matches_text():
    summary = json.loads(json.dumps(summarize_vicon_csv(DEV_TRAJ)))
    by_name = {s["name"]: s for s in summary["sections"]}
    assert by_name["Devices"]["rate_hz"] == 300.0 and by_name["Trajectories"]["rate_hz"] == 100.0
    assert by_name["Devices"]["rows"] == 6 and by_name["Devices"]["frames"] == 2
    assert by_name["Devices"]["columns"] == len(raw_section(DEV_TRAJ, "Devices")["header"]) - 2
    traj = summary["trajectories"]
    assert (traj["frames"], traj["first_frame"], traj["last_frame"]) == (2, 1, 2)
    assert traj["subjects"] == [{"name": "Angelica", "markers": ["HV", "CM_E", "CL_E", "ELAST_DP"]}]
    assert traj["gaps"]["Angelica:CM_E"] == {"nan_frames": 2, "gap_runs": 1, "longest_gap": 2}
    assert traj["gaps"]["Angelica:HV"] == {"nan_frames": 0, "gap_runs": 0, "longest_gap": 0}


# ---------------------------------------------------------------- variants

def test_embedded_section_reads(tmp_path):
    assert_same_markers(write_text(tmp_path, REAL_TRAJ_LINES))


def test_leading_blank_lines_bom_and_crlf(tmp_path):
    lines = ["", ",,,,", "   "] + REAL_TRAJ_LINES
    assert_same_markers(write_text(tmp_path, lines, newline="\r\n", prefix="\ufeff"))


def test_trailing_empty_columns_everywhere(tmp_path):
    assert_same_markers(write_text(tmp_path, [line + ",,,,," for line in REAL_TRAJ_LINES]))


def test_rate_with_hz_and_uppercase_name_without_subject(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[0], lines[1] = "TRAJECTORIES", "100,Hz"
    lines[NAMES_LINE] = lines[NAMES_LINE].replace("Angelica:", "")
    export = read_vicon_csv(write_text(tmp_path, lines))
    assert export.trajectories.name == "TRAJECTORIES" and export.trajectories.rate_hz == 100.0
    assert export.trajectories.columns[:3] == ["HV.X", "HV.Y", "HV.Z"]
    assert_same_markers(tmp_path / "variant.csv",
                        names=[n.split(":")[1] for n in EXPECTED_NAMES])


def test_unlabeled_markers(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[NAMES_LINE] = ",,*111,,,*112,,,*113,,,*114,,"
    path = write_text(tmp_path, lines)
    assert_same_markers(path, names=["*111", "*112", "*113", "*114"])
    traj = summarize_vicon_csv(path)["trajectories"]
    assert traj["unlabeled"] == ["*111", "*112", "*113", "*114"]
    assert traj["subjects"] == [{"name": None, "markers": ["*111", "*112", "*113", "*114"]}]


def test_no_units_line_means_millimetres(tmp_path):
    lines = REAL_TRAJ_LINES[:UNITS_LINE] + REAL_TRAJ_LINES[UNITS_LINE + 1:]
    path = write_text(tmp_path, lines)
    assert read_vicon_csv(path).trajectories.units is None
    assert_same_markers(path)


@pytest.mark.parametrize("unit,to_m", [("m", 1.0), ("cm", 0.01), ("mm", 0.001)])
def test_units_line_converts_to_metres(tmp_path, unit, to_m):
    lines = list(REAL_TRAJ_LINES)
    lines[UNITS_LINE] = ",," + ",".join([unit] * 12)
    assert_same_markers(write_text(tmp_path, lines), expected=EXPECTED_M * 1000.0 * to_m)


def test_unknown_length_unit_is_an_error(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[UNITS_LINE] = ",," + ",".join(["in"] * 12)
    with pytest.raises(ValueError, match="unit 'in'"):
        marker_trajectories(read_vicon_csv(write_text(tmp_path, lines)))


def test_workstation_field_header_with_preamble(tmp_path):
    # VICON Workstation: metadata preamble, one index column, no units line.
    names = [n.split(":")[1] for n in EXPECTED_NAMES]
    lines = ["Title,,,,", "Date:,,,,", "Notes:,,,,", ",,,,", "TRAJECTORIES", "100,Hz",
             "," + ",,,".join(names) + ",,",
             "Field #," + ",".join("XYZ" * len(names))]
    for line in REAL_TRAJ_LINES[FIRST_DATA_LINE:]:
        cells = line.split(",")
        lines.append(",".join([cells[0]] + cells[2:]))
    path = write_text(tmp_path, lines)
    section = read_vicon_csv(path).trajectories
    assert section.frame.tolist() == [1, 2] and section.sub_frame.tolist() == [0, 0]
    assert section.units is None
    assert_same_markers(path, names=names)


def test_semicolon_delimiter(tmp_path):
    lines = [line.replace(",", ";") for line in REAL_TRAJ_LINES]
    assert_same_markers(write_text(tmp_path, lines))


def test_semicolon_delimiter_with_decimal_comma(tmp_path):
    lines = [line.replace(",", ";").replace(".", ",") for line in REAL_TRAJ_LINES]
    assert "209,331" in lines[FIRST_DATA_LINE]
    assert_same_markers(write_text(tmp_path, lines))


def test_several_subjects_and_subject_filter(tmp_path):
    lines = ["Trajectories", "200", ",,bucket:alpha,,,bucket:beta,,,hoist:gamma,,",
             "Frame,Sub Frame" + ",X,Y,Z" * 3, ",," + ",".join(["mm"] * 9),
             "10,0,1,2,3,4,5,6,7,8,9", "11,0,-1,-2,-3,,,,70,80,90"]
    path = write_text(tmp_path, lines)
    names, pos = marker_trajectories(read_vicon_csv(path))
    assert names == ["bucket:alpha", "bucket:beta", "hoist:gamma"]
    names, pos = marker_trajectories(read_vicon_csv(path), subject="hoist")
    assert names == ["hoist:gamma"]
    np.testing.assert_allclose(pos[:, 0], [[0.007, 0.008, 0.009], [0.07, 0.08, 0.09]], rtol=1e-15)
    names, pos = marker_trajectories(read_vicon_csv(path), subject="bucket")
    assert names == ["bucket:alpha", "bucket:beta"] and np.isnan(pos[1, 1]).all()
    with pytest.raises(ValueError, match="no markers of subject 'drag'.*bucket, hoist"):
        marker_trajectories(read_vicon_csv(path), subject="drag")
    subjects = summarize_vicon_csv(path)["trajectories"]["subjects"]
    assert subjects == [{"name": "bucket", "markers": ["alpha", "beta"]},
                        {"name": "hoist", "markers": ["gamma"]}]


def test_point_missing_one_coordinate_is_nan_in_all_three(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[FIRST_DATA_LINE] = lines[FIRST_DATA_LINE].replace(",1219.74,", ",,")
    path = write_text(tmp_path, lines)
    section = read_vicon_csv(path).trajectories
    assert section.data[0, 0] == 209.331 and np.isnan(section.data[0, 1])
    _, pos = marker_trajectories(read_vicon_csv(path))
    assert np.isnan(pos[0, 0]).all()
    np.testing.assert_allclose(pos[1, 0], EXPECTED_M[1, 0], rtol=1e-15)


def test_three_sections_keep_their_own_rates_and_columns(tmp_path):
    dev = DEV_TRAJ.read_text().splitlines()[:11]
    model = MODEL.read_text().splitlines()[:8]
    path = write_text(tmp_path, model + [""] + dev + [",,,"] + REAL_TRAJ_LINES)
    export = read_vicon_csv(path)
    assert list(export.sections) == ["model outputs", "devices", "trajectories"]
    assert [s.rate_hz for s in export.sections.values()] == [120.0, 300.0, 100.0]
    assert [len(s.frame) for s in export.sections.values()] == [3, 6, 2]
    assert [len(s.columns) for s in export.sections.values()] == [417, 26, 12]
    first = [float(c) for c in model[5].split(",")[2:5]]
    np.testing.assert_array_equal(export.sections["model outputs"].data[0, :3], first)
    assert_same_markers(path)


def test_section_following_data_without_blank_line(tmp_path):
    lines = ["Devices", "300", ",,Plate - Force,,", "Frame,Sub Frame,Fx,Fy,Fz", ",,N,N,N",
             "1,0,1.5,2.5,3.5", "1,1,4,5,6"] + REAL_TRAJ_LINES
    export = read_vicon_csv(write_text(tmp_path, lines))
    np.testing.assert_array_equal(export.sections["devices"].data, [[1.5, 2.5, 3.5], [4, 5, 6]])
    assert_same_markers(tmp_path / "variant.csv")


# ---------------------------------------------------------------- errors

def read_error(path):
    with pytest.raises(ValueError) as info:
        read_vicon_csv(path)
    message = str(info.value)
    assert "\n" not in message and path.name in message
    return message


def test_plain_csv_is_not_a_vicon_export(tmp_path):
    message = read_error(write_text(tmp_path, ["", "time,x,y", "0,1,2", "1,2,3"]))
    assert "line 2" in message and "no VICON section" in message


def test_empty_file(tmp_path):
    assert "line 1: empty file" in read_error(write_text(tmp_path, ["", ",,,"]))


def test_ragged_row(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[6] = lines[6].rsplit(",", 1)[0]          # one cell short, on line 7
    message = read_error(write_text(tmp_path, lines))
    assert "line 7:" in message and "13 cells" in message and "14" in message


def test_value_beyond_the_header(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[5] += ",,42"
    assert "line 6:" in read_error(write_text(tmp_path, lines))


def test_non_numeric_cell(tmp_path):
    lines = ["", ""] + list(REAL_TRAJ_LINES)
    lines[8] = lines[8].replace("227.702", "n/a")   # line 9 of the file
    message = read_error(write_text(tmp_path, lines))
    assert "line 9:" in message and "'n/a'" in message and "Angelica:CL_E.X" in message


def test_non_integer_frame(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[5] = "1.5" + lines[5][1:]
    assert "line 6:" in read_error(write_text(tmp_path, lines))


def test_known_section_without_rate_line(tmp_path):
    lines = [REAL_TRAJ_LINES[0]] + REAL_TRAJ_LINES[2:]
    message = read_error(write_text(tmp_path, lines))
    assert "line 2:" in message and "rate" in message


def test_section_without_header(tmp_path):
    message = read_error(write_text(tmp_path, ["Trajectories", "100", "1,0,1,2,3"]))
    assert "line 3:" in message and "header" in message


def test_garbage_after_a_section_is_skipped_and_said(tmp_path):
    lines = REAL_TRAJ_LINES + ["", "hello,world"]
    export = read_vicon_csv(write_text(tmp_path, lines))
    assert_same_markers(write_text(tmp_path, lines))
    assert any("lines 9-9" in note and "hello" in note for note in export.notes), export.notes


def test_garbage_before_any_section_is_still_refused(tmp_path):
    assert "no VICON section" in read_error(write_text(tmp_path, ["hello,world", "1,2"]))


# Sections and columns Nexus writes that the trajectories do not need: read
# or skipped by their header, never a reason to refuse the file (issue: five
# of ten real exports were refused for one of these).

EVENTS = ["Events", "100", "Subject,Context,Name,Time (s),Description",
          "Angelica,Left,Foot Strike,0.01,The instant the heel strikes the ground",
          "Angelica,Right,Foot Off,0.015,", ""]


def test_an_events_section_before_the_trajectories_is_read_as_labelled_times(tmp_path):
    path = write_text(tmp_path, EVENTS + REAL_TRAJ_LINES)
    assert_same_markers(path)
    export = read_vicon_csv(path)
    assert [(e["context"], e["name"], e["time_s"]) for e in export.events] == [
        ("Left", "Foot Strike", 0.01), ("Right", "Foot Off", 0.015)]
    summary = summarize_vicon_csv(path)
    assert summary["events"][0]["subject"] == "Angelica" and summary["trajectories"]["markers"] == 4
    # without its rate line too
    path = write_text(tmp_path, [EVENTS[0]] + EVENTS[2:] + REAL_TRAJ_LINES, name="norate.csv")
    assert len(read_vicon_csv(path).events) == 2


def test_derivative_columns_are_left_out_with_a_note_never_taken_for_markers(tmp_path):
    # Nexus can write each marker's X' Y' Z' (velocity) and X'' Y'' Z'' (acceleration) after its X Y Z.
    lines = list(REAL_TRAJ_LINES)
    names, header, units, rows = [], [], [], [[] for _ in lines[FIRST_DATA_LINE:]]
    src_names = lines[NAMES_LINE].split(",")
    for k in range(4):
        names += [src_names[2 + 3 * k]] + [""] * 8
        header += ["X", "Y", "Z", "X'", "Y'", "Z'", "X''", "Y''", "Z''"]
        units += ["mm"] * 3 + ["mm/s"] * 3 + ["mm/s^2"] * 3
        for r, line in enumerate(lines[FIRST_DATA_LINE:]):
            cells = line.split(",")[2 + 3 * k:5 + 3 * k]
            rows[r] += cells + (["1.5", "-2", "3"] if cells[0] else [""] * 3) * 2
    lines[NAMES_LINE] = ",".join(["", ""] + names)
    lines[HEADER_LINE] = ",".join(["Frame", "Sub Frame"] + header)
    lines[UNITS_LINE] = ",".join(["", ""] + units)
    for r, line in enumerate(lines[FIRST_DATA_LINE:]):
        lines[FIRST_DATA_LINE + r] = ",".join(line.split(",")[:2] + rows[r])
    path = write_text(tmp_path, lines)
    assert_same_markers(path)
    notes = read_vicon_csv(path).notes
    assert any("derivative" in n and "X''" in n for n in notes), notes


def test_a_trajectory_count_column_is_not_a_marker(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[NAMES_LINE] = ",,Trajectory Count," + lines[NAMES_LINE][2:]
    lines[HEADER_LINE] = "Frame,Sub Frame,Count," + lines[HEADER_LINE][len("Frame,Sub Frame,"):]
    lines[UNITS_LINE] = ",,," + lines[UNITS_LINE][2:]
    for r in range(FIRST_DATA_LINE, len(lines)):
        frame, sub, rest = lines[r].split(",", 2)
        lines[r] = f"{frame},{sub},2,{rest}"
    path = write_text(tmp_path, lines)
    assert_same_markers(path)
    assert any("Trajectory Count" in n for n in read_vicon_csv(path).notes)


def test_joints_and_model_outputs_the_reader_cannot_parse_are_skipped_and_said(tmp_path):
    joints = ["Joints", "100", ",,Angelica:Knee,,", "Frame,Sub Frame,RX,,RZ", ",,deg,deg,deg", "1,0,1,2,3", ""]
    model = ["Model Outputs", "100", ",,Angelica:LKneeAngles,,", "Frame,Sub Frame,X,Y,Z", ",,deg,deg,deg",
             "1,0,1,2,3", "2,,1,2,3", ""]
    path = write_text(tmp_path, joints + model + REAL_TRAJ_LINES)
    assert_same_markers(path)
    export = read_vicon_csv(path)
    assert set(export.sections) == {"trajectories"}
    assert any("'Joints'" in n and "empty header cell" in n for n in export.notes), export.notes
    assert any("'Model Outputs'" in n and "sub frame" in n for n in export.notes), export.notes
    assert summarize_vicon_csv(path)["notes"] == export.notes


def test_a_trajectories_section_the_reader_cannot_parse_still_refuses_the_file(tmp_path):
    lines = list(REAL_TRAJ_LINES)
    lines[HEADER_LINE] = "Frame,Sub Frame,X,,Z,X,Y,Z,X,Y,Z,X,Y,Z"
    assert "empty header cell" in read_error(write_text(tmp_path, lines))


def test_a_table_with_a_mixed_column_warns_of_nothing(tmp_path):
    # pandas reads a big file in chunks and warned (5 kB of DtypeWarning on
    # stderr) when a column's type changed between them.
    import warnings

    from dragline.compare import read_trajectory_table

    rows = ["time,bucket.x"] + [f"{0.005 * k},1.0" for k in range(300_000)] + ["1500.0,oops"]
    path = write_text(tmp_path, rows, name="table.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="'oops': expected a number"):
            read_trajectory_table(path)


def test_duplicate_section(tmp_path):
    message = read_error(write_text(tmp_path, REAL_TRAJ_LINES + [""] + REAL_TRAJ_LINES))
    assert "line 9:" in message and "twice" in message


@pytest.mark.parametrize("names_line,match", [
    (",,,,,Angelica:CM_E,,,Angelica:CL_E,,,Angelica:ELAST_DP,,", "column 1 \\(X\\) has no marker"),
    (",,Angelica:HV,,,Angelica:CM_E,,,Angelica:HV,,,Angelica:ELAST_DP,,", "'Angelica:HV' appears twice"),
])
def test_trajectory_names_that_do_not_make_markers(tmp_path, names_line, match):
    lines = list(REAL_TRAJ_LINES)
    lines[NAMES_LINE] = names_line
    export = read_vicon_csv(write_text(tmp_path, lines))
    with pytest.raises(ValueError, match=match):
        marker_trajectories(export)


@pytest.mark.parametrize("row, match", [
    ("2,1e300,209.475,1219.82,1780.88,,,,227.702,1091.8,496.729,,,", "sub frame '1e300' is outside"),
    ("-2,0,209.475,1219.82,1780.88,,,,227.702,1091.8,496.729,,,", "frame '-2' is outside"),
    ("2,0,209.475,inf,1780.88,,,,227.702,1091.8,496.729,,,", "'inf' in column 4 .* not a finite number"),
    ("2,0,209.475,nan,1780.88,,,,227.702,1091.8,496.729,,,", "'nan' in column 4 .* not a finite number"),
])
def test_cells_a_fuzzer_broke_are_refused_with_their_line(tmp_path, row, match):
    """A sub frame of 1e300 overflowed the int64 index (a traceback); 'inf' was taken as a position."""
    lines = list(REAL_TRAJ_LINES)
    lines[FIRST_DATA_LINE + 1] = row
    message = read_error(write_text(tmp_path, lines))
    assert f"line {FIRST_DATA_LINE + 2}:" in message and re.search(match, message), message


def test_missing_file_is_a_value_error(tmp_path):
    with pytest.raises(ValueError, match="nope.csv: cannot read"):
        read_vicon_csv(tmp_path / "nope.csv")


# ---------------------------------------------------------------- writer

def test_written_text_is_the_nexus_layout(tmp_path):
    pos = np.array([[[0.25, -1.5, 0.0125], [np.nan] * 3],
                    [[1.0, 2.0, 3.0], [0.001, 0.002, 0.003]]])
    path = tmp_path / "markers.csv"
    write_vicon_csv(path, ["bucket:alpha", "bucket:beta"], pos, 100.0, first_frame=7, decimals=3)
    assert path.read_text().split("\n") == [
        "Trajectories", "100", ",,bucket:alpha,,,bucket:beta,,",
        "Frame,Sub Frame,X,Y,Z,X,Y,Z", ",,mm,mm,mm,mm,mm,mm",
        "7,0,250.000,-1500.000,12.500,,,",
        "8,0,1000.000,2000.000,3000.000,1.000,2.000,3.000", ""]
    assert os.listdir(tmp_path) == ["markers.csv"]


@pytest.mark.parametrize("decimals", [0, 2, 5])
def test_round_trip_to_written_precision(tmp_path, decimals):
    rng = np.random.default_rng(7 + decimals)
    frames, names = 400, ["bucket:a", "bucket:b", "hoist:c", "drag:d", "*111"]
    pos = rng.uniform(-4.0, 4.0, (frames, len(names), 3))
    pos[rng.random((frames, len(names))) < 0.1] = np.nan
    pos[50:90, 2] = np.nan
    original = pos.copy()
    path = tmp_path / "markers.csv"
    write_vicon_csv(path, names, pos, 119.88, first_frame=100, decimals=decimals)
    np.testing.assert_array_equal(pos, original)     # input untouched

    export = read_vicon_csv(path)
    section = export.trajectories
    assert section.rate_hz == 119.88
    assert section.frame.tolist() == list(range(100, 100 + frames))
    written_mm = pos.reshape(frames, -1) * 1000.0
    err = np.abs(section.data - written_mm)
    # Decimal rounding, plus the one rounding of parsing the text to a double.
    bound = 0.5 * 10.0 ** -decimals + np.spacing(np.abs(written_mm))
    assert np.all(err[~np.isnan(written_mm)] <= bound[~np.isnan(written_mm)])

    got_names, got = marker_trajectories(export)
    assert got_names == names
    np.testing.assert_array_equal(np.isnan(got), np.isnan(pos))
    ok = ~np.isnan(pos)
    assert np.max(np.abs(got[ok] - pos[ok])) * 1000.0 <= 0.5 * 10.0 ** -decimals * (1 + 1e-9)


def test_summary_gap_counts(tmp_path):
    pos = np.zeros((10, 4, 3))
    pos[[2, 3, 7], 1] = np.nan
    pos[0, 2] = np.nan
    pos[5:, 3] = np.nan
    path = tmp_path / "gaps.csv"
    write_vicon_csv(path, ["bucket:a", "bucket:b", "drag:c", "*111"], pos, 200, first_frame=3)
    summary = summarize_vicon_csv(path)
    assert json.loads(json.dumps(summary)) == summary
    assert summary["sections"] == [{"name": "Trajectories", "rate_hz": 200.0, "rows": 10,
                                    "frames": 10, "first_frame": 3, "last_frame": 12,
                                    "columns": 12, "units": ["mm"]}]
    traj = summary["trajectories"]
    assert traj["gaps"] == {
        "bucket:a": {"nan_frames": 0, "gap_runs": 0, "longest_gap": 0},
        "bucket:b": {"nan_frames": 3, "gap_runs": 2, "longest_gap": 2},
        "drag:c": {"nan_frames": 1, "gap_runs": 1, "longest_gap": 1},
        "*111": {"nan_frames": 5, "gap_runs": 1, "longest_gap": 5},
    }
    assert traj["subjects"] == [{"name": "bucket", "markers": ["a", "b"]},
                                {"name": "drag", "markers": ["c"]},
                                {"name": None, "markers": ["*111"]}]
    assert traj["unlabeled"] == ["*111"] and traj["markers"] == 4


@pytest.mark.parametrize("names,shape,rate,match", [
    (["a"], (3, 2, 3), 100, "1 marker names for 2"),
    (["a", "b"], (3, 2, 2), 100, "shape"),
    (["a", "a"], (3, 2, 3), 100, "unique"),
    (["a,b", "c"], (3, 2, 3), 100, "delimiter"),
    (["a", "b"], (3, 2, 3), 0, "rate_hz"),
])
def test_writer_rejects_bad_input_and_keeps_old_file(tmp_path, names, shape, rate, match):
    path = tmp_path / "markers.csv"
    path.write_text("old")
    with pytest.raises(ValueError, match=match):
        write_vicon_csv(path, names, np.zeros(shape), rate)
    assert path.read_text() == "old" and os.listdir(tmp_path) == ["markers.csv"]


def test_writer_rejects_infinite_positions(tmp_path):
    pos = np.zeros((2, 1, 3))
    pos[1, 0, 2] = np.inf
    with pytest.raises(ValueError, match="infinite"):
        write_vicon_csv(tmp_path / "m.csv", ["a"], pos, 100)


def test_failed_rename_leaves_no_partial_file(tmp_path, monkeypatch):
    def refuse(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OSError, match="disk full"):
        write_vicon_csv(tmp_path / "m.csv", ["a"], np.zeros((5, 1, 3)), 100)
    assert os.listdir(tmp_path) == []


SOLAVLAB_PIVOT = REAL / "solavlab_nexus216_probe_pivot.csv"


def test_real_nexus_216_export_with_blank_lines_before_it_reads_every_value():
    # A third lab's Nexus 2.16 export: two all-comma lines before the
    # Trajectories section, every line padded with commas, 240 Hz, one
    # subject's five cluster markers. Compared with plain splitting.
    raw = SOLAVLAB_PIVOT.read_text().splitlines()
    cells = [line.split(",") for line in raw]
    assert not any(cells[0]) and not any(cells[1]) and cells[2][0] == "Trajectories"
    names = [c for c in cells[4] if c]
    rows = cells[7:]
    n = len(names)
    expected = np.array([[float(c) for c in r[2:2 + 3 * n]] for r in rows]).reshape(len(rows), n, 3) / 1000.0
    export = read_vicon_csv(SOLAVLAB_PIVOT)
    assert export.trajectories.rate_hz == float(cells[3][0]) == 240.0
    assert export.trajectories.frame.tolist() == [int(r[0]) for r in rows] == list(range(1, 21))
    got_names, got = marker_trajectories(export)
    assert got_names == names == ["ZED:TOP", "ZED:BL", "ZED:BR", "ZED:FR", "ZED:FL"]
    np.testing.assert_allclose(got, expected, rtol=1e-14, atol=0)
