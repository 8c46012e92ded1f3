"""`dragline run --rig NAME`: the whole pipeline on machines other than the paper's dragline.

Each built-in machine, and a rig file written from docs/rig-file.md alone,
is filmed in its synthetic lab with the mechanism its rig file's ``[demo]``
hides (the truth rig drawn within its tolerances, a finer discretization),
calibrated, reconstructed, compared with the nominal model and diagnosed:
the diagnosis must name the hidden mechanism, with its parameter within a
factor 1.5 of the truth.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from dragline.compare import compare_tables
from dragline.compare._compare import TOLERANCES
from dragline.compare._preset import comparison_preset
from dragline.pipelines.cli import main
from dragline.simulate import default_maneuver, load_rig, simulate

DATA = Path(__file__).resolve().parent / "data"


@pytest.mark.parametrize("rig", ["pendulum", "slung_load", "gantry_crane", str(DATA / "double_pendulum_release.toml")])
def test_dragline_run_names_the_mechanism_the_rig_hides(tmp_path, rig):
    out = tmp_path / "out"
    assert main(["run", "--rig", rig, "--out", str(out), "--quiet", "--no-study"]) == 0
    truth = json.loads((out / "truth" / "physics.json").read_text())["physics"][0]
    found = json.loads((out / "diagnosis.json").read_text())
    assert found["verdict"] == truth["name"], found["reason"]
    best = next(h for h in found["hypotheses"] if h["name"] == truth["name"])
    key = best["main_parameter"]
    assert best["parameters"][key] == pytest.approx(truth["parameters"][key], rel=0.5)
    metrics = json.loads((out / "metrics.json").read_text())
    machine = load_rig(rig)
    assert metrics["preset"]["name"] == "rig" and "peaks" not in metrics
    largest = max(float(np.max(b.size)) for b in machine.bodies.values())
    assert metrics["tolerances"]["position"]["rms"] == pytest.approx(0.05 * largest)
    assert set(metrics["channels"]) == {c for c in metrics["channels"] if c.split(".")[0] in
                                        (*machine.bodies, *machine.ropes)}
    for name in ("report.pdf", "diagnosis.pdf", "results.mcap"):
        assert (out / name).stat().st_size > 1000


def test_the_dragline_keeps_the_papers_comparison():
    preset = comparison_preset(load_rig())
    assert preset.name == "paper" and preset.tolerances == TOLERANCES
    assert preset.study_channel == "bucket.pitch" and preset.figures[0][0] == "8"


def test_another_machines_tolerances_follow_the_papers_rules():
    rig = load_rig("pendulum")
    table = simulate(rig, duration=4.0, rate_hz=100.0, discretization="low").table
    metrics = compare_tables(table, table, rig=rig, maneuver=default_maneuver(rig))
    tol = metrics["tolerances"]
    assert tol["position"]["rms"] == pytest.approx(0.05 * 0.08)      # 5 % of the 80 mm ball
    assert tol["angle"]["rms"] == pytest.approx(np.radians(3.0))
    speed = np.max(np.linalg.norm(table[["ball.vx", "ball.vy", "ball.vz"]].to_numpy(), axis=1))
    assert tol["velocity"]["rms"] == pytest.approx(0.1 * speed)       # 10 % of the peak speed
    # The model against itself: every compared channel passes; the ball's swing (x, pitch) is drawn.
    assert metrics["summary"]["n_fail"] == 0
    drawn = [f[1] for f in metrics["preset"]["figures"]]
    assert "ball.x" in drawn and "ball.pitch" in drawn and "ball.y" not in drawn
    # Released at 10 deg from the start: the free decay starts at once.
    assert metrics["reels_stop"]["time"] == pytest.approx(0.0)
