"""The two-mechanism cases (``benchmarks/_pairs.py``): what they hide, and how a kept diagnosis is read."""

from __future__ import annotations

import json

import pytest

from dragline.benchmarks._discovery import DETECTION_THRESHOLDS
from dragline.benchmarks._pairs import PAIRS, _fitted, pair_cases, pair_records


def test_each_case_hides_a_dominant_and_a_second_mechanism_at_their_multiples_of_the_threshold():
    cases = pair_cases(seed=7)
    assert [(a, b) for a, _, b, _, _ in cases] == list(PAIRS)
    for a, va, b, vb, _ in cases:
        assert a != b
        assert va == pytest.approx(20 * DETECTION_THRESHOLDS[a], rel=5e-3)
        assert vb == pytest.approx(5 * DETECTION_THRESHOLDS[b], rel=5e-3)
    assert len({c[4] for c in cases}) == len(cases) and all(7500 <= c[4] < 7600 for c in cases)
    # every candidate is dominant once
    assert {a for a, *_ in cases} == set(DETECTION_THRESHOLDS)


def _doc():
    return {"verdict": "aero_drag", "reason": "r",
            "hypotheses": [{"name": "aero_drag", "main_parameter": "cd", "parameters": {"cd": 18.0, "air_density": 1.2},
                            "improvement": 5.0, "rms_before": 2.0, "rms_after": 1.0}],
            "null_test": {"threshold": 1.0, "noise_threshold": 1.0, "model_error_allowance": 0.0,
                          "own_error_chi2": 1.0, "excess_chi2_updated": 2.0, "n_weighted": 10.0},
            "second_mechanism": {"noise_threshold": 1.0, "allowance": 0.0, "named_excess": 2.0,
                                 "candidates": [{"name": "pulley_inertia", "parameters": {"inertia": 1.3e-3,
                                                                                          "radius": 0.05},
                                                 "improvement": 3.0, "resolved_improvement": 3.0, "at_bound": None}]},
            "mismatch_updated": [], "mismatch_after": {"entries": []}}


def test_the_fitted_values_come_from_the_verdict_and_the_second_round():
    doc = _doc()
    assert _fitted(doc, "aero_drag") == 18.0 and _fitted(doc, "pulley_inertia") == 1.3e-3
    assert _fitted(doc, "chain_link_friction") is None


def test_a_runs_kept_diagnoses_become_pair_records(tmp_path):
    (tmp_path / "case4.json").write_text(json.dumps(_doc()))
    report = {"cases": [{"seed": 4, "truth": "aero_drag", "value": 18.5, "second": "pulley_inertia",
                         "second_value": 1.26e-3, "verdict": "aero_drag"},
                        {"seed": 5, "truth": "aero_drag", "value": 18.5, "second": "pulley_inertia",
                         "second_value": 1.26e-3, "verdict": "error"}]}
    (record,) = pair_records(report, str(tmp_path), "test")
    assert record["second"] == "pulley_inertia" and record["verdict"] == "aero_drag"
    assert record["document"]["second_mechanism"]["candidates"][0]["improvement"] == 3.0
