"""Tracked poses (``capture.read_tracked_table``) as the rig's trajectory table and maneuver.

A tracker reports each rigid body's reference point and attitude; the
trajectory table wants its mass centre (the rig file's ``cg_body`` turned
with the body), the output Euler angles, inertial velocity and body rates
(second-order differences, ``_rates``). A point the recording moves (a
drone's hook) becomes the maneuver's track for it: the model's input, not
something to fit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..simulate import BODY_QUANTITIES, Maneuver, angles_from_matrix
from ._bodies import mass_centre
from ._rates import body_rates, finite_difference
from ._reach import check_within_reach

__all__ = ["tracked_trajectory", "tracked_within_reach"]


def tracked_within_reach(poses, rig):
    """ValueError naming the first tracked body or point (and frame) out of the rig's reach (``_reach``)."""
    tracked = {**poses.positions, **poses.points}
    if tracked:
        check_within_reach(np.stack([np.asarray(p, float) for p in tracked.values()], axis=1), list(tracked), rig,
                           noun="tracked")


def tracked_trajectory(poses, rig):
    """The trajectory table and the points' maneuver of tracked ``poses`` on ``rig``.

    Parameters
    ----------
    poses : capture.TrackedPoses
    rig : Rig

    Returns
    -------
    table : pandas.DataFrame
        ``time`` and each tracked body's channels (docs/conventions.md); a
        body tracked without attitude has its position (its reference point
        plus ``cg_body``, as if level) and NaN angles and rates.
    maneuver : Maneuver or None
        The tracked points' positions over time (no winch lengths), or None
        when the mapping tracks no point.

    Raises
    ------
    ValueError
        A body or point the rig does not have.
    """
    for name in poses.positions:
        if name not in rig.bodies:
            raise ValueError(f"the mapping tracks body {name!r}, which the rig does not have "
                             f"(its bodies: {', '.join(rig.bodies)})")
    for name in poses.points:
        if name not in rig.fixed_points:
            raise ValueError(f"the mapping tracks point {name!r}, which the rig does not have "
                             f"(its points: {', '.join(rig.fixed_points) or 'none'})")
    time = np.asarray(poses.time, float)
    dt = float(time[1] - time[0])
    columns = {"time": time}
    for name in rig.bodies:
        if name not in poses.positions:
            continue
        cg = np.asarray(rig.bodies[name].cg_body, float)
        T = poses.rotations.get(name)
        nan = np.full(time.size, np.nan)
        if T is None:
            centre, angles, rates = poses.positions[name] + cg, (nan, nan, nan), np.full((time.size, 3), np.nan)
        else:
            centre = mass_centre(T, poses.positions[name], cg)
            angles = angles_from_matrix(T, rig.bodies[name].euler_sequence)
            rates = body_rates(T, dt)
        velocity = finite_difference(centre, dt)
        values = dict(zip(("x", "y", "z"), centre.T))
        values.update(zip(("roll", "pitch", "yaw"), angles))
        values.update(zip(("vx", "vy", "vz"), velocity.T))
        values.update(zip(("p", "q", "r"), rates.T))
        columns.update({f"{name}.{q}": np.asarray(values[q], float) for q in BODY_QUANTITIES})
    maneuver = None
    if poses.points:
        for name, track in poses.points.items():
            missing = ~np.isfinite(np.asarray(track, float)).all(axis=1)
            if missing.any():
                raise ValueError(f"the track of point {name!r} has gaps ({int(missing.sum())} samples, the first at "
                                 f"{time[int(np.argmax(missing))]:.3f} s); the model's input must be continuous")
        maneuver = Maneuver(time, points=dict(poses.points))
    return pd.DataFrame(columns), maneuver
