"""A body tracked in the frame of the point that moves the rig: no free offset on its position (issue 36).

A tracker that measures the load and the drone above it in one frame puts
the load where the model, hung from the measured drone, must put it: a
constant offset of the load's height is then the rope's length, not a
calibration origin. The truth is the slung load flown on a line 60 mm longer
than the rig file says (``test_trials``' flights, no offset added), so the
load hangs 60 mm lower than the file's model puts it (the line's stretch
under the load, 0.45 mm, the same in both).
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from dragline.compare.diagnose._problem import Problem
from dragline.simulate import rig_from_dict
from test_trials import TRUE_LENGTH, _flight, _rig_text

FILE_LENGTH = 3.0
# The fitted flight's hook swings 20 mm: its period says little about the line's length.
SMALL_SWING = 0.02
# The line's stretch under the load and half the line's weight, T L / EA, known only as well as EA (30 %):
# with the height measured, the length is known no better than that part of the stretch (m).
STRETCH_SD = (0.46 + 0.5 * 0.0245 * 3.0) * 9.81 * 3.0 / 3.0e4 * 0.3


def test_a_channel_without_a_free_offset_keeps_its_constant_in_the_residual():
    t = np.arange(1257) / 100.0  # two whole periods: the rates average to zero, so the clock shift takes no constant
    rng = np.random.default_rng(3)
    measured = np.column_stack([np.sin(t), np.cos(t)]) + 0.02 + rng.normal(0.0, 1e-3, (t.size, 2))
    sim = np.column_stack([np.sin(t), np.cos(t)])
    problem = Problem(t, measured, np.full(2, 1e-3), t_stop=20.0, offset_free=[True, False])
    b, _, _ = problem.nuisance(sim, "all")
    assert b[0] == pytest.approx(0.02, abs=3e-4) and b[1] == 0.0
    r = problem.residual(sim)
    assert abs(np.mean(r[:, 0])) < 3e-4                   # taken up by the free offset
    assert np.mean(r[:, 1]) == pytest.approx(0.02, abs=3e-4)  # left for the model to explain
    # With regressors the offsets are eliminated the same way: a regressor that is the constant itself
    # takes it up on the pinned channel (coefficient 1), and nothing on the free one.
    step = np.zeros_like(sim)
    step[:, 1] = 0.02
    b, _, a = problem.with_regressors([step]).nuisance(sim, "all")
    assert a[0] == pytest.approx(1.0, abs=0.02) and b[1] == 0.0


MAPPING = """
[table]
time = "t"
up = "-z"            # the tool's own frame, K down
{shared}

[bodies.load]
position = ["x", "y", "z"]

[points.anchor]
position = ["ax", "ay", "az"]
"""


def _tracked_csv(path, table, maneuver):
    """The flight as one tracker records it: the load and the hook above it, in one frame."""
    import pandas as pd

    t = table["time"].to_numpy()
    hook = np.column_stack([np.interp(t, maneuver.time, maneuver.points["anchor"][:, k]) for k in range(3)])
    pd.DataFrame({"t": t, "x": table["load.x"], "y": table["load.y"], "z": table["load.z"],
                  "ax": hook[:, 0], "ay": hook[:, 1], "az": hook[:, 2]}).to_csv(path, index=False,
                                                                                  float_format="%.12g")


@pytest.fixture(scope="module")
def fits(tmp_path_factory):
    """``diagnose_path`` (what ``dragline diagnose --mapping`` runs) on one flight, another predicted, through a
    mapping with the load's offsets free and through one that says the frame is shared."""
    from dragline.compare.diagnose import diagnose_path

    folder = tmp_path_factory.mktemp("frames")
    truth_doc = tomllib.loads(_rig_text())
    truth_doc["ropes"]["line"]["length"] = TRUE_LENGTH
    truth = rig_from_dict(truth_doc)
    _tracked_csv(folder / "fitted.csv", *_flight(truth, SMALL_SWING, 5.0, 0, 11, 0.0))
    _tracked_csv(folder / "held.csv", *_flight(truth, 0.10, 6.0, 0, 12, 0.0))
    file_doc = tomllib.loads(_rig_text())
    assert file_doc["ropes"]["line"]["length"] == FILE_LENGTH
    out = {}
    for shared in (False, True):
        mapping = folder / f"mapping_{shared}.toml"
        mapping.write_text(MAPPING.format(shared="shared_frame = true" if shared else ""))
        out[shared] = diagnose_path(folder / "fitted.csv", rig=rig_from_dict(file_doc), discretization="low",
                                    candidates=(), mapping=mapping, held_out=[folder / "held.csv"]).doc
    return out


def _length(doc):
    return next(e for e in doc["calibration"]["parameters"] if e["parameter"] == "ropes.line.length")


def test_with_the_frame_shared_the_height_speaks_for_the_length(fits):
    free, shared = _length(fits[False]), _length(fits[True])
    # Free offsets: the length is read from a small swing's period alone; shared: from the height as well,
    # which the noise over hundreds of samples fixes to hundredths of a millimetre, so the stretch's
    # uncertainty is what is left.
    assert shared["uncertainty"] < free["uncertainty"] / 3
    assert shared["uncertainty"] > 0.7 * STRETCH_SD
    assert abs(shared["estimate"] - TRUE_LENGTH) <= 2 * shared["uncertainty"]
    assert fits[True]["settings"]["shared_frame"] is True and fits[False]["settings"]["shared_frame"] is False
    assert fits[True]["source"]["tracked"]["shared_frame"] is True
    channels = fits[True]["channels"]
    # Every position is compared, the still ones too (their level is geometry), and none has an offset; with
    # the offsets free, the ones the small swing leaves still hold nothing to compare.
    assert {ch: e["offset_free"] for ch, e in channels.items()} == {"load.x": False, "load.y": False, "load.z": False}
    assert all(e["offset"] == 0.0 for e in channels.values())
    assert set(fits[False]["channels"]) == {"load.x"}


def test_with_the_frame_shared_a_held_out_prediction_keeps_the_height_it_misses(fits):
    """The nominal model hangs the load 60 mm too high; only a shared frame shows it in the held-out trial."""
    nominal_free = fits[False]["held_out"][0]["rms_channels"]["load.z"]["nominal"]
    nominal_shared = fits[True]["held_out"][0]["rms_channels"]["load.z"]["nominal"]
    assert nominal_shared == pytest.approx(TRUE_LENGTH - FILE_LENGTH, rel=0.05)
    assert nominal_free < 0.1 * (TRUE_LENGTH - FILE_LENGTH)   # its mean removed, only the swing's error left
    updated_shared = fits[True]["held_out"][0]["rms_channels"]["load.z"]["updated"]
    assert updated_shared < 0.05 * nominal_shared
