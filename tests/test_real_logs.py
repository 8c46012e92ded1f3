"""The three-drone box flights' full logs (hmer101, MIT): found, parsed, and cut to the hold the excerpts are.

The full logs cannot be fetched here; each test writes a log in their
layout (``tests/data/hmer101/SOURCES.md``: 95 space-separated numbers a
row, stage lines between the rows) around an excerpt's real rows, placing
each kept value in the column SOURCES.md names, and checks that the cut
gives the excerpt back, value for value.
"""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[1]
HMER101 = REPO / "tests" / "data" / "hmer101"
EXCERPTS = sorted(p.name for p in HMER101.glob("*_hold.csv"))
# Where SOURCES.md says each kept column sits in a log row (0-based), typed here from it, not from the reader.
SOURCE_COLUMNS = {"time": 0, "box.x": 7, "box.y": 8, "box.z": 9, "box.roll": 10, "box.pitch": 11, "box.yaw": 12,
                  "drone1.x": 41, "drone1.y": 42, "drone1.z": 43, "drone2.x": 61, "drone2.y": 62, "drone2.z": 63,
                  "drone3.x": 81, "drone3.y": 82, "drone3.z": 83}


def _row(t, commanded_z, commanded_yaw, values=None, rng=None):
    """One log row: commanded box height and yaw in columns 3 and 6, the kept values where SOURCES.md puts
    them, anything else elsewhere."""
    row = (rng or np.random.default_rng(0)).normal(size=95)
    row[0], row[3], row[6] = t, commanded_z, commanded_yaw
    for name, value in (values or {}).items():
        row[SOURCE_COLUMNS[name]] = value
    return " ".join(repr(float(v)) for v in row)


def _log_around(excerpt, path, yaw_turns=True):
    """A log: a takeoff, the yaw stage (the commanded yaw out to 0.5 rad and back), the excerpt's rows as the
    hold (commanded height 0.5 m, yaw 0), the descent; stage lines, a blank line and a row cut short between."""
    rng = np.random.default_rng(1)
    frame = pd.read_csv(HMER101 / excerpt)
    t0 = frame["time"].iloc[0]
    lines = ["PHASE_MISSION"] + [_row(t0 - 30 + 0.1 * k, 0.5, 0.0, rng=rng) for k in range(20)]
    lines += ["", "MISSION_STAGE 4 MISSION_YAW_ENGAGE"]
    ramp = 0.5 * np.sin(np.linspace(0.0, np.pi, 40)[1:-1]) if yaw_turns else np.zeros(38)
    lines += [_row(t0 - 4 + 0.1 * k, 0.5 if yaw_turns else 0.5 - 0.0125 * k, y, rng=rng) for k, y in enumerate(ramp)]
    lines += [_row(r["time"], 0.5, 0.0, r, rng) for r in frame.to_dict("records")]
    lines.insert(len(lines) - 10, "MISSION_STAGE 9 MISSION_HOLD")
    lines.insert(len(lines) - 5, " ".join(["1.0"] * 40))  # a row cut short
    lines += [_row(frame["time"].iloc[-1] + 0.1 * (k + 1), 0.5 - 0.0125 * (k + 1), 0.0, rng=rng) for k in range(15)]
    path.write_text("\n".join(lines) + "\n")
    return frame


@pytest.mark.parametrize("excerpt", EXCERPTS)
def test_the_hold_after_the_yaw_stage_is_cut_from_a_full_log_as_its_excerpt_was(excerpt, tmp_path):
    from dragline.benchmarks._real_hmer101 import write_hold

    log = tmp_path / excerpt.replace("_hold.csv", "_logger1.txt")
    frame = _log_around(excerpt, log)
    (tmp_path / "cut").mkdir()
    path, why = write_hold(log, tmp_path / "cut")
    assert why is None
    cut = pd.read_csv(path)
    assert list(cut.columns) == list(frame.columns)
    np.testing.assert_array_equal(cut.to_numpy(), frame.to_numpy())


def test_a_flight_whose_yaw_stage_never_turns_the_box_has_no_hold_and_says_why(tmp_path):
    from dragline.benchmarks._real_hmer101 import write_hold

    log = tmp_path / "2025_07_30_21_36_24_logger1.txt"
    _log_around(EXCERPTS[0], log, yaw_turns=False)
    path, why = write_hold(log, tmp_path)
    assert path is None and "never leaves 0" in why


def test_bench_real_finds_each_dataset_at_any_depth_and_leaves_a_flight_without_a_trial_out(tmp_path):
    from dragline.benchmarks._real import find_datasets
    from dragline.benchmarks._real_hmer101 import read_flight
    from dragline.simulate import load_rig

    (tmp_path / "hmer101" / "real").mkdir(parents=True)
    for excerpt in EXCERPTS[:2]:
        _log_around(excerpt, tmp_path / "hmer101" / "real" / excerpt.replace("_hold.csv", "_logger1.txt"))
    flight = tmp_path / "stormlord" / "data_combined_system" / "rosbag_15"
    flight.mkdir(parents=True)
    for name in ("dataset.csv", "metadata.yaml"):
        (flight / name).write_text("")
    found = {d.NAME: [name for name, _ in flights] for d, flights in find_datasets(tmp_path)}
    assert found == {"stormlord": ["rosbag_15"], "hmer101": [e.removesuffix("_hold.csv") for e in EXCERPTS[:2]]}
    # A log read for the diagnosis: the hold through the dataset's mapping, the drones the maneuver's points.
    log = next(tmp_path.rglob("*_logger1.txt"))
    rig = load_rig(REPO / "benchmarks" / "real" / "hmer101.toml")
    rate, table, maneuver = read_flight(log, tmp_path, rig)
    assert rate == pytest.approx(10.0, rel=0.01) and sorted(maneuver.points) == ["drone1", "drone2", "drone3"]
    assert len(table) in (69, 70)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no flight found"):
        find_datasets(tmp_path / "empty")
