"""The recording's clock, read from its rope lengths against a model's: against the updated rig, not only the
nominal one."""

import numpy as np
import pandas as pd
import pytest

from dragline.benchmarks._discovery import _truth_world
from dragline.compare.diagnose._align_recording import CLOCK_RESOLUTION, align_recording, realigned
from dragline.compare.diagnose._hypotheses import channels_on
from dragline.compare.diagnose._state import DiagnosisState
from dragline.simulate import default_maneuver, load_rig, simulate

CHANNELS = ["bucket.x", "bucket.z", "bucket.pitch", "hoist_rope.length", "drag_rope.length"]


@pytest.fixture(scope="module")
def drawn_dragline():
    """A dragline drawn within its tolerances (a site benchmark's seed-212 truth, whose filmed recording the
    nominal model put 14 ms off), recorded on its own clock with a quarter millimetre of noise."""
    rig = load_rig(None)
    truth_rig, truth_maneuver, _, physics, _ = _truth_world("pulley_friction@hoist_cluster", 0.00117, 212500)
    truth = simulate(truth_rig, truth_maneuver, "baseline", physics, duration=12.0, rate_hz=200.0)
    values = channels_on(truth, {"time": truth.time, "channels": CHANNELS, "reported_rig": rig})
    noise = np.array([2.5e-4, 2.5e-4, 2.5e-3, 2.5e-4, 2.5e-4])
    table = pd.DataFrame(values + np.random.default_rng(3).normal(size=values.shape) * noise, columns=CHANNELS)
    table.insert(0, "time", truth.time)
    state = DiagnosisState(measured=table, rig=rig, maneuver=default_maneuver(rig), discretization="baseline",
                           candidate_names=None, workers=1, seed=0, source=None, note=None, started=0.0,
                           trial_names=None, held_out=())
    return align_recording(state), truth_rig, truth_maneuver


def test_the_nominal_models_rope_lengths_put_a_drawn_rigs_clock_off(drawn_dragline):
    state, _, _ = drawn_dragline
    # The recording's clock is the truth's: any offset is the nominal model's ropes stretching otherwise.
    assert abs(state.recording.offset) > 5 * CLOCK_RESOLUTION


def test_read_against_the_rig_the_recording_is_of_the_clock_comes_back(drawn_dragline):
    state, truth_rig, truth_maneuver = drawn_dragline
    again = realigned(state, truth_rig, truth_maneuver)
    assert again is not None
    assert abs(again.recording.offset) <= CLOCK_RESOLUTION
    assert again.recording.alignment["offset_against_nominal"] == pytest.approx(state.recording.offset)
    assert again.plain_problem.time[0] == pytest.approx(state.plain_problem.time[0], abs=0.02)
    # Read again against the same rig, it does not move: nothing to do.
    assert realigned(again, truth_rig, truth_maneuver) is None
