"""The one trajectory-table schema shared by measured and simulated data.

docs/conventions.md: a pandas DataFrame (or CSV) with a ``time`` column (s) and columns
``<entity>.<quantity>``, the entities the rig's: each body carries its
mass-centre position ``x y z`` (m), Euler angles ``roll pitch yaw`` (rad),
inertial velocity ``vx vy vz`` (m/s) and body rates ``p q r`` (rad/s); each
winch's rope carries ``length`` (m). Extra columns (rope tensions, ...) are
allowed after these. ``BODIES`` and ``ROPE_CHANNELS`` are the built-in
rig's.
"""

from __future__ import annotations

from ..capture import atomic_file
from ._rig import load_rig

__all__ = ["BODIES", "BODY_QUANTITIES", "ROPE_CHANNELS", "trajectory_columns", "rope_channels",
           "write_trajectory_csv"]

BODY_QUANTITIES = ("x", "y", "z", "roll", "pitch", "yaw", "vx", "vy", "vz", "p", "q", "r")


def rope_channels(rig):
    """The rope-length channels of a rig: one per winch, in the winches' order (``<rope>.length``)."""
    return tuple(f"{rope}.length" for rope in rig.winches.values())


def trajectory_columns(rig=None):
    """Column names of a rig's trajectory table, in their canonical order.

    Parameters
    ----------
    rig : Rig, optional
        The built-in rig by default.

    Returns
    -------
    list of str
        ``time``, every body's quantities (``BODY_QUANTITIES``) in the
        rig's body order, then ``rope_channels(rig)``.
    """
    rig = _BUILT_IN if rig is None else rig
    cols = ["time"]
    for body in rig.bodies:
        cols += [f"{body}.{q}" for q in BODY_QUANTITIES]
    cols += list(rope_channels(rig))
    return cols


_BUILT_IN = load_rig()
BODIES = tuple(_BUILT_IN.bodies)
ROPE_CHANNELS = rope_channels(_BUILT_IN)


def write_trajectory_csv(path, table):
    """Write a trajectory table as CSV, atomically (temporary name, then rename).

    Nine significant digits: 1 nm at 1 m, far below any measurement.
    """

    with atomic_file(path) as tmp:
        table.to_csv(tmp, index=False, float_format="%.9g")
