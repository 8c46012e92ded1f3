"""Every JSON the tool writes parses with a strict parser.

Python's ``json`` writes ``NaN`` and ``Infinity`` unless told not to; a
browser's ``JSON.parse`` refuses both. Before the shared writer, ``inspect
--json`` printed them for tables with empty or non-finite cells.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from dragline.capture._strict_json import json_ready, json_text, write_json
from dragline.pipelines.cli import main

from conftest import strict_loads


def test_non_finite_numbers_are_written_as_null_and_the_input_is_kept():
    doc = {"a": float("nan"), "b": [1.0, float("inf"), np.float32(-np.inf)], 3: np.array([0.5, np.nan]),
           "n": np.int64(7), "flag": np.bool_(True), "path": Path("x/y.csv"), "t": (np.float64(2.5),)}
    back = strict_loads(json_text(doc))
    assert back == {"a": None, "b": [1.0, None, None], "3": [0.5, None], "n": 7, "flag": True,
                    "path": os.path.join("x", "y.csv"), "t": [2.5]}
    assert np.isnan(doc["a"]) and np.isnan(doc[3][1])  # not modified
    assert json_ready(1e308) == 1e308  # large but finite stays a number


def test_write_json_is_strict_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "out.json"
    write_json(path, {"rms": np.nan, "x": [np.inf]})
    assert strict_loads(path.read_text()) == {"rms": None, "x": [None]}
    assert os.listdir(tmp_path) == ["out.json"]


def test_inspect_json_of_a_table_with_gaps_is_strict(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text("time,bucket.x\n0,1\n0.01,\n0.02,3\n")
    assert main(["inspect", "--json", str(table)]) == 0
    doc = strict_loads(capsys.readouterr().out)
    assert doc["time_start_s"] == 0.0 and doc["time_end_s"] == pytest.approx(0.02)
    assert doc["nan_values"] == {"bucket.x": 1}


@pytest.mark.parametrize("rows, words", [
    ("nan,1\n0.01,2\n0.02,3\n", "column time, row 2"),  # inspect --json once printed NaN for it
    ("0,1\n0.01,inf\n0.02,3\n", "column bucket.x, row 3 = inf"),
])
def test_a_table_with_a_non_finite_time_or_cell_is_refused(tmp_path, capsys, rows, words):
    table = tmp_path / "t.csv"
    table.write_text("time,bucket.x\n" + rows)
    assert main(["inspect", "--json", str(table)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(table) in err[0] and words in err[0], err
