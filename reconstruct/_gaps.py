"""Filling short gaps in marker trajectories.

Two independent sources of a missing position:

* ``fill_gaps``: in time, by a cubic spline through the marker's own
  samples, for interior gaps up to ``max_gap`` frames;
* ``fill_rigid``: in space, from the other markers of the same rigid body
  (at least three visible), by the least-squares rigid fit.

A marker counts as missing in a frame when any of its coordinates is NaN;
only NaN entries are ever written, measured values are never changed.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from ._bodies import body_frames_svd

__all__ = ["fill_gaps", "fill_rigid", "nan_runs"]


def nan_runs(missing):
    """Runs of ``True`` in a 1-D boolean array.

    Returns
    -------
    starts, stops : ndarray of int
        Half-open runs ``[start, stop)``.
    """
    m = np.concatenate([[False], np.asarray(missing, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return edges[0::2], edges[1::2]


def _check_points(points):
    p = np.asarray(points, dtype=float)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"points must have shape (frames, markers, 3), got {p.shape}")
    return p


def fill_gaps(points, max_gap=10):
    """Cubic-spline fill of short interior gaps, marker by marker.

    Parameters
    ----------
    points : array_like, shape (frames, markers, 3)
        Marker positions (m), NaN where missing.
    max_gap : int, optional
        Longest run of missing frames that is filled.

    Returns
    -------
    filled : ndarray, shape (frames, markers, 3)
        A copy with the short interior gaps filled.
    summary : dict
        ``filled`` and ``unfilled`` (markers,) int: number of gaps filled and
        left open per marker (runs at the start or end of the record and runs
        longer than ``max_gap`` are left open, as are all gaps of a marker
        with fewer than 4 samples); ``filled_frames`` (markers,) int.

    Notes
    -----
    The spline is the not-a-knot cubic interpolant through all of the
    marker's present samples, so a filled value depends mostly on the
    samples next to the gap; values across long gaps are never used.
    """
    p = _check_points(points)
    if int(max_gap) != max_gap or max_gap < 0:
        raise ValueError(f"max_gap must be a non-negative integer, got {max_gap}")
    F, M, _ = p.shape
    out = p.copy()
    n_filled = np.zeros(M, dtype=np.int64)
    n_open = np.zeros(M, dtype=np.int64)
    n_frames = np.zeros(M, dtype=np.int64)
    missing = ~np.isfinite(p).all(axis=-1)
    t = np.arange(F, dtype=float)
    for k in range(M):
        starts, stops = nan_runs(missing[:, k])
        if starts.size == 0:
            continue
        interior = (starts > 0) & (stops < F)
        short = interior & (stops - starts <= max_gap)
        present = ~missing[:, k]
        if present.sum() < 4 or not short.any():
            n_open[k] = starts.size
            continue
        spline = CubicSpline(t[present], p[present, k], axis=0)
        rows = np.concatenate([np.arange(a, b) for a, b in zip(starts[short], stops[short])])
        vals = spline(t[rows])
        block = out[rows, k]
        out[rows, k] = np.where(np.isnan(block), vals, block)
        n_filled[k] = short.sum()
        n_open[k] = starts.size - short.sum()
        n_frames[k] = rows.size
    return out, {"filled": n_filled, "unfilled": n_open, "filled_frames": n_frames}


def fill_rigid(markers, markers_body, max_gap=None):
    """Fill a body's missing markers from its other markers (rigid fit).

    In every frame where at least three of the body's markers are visible
    (not collinear), the rigid fit of ``body_frames_svd`` places each missing
    marker at ``origin + T @ markers_body_i``.

    Parameters
    ----------
    markers : array_like, shape (frames, M, 3)
        One body's marker positions (m), NaN where missing; ``M >= 4`` for
        anything to be fillable.
    markers_body : array_like, shape (M, 3)
        The markers' body-frame coordinates (m).
    max_gap : int, optional
        Fill only runs of at most this many missing frames (per marker);
        ``None`` (default) fills runs of any length, since the fill comes
        from the same frame's markers and does not degrade with gap length.

    Returns
    -------
    filled : ndarray, shape (frames, M, 3)
    summary : dict
        ``filled_frames`` (M,) int: frames filled per marker;
        ``unfilled_frames`` (M,) int: frames still missing.
    """
    m = _check_points(markers)
    mb = np.asarray(markers_body, dtype=float)
    if mb.shape != m.shape[1:]:
        raise ValueError(f"markers_body must have shape {m.shape[1:]} to match markers, got {mb.shape}")
    if max_gap is not None and (int(max_gap) != max_gap or max_gap < 0):
        raise ValueError(f"max_gap must be a non-negative integer or None, got {max_gap}")
    missing = ~np.isfinite(m).all(axis=-1)
    T, origin = body_frames_svd(m, mb)
    pred = origin[:, None, :] + np.einsum("fij,mj->fmi", T, mb)
    fill = missing & np.isfinite(pred).all(axis=-1)
    if max_gap is not None:
        for k in range(m.shape[1]):
            starts, stops = nan_runs(missing[:, k])
            for a, b in zip(starts, stops):
                if b - a > max_gap:
                    fill[a:b, k] = False
    out = np.where(fill[..., None] & np.isnan(m), pred, m)
    summary = {
        "filled_frames": fill.sum(axis=0),
        "unfilled_frames": (missing & ~fill).sum(axis=0),
    }
    return out, summary
