"""The stated interval's constants calibrated (``benchmarks/_intervals.py``).

Truth from elsewhere: records drawn with a known floor and share along
the signature are given back by the likelihood within their sampling
error, and the coverage criterion's choice covers as a normal's intervals
do; the committed records (seeds 92-104's correctly named cases) give the
constants in force, which fails if one is moved.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dragline.benchmarks._intervals import calibrate_error_along, interval_records, load_interval_records
from dragline.compare.diagnose._hypotheses import REFINE_XATOL
from dragline.compare.diagnose._summary import ERROR_ALONG_SIGNATURE


def _drawn(n, floor, along, seed=11):
    rng = np.random.default_rng(seed)
    records = []
    for k in range(n):
        profile = float(rng.uniform(0.001, 0.03))
        marginal = float(rng.uniform(0.0, 0.06))
        improvement = float(rng.uniform(1.0, 400.0))  # E / D from 1 to 1/400
        sd = math.hypot(max(profile, marginal, floor, REFINE_XATOL), along * math.sqrt(1.0 / improvement))
        value = 1.0
        records.append({"set": "drawn", "seed": k, "truth": "x", "value": value,
                         "fitted": value * math.exp(rng.normal(0.0, sd)), "profile_relative": profile,
                         "fold_spread": 0.0, "marginal_relative": marginal, "own_error_chi2": 1.0,
                         "improvement": improvement, "excluded": None})
    return records


def test_records_drawn_with_known_constants_give_them_back():
    # The maximum likelihood recovers both; the coverage criterion's choice meets the Wilson bars on the one set
    # and covers as a normal's intervals do.
    report = calibrate_error_along(_drawn(3000, floor=0.04, along=0.15))
    floor, along = report["constants"]["floor"], report["constants"]["along"]
    assert floor["likelihood"] == pytest.approx(0.04, abs=0.003)
    assert along["likelihood"] == pytest.approx(0.15, rel=0.06)
    assert floor["likelihood_interval_95"][0] <= 0.04 <= floor["likelihood_interval_95"][1]
    assert along["likelihood_interval_95"][0] <= 0.15 <= along["likelihood_interval_95"][1]
    assert report["calibrated"]["seeds_met"] == report["n_sets"] == 1
    assert report["calibrated"]["coverage_68"] == pytest.approx(0.683, abs=0.02)
    assert report["calibrated"]["coverage_95"] == pytest.approx(0.954, abs=0.01)


def test_the_coverage_criterion_prefers_the_values_that_meet_the_bar_on_every_set():
    # Two sets drawn alike: intervals far too narrow (floor and share 0) meet neither bar; the choice meets both
    # on both sets.
    from dragline.benchmarks._intervals import calibrate_coverage

    records = [dict(r, set="a") for r in _drawn(300, floor=0.04, along=0.15, seed=1)]
    records += [dict(r, set="b") for r in _drawn(300, floor=0.04, along=0.15, seed=2)]
    floor, along, met, c68, c95 = calibrate_coverage(records)
    assert met == 2 and abs(c68 - 0.68) < 0.05 and abs(c95 - 0.95) < 0.03
    assert calibrate_error_along(records, floor=0.0, along=0.0)["in_force"]["seeds_met"] == 0


def test_excluded_records_are_left_out():
    records = _drawn(400, floor=0.04, along=0.15)
    bad = [dict(r, fitted=r["value"] * 3.0, excluded="held at the joint refit's old span edge") for r in records[:40]]
    assert calibrate_error_along(bad + records[40:])["n_cases"] == 360
    assert calibrate_error_along(bad + records[40:])["constants"] == calibrate_error_along(records[40:])["constants"]


def test_the_constants_in_force_are_the_committed_records_calibration():
    report = calibrate_error_along(load_interval_records())
    assert report["n_cases"] >= 150 and report["n_sets"] == 6
    assert report["constants"]["along"]["value"] == ERROR_ALONG_SIGNATURE
    assert all(c["value"] == pytest.approx(c["calibrated"]) for c in report["constants"].values()), report
    assert report["in_force"]["seeds_met"] >= 5


def test_a_runs_kept_diagnoses_become_interval_records(tmp_path):
    import json

    hyp = {"name": "aero_drag", "main_parameter": "cd", "parameters": {"cd": 2.0},
           "uncertainty": {"relative": 0.1, "profile_relative": 0.01, "marginal_relative": 0.04,
                           "fold_values": [1.9, 2.1]},
           "improvement": 4.0e5, "profile": [{"value": 2.0, "chi2": 10.0}, {"value": 3.0, "chi2": 20.0}]}
    (tmp_path / "case7.json").write_text(json.dumps({"hypotheses": [hyp], "null_test": {"own_error_chi2": 5.0e4}}))
    report = {"worlds": {"realistic": {"cases": [
        {"seed": 7, "truth": "aero_drag", "value": 1.85, "verdict": "aero_drag"},
        {"seed": 8, "truth": "none", "value": 0.0, "verdict": "none"}]}}}
    (rec,) = interval_records(report, str(tmp_path), "test")
    assert rec["fitted"] == 2.0 and rec["value"] == 1.85 and rec["excluded"] is None
    assert rec["fold_spread"] == pytest.approx(math.log(2.1 / 1.9) / 2)
    assert rec["marginal_relative"] == 0.04 and rec["own_error_chi2"] == 5.0e4


def test_a_joint_refit_held_at_the_old_span_edge_is_marked_in_runs_that_had_the_span(tmp_path):
    import json

    first = 2.0 / math.exp(0.4)
    hyp = {"name": "pulley_inertia", "main_parameter": "inertia", "parameters": {"inertia": 2.0},
           "uncertainty": {"relative": 0.05, "profile_relative": 0.01, "fold_values": [2.0, 2.0]},
           "improvement": 1.0e5, "profile": [{"value": first, "chi2": 10.0}, {"value": 2.5, "chi2": 30.0}]}
    (tmp_path / "case3.json").write_text(json.dumps({"hypotheses": [hyp], "null_test": {"own_error_chi2": 1.0e4}}))
    report = {"worlds": {"realistic": {"cases": [{"seed": 3, "truth": "pulley_inertia", "value": 2.5,
                                                  "verdict": "pulley_inertia"}]}}}
    assert interval_records(report, str(tmp_path), "old", span_until=True)[0]["excluded"]
    assert interval_records(report, str(tmp_path), "new", span_until=False)[0]["excluded"] is None
