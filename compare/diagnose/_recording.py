"""The recording a diagnosis reads, and the checks that it belongs to the rig and its maneuver.

A session directory, an MCAP session, a marker file, a trajectory table,
or a tracker's table or ROS 2 bag read through a mapping becomes the
measured trajectory table (``load_recording``); its channels are the rig's
(``candidate_channels``, ``check_channels``, ``moving_channels``); the
maneuver must explain the recorded rope lengths (``check_maneuver``), whose
clock offset ties the recording to the maneuver (``align_with_maneuver``).
"""

from __future__ import annotations

import math
import os

import numpy as np

from ...capture import resolve_recording
from ...simulate import (
    Maneuver,
    default_maneuver,
    dig_maneuver,
    load_rig,
    maneuver_from_table,
    read_maneuver_csv,
    rope_channels,
)
from .._align import estimate_time_offset, read_trajectory_table
from .._compare import channel_kind

__all__ = ["load_recording", "candidate_channels", "check_channels", "moving_channels", "rope_bias_allowance",
           "check_maneuver", "align_with_maneuver", "free_offsets"]

# The reel table must explain the recorded rope lengths: after aligning the
# clocks, the measured length may differ from the nominal simulation's
# (stretch included) by this much RMS about its mean, and on average (m).
# A rope through a pulley ring gets more: friction or inertia in the ring
# holds rope on one side (pulley friction at full lock moves 40 mm RMS and
# 60 mm at the end of the dig maneuver), which is physics to diagnose, not a
# wrong table; a rope straight from its reel is only stretched.
ROPE_TOLERANCE = {"free": (0.02, 0.025), "ring": (0.08, 0.05)}
# The rope lengths must move at all (m) for the clocks to be aligned.
MIN_REEL_TRAVEL = 0.05
# A free decay shorter than this after the reels stop is too short (s): over
# one swing (0.6 Hz) plus the low-pass window.
MIN_DECAY_S = 2.0
# A channel a recording measures on fewer than this share of its samples is not used.
MEASURED_SHARE = 0.5


def free_offsets(channels, shared_frame=False):
    """Which channels carry a free constant offset: all, unless the positions share the model's frame.

    A camera lab's reconstruction is calibrated on its own: each channel may
    be off by a constant (section 3 of docs/diagnosis.md). A tracker that
    measures a body in the same frame as the points that move the rig (the
    load under a drone it also tracks: ``shared_frame`` in the mapping) puts
    the body's position where the model must: a constant there is the
    rig's geometry (a rope's length, an attachment), not calibration. Its
    angles keep their offsets: a tracked body's axes are defined at a
    rotation from the rig's that nobody writes down.
    """
    return np.array([not (shared_frame and channel_kind(ch) == "position") for ch in channels], bool)


def _read_maneuver_arg(maneuver):
    if maneuver is None or isinstance(maneuver, Maneuver):
        return maneuver
    return dig_maneuver() if maneuver == "dig" else read_maneuver_csv(maneuver)


def _session_maneuver(session, path):
    cols = session.maneuver or {}
    if "time" not in cols:
        raise ValueError(f"{path}: the session holds no maneuver table; pass --maneuver dig|FILE.csv")
    return maneuver_from_table(cols, f"{path} (session info)")


