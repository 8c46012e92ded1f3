"""Tracked poses (``capture.read_tracked_table``) as the rig's trajectory table and maneuver.

A tracker reports each rigid body's reference point and attitude; the
trajectory table wants its mass centre (the rig file's ``cg_body`` turned
with the body), the output Euler angles, inertial velocity and body rates
(second-order differences, ``_rates``). A point the recording moves (a
drone's hook) becomes the maneuver's track for it: the model's input, not
something to fit, smoothed (``smoothed_track``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..simulate import BODY_QUANTITIES, Maneuver, angles_from_matrix
from ._bodies import mass_centre
from ._rates import body_rates, finite_difference
from ._reach import check_within_reach

__all__ = ["tracked_trajectory", "tracked_within_reach", "smoothed_track", "TRACK_RATE_HZ", "MIN_SMOOTHED_SAMPLES"]

# The rate a tracked point's smoothed track is sampled at for the model, which moves the point linearly between
# samples. The polyline is then within a dt^2 / 8 of the spline: 1 um at the slung-load flights' largest
# acceleration (7.6 m/s^2), a hundredth of the spline's distance from the samples (0.09-0.18 mm); its velocity
# steps by a dt, 8 mm/s at most, where the raw 30 Hz samples stepped by 0.05-0.1 m/s.
TRACK_RATE_HZ = 1000.0
# Fewer samples than this are too few to cross-validate a smoothing on: the track stays the samples' polyline.
MIN_SMOOTHED_SAMPLES = 8


def smoothed_track(time, track, rate_hz=TRACK_RATE_HZ):
    """A tracked point's positions as the model's input: a smoothing spline through them, sampled at ``rate_hz``.

    Through the raw samples the model's input is a polyline whose velocity
    jumps at every sample (``simulate`` moves a point linearly between a
    maneuver's samples). On the slung-load flights (30 Hz, the drone
    tracked to a tenth of a millimetre) those jumps kicked the rope slack
    in 32 and 67 of the first 30 s's record intervals, its tension between 0
    and 15 N, where the real drone-to-load distance stayed within 3.13-3.18 m;
    through the smoothed track the model's rope stayed taut (1.6-9.7 N).
    Each axis is a cubic smoothing spline (``scipy.interpolate.
    make_smoothing_spline``) whose smoothing is chosen by generalized
    cross-validation: the smoothing that best predicts each sample from the
    others, no constant of ours.

    Parameters
    ----------
    time : ndarray (K,)
        Strictly increasing sample times (s).
    track : ndarray (K, 3)
        Positions (m), no gaps.
    rate_hz : float
        The rate (Hz) the spline is sampled at.

    Returns
    -------
    fine_time : ndarray (M,)
        From ``time[0]`` to ``time[-1]``, both included.
    fine_track : ndarray (M, 3)
    """
    from scipy.interpolate import make_smoothing_spline

    time, track = np.asarray(time, float), np.asarray(track, float)
    if time.size < MIN_SMOOTHED_SAMPLES:
        return time.copy(), track.copy()
    n = int(np.ceil((time[-1] - time[0]) * rate_hz)) + 1
    fine_time = np.linspace(time[0], time[-1], n)
    fine_track = np.column_stack([make_smoothing_spline(time, track[:, j])(fine_time) for j in range(3)])
    return fine_time, fine_track


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
        The tracked points' positions over time (no winch lengths), each
        smoothed and sampled at ``TRACK_RATE_HZ`` (``smoothed_track``), or
        None when the mapping tracks no point.

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
        smoothed = {name: smoothed_track(time, track) for name, track in poses.points.items()}
        fine_time = next(iter(smoothed.values()))[0]
        maneuver = Maneuver(fine_time, points={name: track for name, (_, track) in smoothed.items()})
    return pd.DataFrame(columns), maneuver
