"""``dragline reconstruct`` end to end on a session file written here.

The session is a short simulation's true markers projected through the
simulated lab's cameras with Gaussian noise, written with ``write_session``;
the truth is the simulation's trajectory table.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from dragline.capture import CaptureSession, write_session, write_vicon_csv
from dragline.capture._cameras import Camera, project_points, save_cameras
from dragline.lab import NOMINAL_FOCAL_PX, default_lab_cameras
from dragline.pipelines.cli import main
from dragline.simulate import marker_positions, simulate, trajectory_columns

RATE = 200.0


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    result = simulate(duration=0.6, rate_hz=RATE)
    names, pos = marker_positions(result)
    cams = default_lab_cameras()
    rng = np.random.default_rng(3)
    det = []
    for cam in cams:
        px = project_points(pos, cam)
        w, h = cam.image_size
        px[~((px[..., 0] >= 0) & (px[..., 0] < w) & (px[..., 1] >= 0) & (px[..., 1] < h))] = np.nan
        det.append(px + rng.normal(0.0, 0.3, px.shape))
    det = np.stack(det)
    # A stretch where one rope marker is seen by one camera only: NaN, then a counted gap.
    k = names.index("hoist_rope.m4")
    det[1:, 40:70, k] = np.nan
    root = tmp_path_factory.mktemp("lab")
    session_dir = root / "session"
    session_dir.mkdir()
    session = CaptureSession(rate_hz=RATE, camera_names=[c.name for c in cams], image_size=cams[0].image_size,
                             nominal_focal_px=NOMINAL_FOCAL_PX, marker_names=names, trial=det,
                             maneuver={"time": np.array([0.0, 1.0]), "hoist_length": np.array([8.6, 8.96]),
                                       "drag_length": np.array([4.2, 3.9])})
    write_session(session_dir, session)
    cam_file = root / "cameras.json"
    save_cameras(cam_file, cams)
    return {"root": root, "session": session_dir, "cameras": cam_file, "truth": result.table, "names": names,
            "pos": pos, "cams": cams}


def run_cli(*argv):
    return main(["reconstruct", *map(str, argv)])


def _one_line_error(capsys):
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dragline: error: "), err
    return lines[0]


def test_session_to_table_and_markers_and_back(lab, tmp_path, capsys):
    out, markers, summary = tmp_path / "measured.csv", tmp_path / "markers.csv", tmp_path / "summary.json"
    assert run_cli(lab["session"], "--calibration", lab["cameras"], "--out", out, "--vicon-csv", markers,
                   "--summary-json", summary) == 0
    err = capsys.readouterr().err
    assert "1 left open (30 marker-frames, limit 10 frames)" in err
    table = pd.read_csv(out)
    truth = lab["truth"]
    assert list(table.columns) == trajectory_columns()
    assert len(table) == len(truth)
    cg = np.column_stack([table[f"bucket.{q}"] - truth[f"bucket.{q}"] for q in "xyz"])
    assert np.sqrt(np.mean(np.sum(cg**2, axis=1))) < 1e-3
    assert np.degrees(np.sqrt(np.mean((table["bucket.pitch"] - truth["bucket.pitch"]) ** 2))) < 0.2
    for rope in ("hoist_rope", "drag_rope"):
        assert np.max(np.abs(table[f"{rope}.length"] - truth[f"{rope}.length"])) < 5e-3
    assert table["drag_cluster.pitch"].isna().all() and table["bucket.q"].notna().all()
    doc = json.loads(summary.read_text())
    gap = doc["gaps"]["markers"]["hoist_rope.m4"]
    assert (gap["open_gaps"], gap["open_frames"]) == (1, 30)
    assert doc["triangulation"]["markers"]["hoist_rope.m4"]["nan_frames"] == 30
    assert doc["smoothing"]["name"] == "running_average"
    # The exported markers: VICON names, mm, NaN where only one camera saw the marker.
    text = markers.read_text().splitlines()
    assert text[0] == "Trajectories" and "bucket:alpha" in text[2] and "hoist_rope:m4" in text[2]
    # Feeding the CSV back in gives the same table, to the CSV's precision (5e-9 m).
    again = tmp_path / "again.csv"
    assert run_cli(markers, "--out", again) == 0
    b = pd.read_csv(again)
    tol = {"x": 1e-7, "y": 1e-7, "z": 1e-7, "roll": 1e-6, "pitch": 1e-6, "yaw": 1e-6, "vx": 3e-5, "vy": 3e-5,
           "vz": 3e-5, "p": 3e-4, "q": 3e-4, "r": 3e-4, "length": 1e-6, "time": 1e-12}
    for c in table.columns:
        x, y = table[c].to_numpy(), b[c].to_numpy()
        assert np.array_equal(np.isnan(x), np.isnan(y)), c
        assert np.nanmax(np.abs(x - y), initial=0.0) < tol[c.split(".")[-1]], c


def test_mcap_path_and_calibration_in_the_session_directory(lab, tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert run_cli(lab["session"] / "capture.mcap", "--calibration", lab["cameras"], "--out", a,
                   "--method", "svd", "--quiet") == 0
    assert capsys.readouterr().err == ""
    session = tmp_path / "session"
    session.mkdir()
    os.link(lab["session"] / "capture.mcap", session / "capture.mcap")
    save_cameras(session / "cameras.json", lab["cams"])
    assert run_cli(session, "--out", b, "--method", "svd", "--quiet") == 0
    pd.testing.assert_frame_equal(pd.read_csv(a), pd.read_csv(b))


def test_smoothing_option(lab, tmp_path):
    raw, avg = tmp_path / "raw.csv", tmp_path / "avg.csv"
    assert run_cli(lab["session"], "--calibration", lab["cameras"], "--out", raw, "--smoothing", "none", "--quiet") == 0
    assert run_cli(lab["session"], "--calibration", lab["cameras"], "--out", avg, "--quiet") == 0
    r, a = pd.read_csv(raw), pd.read_csv(avg)
    pd.testing.assert_series_equal(r["bucket.pitch"], a["bucket.pitch"])  # angles are not smoothed
    # The 12-sample average of the differenced noise is far quieter than the raw difference.
    truth = lab["truth"]["bucket.q"]
    assert np.std(a["bucket.q"] - truth) < 0.5 * np.std(r["bucket.q"] - truth)


def test_csv_without_the_rig_markers(lab, tmp_path, capsys):
    path = tmp_path / "foreign.csv"
    write_vicon_csv(path, ["Pelvis:LASI", "Pelvis:RASI"], lab["pos"][:, :2], RATE)
    out = tmp_path / "m.csv"
    assert run_cli(path, "--out", out) == 2
    line = _one_line_error(capsys)
    assert "foreign.csv" in line and "missing 21 of the rig's 21 markers" in line and "bucket:alpha" in line
    assert not out.exists()


def test_session_without_a_calibration(lab, tmp_path, capsys):
    out = tmp_path / "m.csv"
    assert run_cli(lab["session"], "--out", out) == 2
    line = _one_line_error(capsys)
    assert "no calibration" in line and "--calibration" in line
    assert not out.exists()


def test_calibration_for_other_cameras(lab, tmp_path, capsys):
    four = tmp_path / "four.json"
    save_cameras(four, lab["cams"][:4])
    out = tmp_path / "m.csv"
    assert run_cli(lab["session"], "--calibration", four, "--out", out) == 2
    line = _one_line_error(capsys)
    assert "four.json has no camera cam5, cam6 of the session" in line
    renamed = tmp_path / "renamed.json"
    save_cameras(renamed, [Camera(f"lab{c.name}", c.image_size, c.K, c.dist, c.rvec, c.tvec) for c in lab["cams"]])
    assert run_cli(lab["session"], "--calibration", renamed, "--out", out) == 2
    assert "has no camera cam1, cam2, cam3, cam4, cam5, cam6" in _one_line_error(capsys)
    assert not out.exists()


@pytest.mark.parametrize("argv, words", [
    (["nowhere/session", "--out", "{tmp}/m.csv"], "no such file or directory"),
    (["{tmp}", "--out", "{tmp}/m.csv"], "neither capture.mcap nor markers.csv"),
    (["{cams}", "--out", "{tmp}/m.csv"], "expected a session directory"),
    (["{session}", "--calibration", "{tmp}/none.json", "--out", "{tmp}/m.csv"], "none.json: no such calibration"),
    (["{session}", "--calibration", "{cams}", "--out", "{tmp}/no/m.csv"], "does not exist"),
    (["{session}", "--calibration", "{cams}", "--out", "{tmp}/m.csv", "--max-gap", "-1"], "--max-gap"),
    (["{session}", "--calibration", "{cams}", "--out", "{tmp}/m.csv", "--method", "quat"], "invalid choice"),
    (["{session}", "--calibration", "{cams}"], "--out"),
])
def test_bad_input_exits_2_with_one_line(lab, tmp_path, capsys, argv, words):
    subs = {"tmp": tmp_path, "cams": lab["cameras"], "session": lab["session"]}
    argv = [a.format(**subs) for a in argv]
    assert run_cli(*argv) == 2
    assert words in _one_line_error(capsys)
    assert not (tmp_path / "m.csv").exists()


def test_the_installed_command_exits_2(lab, tmp_path):
    exe = os.path.join(os.path.dirname(sys.executable), "dragline")
    out = tmp_path / "m.csv"
    proc = subprocess.run([exe, "reconstruct", str(lab["session"]), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "no calibration" in proc.stderr
    assert not out.exists()


def test_session_markers_written_as_csv_c3d_and_trc_alike(lab, tmp_path):
    from dragline.capture._marker_file import read_marker_file

    paths = {ext: tmp_path / f"markers.{ext}" for ext in ("csv", "c3d", "trc")}
    assert run_cli(lab["session"], "--calibration", lab["cameras"], "--out", tmp_path / "m.csv", "--quiet",
                   "--vicon-csv", paths["csv"], "--c3d", paths["c3d"], "--trc", paths["trc"]) == 0
    files = {ext: read_marker_file(p) for ext, p in paths.items()}
    ref = files["csv"]
    assert ref.positions.shape == (len(lab["truth"]), len(lab["names"]), 3)
    for ext in ("c3d", "trc"):
        assert files[ext].names == ref.names and files[ext].rate_hz == ref.rate_hz
        assert np.array_equal(np.isnan(files[ext].positions), np.isnan(ref.positions))  # the open gap too
        np.testing.assert_allclose(files[ext].positions, ref.positions, atol=1e-6, equal_nan=True)
    # A marker file as input cannot have marker files as outputs: there is nothing to triangulate.
    assert run_cli(paths["c3d"], "--out", tmp_path / "n.csv", "--trc", tmp_path / "n.trc") == 2