def load_recording(path, maneuver=None, rig=None, calibration=None, progress=None, between=None, mapping=None):
    """The measured trajectory table and the maneuver of a recording.

    Parameters
    ----------
    path : str or path-like
        A session directory (``capture.mcap`` or, without one,
        ``markers.csv``), a ``.mcap`` session file, a VICON-style marker CSV,
        or a measured trajectory table (CSV with ``time`` and
        ``<body>.<quantity>`` columns).
    maneuver : Maneuver, "dig", path or None
        The maneuver; by default the session's (``maneuver.csv`` in the
        directory, else the MCAP's session info), for a CSV a
        ``maneuver.csv`` beside it, else the rig's own (the dig for the
        dragline).
    rig : Rig, optional
    calibration : path, optional
        ``cameras.json`` for a session; by default the one in the session
        directory, else the cameras are calibrated from the session's
        L-frame and wand takes.
    progress : callable, optional
        Receives one-line notes.
    between : (str, str), optional
        A marker file's start and end event labels: the trial between them
        (``reconstruct_marker_file``); ``source["cut"]`` says what was kept.
    mapping : path, optional
        Read ``path`` as a table of tracked poses (a ``.mcap`` as a ROS 2
        bag of pose topics) through this mapping (``capture.read_tracked_table``,
        ``read_tracked_bag``); its tracked points' positions are the
        maneuver when none is given.

    Returns
    -------
    measured : pandas.DataFrame
    maneuver : Maneuver
    source : dict
        What was read and how (JSON-ready).

    Raises
    ------
    ValueError
        Unreadable input, a different rig's markers, no maneuver.
    """
    from ...capture import read_session

    note = progress or (lambda msg: None)
    path = os.fspath(path)
    rig = load_rig() if rig is None else rig
    maneuver = _read_maneuver_arg(maneuver)
    if mapping is not None:
        return _load_tracked(path, mapping, rig, maneuver, note)
    source = {"input": path}
    recording = resolve_recording(path, tables=True)
    kind, file, folder = recording.kind, recording.file, recording.folder
    source["kind"] = kind
    beside = os.path.join(folder, "maneuver.csv") if folder else None

    if kind == "session":
        session, report = read_session(file)
        if report.get("lost", "nothing") != "nothing":
            note(f"{file} is {'cut short' if report.get('truncated') else 'damaged'}; lost {report.get('lost')}")
        if maneuver is None:
            if beside and os.path.isfile(beside) and os.path.dirname(os.path.abspath(file)) == os.path.abspath(folder):
                maneuver, source["maneuver"] = read_maneuver_csv(beside), beside
            else:
                maneuver, source["maneuver"] = _session_maneuver(session, file), f"{file} (session info)"
        cameras, source["calibration"] = _session_cameras(session, file, folder, calibration, note)
        from ...reconstruct import reconstruct_session

        try:
            table, _, _, _ = reconstruct_session(session, cameras, rig=rig)
        except ValueError as exc:
            raise ValueError(f"{file}: {exc}") from None
    elif kind == "markers":
        from ...reconstruct import reconstruct_marker_file

        table, summary = reconstruct_marker_file(file, rig=rig, between=between)
        if "cut_short" in summary:
            note(f"{file} is cut short: {summary['cut_short']}; the frames there are read")
            source["cut_short"] = summary["cut_short"]
        if between is not None:
            source["cut"] = summary["cut"]
    else:
        table = read_trajectory_table(file, "measured")
    if maneuver is None:
        if beside and os.path.isfile(beside):
            maneuver, source["maneuver"] = read_maneuver_csv(beside), beside
        else:
            maneuver = default_maneuver(rig)
            source["maneuver"] = "the rig's own (default; no maneuver table came with the input)"
            note("no maneuver table came with the input; using the rig's own (checked against the rope lengths)")
    source.setdefault("maneuver", "given")
    return table, maneuver, source


def _load_tracked(path, mapping, rig, maneuver, note):
    """A tracker's table of poses, through its mapping: the trajectory table, the maneuver, the source."""
    from ...capture import read_tracked_bag, read_tracked_table
    from ...reconstruct import tracked_trajectory, tracked_within_reach

    bag = str(path).lower().endswith(".mcap")
    poses = (read_tracked_bag if bag else read_tracked_table)(path, mapping)
    try:
        tracked_within_reach(poses, rig)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    # A mapping is a TOML file, or one built in code (a benchmark's, at a flight's own rate).
    named = os.fspath(mapping) if isinstance(mapping, (str, os.PathLike)) else "given in code"
    try:
        table, tracked = tracked_trajectory(poses, rig)
    except ValueError as exc:
        # What the mapping names that the rig lacks is the mapping's fault; the rest (a gap in a point's
        # track) is the recording's.
        raise ValueError(f"{named if str(exc).startswith('the mapping') else path}: {exc}") from None
    source = {"input": path, "kind": "ROS 2 bag" if bag else "tracked table", "mapping": named,
              "tracked": poses.report}
    report = poses.report
    if report["rows_dropped"] or report["gaps"] or report["off_step"]:
        note(f"{path}: {report['rows_dropped']} rows without a usable time dropped, {report['off_step']} intervals "
             f"off the median step, {report['gaps']} gaps left missing")
    if tracked is not None:
        source["point_smoothing"] = _smoothing_report(poses, tracked)
    if maneuver is None:
        maneuver, source["maneuver"] = (tracked, "the tracked points' track") if tracked is not None else (
            default_maneuver(rig), "the rig's own")
    else:
        source["maneuver"] = "given"
    return table, maneuver, source


