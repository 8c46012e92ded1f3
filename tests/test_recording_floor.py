"""A reference motion weighed against a recording as the diagnosis weighs: the floor no model goes below."""

import numpy as np
import pandas as pd
import pytest

from dragline.compare import recording_floor
from dragline.compare.diagnose._hypotheses import channels_on
from dragline.simulate import apply_parameters, default_maneuver, load_rig, simulate

CHANNELS = ["ball.x", "ball.z", "ball.pitch"]
NOISE = np.array([5e-4, 5e-4, 5e-3])  # m, m, rad


@pytest.fixture(scope="module")
def pendulum_truth():
    rig = load_rig("pendulum")
    truth = simulate(rig, default_maneuver(rig), "low", duration=16.0, rate_hz=100.0)
    return rig, truth, channels_on(truth, {"time": truth.time, "channels": CHANNELS, "reported_rig": rig})


def _recording(tmp_path, truth, channels, offsets=(0.0, 0.0, 0.0)):
    noisy = channels + np.asarray(offsets) + np.random.default_rng(6).normal(size=channels.shape) * NOISE
    table = pd.DataFrame(noisy, columns=CHANNELS)
    table.insert(0, "time", truth.time)
    path = tmp_path / "measured.csv"
    table.to_csv(path, index=False)
    return str(path)


def test_the_filmed_motion_itself_sits_at_the_noise_whatever_its_constant_offsets(tmp_path, pendulum_truth):
    rig, truth, channels = pendulum_truth
    # A marker 3 mm off the body's point, as placement leaves it: an offset the diagnosis fits on every channel.
    path = _recording(tmp_path, truth, channels, offsets=(3e-3, 0.0, 0.0))
    floor = recording_floor(path, rig, truth)
    # White noise at the stated level: chi2 per sample 1 within the noise estimate's few per cent.
    assert floor["chi2_per_sample"] == pytest.approx(1.0, abs=0.1)
    assert all(v == pytest.approx(1.0, abs=0.15) for v in floor["per_channel"].values())


def test_a_motion_the_recording_is_not_of_weighs_its_difference_over_the_noise(tmp_path, pendulum_truth):
    rig, truth, channels = pendulum_truth
    path = _recording(tmp_path, truth, channels)
    params = rig.tolerances
    coords = np.array([2 * p.tolerance if p.name == "bodies.ball.cg_z" else 0.0 for p in params])
    other = simulate(*apply_parameters(rig, default_maneuver(rig), params, coords), "low", duration=16.0,
                     rate_hz=100.0)
    moved = channels_on(other, {"time": other.time, "channels": CHANNELS, "reported_rig": rig})
    floor = recording_floor(path, rig, other)

    def excess(shift):
        """What the difference weighs with the reference read ``shift`` s late, each channel's mean taken out
        (the offsets), in the recording's noise."""
        late = np.column_stack([np.interp(other.time + shift, other.time, moved[:, j]) for j in range(3)])
        difference = late - channels
        return ((difference - difference.mean(axis=0)) ** 2 / NOISE**2).mean(axis=0)

    # The lower ball swings slower: a phase that grows through the run, which the diagnosis's clock shift
    # centres (about a quarter of a linear ramp's weight is left), so the floor is the best shift's.
    best = min(np.linspace(-0.05, 0.05, 1001), key=lambda s: excess(s).sum())
    assert excess(0.0).mean() > 3.0 * excess(best).mean() > 10.0  # a difference well above the noise
    assert floor["worst_channel"] == CHANNELS[int(np.argmax(excess(best)))]
    assert floor["chi2_per_sample"] == pytest.approx(1.0 + excess(best).mean(), rel=0.1)
