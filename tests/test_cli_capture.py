"""``dragline synth``, ``calibrate`` and ``inspect`` end to end, through ``cli.main``.

Independent truth: the true cameras (``default_lab_cameras``), the rig's
marker list, the dig maneuver, and facts read by eye from the real VICON
exports in tests/data/real_exports (see SOURCES.md there).
"""

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader

from dragline.capture import read_session, write_session
from dragline.capture._cameras import camera_centre, load_cameras, project_points
from dragline.lab import WAND_LENGTH, default_lab_cameras
from dragline.pipelines.cli import main
from dragline.simulate import MECHANISMS, dig_maneuver, load_rig, marker_names, trajectory_columns

EXPORTS = Path(__file__).parent / "data" / "real_exports"
DEVICES_CSV = EXPORTS / "vicon_nexus_devices_and_trajectories_with_gaps.csv"
MODEL_CSV = EXPORTS / "vicon_nexus_model_outputs.csv"
SEED = 3
SYNTH = ["synth", "--duration", "0.5", "--seed", str(SEED), "--quiet"]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A session with air drag in its physics and its truth; calibrated once."""
    root = tmp_path_factory.mktemp("lab")
    session, truth, cams = root / "session", root / "truth", root / "cameras.json"
    assert main(SYNTH + ["--physics", "aero_drag:cd=1.5", "--out", str(session), "--truth-out", str(truth)]) == 0
    return {"root": root, "session": session, "truth": truth, "cameras": cams}


@pytest.fixture(scope="module")
def calibrated(lab):
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(["calibrate", str(lab["session"]), "--out", str(lab["cameras"])])
    assert rc == 0
    return out.getvalue()


def _error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("dragline: error: ")
    return err[0]


# ---------------------------------------------------------------- synth

def test_synth_writes_the_session_and_the_truth_apart(lab):
    assert sorted(os.listdir(lab["session"])) == [".dragline-output", "capture.mcap", "maneuver.csv"]
    assert sorted(os.listdir(lab["truth"])) == [".dragline-output", "cameras.json", "markers.csv", "physics.json",
                                                "trajectories.csv"]
    assert not [f for f in os.listdir(lab["root"]) if f.startswith(".")]  # no temporary leftovers
    traj = pd.read_csv(lab["truth"] / "trajectories.csv")
    assert list(traj.columns[: len(trajectory_columns())]) == trajectory_columns()
    np.testing.assert_allclose(traj["time"], np.arange(101) / 200.0, atol=1e-9)
    truth_cams = load_cameras(lab["truth"] / "cameras.json")
    for got, true in zip(truth_cams, default_lab_cameras(SEED)):
        np.testing.assert_array_equal(got.K, true.K)
        np.testing.assert_array_equal(got.dist, true.dist)
    physics = json.loads((lab["truth"] / "physics.json").read_text())
    assert physics["physics"] == [{"name": "aero_drag", "parameters": {"cd": 1.5, "air_density": 1.2, "body": "all"}}]
    man = pd.read_csv(lab["session"] / "maneuver.csv")
    dig = dig_maneuver()
    np.testing.assert_allclose(man["drag_length"], dig.lengths["drag"])
    session, report = read_session(lab["session"])
    assert report["lost"] == "nothing"
    assert session.marker_names == marker_names(load_rig())
    assert session.trial.shape == (6, 101, len(session.marker_names), 2)
    assert session.wand.shape[1] == 2000 and session.wand_length == WAND_LENGTH


def test_nothing_in_the_session_directory_reveals_the_physics(lab):
    words = ["physics", "truth", "mechanism", "aero", "cd="] + list(MECHANISMS)
    texts = []
    for name in os.listdir(lab["session"]):
        path = lab["session"] / name
        if name.endswith(".mcap"):
            with open(path, "rb") as fh:
                reader = make_reader(fh)
                for schema, channel, message in reader.iter_messages():
                    if channel.topic != "/trial/centroids":  # centroids are numbers only
                        texts.append(message.data.decode())
                    texts += [channel.topic, json.dumps(channel.metadata),
                              schema.name, schema.data.decode()]
                texts += [json.dumps(m.metadata) + m.name for m in reader.iter_metadata()]
                texts.append(json.dumps(reader.get_header().__dict__, default=str))
        else:
            texts.append(path.read_text())
    blob = "\n".join(texts).lower()
    for word in words:
        assert word not in blob, word
    info = json.loads(next(t for t in texts if t.startswith('{"format":"dragline.session/1"')))
    assert set(info["metadata"]) == {"generator", "rig"}


def test_same_seed_same_bytes_other_seed_other_bytes(tmp_path):
    runs = {"a": SEED, "b": SEED, "c": SEED + 1}
    for name, seed in runs.items():
        assert main(["synth", "--duration", "0.2", "--wand-frames", "300", "--seed", str(seed), "--quiet",
                     "--out", str(tmp_path / name)]) == 0
    data = {k: (tmp_path / k / "capture.mcap").read_bytes() for k in runs}
    assert data["a"] == data["b"]
    assert data["a"] != data["c"]


def test_synth_rejects_bad_options_before_writing(tmp_path, capsys):
    bad = [
        (["--rate", "2000"], "--rate"),
        (["--noise-px", "-1"], "--noise-px"),
        (["--dropout", "1.5"], "--dropout"),
        (["--physics", "warp_drive"], "warp_drive"),
        (["--truth-out", str(tmp_path / "s" / "truth")], "truth"),
    ]
    for extra, word in bad:
        assert main(SYNTH + ["--out", str(tmp_path / "s")] + extra) == 2
        assert word in _error_line(capsys)
        assert os.listdir(tmp_path) == []
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "keep.txt").write_text("mine")
    assert main(SYNTH + ["--out", str(tmp_path / "s")]) == 2
    assert "not empty" in _error_line(capsys)
    assert os.listdir(tmp_path / "s") == ["keep.txt"]


# ---------------------------------------------------------------- calibrate

def test_calibrate_recovers_the_true_cameras(lab, calibrated):
    cams = load_cameras(lab["cameras"])
    truth = default_lab_cameras(SEED)
    quality = json.loads(lab["cameras"].read_text())["quality"]
    for cam, true in zip(cams, truth):
        assert cam.name == true.name
        assert np.linalg.norm(camera_centre(cam) - camera_centre(true)) < 0.005
        assert 0.7 * 0.3 < quality["reprojection_rms_px"][cam.name] < 1.2 * 0.3
        # Distortion recovered: points in the bucket's work volume project alike.
        pts = np.random.default_rng(0).uniform([-5.0, -0.4, -1.5], [-1.5, 0.4, -0.1], (500, 3))
        a, b = project_points(pts, cam), project_points(pts, true)
        ok = np.isfinite(a).all(axis=1) & ((b >= 0) & (b <= [1279, 959])).all(axis=1)
        assert np.sqrt(np.mean((a[ok] - b[ok]) ** 2)) < 0.5
    assert quality["wand_length_mean_mm"] == pytest.approx(1000 * WAND_LENGTH, abs=0.5)
    assert 0 < quality["wand_length_std_mm"] < 3.0
    # The printed summary carries the same figures.
    for cam in cams:
        assert f"{quality['reprojection_rms_px'][cam.name]:.3f}" in calibrated
    assert f"{quality['wand_length_mean_mm']:.2f} mm mean" in calibrated
    assert f"{quality['wand_length_std_mm']:.2f} mm standard deviation" in calibrated


def test_calibrate_refuses_missing_and_degenerate_takes(lab, tmp_path, capsys):
    out = str(tmp_path / "cams.json")
    assert main(["calibrate", str(tmp_path / "nowhere"), "--out", out]) == 2
    assert "nowhere" in _error_line(capsys)
    assert main(SYNTH + ["--wand-frames", "0", "--lframe-frames", "0", "--out", str(tmp_path / "bare")]) == 0
    assert main(["calibrate", str(tmp_path / "bare" / "capture.mcap"), "--out", out]) == 2
    assert "no calibration takes" in _error_line(capsys)
    session, _ = read_session(lab["session"])
    session.lframe = None
    write_session(tmp_path / "no_lframe.mcap", session)
    assert main(["calibrate", str(tmp_path / "no_lframe.mcap"), "--out", out]) == 2
    assert "no L-frame take" in _error_line(capsys)
    session, _ = read_session(lab["session"])
    session.wand[4] = np.nan  # cam5 never sees the wand
    write_session(tmp_path / "blind.mcap", session)
    assert main(["calibrate", str(tmp_path / "blind.mcap"), "--out", out]) == 2
    line = _error_line(capsys)
    assert "cam5" in line and "wand" in line
    assert not os.path.exists(out)


# ---------------------------------------------------------------- inspect

def _inspect(capsys, *args):
    assert main(["inspect", *map(str, args)]) == 0
    return capsys.readouterr().out


def test_inspect_session_text_and_json(lab, capsys):
    text = _inspect(capsys, lab["session"])
    for word in ("/calibration/wand", "/trial/centroids", "cam6", "bucket: alpha beta gamma delta",
                 "hoist_rope: m1", "2000 frames at 200 Hz", "101 frames at 200 Hz", "wand length 500.0 mm"):
        assert word in text, word
    doc = json.loads(_inspect(capsys, lab["session"], "--json"))
    assert doc["kind"] == "session"
    assert doc["files"] == ["capture.mcap", "maneuver.csv"]
    se = doc["session"]
    assert se["frames"] == {"lframe": 200, "wand": 2000, "trial": 101}
    assert se["cameras"] == [f"cam{i}" for i in range(1, 7)]
    assert se["markers"] == marker_names(load_rig())
    assert set(se["trial_gaps"]) == set(se["markers"])
    topics = {ch["topic"]: ch["messages"] for ch in doc["channels"]}
    assert topics == {"/session/info": 1, "/calibration/lframe": 200, "/calibration/wand": 2000,
                      "/trial/centroids": 101}
    assert json.loads(_inspect(capsys, lab["session"] / "capture.mcap", "--json"))["kind"] == "mcap"


def test_inspect_truth_files(lab, calibrated, capsys):
    doc = json.loads(_inspect(capsys, lab["truth"] / "trajectories.csv", "--json"))
    assert doc["kind"] == "table" and doc["rows"] == 101 and doc["rate_hz"] == pytest.approx(200.0)
    assert "bucket" in doc["entities"]
    doc = json.loads(_inspect(capsys, lab["cameras"], "--json"))
    assert doc["kind"] == "cameras" and len(doc["cameras"]) == 6
    assert "reprojection RMS" in _inspect(capsys, lab["cameras"])
    doc = json.loads(_inspect(capsys, lab["truth"] / "markers.csv", "--json"))
    assert doc["kind"] == "vicon_csv" and doc["trajectories"]["markers"] == len(marker_names(load_rig()))


def test_inspect_real_vicon_exports(capsys):
    text = _inspect(capsys, DEVICES_CSV)
    for word in ("Devices", "Trajectories", "subject Angelica: HV CM_E CL_E ELAST_DP", "gaps: 2 of 4 markers"):
        assert word in text, word
    doc = json.loads(_inspect(capsys, DEVICES_CSV, "--json"))
    assert doc["kind"] == "vicon_csv"
    assert [(s["name"], s["rate_hz"], s["rows"], s["frames"]) for s in doc["sections"]] == [
        ("Devices", 300.0, 6, 2), ("Trajectories", 100.0, 2, 2)]
    gaps = doc["trajectories"]["gaps"]
    assert gaps["Angelica:CM_E"]["nan_frames"] == 2 and gaps["Angelica:HV"]["nan_frames"] == 0
    doc = json.loads(_inspect(capsys, MODEL_CSV, "--json"))
    (sec,) = doc["sections"]
    assert (sec["name"], sec["rate_hz"], sec["first_frame"], sec["last_frame"]) == ("Model Outputs", 120.0, 695, 1017)
    assert doc["trajectories"] is None
    assert "no Trajectories section" in _inspect(capsys, MODEL_CSV)


def test_inspect_bad_input(tmp_path, capsys):
    assert main(["inspect", str(tmp_path / "missing.mcap")]) == 2
    assert "missing.mcap" in _error_line(capsys)
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"\x00\x01 not a capture")
    assert main(["inspect", str(junk)]) == 2
    assert "junk.bin" in _error_line(capsys)
    assert main(["inspect", str(tmp_path)]) == 2  # a folder without capture.mcap
    assert "not a session directory" in _error_line(capsys)
