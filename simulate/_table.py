"""The one trajectory-table schema shared by measured and simulated data.

docs/conventions.md: a pandas DataFrame (or CSV) with a ``time`` column (s) and columns
``<entity>.<quantity>``. Bodies carry mass-centre position ``x y z`` (m),
Euler angles ``roll pitch yaw`` (rad), inertial velocity ``vx vy vz`` (m/s)
and body rates ``p q r`` (rad/s); ropes carry ``length`` (m). Extra columns
(rope tensions, ...) are allowed after these.
"""

from __future__ import annotations

from ..capture import atomic_file

__all__ = ["BODIES", "BODY_QUANTITIES", "ROPE_CHANNELS", "trajectory_columns", "write_trajectory_csv"]

BODIES = ("bucket", "spreader_bar", "hoist_cluster", "drag_cluster")
BODY_QUANTITIES = ("x", "y", "z", "roll", "pitch", "yaw", "vx", "vy", "vz", "p", "q", "r")
ROPE_CHANNELS = ("hoist_rope.length", "drag_rope.length")


def trajectory_columns():
    """Column names of a trajectory table, in their canonical order.

    Returns
    -------
    list of str
        ``["time", "bucket.x", ..., "drag_rope.length"]``.
    """
    cols = ["time"]
    for body in BODIES:
        cols += [f"{body}.{q}" for q in BODY_QUANTITIES]
    cols += list(ROPE_CHANNELS)
    return cols


def write_trajectory_csv(path, table):
    """Write a trajectory table as CSV, atomically (temporary name, then rename).

    Nine significant digits: 1 nm at 1 m, far below any measurement.
    """

    with atomic_file(path) as tmp:
        table.to_csv(tmp, index=False, float_format="%.9g")
