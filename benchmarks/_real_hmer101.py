"""The three-drone box flights (hmer101/musls_cable_modeling, MIT): their logs, and the hold each is cut to.

A log (``*_logger1.txt``, ``docs/real-recordings.md``) is space-separated
text, one row of 95 numbers per 0.1 s, with ``PHASE_MISSION`` and
``MISSION_STAGE N NAME`` lines between the rows. The authors' reader lays
a row out as 35 columns for the box, then 20 for each drone: the time
(column 0), the box's commanded position and roll-pitch-yaw (1-6), its
tracked ones (7-12), and for drone i (0, 1, 2) its tracked position at
``35 + 20 i + 6`` to ``+ 8``.

The trial each flight gives is the stage every flight of the protocol has
and the tests' excerpts are (``tests/data/hmer101/SOURCES.md``): the hold
after the yaw stage, from the first row at which the box's commanded yaw
is back at 0 to the last row before its commanded height changes (the
descent). The drones hold their places and the box turns on its cables:
it starts mid-swing, so it is diagnosed from its recording's start.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["find_flights", "hold_after_yaw", "read_flight", "write_hold"]

# Columns kept, by their number in the log, under the excerpts' names.
COLUMNS = {"time": 0, "box.x": 7, "box.y": 8, "box.z": 9, "box.roll": 10, "box.pitch": 11, "box.yaw": 12,
           **{f"drone{i + 1}.{q}": 35 + 20 * i + 6 + k for i in range(3) for k, q in enumerate("xyz")}}
ROW_WIDTH = 95
COMMANDED_Z, COMMANDED_YAW = 3, 6
YAW_STAGE = "MISSION_YAW_ENGAGE"
# Fewer rows than this (3 s, between two and three of the box's 1.2 s turns) is no trial.
MIN_HOLD_ROWS = 30
_HERE = Path(__file__).resolve().parent / "real"
RIG = _HERE / "hmer101.toml"
MAPPING = _HERE / "hmer101_mapping.toml"
NAME = "hmer101"
# The three cables whose documented 2.421 m is put wrong on purpose for the known answer.
KNOWN_ROPES = ("c1", "c2", "c3")
# Every hold starts mid-swing.
START_FROM_RECORDING = True


def find_logs(data):
    """Every ``*_logger1.txt`` under ``data`` (any depth), in name order."""
    return sorted(Path(data).rglob("*_logger1.txt"), key=lambda p: p.name)


def read_log(path):
    """A log's rows (n, 95) and the index of the first row after its yaw stage's line (0 without one).

    Lines that are not 95 numbers (the mission's stage lines, blank lines)
    are skipped; a row cut short (a log ended mid-write) too, and bytes
    that are not text read as a line that is not.
    """
    rows, yaw_stage_at = [], 0
    with open(path, errors="replace") as src:
        for line in src:
            parts = line.split()
            if parts and parts[0] == "MISSION_STAGE" and YAW_STAGE in parts:
                yaw_stage_at = len(rows)
                continue
            if len(parts) != ROW_WIDTH:
                continue
            try:
                rows.append([float(v) for v in parts])
            except ValueError:
                continue
    return np.array(rows).reshape(-1, ROW_WIDTH), yaw_stage_at


def hold_after_yaw(rows, start=0):
    """Row indices ``[first, stop)`` of the hold after the yaw stage, or a sentence saying why there is none.

    The first row from ``start`` at which the commanded yaw is back at 0
    after having left it, to the last row before the commanded height
    changes.
    """
    yaw, height = rows[:, COMMANDED_YAW], rows[:, COMMANDED_Z]
    turned = np.flatnonzero(yaw[start:] != 0.0)
    if turned.size == 0:
        return "the box's commanded yaw never leaves 0 after the yaw stage begins"
    back = np.flatnonzero(yaw[start + turned[0]:] == 0.0)
    if back.size == 0:
        return "the box's commanded yaw never comes back to 0"
    first = start + turned[0] + back[0]
    moved = np.flatnonzero(height[first:] != height[first])
    stop = first + (moved[0] if moved.size else rows.shape[0] - first)
    if stop - first < MIN_HOLD_ROWS:
        return f"the hold after the yaw stage is {stop - first} rows, under {MIN_HOLD_ROWS}"
    return first, stop


def write_hold(log, folder):
    """The hold after a flight's yaw stage as an excerpt CSV in ``folder`` (the 16 named columns, values as
    logged); ``(path, None)``, or ``(None, why)`` for a flight without one."""
    rows, yaw_stage_at = read_log(log)
    if rows.shape[0] == 0:
        return None, f"{log}: no row of {ROW_WIDTH} numbers"
    found = hold_after_yaw(rows, yaw_stage_at)
    if isinstance(found, str):
        return None, found
    first, stop = found
    path = Path(folder) / (Path(log).name.replace("_logger1.txt", "_hold.csv"))
    kept = rows[first:stop][:, list(COLUMNS.values())]
    np.savetxt(path, kept, delimiter=",", header=",".join(COLUMNS), comments="", fmt="%.9g")
    return path, None


def find_flights(data):
    """``(name, log)`` of every ``*_logger1.txt`` under ``data`` (any depth), in name order."""
    return [(log.name.removesuffix("_logger1.txt"), log) for log in find_logs(data)]


def shared_frame():
    """One motion-capture system tracked the box and the drones (the mapping says so)."""
    from dragline.capture import load_tracked_mapping

    return load_tracked_mapping(MAPPING).table.shared_frame


def read_flight(source, folder, rig, rows=None):
    """The hold after a flight's yaw stage as ``(rate, trajectory table, maneuver)``, or ``(None, why, None)``
    for a flight without one; ``rows`` is not used (the stage sets the length)."""
    from dragline.capture import read_tracked_table
    from dragline.reconstruct import tracked_trajectory

    path, why = write_hold(source, folder)
    if path is None:
        return None, why, None
    poses = read_tracked_table(path, MAPPING)
    table, maneuver = tracked_trajectory(poses, rig)
    return poses.report["rate_hz"], table, maneuver
