"""A session whose capture.mcap has corrupt chunks: calibration and reconstruction
go on from what survives, and every command says what was lost.

Independent truth: the same session read intact, the true lab cameras, and
mcap's own summary index (which chunk holds which log times).
"""

import json
import shutil

import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader

from dragline.capture import read_session
from dragline.capture._cameras import camera_centre, load_cameras
from dragline.lab import default_lab_cameras
from dragline.pipelines.cli import main

SEED = 5


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    root = tmp_path_factory.mktemp("damaged")
    intact = root / "intact"
    assert main(["synth", "--duration", "2", "--seed", str(SEED), "--quiet", "--out", str(intact)]) == 0
    mcap = intact / "capture.mcap"
    with open(mcap, "rb") as fh:
        summary = make_reader(fh).get_summary()
    topics = {ch.id: ch.topic for ch in summary.channels.values()}
    by_topic = {}
    for chunk in summary.chunk_indexes:
        for channel_id in chunk.message_index_offsets:
            by_topic.setdefault(topics[channel_id], []).append(chunk)
    wand = [c for c in by_topic["/calibration/wand"] if len(c.message_index_offsets) == 1][1]
    trial = [c for c in by_topic["/trial/centroids"] if len(c.message_index_offsets) == 1][2]
    damaged = root / "damaged"
    shutil.copytree(intact, damaged)
    data = bytearray(mcap.read_bytes())
    for chunk in (wand, trial):
        data[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0x5A
    (damaged / "capture.mcap").write_bytes(bytes(data))
    return {"intact": intact, "damaged": damaged, "wand": wand, "trial": trial}


def _calibrate_and_reconstruct(folder, capsys):
    assert main(["calibrate", str(folder), "--out", str(folder / "cameras.json")]) == 0
    err = capsys.readouterr().err
    assert main(["reconstruct", str(folder), "--out", str(folder / "measured.csv"),
                 "--summary-json", str(folder / "summary.json"), "--quiet"]) == 0
    capsys.readouterr()
    return err, pd.read_csv(folder / "measured.csv"), json.loads((folder / "summary.json").read_text())


def test_calibration_and_reconstruction_go_on_from_what_survives(sessions, capsys):
    _, intact, _ = _calibrate_and_reconstruct(sessions["intact"], capsys)
    warning, damaged, summary = _calibrate_and_reconstruct(sessions["damaged"], capsys)
    assert "is damaged" in warning and "corrupt stretch skipped" in warning

    back, report = read_session(sessions["damaged"])
    whole, _ = read_session(sessions["intact"])
    assert len(report["lost_chunks"]) == 2
    assert back.trial.shape == whole.trial.shape and back.wand.shape == whole.wand.shape
    assert summary["session"]["lost_chunks"] == json.loads(json.dumps(report["lost_chunks"]))

    # Calibrated from the wand frames that survive: still the true cameras, each centre within 1 cm at 2-6 m
    # (a centre is fixed worst along its optical axis, where focal length trades against distance: up to
    # 5 mm with every wand frame, `dragline bench capture`; which frames the lost chunk held moves with the
    # trial's size, and one such loss put the camera that sees the far end 7.4 mm out).
    for cam, true in zip(load_cameras(sessions["damaged"] / "cameras.json"), default_lab_cameras(SEED)):
        assert np.linalg.norm(camera_centre(cam) - camera_centre(true)) < 0.01

    # The lost trial frames are NaN in the table (the stretch is longer than the
    # gap filler's limit); everywhere away from them the table is the intact one.
    chunk = sessions["trial"]
    lost_frames = np.flatnonzero(np.isnan(back.trial).all(axis=(0, 2, 3)) & ~np.isnan(whole.trial).all(axis=(0, 2, 3)))
    assert 40 <= lost_frames.size
    assert len(damaged) == len(intact)
    assert damaged["bucket.x"].iloc[lost_frames].isna().all()
    assert intact["bucket.x"].iloc[lost_frames].notna().all()
    far = np.ones(len(intact), bool)
    far[max(lost_frames.min() - 30, 0): lost_frames.max() + 30] = False
    # (the two calibrations differ, above, which moves the triangulated bucket by about a millimetre)
    assert np.nanmax(np.abs(damaged.loc[far, "bucket.x"] - intact.loc[far, "bucket.x"])) < 2e-3
    times = intact["time"].iloc[lost_frames]
    assert times.iloc[-1] - times.iloc[0] <= (chunk.message_end_time - chunk.message_start_time) / 1e9 + 1e-9


def test_inspect_says_what_was_lost(sessions, capsys):
    assert main(["inspect", str(sessions["damaged"])]) == 0
    text = capsys.readouterr().out
    assert "DAMAGED, 2 corrupt stretches skipped" in text
    for chunk in (sessions["wand"], sessions["trial"]):
        assert f"bytes {chunk.chunk_start_offset}-{chunk.chunk_start_offset + chunk.chunk_length}" in text
        assert f"log time {chunk.message_start_time / 1e9:.3f}-{chunk.message_end_time / 1e9:.3f} s" in text
    assert "/calibration/wand" in text and "/trial/centroids" in text
