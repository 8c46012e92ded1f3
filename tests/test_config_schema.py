"""The ``dragline run --config`` schema: each bad value refused at the door.

Each case here was accepted before the schema existed (the bad-input issue
lists them): ``study = "no"`` ran the study, ``max_gap = inf`` raised an
OverflowError traceback deep in reconstruction.
"""

from __future__ import annotations

import re

import pytest

from conftest import REPO
from dragline.capture._session_schema import session_info_markdown
from dragline.pipelines._config_schema import config_schema_markdown
from dragline.pipelines._run import read_config
from dragline.pipelines.cli import main


@pytest.mark.parametrize("body, key, value", [
    ('[run]\nstudy = "no"\n', "[run] study", "'no'"),
    ("[run]\nseed = -3\n", "[run] seed", "-3"),
    ("[run]\nseed = 1.5\n", "[run] seed", "1.5"),
    ("[reconstruct]\nmax_gap = inf\n", "[reconstruct] max_gap", "inf"),
    ("[reconstruct]\nmax_gap = 100000000\n", "[reconstruct] max_gap", "100000000"),
    ('[reconstruct]\nmethod = "kalman"\n', "[reconstruct] method", "'kalman'"),
    ('[simulate]\ndiscretization = [0, 5, 12, 4, 2, 3]\n', "[simulate] discretization", "[0, 5, 12, 4, 2, 3]"),
    ('[simulate]\nrig = ""\n', "[simulate] rig", "''"),
    ("run = 5\n", "[run]", "5"),
    ('[run]\nscheduler = "tcp://host:8786 extra"\n', "[run] scheduler", "'tcp://host:8786 extra'"),
])
def test_a_bad_value_exits_2_with_one_line_naming_file_key_and_value(tmp_path, capsys, body, key, value):
    config = tmp_path / "lab.toml"
    config.write_text(body)
    out = tmp_path / "out"
    assert main(["run", "--config", str(config), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert str(config) in err[0] and key in err[0] and value in err[0] and "expected" in err[0]
    assert not out.exists()


def test_a_valid_config_is_read_with_its_values_and_the_defaults(tmp_path):
    config = tmp_path / "lab.toml"
    config.write_text('[run]\nstudy = false\nseed = 7\n[reconstruct]\nsmoothing = "savgol"\nmax_gap = 0\n')
    got = read_config(config)
    assert got["run"] == {"seed": 7, "study": False, "diagnose": True, "scheduler": None}
    assert got["reconstruct"] == {"method": "paper", "smoothing": "savgol", "max_gap": 0}
    assert got["simulate"]["discretization"] == "baseline"


def test_the_docs_list_the_schemas_as_generated_from_them():
    doc = (REPO / "docs" / "schemas.md").read_text()

    def block(name):
        return re.search(rf"<!-- generated: {name} -->\n(.*?)<!-- end generated -->", doc, re.S).group(1)

    table = block("config schema")
    assert table == config_schema_markdown()
    for key in ("run.seed", "run.study", "simulate.rig", "simulate.discretization", "reconstruct.max_gap"):
        assert f"| `{key}` |" in table
    table = block("session info schema")
    assert table == session_info_markdown()
    assert "| `rate_hz` | number | required | > 0; <= 100000 |" in table
