"""Shared simulated ground truth (PySINDy style): built once per test session."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DRAGLINE_SHARED", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def rig():
    from dragline.simulate import load_rig

    return load_rig()


@pytest.fixture(scope="session")
def dig_baseline(rig):
    """The paper's 10 s dig maneuver, nominal model, baseline discretization."""
    from dragline.simulate import simulate

    return simulate(rig, duration=10.0, rate_hz=200.0)
