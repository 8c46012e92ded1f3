"""The recording's clock, read from its rope lengths against a model's: a rig drawn within its tolerances puts
the nominal model's reading off by more than a linear clock shift follows; the rig it was recorded from
does not. The fits read the shift exactly, where a linear term cannot follow."""

import numpy as np
import pandas as pd
import pytest

from dragline.benchmarks._discovery import _truth_world
from dragline.compare.diagnose._align_recording import align_recording
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
    return state, truth, align_recording(state)


def test_the_nominal_models_rope_lengths_put_a_drawn_rigs_clock_off(drawn_dragline):
    _, _, aligned = drawn_dragline
    # The recording's clock is the truth's: the offset is the nominal model's ropes stretching otherwise, a
    # whole 200 Hz sample or more (the site benchmark's filmed recordings: -18 to +9 ms).
    assert abs(aligned.recording.offset) > 5e-3


def test_read_against_the_rig_the_recording_is_of_the_clock_comes_back(drawn_dragline):
    state, truth, aligned = drawn_dragline
    again = align_recording(state, clock_table=truth.table)
    assert abs(again.recording.offset) < 1e-3  # a fifth of a sample
    assert again.recording.channels == aligned.recording.channels


def _rattling_recording(late, noise, rate_hz=200.0):
    """A swing (0.6 Hz) with a rattle (40 Hz, as the spreader bar's after the reels stop) on two channels,
    recorded ``late`` seconds late with white noise: the analytic motion, its recording and the noise. Before
    it starts the machine is still."""
    t = np.arange(0.0, 10.0, 1.0 / rate_hz)

    def motion(at):
        at = np.maximum(at, 0.0)
        rattle = 0.004 * np.exp(-0.3 * at) * np.sin(2 * np.pi * 40.0 * at)
        swing = 2 * np.pi * 0.6 * at
        return np.column_stack([0.3 * np.sin(swing) + rattle, 0.1 * np.cos(swing) - rattle])

    recorded = motion(t - late) + np.random.default_rng(5).normal(size=(t.size, 2)) * noise
    return t, motion(t), recorded


def test_the_clock_shift_is_read_exactly_where_the_linear_term_cannot_follow():
    from dragline.compare.diagnose._objective import _objective_at
    from dragline.compare.diagnose._problem import Problem

    late, noise = 0.008, np.array([2.5e-4, 2.5e-4])
    t, sim, recorded = _rattling_recording(late, noise)
    problem = Problem(t, recorded, noise, t_stop=5.0)
    fitted = problem.evaluate(sim)
    # The model read late (delta = -late reads it at t - late): the noise alone is left.
    assert fitted["nuisance"][1] == pytest.approx(-late, abs=5e-5)
    assert fitted["full"] / problem.n_weighted == pytest.approx(1.0, abs=0.1)
    _, chi2, nuisance, _ = _objective_at(problem, sim, np.zeros(0), np.ones(0), np.array([0.005, 0.005]), [])
    assert nuisance[-1] == pytest.approx(-late, abs=5e-5)
    assert chi2 / problem.n_weighted == pytest.approx(1.0, abs=0.1)
    # What the linear term would leave at its best shift: a quarter of the rattle's period is 6 ms, so the
    # rattle stays in the residual at about its own size, far above the noise.
    rate = np.gradient(sim, t, axis=0)
    r = recorded - sim
    delta = float((r * rate / noise**2).sum() / (rate * rate / noise**2).sum())
    linear = ((r - delta * rate - (r - delta * rate).mean(0)) / noise) ** 2
    assert linear.mean() > 20.0
