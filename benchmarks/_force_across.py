"""The force across the rope on a load hanging from a tracked point, measured with no model.

``bench real`` prints it per single-rope flight (``docs/real-recordings.md``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["force_across_rope", "ACROSS_KEPT_S", "ACROSS_EDGE_S"]

# The load's swing is 0.28 Hz and a drone's moves a few tenths of a hertz; above 1 Hz the second difference of
# rows timed to a few milliseconds is jitter, not force.
ACROSS_CUTOFF_HZ = 1.0
# The zero-phase filter's start and end transients, dropped (s): five time constants of its 1 Hz corner.
ACROSS_EDGE_S = 5.0
# Less than this left (s) is less than two of the swing's periods: no estimate.
ACROSS_KEPT_S = 7.0


def force_across_rope(time, anchor, load, gravity, cutoff_hz=ACROSS_CUTOFF_HZ, edge_s=ACROSS_EDGE_S):
    """The force across the rope on a load hanging from a tracked point, from the tracked motion alone.

    A taut rope pulls the load along itself, towards ``anchor``: per unit
    mass, ``a - gravity = (T / m) u + f``, so the part of ``a - gravity``
    across ``u`` is ``f``, every other force (air drag, downwash, a frame
    not level), with no model of the rope or of the load. It is fitted by
    quadratic drag on the load's velocity, ``-k |v| v`` across the rope,
    plus a constant level force (a steady wind, a frame tilted from gravity).

    Parameters
    ----------
    time : ndarray (N,)
        Even sample times (s).
    anchor, load : ndarray (N, 3)
        The rope's upper end and the load's mass centre (m), in one frame.
    gravity : ndarray (3,)
        Gravity's acceleration in that frame (m/s^2).

    Returns
    -------
    dict
        ``rms`` of the force across the rope (m/s^2); ``drag_per_length``
        (k, 1/m: ``rho cd A / (2 m)``) and ``steady`` (m/s^2, its two level
        components, in the frame's axis order) of the fit; ``share_drag``
        and ``share_drag_steady``: the shares of the force's square that
        drag alone, and drag with the steady force, explain. Samples
        within ``edge_s`` of either end or of a sample where either end is
        not tracked (NaN) are left out; None when less than
        ``ACROSS_KEPT_S`` is left.
    """
    from scipy.signal import butter, filtfilt

    time = np.asarray(time, float)
    dt = float(time[1] - time[0])
    anchor, load = np.asarray(anchor, float), np.asarray(load, float)
    tracked = np.isfinite(anchor).all(axis=1) & np.isfinite(load).all(axis=1)
    if tracked.sum() < 2:
        raise ValueError("force_across_rope: fewer than two samples with both ends tracked")
    # A hole is bridged for the filter and, with the filter's transient about it, left out of the fit.
    anchor, load = (np.column_stack([np.interp(time, time[tracked], x[tracked]) for x in v.T]) for v in (anchor, load))
    b, a = butter(4, cutoff_hz * 2.0 * dt)
    anchor, load = (filtfilt(b, a, x, axis=0) for x in (anchor, load))
    velocity = np.gradient(load, dt, axis=0)
    specific = np.gradient(velocity, dt, axis=0) - np.asarray(gravity, float)
    u = anchor - load
    u /= np.linalg.norm(u, axis=1)[:, None]

    def across(x):
        return x - np.einsum("ij,ij->i", x, u)[:, None] * u

    # "full" and cut, not "same": a window longer than the record would lengthen the result.
    half = int(np.ceil(edge_s / dt))
    near_hole = np.convolve(~tracked, np.ones(2 * half + 1), mode="full")[half:half + time.size] > 0
    kept = (time >= time[0] + edge_s) & (time <= time[-1] - edge_s) & ~near_hole
    if kept.sum() * dt < ACROSS_KEPT_S:
        return None
    force = across(specific)[kept].ravel()
    drag = -across(np.linalg.norm(velocity, axis=1)[:, None] * velocity)[kept].ravel()
    # Horizontal: across a rope that hangs near vertical a vertical constant is not seen.
    level = np.eye(3)[np.sort(np.argsort(np.abs(np.asarray(gravity, float)))[:2])]
    steady = [across(np.broadcast_to(e, load.shape))[kept].ravel() for e in level]

    def fit(columns):
        design = np.column_stack(columns)
        coef = np.linalg.lstsq(design, force, rcond=None)[0]
        return coef, 1.0 - float(np.sum((force - design @ coef) ** 2) / np.sum(force**2))

    _, share_drag = fit([drag])
    both, share_both = fit([drag, *steady])
    return {"rms": float(np.sqrt(np.mean(force**2) * 3)), "drag_per_length": float(both[0]),
            "steady": both[1:].tolist(), "share_drag": share_drag,
            "share_drag_steady": share_both}
