"""The assembled reconstruction: 2D centroids or 3D markers -> trajectory table.

Stages (paper section 3.3), each a function of the ``reconstruct``
package:

1. **Triangulation** (``reconstruct_markers``): every camera that sees a
   marker, outlier views dropped; a marker seen by fewer than two agreeing
   views is NaN.
2. **Outliers and gaps** (``fill_markers``): a sample farther than
   ``max_deviation`` (20 mm) from the median of its +-3 frames is removed:
   triangulation rejects a ghost only where a third view outvotes it, and a
   ghost seen by two cameras makes a point that jumps away for a frame.
   Then, for every body with three or more
   markers, a missing marker is placed from the same frame's other markers
   by the rigid fit (``fill_rigid``; it needs three visible markers, so in
   practice only the four-marker bucket gets filled this way, and any gap
   length is filled since nothing is interpolated in time). Then interior
   gaps of at most ``max_gap`` frames are filled in time by a cubic spline
   (``fill_gaps``). Everything else stays NaN and is counted in the summary.
3. **Body frames**: ``method="paper"`` applies Eqs. 14-16 to an ordered
   marker triple (bucket alpha, beta, gamma; the three-marker bodies left,
   right, then the third), corrected from the marker frame to the body frame
   with the markers' body coordinates, and takes the reference point as the
   mean over the body's visible markers of ``marker - T @ marker_body`` (the
   paper's "linear combination of the marker points"). ``method="svd"`` is
   the least-squares rigid fit over all visible markers. The mass centre is
   ``origin + T @ cg_body`` (Eq. 10); Euler angles from ``T`` by the Eq. 11
   inversion of docs/conventions.md.
4. **Two-marker bodies** (the drag cluster) give position only: a body point
   is the markers' midpoint plus its offset along the marker axis; a point
   off that axis (the drag rope attachment, 3 cm forward of the cluster) is
   placed at its known distance from the axis, in the direction, normal to
   the axis, of the rope that ends there (towards its first visible rope
   marker, else the rope's fixed start). Angles and rates are NaN.
5. **Ropes** (Eq. 22): ``rope_length_cubic`` over the span from the rope's
   fixed point (the ring it passes, else its start: boom pulley for the
   hoist rope, drag reel for the drag rope) to its attachment on the body,
   plus the fixed part of the path before that point (hoist reel to boom
   pulley). This is the stretched length, the same quantity as a simulated
   table's ``<rope>.length``; it exceeds the reel table by the rope's stretch.
6. **Rates**: positions and ``T`` are differentiated by second-order finite
   differences (velocities in inertial components, ``p q r`` from
   ``T^T dT/dt``), then smoothed. Only these rate columns are smoothed;
   positions, angles and rope lengths are reported as measured. The default
   smoother is the paper's 12-sample running average, **centred** on samples
   ``i-5 ... i+6``: it leads the input by half a sample (2.5 ms at 200 Hz);
   ``RunningAverage(12, centred=False)`` gives the trailing form (lags 5.5
   samples). Differencing and smoothing run on each NaN-free stretch of a
   signal separately, with the stretch's ends treated like the record's, so
   a gap costs only its own frames; stretches shorter than 3 samples (or than
   the Savitzky-Golay window) have no rates.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pandas as pd
from numpy.lib.stride_tricks import sliding_window_view

from ..capture import between_events, read_marker_file, read_session
from ..simulate import (
    angles_from_matrix,
    load_rig,
    marker_names,
    rope_channels,
    trajectory_columns,
)
from ._bodies import body_frames_paper, body_frames_svd, body_origin, mass_centre
from ._gaps import fill_gaps, fill_rigid, nan_runs
from ._reach import check_within_reach
from ._rates import (
    RunningAverage,
    SavitzkyGolay,
    Smoother,
    body_rates,
    finite_difference,
    make_smoother,
)
from ._ropes import rope_length_cubic
from ._triangulate import triangulate

__all__ = [
    "METHODS",
    "SMOOTHINGS",
    "reconstruct_markers",
    "fill_markers",
    "trajectory_from_markers",
    "reconstruct_session",
    "reconstruct_vicon_csv",
    "reconstruct_marker_file",
    "match_cameras",
    "vicon_name",
]

METHODS = ("paper", "svd")
SMOOTHINGS = ("running_average", "savgol", "none")


def vicon_name(name):
    """``'bucket.alpha'`` -> ``'bucket:alpha'`` (the VICON CSV spelling)."""
    return name.replace(".", ":", 1)


def _canonical(name):
    """``'bucket:alpha'`` -> ``'bucket.alpha'``; dotted names unchanged."""
    return name if "." in name else name.replace(":", ".", 1)


def _json(x):
    """Plain Python numbers and lists, so a summary can go to JSON."""
    if isinstance(x, dict):
        return {k: _json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json(v) for v in x]
    if isinstance(x, np.ndarray):
        return _json(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


# ------------------------------------------------------------------ markers

def reconstruct_markers(detections, cameras, max_reprojection_px=3.0, min_views=2, refine=False):
    """Triangulate every marker of every frame (stage 1).

    Parameters
    ----------
    detections : array_like, shape (cameras, frames, markers, 2)
        Centroids (px), NaN where not seen.
    cameras : sequence of Camera
        In the order of the first axis of ``detections``.
    max_reprojection_px, min_views, refine
        As for ``triangulate``.

    Returns
    -------
    points : ndarray, shape (frames, markers, 3)
        Inertial positions (m); NaN where fewer than ``min_views`` views agree.
    info : dict
        ``triangulate``'s info plus ``summary`` (JSON-able): per marker
        ``nan_frames``, ``mean_views`` (over the frames it was found) and
        ``median_rms_px``; ``rejected_views`` in all.
    """
    points, info = triangulate(detections, cameras, max_reprojection_px, min_views, refine)
    found = np.isfinite(points).all(axis=-1)
    with np.errstate(invalid="ignore"):
        mean_views = np.where(found, info["n_views"], 0).sum(axis=0) / found.sum(axis=0)
    rms = info["rms_px"]
    med = [float(np.median(rms[found[:, k], k])) if found[:, k].any() else None for k in range(rms.shape[1])]
    info["summary"] = _json({
        "nan_frames": (~found).sum(axis=0),
        "mean_views": mean_views,
        "median_rms_px": med,
        "rejected_views": info["rejected_views"],
    })
    return points, info


def _marker_index(names, rig):
    """Column of every rig marker in ``names`` (VICON or dotted spelling)."""
    canon = [_canonical(str(n)) for n in names]
    where = {}
    for k, n in enumerate(canon):
        if n in where:
            raise ValueError(f"marker {n} appears twice")
        where[n] = k
    wanted = marker_names(rig)
    missing = [n for n in wanted if n not in where]
    if missing:
        shown = ", ".join(vicon_name(n) for n in missing[:8]) + (" ..." if len(missing) > 8 else "")
        raise ValueError(f"missing {len(missing)} of the rig's {len(wanted)} markers: {shown}")
    return {n: where[n] for n in wanted}


def _body_blocks(rig):
    """(body, marker names, body coordinates (M, 3)) for every body with markers."""
    for body, spec in rig.bodies.items():
        if spec.markers:
            mb = np.array([spec.markers[m] for m in spec.markers], dtype=float).reshape(-1, 3)
            yield body, [f"{body}.{m}" for m in spec.markers], mb


def _outliers(p, max_deviation, half_window=3):
    """Samples farther than ``max_deviation`` (m) from the median of their +-half_window frames.

    The median of seven samples ignores one or two wild ones, so a marker
    that jumps for a frame or two (a ghost that two views agreed on) stands
    out, while smooth motion stays within a few mm of it (a deviation of
    20 mm over +-15 ms takes some 180 m/s^2). Needs three finite samples in
    the window; returns a (frames, markers) bool array.
    """
    F = p.shape[0]
    pad = np.pad(p, ((half_window, half_window), (0, 0), (0, 0)), constant_values=np.nan)
    win = sliding_window_view(pad, 2 * half_window + 1, axis=0)[:F]
    enough = np.isfinite(win[..., 0, :]).sum(axis=-1) >= 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows
        med = np.nanmedian(win, axis=-1)
    with np.errstate(invalid="ignore"):
        return enough & (np.linalg.norm(p - med, axis=-1) > max_deviation)


def fill_markers(names, positions, rig, max_gap=10, max_deviation=0.02):
    """Outliers out, then rigid-body fill, then short spline fill (stage 2).

    Parameters
    ----------
    names : sequence of str
        Marker names (``bucket.alpha`` or ``bucket:alpha``), one per column.
    positions : array_like, shape (frames, markers, 3)
        Marker positions (m), NaN where missing.
    rig : Rig
    max_gap : int
        Longest interior run of missing frames filled in time (frames).
    max_deviation : float or None
        A sample farther than this (m) from the median of its +-3 frames is
        an outlier and removed before filling (None: keep every sample).

    Returns
    -------
    filled : ndarray, shape (frames, markers, 3)
    summary : dict
        Per marker (dotted names): ``missing_frames`` (NaN on input),
        ``outlier_frames`` (removed as outliers), ``rigid_frames`` (filled
        from the body's other markers), ``spline_gaps`` and ``spline_frames``
        (filled in time), ``open_gaps``, ``open_frames`` and
        ``longest_open_gap`` (left NaN: longer than ``max_gap``, or at the
        start or end of the record); the same counts summed over markers
        under ``total``.
    """
    p = np.asarray(positions, dtype=float)
    if p.ndim != 3 or p.shape[-1] != 3 or p.shape[1] != len(names):
        raise ValueError(f"positions must have shape (frames, {len(names)}, 3), got {p.shape}")
    if int(max_gap) != max_gap or max_gap < 0:
        raise ValueError(f"max_gap must be a non-negative integer, got {max_gap}")
    if max_deviation is not None and not max_deviation > 0:
        raise ValueError(f"max_deviation must be positive or None, got {max_deviation}")
    canon = [_canonical(str(n)) for n in names]
    col = {n: k for k, n in enumerate(canon)}
    out = p.copy()
    bad = _outliers(p, max_deviation) if max_deviation is not None else np.zeros(p.shape[:2], bool)
    out[bad] = np.nan
    rigid = np.zeros(len(canon), dtype=np.int64)
    for _, mnames, mb in _body_blocks(rig):
        if len(mnames) < 3 or not all(n in col for n in mnames):
            continue
        cols = [col[n] for n in mnames]
        out[:, cols], s = fill_rigid(out[:, cols], mb)
        rigid[cols] = s["filled_frames"]
    out, s = fill_gaps(out, int(max_gap))
    missing = ~np.isfinite(out).all(axis=-1)
    per = {}
    for k, n in enumerate(canon):
        starts, stops = nan_runs(missing[:, k])
        per[n] = {
            "missing_frames": int((~np.isfinite(p[:, k]).all(axis=-1)).sum()),
            "outlier_frames": int(bad[:, k].sum()),
            "rigid_frames": int(rigid[k]),
            "spline_gaps": int(s["filled"][k]),
            "spline_frames": int(s["filled_frames"][k]),
            "open_gaps": int(starts.size),
            "open_frames": int((stops - starts).sum()),
            "longest_open_gap": int((stops - starts).max()) if starts.size else 0,
        }
    keys = ("missing_frames", "outlier_frames", "rigid_frames", "spline_gaps", "spline_frames", "open_gaps",
            "open_frames")
    total = {key: sum(v[key] for v in per.values()) for key in keys}
    return out, {"max_gap": int(max_gap), "max_deviation": max_deviation, "markers": per, "total": total}


# ------------------------------------------------------------------ bodies

def _paper_triple(mnames):
    """Markers for Eqs. 14-16: alpha, beta, gamma; else left, right, the first other."""
    short = [n.split(".", 1)[1] for n in mnames]
    if {"alpha", "beta", "gamma"} <= set(short):
        pick = ["alpha", "beta", "gamma"]
    elif {"left", "right"} <= set(short):
        pick = ["left", "right", next(m for m in short if m not in ("left", "right"))]
    else:
        pick = short[:3]
    return [short.index(m) for m in pick]


def _rigid_pose(block, mb, method, triple):
    if method == "svd":
        return body_frames_svd(block, mb)
    i, j, k = triple
    T = body_frames_paper(block[:, i], block[:, j], block[:, k], markers_body=mb[[i, j, k]])
    return T, body_origin(block, mb, T)


def _unit(v):
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _axis_point(a, b, mb, p_body, toward):
    """A body point from two markers a, b (position-only body); see module notes."""
    axis_b = mb[1] - mb[0]
    axis_b = axis_b / np.linalg.norm(axis_b)
    off = np.asarray(p_body, float) - 0.5 * (mb[0] + mb[1])
    along = off @ axis_b
    normal = np.linalg.norm(off - along * axis_b)
    j = _unit(b - a)
    point = 0.5 * (a + b) + along * j
    if normal < 1e-12:
        return point
    if toward is None:
        return np.full(point.shape, np.nan)
    d = toward - point
    d = _unit(d - np.sum(d * j, axis=-1, keepdims=True) * j)
    return point + normal * d


def _fixed(rig, name, frames):
    return np.broadcast_to(np.asarray(rig.fixed_points[name], float), (frames, 3)).copy()


def _rope_markers(rig, rope, col, pts):
    spec = rig.ropes[rope]
    return pts[:, [col[f"{rope}.m{k + 1}"] for k in range(len(spec.marker_distances))]]


def _span(rig, rope, frames):
    """The rope's measured span start (its last fixed point) and the fixed path before it (m).

    The rope's markers measure it from its last ring (or its start) to its
    end; a ring on a moving body before that cannot be measured.
    """
    spec = rig.ropes[rope]
    kind, _, name = spec.start.partition(".")
    if kind != "fixed":
        raise ValueError(f"rope {rope} must start at a fixed point to be measured, starts at {spec.start}")
    points = [_fixed(rig, name, frames)]
    for ring in spec.rings:
        rkind, _, rname = ring.partition(".")
        if rkind != "fixed":
            raise ValueError(f"rope {rope} passes a moving ring {ring}; only fixed rings can be measured")
        points.append(_fixed(rig, rname, frames))
    path = sum(float(np.linalg.norm(b[0] - a[0])) for a, b in zip(points[:-1], points[1:]))
    return points[-1], path


# ------------------------------------------------------------------ rates

def _per_run(fn, x, min_len, shape=None):
    """``fn`` on each NaN-free stretch of x (time on axis 0); NaN elsewhere.

    ``shape`` is the output's shape when it differs from x's.
    """
    x = np.asarray(x, dtype=float)
    out = np.full(shape if shape is not None else x.shape, np.nan)
    ok = np.isfinite(x.reshape(x.shape[0], -1)).all(axis=1)
    starts, stops = nan_runs(ok)
    for s0, s1 in zip(starts, stops):
        if s1 - s0 >= min_len:
            out[s0:s1] = fn(x[s0:s1])
    return out


def _smoother(smoothing):
    if isinstance(smoothing, Smoother):
        return smoothing
    if smoothing not in SMOOTHINGS:
        raise ValueError(f"unknown smoothing {smoothing!r}; choose from {', '.join(SMOOTHINGS)}")
    return make_smoother(smoothing)


def _describe(sm):
    if isinstance(sm, RunningAverage):
        if sm.centred:
            lo, hi = (sm.window - 1) // 2, sm.window // 2
            lead = "no lag" if sm.window % 2 else "leads half a sample"
            return f"running average of {sm.window} samples, centred (i-{lo} ... i+{hi}; {lead})"
        return f"running average of {sm.window} samples, trailing (lags {(sm.window - 1) / 2:g} samples)"
    if isinstance(sm, SavitzkyGolay):
        return f"Savitzky-Golay, {sm.window} samples, order {sm.polyorder} (no lag)"
    return sm.name


def _rates(x, dt, smoother, derivative=finite_difference):
    """Derivative per NaN-free stretch, then the smoother per stretch.

    ``derivative`` is ``finite_difference`` (same shape out) or ``body_rates``
    (``(F, 3, 3)`` in, ``(F, 3)`` out).
    """
    shape = (x.shape[0], 3) if derivative is body_rates else None
    d = _per_run(lambda s: derivative(s, dt), x, 3, shape)
    need = smoother.window if isinstance(smoother, SavitzkyGolay) else 1
    return _per_run(lambda s: smoother(s, dt), d, need)


# ------------------------------------------------------------------ table

def trajectory_from_markers(names, positions, rate_hz, rig=None, method="paper",
                            smoothing="running_average", max_gap=10, start_time=0.0, max_deviation=0.02):
    """The trajectory table (docs/conventions.md) from labelled 3D markers (stages 2-6).

    Parameters
    ----------
    names : sequence of str
        One per marker column: ``bucket.alpha`` or ``bucket:alpha``; must
        include every marker of the rig (others are ignored).
    positions : array_like, shape (frames, markers, 3)
        Inertial marker positions (m), NaN where not seen.
    rate_hz : float
        Frame rate (Hz); frames are taken as equally spaced.
    rig : Rig, optional
        The built-in rig by default.
    method : {'paper', 'svd'}
        Body frames by Eqs. 14-16 or by the least-squares rigid fit.
    smoothing : {'running_average', 'savgol', 'none'} or Smoother
        Applied to the rate columns only (module notes).
    max_gap : int
        Longest gap (frames) filled by the spline.
    start_time : float
        Time (s) of the first frame.
    max_deviation : float or None
        Outlier limit of ``fill_markers`` (m).

    Returns
    -------
    table : pandas.DataFrame
        Columns ``trajectory_columns(rig)`` in order; NaN where unknown (drag
        cluster angles and body rates, frames without enough markers).
    summary : dict
        JSON-able: ``frames``, ``rate_hz``, ``method``, ``smoothing`` (with
        its centring), ``gaps`` (``fill_markers``' summary) and
        ``nan_frames`` per table column that has any.

    Raises
    ------
    ValueError
        A rig marker missing from ``names``, bad shapes, rate, method or
        smoothing.
    """
    rig = load_rig() if rig is None else rig
    p = np.asarray(positions, dtype=float)
    if p.ndim != 3 or p.shape[-1] != 3 or p.shape[1] != len(names):
        raise ValueError(f"positions must have shape (frames, {len(names)}, 3), got {p.shape}")
    check_within_reach(p, names, rig)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be positive, got {rate_hz}")
    if method not in METHODS:
        raise ValueError(f"unknown body-frame method {method!r}; choose from {', '.join(METHODS)}")
    if p.shape[0] < 3:
        raise ValueError(f"need at least 3 frames to differentiate, got {p.shape[0]}")
    smoother = _smoother(smoothing)
    idx = _marker_index(names, rig)
    order = list(idx)
    pts, gaps = fill_markers(order, p[:, [idx[n] for n in order]], rig, max_gap, max_deviation)
    col = {n: k for k, n in enumerate(order)}
    F, dt = p.shape[0], 1.0 / float(rate_hz)
    nan = np.full(F, np.nan)
    cols = {"time": float(start_time) + np.arange(F) * dt}

    # body -> function(point in body coordinates about the reference point) -> (F, 3)
    locate = {}
    two_marker = []
    for body, mnames, mb in _body_blocks(rig):
        block = pts[:, [col[n] for n in mnames]]
        if len(mnames) >= 3:
            T, origin = _rigid_pose(block, mb, method, _paper_triple(mnames))
            locate[body] = lambda pb, T=T, origin=origin: origin + T @ np.asarray(pb, float)
            centre = mass_centre(T, origin, rig.bodies[body].cg_body)
            roll, pitch, yaw = angles_from_matrix(T, rig.bodies[body].euler_sequence)
            pqr = _rates(T, dt, smoother, body_rates)
        elif len(mnames) == 2:
            two_marker.append((body, block, mb))
            continue
        else:
            continue
        _body_columns(cols, body, centre, (roll, pitch, yaw), pqr, dt, smoother)

    ends = {spec.end.partition(".")[0]: rope for rope, spec in rig.ropes.items() if spec.marker_distances}
    for body, block, mb in two_marker:
        toward = None
        if body in ends:
            rope = ends[body]
            rm = _rope_markers(rig, rope, col, pts)
            # The first visible rope marker, counted from the body end.
            vis = np.isfinite(rm).all(axis=-1)
            first = np.argmax(vis, axis=1)
            toward = np.where(vis.any(axis=1)[:, None], rm[np.arange(F), first], _span(rig, rope, F)[0])
        locate[body] = lambda pb, a=block[:, 0], b=block[:, 1], mb=mb, toward=toward: _axis_point(a, b, mb, pb, toward)
        centre = locate[body](rig.bodies[body].cg_body)
        _body_columns(cols, body, centre, (nan, nan, nan), np.full((F, 3), np.nan), dt, smoother)

    for channel in rope_channels(rig):
        rope = channel.split(".")[0]
        spec = rig.ropes.get(rope)
        if spec is None or not spec.marker_distances:
            continue
        start, fixed_part = _span(rig, rope, F)
        body, _, point = spec.end.partition(".")
        if body == "fixed":
            end = _fixed(rig, point, F)
        elif body in locate:
            end = locate[body](rig.bodies[body].points[point])
        else:
            continue
        cols[channel] = fixed_part + rope_length_cubic(_rope_markers(rig, rope, col, pts), start, end)

    table = pd.DataFrame({c: cols.get(c, nan) for c in trajectory_columns(rig)})
    nan_frames = {c: int(n) for c, n in table.isna().sum().items() if n}
    summary = _json({
        "frames": F, "rate_hz": float(rate_hz), "method": method,
        "smoothing": {"name": smoother.name, "description": _describe(smoother),
                      "columns": "velocities vx vy vz and body rates p q r only"},
        "gaps": gaps, "nan_frames": nan_frames,
    })
    return table, summary


def _body_columns(cols, body, centre, angles, pqr, dt, smoother):
    v = _rates(centre, dt, smoother)
    for k, q in enumerate("xyz"):
        cols[f"{body}.{q}"] = centre[:, k]
        cols[f"{body}.v{q}"] = v[:, k]
    for q, a in zip(("roll", "pitch", "yaw"), angles):
        cols[f"{body}.{q}"] = np.asarray(a, float)
    for k, q in enumerate("pqr"):
        cols[f"{body}.{q}"] = pqr[:, k]


# ------------------------------------------------------------------ inputs

def match_cameras(cameras, camera_names, image_size=None, source="the calibration"):
    """The calibrated cameras in the session's order, checked by name and image size.

    Raises
    ------
    ValueError
        One line naming the session cameras the calibration lacks, or the
        camera whose image size differs.
    """
    by_name = {c.name: c for c in cameras}
    missing = [n for n in camera_names if n not in by_name]
    if missing:
        raise ValueError(
            f"{source} has no camera {', '.join(missing)} of the session "
            f"(it has {', '.join(by_name) or 'none'}): it was made for other cameras"
        )
    out = [by_name[n] for n in camera_names]
    if image_size is not None:
        for c in out:
            if tuple(c.image_size) != tuple(image_size):
                raise ValueError(
                    f"{source}: camera {c.name} is {c.image_size[0]}x{c.image_size[1]} px "
                    f"but the session's images are {image_size[0]}x{image_size[1]} px"
                )
    return out


def reconstruct_session(session, cameras, rig=None, method="paper", smoothing="running_average",
                        max_gap=10, max_reprojection_px=3.0, min_views=2, calibration_name="the calibration",
                        max_deviation=0.02):
    """Trajectory table of a capture session's trial (all stages).

    Parameters
    ----------
    session : CaptureSession or path
        A session, or ``capture.mcap`` / a session directory to read.
    cameras : sequence of Camera
        The calibration; matched to the session's cameras by name.
    rig, method, smoothing, max_gap, max_deviation
        As for ``trajectory_from_markers``.
    max_reprojection_px, min_views
        As for ``triangulate``.
    calibration_name : str
        How error messages name the calibration (e.g. its file).

    Returns
    -------
    table : pandas.DataFrame
    names : list of str
        The session's marker names.
    points : ndarray, shape (frames, markers, 3)
        Triangulated markers (m), before any gap filling; NaN where not found.
    summary : dict
        ``trajectory_from_markers``' summary plus ``triangulation``
        (``reconstruct_markers``' summary, per marker keyed by name) and,
        for a session read from a file, ``session`` (its read report).
    """
    report = None
    if isinstance(session, (str, os.PathLike)):
        session, report = read_session(session)
    cams = match_cameras(cameras, session.camera_names, session.image_size, calibration_name)
    trial = np.asarray(session.trial, dtype=float)
    if trial.shape[1] < 3:
        raise ValueError(f"the session's trial has {trial.shape[1]} frames; at least 3 are needed")
    points, info = reconstruct_markers(trial, cams, max_reprojection_px, min_views)
    names = list(session.marker_names)
    table, summary = trajectory_from_markers(names, points, session.rate_hz, rig, method, smoothing, max_gap,
                                             max_deviation=max_deviation)
    tri = info["summary"]
    summary["triangulation"] = {
        "rejected_views": tri["rejected_views"],
        "markers": {n: {"nan_frames": tri["nan_frames"][k], "mean_views": tri["mean_views"][k],
                        "median_rms_px": tri["median_rms_px"][k]} for k, n in enumerate(names)},
    }
    if report is not None:
        summary["session"] = _json({k: report[k] for k in ("path", "truncated", "lost", "frames", "lost_chunks")})
    return table, names, points, summary


def reconstruct_vicon_csv(path, rig=None, method="paper", smoothing="running_average", max_gap=10,
                          max_deviation=0.02):
    """Trajectory table from a VICON-style CSV of labelled 3D markers.

    Marker names ``subject:marker`` (``bucket:alpha``, ``hoist_rope:m1``);
    time is ``(frame - first frame) / rate``; a frame number skipped in the
    file is a frame with every marker missing. Options as for
    ``trajectory_from_markers``.

    Returns
    -------
    table : pandas.DataFrame
    summary : dict
        As for ``trajectory_from_markers``, plus ``path``.

    Raises
    ------
    ValueError
        One line starting with the path: unreadable file, no Trajectories
        section, missing rig markers, frame numbers out of order.
    """
    return reconstruct_marker_file(path, rig, method, smoothing, max_gap, max_deviation)


def reconstruct_marker_file(path, rig=None, method="paper", smoothing="running_average", max_gap=10,
                            max_deviation=0.02, between=None):
    """Trajectory table from labelled 3D markers: a VICON-style CSV, a C3D or a TRC file.

    The format is told by the extension (``.csv``, ``.c3d``, ``.trc``);
    lengths come from the file's units; a marker not seen (C3D: negative
    residual; TRC: empty cells) is a gap. ``between`` = ``(START, END)``
    event labels cuts the trial to the frames from one event to the other
    (``capture.between_events``): time 0 of the table is the start event.
    Other options as for ``trajectory_from_markers``.

    Returns
    -------
    table : pandas.DataFrame
    summary : dict
        As for ``trajectory_from_markers``, plus ``path``, ``format`` and,
        with ``between``, ``cut`` (the events and frames kept).

    Raises
    ------
    ValueError
        One line starting with the path: unreadable file, missing rig
        markers (named), frame numbers out of order.
    """

    path = os.fspath(path)
    markers = read_marker_file(path)
    if between is not None:
        markers = between_events(markers, *between)
    try:
        table, summary = trajectory_from_markers(markers.names, markers.positions, markers.rate_hz, rig,
                                                 method, smoothing, max_gap, max_deviation=max_deviation)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    summary["path"] = path
    summary["format"] = markers.format
    if "cut_short" in markers.info:
        summary["cut_short"] = markers.info["cut_short"]
    if between is not None:
        summary["cut"] = markers.info["cut"]
    return table, summary
