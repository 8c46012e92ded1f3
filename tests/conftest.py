"""Shared simulated ground truth (PySINDy style): built once per test session."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dragline.compare._paper import FIGURES

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "tests" / "data"
# The seed paper's numbers, transcribed by hand (tests/data/paper/SOURCES.md).
PAPER_PARAMETERS = DATA / "paper" / "paper_parameters.toml"


# The report's pages: at a glance, summary + all channels, Figs. 8-20 two per page, free-decay text and plots
# (the study's Fig. 21 one more).
REPORT_PAGES_WITHOUT_STUDY = 1 + 2 + math.ceil(len(FIGURES) / 2) + 2


def pages_text(path):
    """Each page's text of a PDF (pypdf)."""
    import pypdf

    return [page.extract_text() for page in pypdf.PdfReader(str(path)).pages]


def strict_loads(text):
    """``json.loads`` that refuses NaN and Infinity, as a browser's ``JSON.parse`` does."""
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=refuse)


@pytest.fixture(scope="session")
def rig():
    from dragline.simulate import load_rig

    return load_rig()


@pytest.fixture(scope="session")
def dig_baseline(rig):
    """The paper's 10 s dig maneuver, nominal model, baseline discretization."""
    from dragline.simulate import simulate

    return simulate(rig, duration=10.0, rate_hz=200.0)


def refused_edit(tmp_path, source, edit, load):
    """``load`` of a copy of file ``source`` with ``edit`` (old, new) applied once: its one-line ValueError,
    which must start with the copy's path."""
    bad = tmp_path / Path(source).name
    bad.write_text(Path(source).read_text().replace(*edit, 1))
    with pytest.raises(ValueError) as info:
        load(bad)
    message = str(info.value)
    assert message.startswith(str(bad)) and "\n" not in message
    return message


def synthetic_table(t, reel_columns=True):
    """A trajectory table of smooth made-up channels over the dig's reel table."""
    from dragline.simulate import dig_maneuver, trajectory_columns

    cols = {"time": t}
    for k, ch in enumerate(trajectory_columns()[1:-2]):
        cols[ch] = 0.3 * np.sin(2 * np.pi * (0.2 + 0.01 * k) * t + k) + 0.01 * k * t
    hoist, drag = (dig_maneuver().lengths_at(t)[w] for w in ("hoist", "drag"))
    tau = np.clip(t - 6.5, 0.0, None)
    cols["hoist_rope.length"] = hoist + 0.02 * np.sin(4.0 * tau) * np.exp(-0.3 * tau)
    cols["drag_rope.length"] = drag
    if reel_columns:
        cols["hoist_rope.reel_length"], cols["drag_rope.reel_length"] = hoist, drag
    return pd.DataFrame(cols)
