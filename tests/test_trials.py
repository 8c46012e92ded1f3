"""Several trials of one machine fitted together, and a trial the fit never saw predicted (issue 36).

The truth is the slung load with its line 60 mm longer than the rig file says
(3.06 m for 3.0 m, 1.2 of the tolerance the test's rig file states): the
trials are flown with it, the diagnosis reads the file's 3.0 m. Each trial's
recording has its own constant offset on the load's height (a calibration
origin of its own), which a fit that shared offsets between trials could not
take up. And the dragline's dig with air drag, two trials on their own clocks,
the drag named and a third trial predicted by the named model.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from dragline.pipelines.cli import main
from dragline.simulate import Maneuver, rig_from_dict, simulate, write_maneuver_csv

NOISE = 5e-4  # m, white, on every position channel
TRUE_LENGTH = 3.06
RIG_TEXT_EDITS = (('maneuver = "slung_load.csv"', ""),
                  ("[tolerances]\n", '[tolerances]\n"ropes.line.length" = { absolute = 0.05 }\n'))
# name: (amplitude m, period s, axis, noise seed, offset on load.z m)
FLIGHTS = {"a": (0.15, 5.0, 0, 1, 0.004), "b": (0.12, 4.0, 1, 2, -0.003), "c": (0.10, 6.0, 0, 3, 0.0)}


def _rig_text():
    from importlib.resources import files

    text = files("dragline.simulate").joinpath("data", "slung_load.toml").read_text()
    for old, new in RIG_TEXT_EDITS:
        assert old in text
        text = text.replace(old, new)
    return text


def _flight(truth, amplitude, period, axis, seed, z_offset):
    t = np.round(np.arange(0.0, 12.0 + 1e-9, 0.02), 6)
    track = np.zeros((t.size, 3))
    track[:, 2] = -4.0
    track[:, axis] = amplitude * np.sin(2 * np.pi * t / period)
    maneuver = Maneuver(t, points={"anchor": track})
    run = simulate(truth, maneuver, duration=12.0, rate_hz=100.0, discretization="low")
    rng = np.random.default_rng(seed)
    table = run.table[["time", "load.x", "load.y", "load.z"]].copy()
    for c in ("load.x", "load.y", "load.z"):
        table[c] = table[c] + rng.normal(0.0, NOISE, len(table)) + (z_offset if c == "load.z" else 0.0)
    return table, maneuver


@pytest.fixture(scope="module")
def trials(tmp_path_factory):
    """``dragline diagnose a/measured.csv b/measured.csv --predict c/measured.csv`` on the flights."""
    import tomllib

    folder = tmp_path_factory.mktemp("trials")
    rig_path = folder / "slung.toml"
    rig_path.write_text(_rig_text())
    truth_doc = tomllib.loads(rig_path.read_text())
    truth_doc["ropes"]["line"]["length"] = TRUE_LENGTH
    truth = rig_from_dict(truth_doc)
    paths = {}
    for name, spec in FLIGHTS.items():
        table, maneuver = _flight(truth, *spec)
        (folder / name).mkdir()
        paths[name] = folder / name / "measured.csv"
        table.to_csv(paths[name], index=False)
        write_maneuver_csv(folder / name / "maneuver.csv", maneuver)
    out = folder / "diagnosis.json"
    code = main(["diagnose", str(paths["a"]), str(paths["b"]), "--predict", str(paths["c"]), "--rig", str(rig_path),
                 "--discretization", "low", "--candidates", "aero_drag,rope_bending_damping", "--json", str(out),
                 "--report", str(folder / "report.pdf"), "--leave-one-out", "--quiet"])
    assert code == 0
    assert (folder / "report.pdf").stat().st_size > 0
    return json.loads(out.read_text()), folder, paths, rig_path


def test_trials_share_the_rig_and_recover_the_true_length(trials):
    doc = trials[0]
    assert [t["name"] for t in doc["trials"]] == ["a-measured", "b-measured"]
    assert doc["verdict"] == "none", doc["reason"]
    length = next(e for e in doc["calibration"]["parameters"] if e["parameter"] == "ropes.line.length")
    # 60 mm off in the file: found to a twentieth of the tolerance.
    assert length["estimate"] == pytest.approx(TRUE_LENGTH, abs=0.0025)


def test_each_trial_keeps_its_own_offsets(trials):
    offsets = {ch: e["offset"] for ch, e in trials[0]["channels"].items()}
    # A flight along x leaves load.y still (not a channel); one along y, load.x.
    assert set(offsets) == {"a-measured/load.x", "a-measured/load.z", "b-measured/load.y", "b-measured/load.z"}
    assert offsets["a-measured/load.z"] == pytest.approx(FLIGHTS["a"][4], abs=1e-3)
    assert offsets["b-measured/load.z"] == pytest.approx(FLIGHTS["b"][4], abs=1e-3)


def test_a_trial_never_fitted_is_predicted_within_noise_by_the_update_only(trials):
    (entry,) = trials[0]["held_out"]
    assert entry["trial"] == "c-measured"
    rms = entry["rms_noise"]
    # Nominal: the 60 mm shorter line swings 1 % faster, ten times the noise after 12 s; updated: noise.
    assert rms["nominal"] > 5.0
    assert rms["updated"] < 1.3
    assert entry["better_than_nominal"] == {"updated": True}


def test_leaving_each_trial_out_the_others_predict_it_and_agree(trials):
    loo = trials[0]["leave_one_out"]
    assert [(s["held_out"], s["fitted"]) for s in loo["splits"]] == [("a-measured", ["b-measured"]),
                                                                     ("b-measured", ["a-measured"])]
    assert loo["verdicts"] == {"none": 2} and loo["verdict_agreement"] == 1.0
    assert loo["updated_better_share"] == 1.0 and loo["named_better_share"] is None
    length = loo["parameters"]["ropes.line.length"]
    assert length["n"] == 2 and abs(length["min"] - TRUE_LENGTH) < 0.0025 and abs(length["max"] - TRUE_LENGTH) < 0.0025


def test_a_held_out_trial_the_rig_cannot_read_is_refused_before_any_fit(trials, tmp_path, capsys):
    doc, folder, paths, rig_path = trials
    bad = tmp_path / "other.csv"
    bad.write_text("time,crate.x\n0,1\n0.01,1\n")
    code = main(["diagnose", str(paths["a"]), "--predict", str(bad), "--rig", str(rig_path), "--json",
                 str(tmp_path / "d.json")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and str(bad) in err[0]
    assert not (tmp_path / "d.json").exists()


def test_dig_trials_on_their_own_clocks_name_the_hidden_drag_and_it_predicts_a_third():
    """The dragline's dig with air drag on the bucket (cd 8), recorded three times with their own noise, the
    second on a clock 0.3 s late: each trial aligned by its own rope lengths, the drag named from two, the
    third predicted by the named model within twice its noise where the nominal and the updated one miss."""
    from dragline.compare.diagnose import diagnose
    from dragline.simulate import parse_physics

    noise = {"position": 0.0005, "angle": 0.005}  # m, rad
    run = simulate(physics=[parse_physics("aero_drag:cd=8.0")], discretization="low")

    def recorded(seed, late=0.0):
        rng = np.random.default_rng(seed)
        table = run.table[[c for c in run.table.columns if "reel_length" not in c and "tension" not in c]].copy()
        for c in table.columns[1:]:
            kind = "angle" if c.rsplit(".", 1)[1] in ("roll", "pitch", "yaw", "p", "q", "r") else "position"
            table[c] = table[c] + rng.normal(0.0, noise[kind], len(table))
        table["time"] = table["time"] + late
        return table

    doc = diagnose([recorded(21), recorded(22, late=0.3)], candidates=["aero_drag", "pulley_inertia"],
                   discretization="low", trial_names=["a", "b"], held_out=[("c", recorded(23), None)]).doc
    assert doc["verdict"] == "aero_drag", doc["reason"]
    assert [t["time_offset"] for t in doc["trials"]] == [pytest.approx(0.0, abs=0.002), pytest.approx(0.3, abs=0.002)]
    named = next(h for h in doc["hypotheses"] if h["name"] == "aero_drag")
    assert named["parameters"]["cd"] == pytest.approx(8.0, rel=0.15)
    rms = doc["held_out"][0]["rms_noise"]
    assert rms["named"] < 2.0 < rms["updated"] < rms["nominal"]


def test_trials_that_agree_leave_the_stated_uncertainty_as_it_was(trials):
    """One true length in every trial: each trial's own estimate agrees with it, the spread between trials is
    what noise gives (Cochran's Q about its degrees of freedom), and the stated uncertainty stays at the
    millimetre a 60 mm correction found to 2.5 mm needs - not widened."""
    length = next(e for e in trials[0]["calibration"]["parameters"] if e["parameter"] == "ropes.line.length")
    spread = trials[0]["calibration"]["between_trials"]["parameters"]["ropes.line.length"]
    for value, sd in zip(spread["trial_estimates"], spread["trial_uncertainties"]):
        assert abs(value - TRUE_LENGTH) < max(3 * sd, 0.0025)
    assert spread["between_trials_sd"] < 0.002
    assert length["uncertainty"] < 0.002


def test_trials_that_disagree_widen_the_stated_uncertainty_to_their_spread():
    """Three trials flown with lines of 3.00, 3.06 and 3.12 m (a model wrong differently on each trial) fitted
    as one rig: the shared length lands among them, each trial's own estimate finds its own line, and the
    stated uncertainty is the random-effects one - the spread between trials over sqrt(3), with the file's
    0.05 m tolerance as prior: 1 / sqrt(1 / 0.05^2 + 3 / 0.06^2) = 0.028 m - not the 0.3 mm that pooling all
    the rows claims."""
    import tomllib

    from dragline.compare.diagnose import diagnose

    base = tomllib.loads(_rig_text())
    lengths = {"a": 3.00, "b": 3.06, "c": 3.12}
    tables, maneuvers = [], []
    for name, length in lengths.items():
        doc = tomllib.loads(_rig_text())
        doc.pop("maneuver", None)
        doc["ropes"]["line"]["length"] = length
        amplitude, period, axis, seed, _ = FLIGHTS[name]
        table, maneuver = _flight(rig_from_dict(doc), amplitude, period, axis, seed, 0.0)
        tables.append(table)
        maneuvers.append(maneuver)
    base.pop("maneuver", None)
    base["ropes"]["line"]["length"] = 3.06
    out = diagnose(tables, maneuvers, rig=rig_from_dict(base), discretization="low", candidates=["aero_drag"],
                   trial_names=list(lengths)).doc
    length = next(e for e in out["calibration"]["parameters"] if e["parameter"] == "ropes.line.length")
    spread = out["calibration"]["between_trials"]["parameters"]["ropes.line.length"]
    assert 3.00 < length["estimate"] < 3.12
    # One Gauss-Newton step from the shared fit: each trial nearer its own line than its neighbour's.
    for value, truth in zip(spread["trial_estimates"], lengths.values()):
        assert value == pytest.approx(truth, abs=0.03)
    assert spread["between_trials_sd"] == pytest.approx(0.06, rel=0.3)
    assert length["uncertainty"] == pytest.approx(1 / np.sqrt(1 / 0.05**2 + 3 / 0.06**2), rel=0.35)
    # A parameter the trials pull apart is never stated wider than the lab's prior.
    assert all(e["posterior_over_prior"] <= 1.0 + 1e-9 for e in out["calibration"]["parameters"])