def _smoothing_report(poses, tracked):
    """Each tracked point's smoothed track (``reconstruct.smoothed_track``) against its samples: the RMS (m)."""
    from ...reconstruct import MIN_SMOOTHED_SAMPLES

    t = np.asarray(poses.time, float)
    out = {}
    for name, samples in poses.points.items():
        fine = tracked.points[name]
        at = np.column_stack([np.interp(t, tracked.time, fine[:, j]) for j in range(3)])
        smoothed = t.size >= MIN_SMOOTHED_SAMPLES  # fewer are left as they are (``smoothed_track``)
        out[name] = {"method": "cubic smoothing spline, smoothing by generalized cross-validation" if smoothed
                     else "the samples' polyline (too few samples to smooth)",
                     "rate_hz": float(1.0 / (tracked.time[1] - tracked.time[0])) if tracked.time.size > 1 else None,
                     "rms_from_samples_m": float(np.sqrt(np.mean(np.sum((at - samples) ** 2, axis=1))))}
    return out


def _session_cameras(session, file, folder, calibration, note):
    from ...capture import calibrate, load_cameras

    if calibration is None and folder and os.path.isfile(os.path.join(folder, "cameras.json")):
        calibration = os.path.join(folder, "cameras.json")
    if calibration is not None:
        if not os.path.isfile(calibration):
            raise ValueError(f"{calibration}: no such calibration file")
        return load_cameras(calibration), calibration
    if session.lframe is None or session.wand is None or session.wand_length is None:
        raise ValueError(f"{file}: no calibration given and the session lacks the L-frame or wand take")
    note("calibrating the cameras from the session's L-frame and wand takes")
    try:
        cameras, _ = calibrate(session.lframe, session.wand, session.wand_length, session.lframe_points,
                               session.image_size, session.nominal_focal_px, names=session.camera_names)
    except ValueError as exc:
        raise ValueError(f"{file}: calibration failed: {exc}") from None
    return cameras, "calibrated from the session's L-frame and wand takes"


def candidate_channels(rig):
    """The channels a diagnosis may compare, from the rig: every body's position (x, y, z), the attitude
    (roll, pitch, yaw) of every body whose markers can give one (three or more), every winch's rope length."""
    channels = []
    for name, body in rig.bodies.items():
        quantities = ("x", "y", "z") + (("roll", "pitch", "yaw") if len(body.markers) >= 3 else ())
        channels += [f"{name}.{q}" for q in quantities]
    return channels + list(rope_channels(rig))


def check_channels(measured, rig):
    """The rig's candidate channels the recording measures (on at least ``MEASURED_SHARE`` of its samples).

    Raises ValueError when it measures no body of the rig.
    """
    def measured_enough(c):
        return c in measured.columns and np.isfinite(np.asarray(measured[c], float)).mean() >= MEASURED_SHARE

    channels = [c for c in candidate_channels(rig) if measured_enough(c)]
    if not any(c.partition(".")[0] in rig.bodies for c in channels):
        raise ValueError(f"the recording measures none of the rig's bodies ({', '.join(rig.bodies)}) on most of "
                         "its samples: not a recording of this rig")
    return channels


def moving_channels(channels, nominal, noise):
    """The channels the nominal model moves by more than the recording's noise on them.

    A planar maneuver leaves the out-of-plane channels (a body's y, roll and
    yaw) at rest in the model, to the last bits: there the recording holds
    noise alone about a constant offset, and the diagnosis has nothing to
    compare (unless the offset is not free: ``free_offsets``).

    Parameters
    ----------
    channels : list of str
    nominal : ndarray (n, c)
        The nominal model's channels.
    noise : ndarray (c,)
        The recording's noise on each.
    """
    spread = np.nanmax(nominal, axis=0) - np.nanmin(nominal, axis=0)
    return [c for c, s, sigma in zip(channels, spread, noise) if s > sigma]


def rope_bias_allowance(rig, nominal_table, sigmas=2.5):
    """How far (m) each rope's mean recorded length may sit from the nominal model's, given the rig's tolerances.

    A rope's recorded (stretched) length moves with its reel's zero and,
    through its static stretch, with its stiffness: ``sigmas`` standard
    deviations of both together. Zero for a rig without tolerances.
    """
    out = {}
    first = nominal_table["time"] == float(nominal_table["time"].iloc[0])
    for channel in rope_channels(rig):
        rope = channel.split(".")[0]
        spec = rig.ropes.get(rope)
        reel_col = f"{rope}.reel_length"
        if spec is None or channel not in nominal_table or reel_col not in nominal_table:
            continue
        stretch = float(nominal_table.loc[first, channel].iloc[0] - nominal_table.loc[first, reel_col].iloc[0])
        var = 0.0
        for p in rig.tolerances:
            if p.kind == "reel_zero" and spec.winch in p.targets:
                var += p.tolerance**2
            elif p.kind == "rope" and p.field == "static_stiffness" and rope in p.targets:
                var += (abs(stretch) * p.tolerance) ** 2
        out[channel] = sigmas * math.sqrt(var)
    return out


