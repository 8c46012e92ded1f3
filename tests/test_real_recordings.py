"""Real recordings from another lab: a slung load under a multirotor (tests/data/stormlord, MIT).

The flights' logs have no time column: rows were written on callbacks at a
known mean rate. The clock is recovered from the tracked motion
(``capture/_clock.py``); it is proven on rows sampled at known, jittered
instants (the truth is the instants, not a model of the machine), then
read on the real excerpts.
"""

from pathlib import Path

import numpy as np
import pytest
from dragline.capture import read_tracked_table, recover_clock
from dragline.reconstruct import tracked_trajectory
from dragline.simulate import apply_parameters, default_maneuver, load_rig, simulate

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "tests" / "data" / "stormlord"
RIG = REPO / "benchmarks" / "real" / "stormlord.toml"
MAPPING = REPO / "benchmarks" / "real" / "stormlord_mapping.toml"
FRAME = 1.0 / 30.0


def _flight(t):
    """A drone flying point to point and a load swinging 3.15 m below it (6 coordinates, m)."""
    w = 2 * np.pi / 3.5
    drone = np.stack([0.3 * np.sin(0.2 * t), 1.5 * np.tanh(3 * np.sin(2 * np.pi * t / 30)),
                      3.5 + 0.1 * np.sin(0.5 * t)], 1)
    swing = np.stack([0.3 * np.sin(w * t + 0.4), 0.8 * np.sin(w * t) * np.exp(-0.02 * t),
                      0.05 * np.cos(2 * w * t)], 1)
    return np.hstack([drone, drone + swing - [0.0, 0.0, 3.15]])


def _jittered_rows(seed, seconds=60.0, latency=0.0066, noise=3e-4):
    """Rows logged on a 30 Hz frame clock, each after a random latency: the instants and the rows."""
    rng = np.random.default_rng(seed)
    grid = np.arange(int(seconds / FRAME)) * FRAME
    instants = np.sort(grid + rng.normal(0.0, latency, grid.size))
    return instants - instants[0], _flight(instants) + rng.normal(0.0, noise, (grid.size, 6))


@pytest.mark.parametrize("seed", [3, 4])
def test_the_clock_recovered_from_the_motion_times_each_row_far_better_than_even_rows(seed):
    truth, rows = _jittered_rows(seed)
    mean_step = truth[-1] / (truth.size - 1)
    even = np.arange(truth.size) * mean_step
    recovered = recover_clock(rows, mean_step)
    assert np.all(np.diff(recovered) > 0)
    assert recovered[-1] - recovered[0] == pytest.approx(truth[-1], abs=0.02)  # the stated rate, to a latency

    def interval_error(t):
        return np.sqrt(np.mean((np.diff(t) - np.diff(truth)) ** 2))

    def drift(t, lag=100):  # error in the time between rows 100 apart (3.3 s, about one swing)
        e = t - truth
        return np.sqrt(np.mean((e[lag:] - e[:-lag]) ** 2))

    # Each interval is off by the difference of two latencies (9.3 ms) on even rows; the motion
    # measures it to about its own noise over the speed (a few ms at most).
    assert interval_error(recovered) < interval_error(even) / 3
    assert drift(recovered) < 0.6 * drift(even)


def test_a_still_recording_keeps_the_stated_rate():
    rows = np.zeros((50, 3)) + np.random.default_rng(0).normal(0.0, 1e-4, (50, 3))
    t = recover_clock(rows, 0.02)
    np.testing.assert_allclose(np.diff(t), 0.02, rtol=0.1)  # noise is not motion: the rows stay even


@pytest.fixture(scope="module", params=["rosbag_15_rows_0_899.csv", "rosbag_19_rows_0_899.csv"])
def excerpt(request):
    return DATA / request.param


def test_a_real_flight_reads_through_its_mapping_with_the_load_hanging_below_the_drone(excerpt):
    rig = load_rig(RIG)
    poses = read_tracked_table(excerpt, MAPPING)
    table, maneuver = tracked_trajectory(poses, rig)
    drone = maneuver.points["drone"]
    load = table[["load.x", "load.y", "load.z"]].to_numpy()
    # K points down: the load is below the drone by the rope and its fittings, about 3.16 m.
    below = load[:, 2] - drone[:, 2]
    assert np.all(below > 2.5)
    assert np.median(np.linalg.norm(load - drone, axis=1)) == pytest.approx(3.16, abs=0.05)
    assert poses.report["rows"] == 900
    assert 29.0 < poses.report["rate_hz"] < 31.0


def test_on_the_real_flights_the_recovered_clock_smooths_the_motion(excerpt):
    """Read on even rows, the rows' latencies show as jumps in the acceleration; on the recovered clock
    they are gone (the mocap's own noise is far below them)."""
    raw = np.loadtxt(excerpt, delimiter=",")
    x = raw[:, [0, 1, 2, 14, 15, 16]]
    mean_step = 1.0 / 29.6035

    def roughness(t):
        v = np.diff(x, axis=0) / np.diff(t)[:, None]
        a = np.diff(v, axis=0) / (0.5 * (t[2:] - t[:-2]))[:, None]
        return np.sqrt(np.mean(np.diff(a, axis=0) ** 2))

    even = np.arange(x.shape[0]) * mean_step
    assert roughness(recover_clock(x, mean_step)) < roughness(even) / 2


def test_a_rope_length_tolerance_moves_the_hanging_load_by_the_change():
    rig = load_rig(RIG)
    (length,) = [p for p in rig.tolerances if p.name == "ropes.rope.length"]
    assert length.unit == "m" and length.nominal == 3.0
    longer, maneuver = apply_parameters(rig, default_maneuver(rig), [length], [0.1])
    z0 = simulate(rig, duration=0.1).table["load.z"].iloc[0]
    z1 = simulate(longer, maneuver, duration=0.1).table["load.z"].iloc[0]
    # Same tension, so the same strain: the load hangs 0.1 m (and 0.1 m's stretch) lower.
    assert z1 - z0 == pytest.approx(0.1, abs=1e-4)


def test_a_length_tolerance_on_a_winch_rope_is_refused(tmp_path):
    text = (REPO / "simulate" / "data" / "rig.toml").read_text()
    path = tmp_path / "rig.toml"
    path.write_text(text + '\n[tolerances."ropes.hoist_rope.length"]\nabsolute = 0.1\n'
                    if "[tolerances]" not in text else
                    text.replace("[tolerances]", '[tolerances]\n"ropes.hoist_rope.length" = { absolute = 0.1 }', 1))
    with pytest.raises(ValueError, match="winch"):
        load_rig(path)
