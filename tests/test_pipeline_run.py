"""``dragline run``/``replay``: the whole pipeline, its outputs and its failures."""

import json
import math

import pandas as pd
import pytest

from dragline.pipelines import _run
from dragline.pipelines.cli import main
from dragline.simulate import dig_maneuver, trajectory_columns

from conftest import REPORT_PAGES_WITHOUT_STUDY, pages_text, strict_loads


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The built-in run exactly as ``dragline run`` makes it (seed 0, the study, the diagnosis): the main job."""
    out = tmp_path_factory.mktemp("run") / "out"
    summary = _run.run_pipeline(None, out, quiet=True)
    return out, summary


def test_builtin_run_writes_every_output(demo):
    out, summary = demo
    for name in ("report.pdf", "metrics.json", "measured.csv", "simulated.csv", "results.mcap", "cameras.json"):
        assert (out / name).stat().st_size > 0, name
    measured = pd.read_csv(out / "measured.csv")
    simulated = pd.read_csv(out / "simulated.csv")
    assert list(measured.columns[: len(trajectory_columns())]) == trajectory_columns()
    assert abs(measured["time"].iloc[-1] - simulated["time"].iloc[-1]) < 0.01
    assert set(summary["stage_seconds"]) >= {"calibrate the cameras", "reconstruct", "compare"}
    assert not list(out.parent.glob(".*partial*"))


def test_builtin_results_are_dated_from_the_sessions_recording(demo):
    from mcap.reader import make_reader

    from dragline.capture import read_session

    out, _ = demo
    session, _ = read_session(out / "session")
    assert session.recorded_ns is not None  # filmed during this run
    with open(out / "results.mcap", "rb") as fh:
        reader = make_reader(fh)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}["dragline"]
        first = min(m.log_time for _, _, m in reader.iter_messages())
    assert meta["log_time_origin_source"] == "the recording's start"
    assert first == session.recorded_ns  # the trial's first frame, time 0 of the measured table


def test_the_session_does_not_reveal_the_hidden_physics(demo):
    out, _ = demo
    name = _run.BUILTIN_HIDDEN_PHYSICS.split(":")[0]
    for path in (out / "session").rglob("*"):
        if path.is_file():
            assert name.encode() not in path.read_bytes() and b"friction" not in path.read_bytes(), path
    assert name in (out / "truth" / "physics.json").read_text()


def test_builtin_recording_damps_faster_than_the_model(demo):
    # the paper's finding, which the built-in lab truth is chosen to show
    out, summary = demo
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["free_decay_summary"]["damping_ratio_ratio"]["median"] > 1.5
    assert abs(metrics["time_offset"]["applied"]) < 0.01  # the trial is aligned


def test_replay_of_the_session_gives_the_same_measurement(demo, tmp_path):
    out, _ = demo
    again = tmp_path / "results" / "nested" / "replay"  # parents made like mkdir -p
    assert main(["replay", str(out / "session" / "capture.mcap"), "--out", str(again), "--no-study", "--no-diagnose", "--quiet"]) == 0
    a = pd.read_csv(out / "measured.csv")
    b = pd.read_csv(again / "measured.csv")
    pd.testing.assert_frame_equal(a, b)


def test_bad_inputs_exit_2_and_leave_nothing(tmp_path, capsys):
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "keep.txt").write_text("mine")
    assert main(["run", "--out", str(busy), "--quiet"]) == 2
    assert main(["run", str(tmp_path / "nothing-here"), "--out", str(tmp_path / "o1")]) == 2
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file")
    assert main(["replay", str(junk), "--out", str(tmp_path / "o2")]) == 2
    assert main(["run", "--out", str(junk / "o3"), "--quiet"]) == 2  # a file stands where its folder must
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 4 and all(line.startswith("dragline: error:") for line in lines), lines
    assert (busy / "keep.txt").read_text() == "mine"
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()
    assert not list(tmp_path.glob(".*partial*"))


def test_an_interrupted_run_leaves_no_output(tmp_path, monkeypatch):
    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("dragline.reconstruct.reconstruct_session", interrupt)
    out = tmp_path / "out"
    assert main(["run", "--out", str(out), "--no-study", "--quiet"]) == 130
    assert not out.exists() and not list(tmp_path.glob(".*partial*"))


def test_committed_sample_session_replays(tmp_path):
    from pathlib import Path

    sample = Path(__file__).resolve().parents[1] / "samples" / "dig_sample"
    out = tmp_path / "out"
    assert main(["run", str(sample), "--out", str(out), "--no-study", "--no-diagnose", "--quiet"]) == 0
    measured = pd.read_csv(out / "measured.csv")
    truth = pd.read_csv(sample.parent / "dig_sample_truth" / "trajectories.csv")
    n = min(len(measured), len(truth))
    err = (measured["bucket.z"].iloc[:n] - truth["bucket.z"].iloc[:n]).abs()
    assert err.max() < 0.005  # m: the reconstruction agrees with the sample's truth


def test_config_file_sets_stage_options_and_rejects_unknown_keys(tmp_path, capsys):
    good = tmp_path / "good.toml"
    good.write_text('[run]\nstudy = false\n[reconstruct]\nmethod = "svd"\n')
    config = _run.read_config(good)
    assert config["reconstruct"]["method"] == "svd" and config["run"]["study"] is False
    assert config["simulate"]["discretization"] == "baseline"  # defaults kept
    bad = tmp_path / "bad.toml"
    bad.write_text('[reconstruct]\nsmoother = "x"\n')
    assert main(["run", "--config", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown key 'smoother'" in err[0]


def test_the_builtin_run_names_its_hidden_mechanism(demo):
    """End to end: ``dragline run`` finds the physics its lab truth hid."""
    out, _ = demo
    doc = json.loads((out / "diagnosis.json").read_text())
    hidden = json.loads((out / "truth" / "physics.json").read_text())["physics"][0]
    assert doc["verdict"] == hidden["name"]
    best = doc["hypotheses"][0]
    main_param = next(iter(hidden["parameters"]))
    assert best["parameters"][main_param] == pytest.approx(hidden["parameters"][main_param], rel=0.25)
    assert best["rms_after"] < 0.5 * best["rms_before"]


def test_every_json_the_builtin_run_wrote_is_strict(demo):
    out, _ = demo
    files = sorted(out.rglob("*.json"))
    assert {"diagnosis.json", "metrics.json", "cameras.json", "physics.json"} <= {f.name for f in files}
    for f in files:
        strict_loads(f.read_text())


def test_the_builtin_runs_report_reads_back(demo):
    """The report of the built-in dig: its summary prints the metrics' figures, and the study closes it."""
    out, _ = demo
    metrics = json.loads((out / "metrics.json").read_text())
    text = pages_text(out / "report.pdf")
    assert len(text) == REPORT_PAGES_WITHOUT_STUDY + 1  # with the discretization study
    summary = text[1]
    assert "measured vs predicted" in summary
    off = metrics["time_offset"]
    assert f"Offset applied: {round(off['applied'], 4) + 0.0:+.4f} s" in summary
    for row in metrics["peaks"]:
        for side in ("measured", "simulated"):
            assert f"{row[side]['value']:+.3f} @ {row[side]['time']:.2f} s" in summary, (row["channel"], side)
    pitch = metrics["channels"]["bucket.pitch"]
    assert f"{math.degrees(pitch['rms_error']):.3g} deg" in summary
    assert "-2.400 @ 6.77 s" in summary
    assert metrics["reels_stop"]["time"] == pytest.approx(dig_maneuver().end_time, abs=0.005)  # a 200 Hz sample
    assert "Fig. 21." in text[-1]
    assert all(level in text[-1] for level in ("low", "baseline", "medium", "high"))