def measured_rope_channels(measured, rig):
    """The rig's rope-length channels the recording has finite samples of."""
    return [c for c in rope_channels(rig) if c in measured.columns
            and np.isfinite(np.asarray(measured[c], float)).any()]


def check_maneuver(measured, estimate, rig, bias_allowance=None):
    """Raise ValueError unless the reel table explains the recorded rope lengths.

    Parameters
    ----------
    measured : pandas.DataFrame
    estimate : dict
        ``estimate_time_offset(measured, nominal_table)``.
    rig : Rig
        Says which ropes pass a pulley ring (looser tolerance, see
        ``ROPE_TOLERANCE``).
    bias_allowance : dict, optional
        Channel -> further mean offset (m) the rig's tolerances allow
        (``rope_bias_allowance``).
    """
    ropes = measured_rope_channels(measured, rig)
    if not ropes:
        raise ValueError("the recording has no rope lengths; cannot check it against the maneuver table")
    travel = max(np.nanmax(np.asarray(measured[c], float)) - np.nanmin(np.asarray(measured[c], float)) for c in ropes)
    if travel < MIN_REEL_TRAVEL:
        raise ValueError(f"the recorded rope lengths change by {1000 * travel:.0f} mm at most: the recording "
                         "holds no reeling, so its clock cannot be tied to the maneuver table")
    if not estimate["estimated"]:
        raise ValueError(f"cannot align the recording with the maneuver table: {estimate['reason']}")
    if estimate["at_search_edge"]:
        raise ValueError("the maneuver table does not match the recorded rope lengths: the best clock offset "
                         f"lies at the search limit ({estimate['offset']:+.2f} s)")
    bad = []
    for rope, r in estimate["ropes"].items():
        rms_tol, bias_tol = ROPE_TOLERANCE[_rope_kind(rig, rope)]
        bias_tol += (bias_allowance or {}).get(rope, 0.0)
        if r["residual_rms"] > rms_tol:
            bad.append((r["residual_rms"] / rms_tol,
                        f"{rope} by {1000 * r['residual_rms']:.0f} mm RMS (tolerance {1000 * rms_tol:.0f} mm)"))
        elif abs(r["bias"]) > bias_tol:
            bad.append((abs(r["bias"]) / bias_tol,
                        f"{rope} by {1000 * abs(r['bias']):.0f} mm on average, "
                        f"{'longer' if r['bias'] > 0 else 'shorter'} (tolerance {1000 * bias_tol:.0f} mm)"))
    if bad:
        raise ValueError("the maneuver table does not match the recorded rope lengths: after aligning the clocks "
                         "they differ from what the table gives: " + "; ".join(t for _, t in sorted(bad, reverse=True)))


def _rope_kind(rig, channel):
    rope = rig.ropes.get(channel.split(".")[0])
    return "ring" if rope is not None and rope.rings else "free"


def align_with_maneuver(measured, nominal_table, rig):
    """Clock offset of the recording, from the rope lengths that run straight from their reels.

    A rope through a pulley ring is used only when no other one is
    measured: ring friction or inertia changes its length in ways that would
    pull the offset.
    """
    ropes = measured_rope_channels(measured, rig)
    free = [c for c in ropes if _rope_kind(rig, c) == "free"]
    use = free or ropes
    if use == ropes:
        return estimate_time_offset(measured, nominal_table)
    drop = [c for c in ropes if c not in use]
    estimate = estimate_time_offset(measured.drop(columns=drop), nominal_table.drop(columns=drop))
    if estimate["estimated"]:
        # Every rope's agreement at that offset (a zero-width search at the shifted clock).
        shifted = measured.assign(time=np.asarray(measured["time"], float) - estimate["offset"])
        estimate["ropes"] = estimate_time_offset(shifted, nominal_table, max_offset=0.0)["ropes"]
    estimate["channels_used"] = use
    return estimate


