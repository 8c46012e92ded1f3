"""``dragline compare`` on the command line: outputs, JSON content and exit codes."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from dragline.pipelines.cli import main
from dragline.simulate import dig_maneuver
from conftest import synthetic_table

T = np.round(np.arange(0.0, 10.0 + 1e-9, 0.02), 10)



@pytest.fixture()
def files(tmp_path):
    measured = synthetic_table(T, reel_columns=False)
    measured["time"] = measured["time"] + 0.3  # the cameras started 0.3 s before the reels
    measured["bucket.z"] = measured["bucket.z"] + 0.05  # 50 mm off: outside the 20 mm tolerance
    measured["bucket.q"] = np.nan
    simulated = synthetic_table(T)
    paths = {"measured": tmp_path / "measured.csv", "simulated": tmp_path / "simulated.csv"}
    measured.to_csv(paths["measured"], index=False)
    simulated.to_csv(paths["simulated"], index=False)
    return tmp_path, paths


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    return code, err


def test_compare_writes_report_and_json(files, capsys):
    folder, p = files
    report, metrics_path = folder / "report.pdf", folder / "metrics.json"
    code, err = _run(capsys, "compare", p["measured"], p["simulated"], "--report", report, "--json", metrics_path)
    assert code == 0, err
    assert report.read_bytes()[:5] == b"%PDF-"
    metrics = json.loads(metrics_path.read_text())
    assert metrics["time_offset"]["applied"] == pytest.approx(0.3, abs=1e-3)
    assert metrics["time_offset"]["source"] == "estimated"
    z = metrics["channels"]["bucket.z"]
    assert z["rms_error"] == pytest.approx(0.05, abs=1e-3) and z["verdict"] == "fail"
    assert metrics["channels"]["bucket.q"]["verdict"] == "missing"
    assert metrics["summary"] == {"n_channels": 50, "n_pass": 48, "n_fail": 1, "n_missing": 1}
    assert {row["channel"] for row in metrics["peaks"]} == {"bucket.vx", "bucket.vz", "bucket.q"}
    # the simulated table's reel columns: the first 20 ms sample after the dig's table ends (6.44 s)
    assert metrics["reels_stop"]["time"] == pytest.approx(T[np.searchsorted(T, dig_maneuver().end_time)])
    assert set(metrics["free_decay"]["bucket.pitch"]) == {"measured", "simulated", "difference"}
    assert "+0.3" in err and "48 of 50" in err
    assert sorted(x.name for x in folder.iterdir()) == ["measured.csv", "metrics.json", "report.pdf", "simulated.csv"]


def test_given_time_offset_is_applied(files, capsys):
    folder, p = files
    out = folder / "m.json"
    code, err = _run(capsys, "compare", p["measured"], p["simulated"], "--json", out, "--time-offset", "0")
    assert code == 0, err
    metrics = json.loads(out.read_text())
    assert metrics["time_offset"]["applied"] == 0.0 and metrics["time_offset"]["source"] == "given"
    assert metrics["time_offset"]["offset"] == pytest.approx(0.3, abs=1e-3)
    assert metrics["channels"]["bucket.x"]["verdict"] == "fail"  # 0.3 s out of step


def _one_line_error(code, err, text):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dragline: error:") and text in lines[0], err
    assert "Traceback" not in err


def test_no_common_channels_exits_2(files, capsys):
    folder, p = files
    other = folder / "other.csv"
    pd.DataFrame({"time": T, "unrelated": 1.0}).to_csv(other, index=False)
    code, err = _run(capsys, "compare", other, p["simulated"], "--json", folder / "x.json")
    _one_line_error(code, err, "no trajectory channel in common")
    assert not (folder / "x.json").exists()


def test_no_time_overlap_exits_2(files, capsys):
    folder, p = files
    late = folder / "late.csv"
    table = synthetic_table(T, reel_columns=False)
    table["time"] += 500.0
    table.to_csv(late, index=False)
    code, err = _run(capsys, "compare", late, p["simulated"], "--report", folder / "r.pdf")
    _one_line_error(code, err, "do not overlap in time")
    assert not (folder / "r.pdf").exists()


def test_nan_only_table_exits_2(files, capsys):
    folder, p = files
    blank = folder / "blank.csv"
    table = synthetic_table(T, reel_columns=False)
    table.loc[:, table.columns != "time"] = math.nan
    table.to_csv(blank, index=False)
    code, err = _run(capsys, "compare", blank, p["simulated"], "--json", folder / "x.json")
    _one_line_error(code, err, "no channel has finite samples")


@pytest.mark.parametrize(
    "extra, text",
    [
        ((), "give --report REPORT.pdf and/or --json METRICS.json"),
        (("--json", "x.json", "--time-offset", "soon"), "--time-offset must be 'auto' or a number"),
        (("--json", "no_such_folder/x.json"), "does not exist"),
    ],
)
def test_usage_errors_exit_2(files, capsys, monkeypatch, extra, text):
    folder, p = files
    monkeypatch.chdir(folder)
    code, err = _run(capsys, "compare", p["measured"], p["simulated"], *extra)
    _one_line_error(code, err, text)


def test_missing_input_file_exits_2(files, capsys):
    folder, p = files
    code, err = _run(capsys, "compare", folder / "absent.csv", p["simulated"], "--json", folder / "x.json")
    _one_line_error(code, err, "measured table")
