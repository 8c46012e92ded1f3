"""``dragline diagnose``: what physics does the nominal model leave out?

The steps on one recording (``docs/diagnosis.md`` states the method):

1. **Locate** (``_locate``): the nominal simulation of the recorded maneuver
   against the recording, channel by channel and window by window (the
   maneuver's phases, the free decay), in units of the measurement noise
   estimated from the recording itself.
2. **Model error** (``_updating.model_error``): the nominal model against
   itself at a finer discretization and a smaller step, on this maneuver;
   those differences become nuisance directions.
3. **Update** (``_updating.update_model``): the rig's uncertain parameters
   (the rig file's tolerances) fitted to the recording within their
   tolerances, before anything is blamed.
4. **Fit** each candidate mechanism through the simulator on top of the
   updated model, the parameters refitted with it (linearly for every
   candidate, nonlinearly for the leading one: ``_updating.joint_refit``),
   and score it on held-out data (``_hypotheses``).
5. **Decide** (``_decide``): a mechanism only when its held-out
   improvement beats what noise alone gives and the model-error budget, at
   no edge of its range, not confounded with a parameter, and leaving the
   recording near its noise; "none" when the updated model fits within
   noise (with the updates that made it fit); "unexplained" otherwise.

Only the motion is read: from a session, the calibration takes and the
trial's centroids (``capture.mcap``) and the reel table; nothing else the
directory holds is opened. Bad input (a different rig's markers, a reel
table that the recorded rope lengths do not follow, a recording without a
free decay) raises ``ValueError`` with one line.
"""

from __future__ import annotations

import math
import os
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ...capture import json_ready, resolve_recording, write_json
from ...simulate import (
    ROPE_CHANNELS,
    Maneuver,
    SimulationError,
    StaticsError,
    dig_maneuver,
    load_rig,
    make_mechanism,
    read_maneuver_csv,
    simulate,
)
from .._align import (
    MAX_OFFSET,
    check_table,
    estimate_time_offset,
    read_trajectory_table,
    reels_stop_time,
)
from .._executor import as_executor
from .._compare import channel_kind
from .._decay import free_decay
from .._metrics import channel_metrics
from ._band import RESOLVED_HZ, RESOLVED_MIN, band_improvement
from ._decide import decide, leftover_share, model_error_share
from ._hypotheses import (
    BLOCK_S,
    DECAY_WEIGHT,
    MIN_IMPROVEMENT,
    NULL_QUANTILE,
    NULL_SURROGATES,
    REFINE_XATOL,
    Problem,
    affordable_range,
    autocorrelation_time,
    candidate_list,
    fit_candidates,
    null_threshold,
    profile_uncertainty,
    score_candidate,
    signature_match,
    unavailable_reason,
)
from ._locate import (
    DYNAMIC_CHANNELS,
    LOWPASS_S,
    locate_mismatch,
    low_pass,
    noise_level,
    structure_threshold,
    time_windows,
)
from ._second_round import second_round
from ._updating import (
    OFFSET_FINDING,
    joint_refit,
    mark_model_error,
    model_error,
    nuisance_correlation,
    parameter_span_share,
    update_model,
)

__all__ = ["Diagnosis", "diagnose", "diagnose_path", "load_recording", "write_diagnosis_json", "write_diagnosis_report"]

SCHEMA = "dragline.diagnosis/1"
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
# Channels needed at all: a table without the bucket is not this rig.
REQUIRED_CHANNELS = ("bucket.x", "bucket.z", "bucket.pitch")
# Constant offsets beyond these mean the geometry or calibration differs.
OFFSET_LIMIT = {"position": 0.010, "angle": math.radians(2.0)}
# With the rig's tolerances, offsets are judged after updating: an offset
# this many times OFFSET_LIMIT that no parameter explains is another rig.
DIFFERENT_RIG = 5.0
# A second mechanism must explain at least this share of the chi2 the named
# model leaves above noise (see ``diagnose``).
SECOND_EXCESS_SHARE = 0.4
# A candidate (not the lead) whose signature a parameter change reproduces
# to this share is refitted jointly with the parameters too (``diagnose``).
SPAN_REFIT = 0.7
FREE_DECAY_KEYS = ("frequency_hz", "damping_ratio", "amplitude", "shape", "confidence", "decay_rate",
                   "decrement_per_cycle", "quadratic_coefficient")
DECAY_CHANNELS = ("bucket.x", "bucket.z", "bucket.pitch", "drag_cluster.x", "spreader_bar.pitch",
                  "hoist_cluster.pitch")
MAX_MISMATCH_ENTRIES = 30


@dataclass
class Diagnosis:
    """A diagnosis: the JSON document and the series the report draws.

    Attributes
    ----------
    doc : dict
        JSON-ready (``write_diagnosis_json``), see :func:`diagnose`.
    time : ndarray (n,)
        Time base (s, simulation clock).
    channels : list of str
    measured, nominal : ndarray (n, c)
        SI; the nominal simulation with its nuisance (offsets, clock shift)
        applied, so that ``measured - nominal`` is the nominal model's
        residual.
    updated : ndarray (n, c) or None
        The updated model (``_updating``) with its nuisance applied:
        ``measured - updated`` is the residual the mechanisms were judged
        against.
    fitted : dict
        Hypothesis name -> (n, c) simulation with its nuisance applied.
    located : dict
        ``before`` (nominal) and ``after`` (best significant candidate):
        every channel-window entry of ``_locate.locate_mismatch``.
    """

    doc: dict
    time: np.ndarray
    channels: list
    measured: np.ndarray
    nominal: np.ndarray
    updated: np.ndarray | None = None
    fitted: dict = field(default_factory=dict)
    located: dict = field(default_factory=dict)


# ---------------------------------------------------------------- input

def _read_maneuver_arg(maneuver):
    if maneuver is None or isinstance(maneuver, Maneuver):
        return maneuver
    return dig_maneuver() if maneuver == "dig" else read_maneuver_csv(maneuver)


def _session_maneuver(session, path):
    cols = session.maneuver or {}
    if not all(k in cols for k in ("time", "hoist_length", "drag_length")):
        raise ValueError(f"{path}: the session holds no maneuver table; pass --maneuver dig|FILE.csv")
    points = {}
    for key in cols:
        if key.endswith(".x") and key[:-2] + ".y" in cols and key[:-2] + ".z" in cols:
            name = key[:-2]
            points[name] = np.column_stack([cols[f"{name}.{a}"] for a in "xyz"])
    return Maneuver(cols["time"], cols["hoist_length"], cols["drag_length"], points)


def load_recording(path, maneuver=None, rig=None, calibration=None, progress=None, between=None):
    """The measured trajectory table and the maneuver of a recording.

    Parameters
    ----------
    path : str or path-like
        A session directory (``capture.mcap`` or, without one,
        ``markers.csv``), a ``.mcap`` session file, a VICON-style marker CSV,
        or a measured trajectory table (CSV with ``time`` and
        ``<body>.<quantity>`` columns).
    maneuver : Maneuver, "dig", path or None
        The reel table; by default the session's (``maneuver.csv`` in the
        directory, else the MCAP's session info), for a CSV a
        ``maneuver.csv`` beside it, else the dig maneuver.
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
        if between is not None:
            source["cut"] = summary["cut"]
    else:
        table = read_trajectory_table(file, "measured")
    if maneuver is None:
        if beside and os.path.isfile(beside):
            maneuver, source["maneuver"] = read_maneuver_csv(beside), beside
        else:
            maneuver, source["maneuver"] = dig_maneuver(), "dig (default; no maneuver table came with the input)"
            note("no maneuver table came with the input; using the dig maneuver (checked against the rope lengths)")
    source.setdefault("maneuver", "given")
    return table, maneuver, source


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


# ---------------------------------------------------------------- checks

def _check_channels(measured):
    missing = [c for c in REQUIRED_CHANNELS if c not in measured.columns
               or np.isfinite(np.asarray(measured[c], float)).mean() < 0.5]
    if missing:
        raise ValueError(f"the recording lacks {', '.join(missing)} (or they are mostly missing): "
                         "not a recording of this rig's bucket")
    channels = [c for c in DYNAMIC_CHANNELS if c in measured.columns
                and np.isfinite(np.asarray(measured[c], float)).mean() >= 0.5]
    return channels


def rope_bias_allowance(rig, nominal_table, sigmas=2.5):
    """How far (m) each rope's mean recorded length may sit from the nominal model's, given the rig's tolerances.

    A rope's recorded (stretched) length moves with its reel's zero and,
    through its static stretch, with its stiffness: ``sigmas`` standard
    deviations of both together. Zero for a rig without tolerances.
    """
    out = {}
    first = nominal_table["time"] == float(nominal_table["time"].iloc[0])
    for channel in ROPE_CHANNELS:
        rope = channel.split(".")[0]
        spec = rig.ropes.get(rope)
        reel_col = f"{rope}.reel_length"
        if spec is None or channel not in nominal_table or reel_col not in nominal_table:
            continue
        stretch = float(nominal_table.loc[first, channel].iloc[0] - nominal_table.loc[first, reel_col].iloc[0])
        var = 0.0
        for p in rig.tolerances:
            if p.kind == "reel_zero" and spec.reel in p.targets:
                var += p.tolerance**2
            elif p.kind == "rope" and p.field == "static_stiffness" and rope in p.targets:
                var += (abs(stretch) * p.tolerance) ** 2
        out[channel] = sigmas * math.sqrt(var)
    return out


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
    ropes = [c for c in ROPE_CHANNELS if c in measured.columns and np.isfinite(np.asarray(measured[c], float)).any()]
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
    return "ring" if rope is not None and rope.ring is not None else "free"


def align_with_maneuver(measured, nominal_table, rig):
    """Clock offset of the recording, from the rope lengths that run straight from their reels.

    A rope through a pulley ring is used only when no other one is
    measured: ring friction or inertia changes its length in ways that would
    pull the offset.
    """
    ropes = [c for c in ROPE_CHANNELS if c in measured.columns and np.isfinite(np.asarray(measured[c], float)).any()]
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


# ---------------------------------------------------------------- diagnosis

def _decay_entry(time, values, t_stop):
    try:
        res = free_decay(time, values, t_stop)
    except ValueError as exc:
        return {"status": "missing", "reason": str(exc)}
    out = {"status": "ok"}
    out.update({k: res[k] for k in FREE_DECAY_KEYS})
    return out


def _free_decay_section(time, channels, measured, nominal, fitted, fitted_name, t_stop, updated=None):
    out = {"t_start": float(t_stop), "t_end": float(time[-1]), "fitted_model": fitted_name, "channels": {}}
    for ch in DECAY_CHANNELS:
        if ch not in channels:
            continue
        j = channels.index(ch)
        entry = {"measured": _decay_entry(time, measured[:, j], t_stop),
                 "nominal": _decay_entry(time, nominal[:, j], t_stop)}
        if updated is not None:
            entry["updated"] = _decay_entry(time, updated[:, j], t_stop)
        if fitted is not None:
            entry["fitted"] = _decay_entry(time, fitted[:, j], t_stop)
        m, s = entry["measured"], entry["nominal"]
        if m.get("frequency_hz") and s.get("frequency_hz"):
            entry["frequency_shift"] = (s["frequency_hz"] - m["frequency_hz"]) / m["frequency_hz"]
        if m.get("damping_ratio") is not None and s.get("damping_ratio"):
            entry["damping_ratio_ratio"] = m["damping_ratio"] / s["damping_ratio"]
        out["channels"][ch] = entry
    return out


METRIC_KEYS = ("rms_error", "peak_error", "sg_combined", "iso_rating")


def _before_after_metrics(time, channels, measured, nominal, fitted, model, t_stop):
    """The comparison metrics (``channel_metrics``) over the free decay, nominal and fitted model."""
    sel = time >= t_stop
    out = {"model": model, "window": [float(t_stop), float(time[-1])], "channels": {}}
    for j, ch in enumerate(channels):
        entry = {}
        for side, sim in (("before", nominal), ("after", fitted)):
            if sim is None:
                continue
            try:
                m = channel_metrics(time[sel], measured[sel, j], sim[sel, j])
            except ValueError:
                continue
            entry[side] = {k: m[k] for k in METRIC_KEYS}
        out["channels"][ch] = entry
    return out


def _structure_energy(residual, channels, sigma, width):
    """Sum of squared low-passed residuals, each channel over its structure threshold."""
    lp = low_pass(residual, width)
    thr = np.array([structure_threshold(ch, s, width) for ch, s in zip(channels, sigma)])
    return float(np.nansum((lp / thr) ** 2))


# Smallest stated relative uncertainty (in ln p). In the blind benchmark
# (26 sessions, 2026-11-21) strong fits erred by up to 2-4 % (sheave
# inertia 2.3-3.6 % low, pulley friction 2.0 %) while their profile
# curvature stated under 1 %: the 68 % intervals covered 0 of 4 sheave
# inertia cases.
SYSTEMATIC_FLOOR = 0.05


def _uncertainty(scored, main, kappa):
    """The stated uncertainty of a fitted main parameter (see ``_hypotheses``)."""
    value = scored["value"]
    sx = profile_uncertainty(scored["profile"], value, kappa)
    fold_x = [math.log(v) for v in scored["fold_values"] if v > 0]
    spread = abs(fold_x[0] - fold_x[1]) / 2.0 if len(fold_x) == 2 else None
    # The fold estimates are discrete choices among evaluated points, so
    # their spread alone may be 0: only a measured curvature states one.
    # Never below SYSTEMATIC_FLOOR: the reconstruction's small systematic
    # errors bias even strong fits by a few percent, which no curvature
    # sees (and never below the search's resolution, REFINE_XATOL).
    stated = None if sx is None or scored["at_bound"] else max(sx, spread or 0.0, SYSTEMATIC_FLOOR, REFINE_XATOL)
    return {
        "parameter": main,
        "std": value * stated if stated is not None and value > 0 else None,
        "relative": stated,
        "interval_68": ([value * math.exp(-stated), value * math.exp(stated)]
                        if stated is not None and value > 0 else None),
        "profile_relative": sx,
        "fold_values": scored["fold_values"],
        "method": "largest of the chi2(ln p) profile curvature (scaled by the residual's dispersion and "
                  "autocorrelation), half the spread of the two folds' estimates and a floor for the "
                  f"reconstruction's systematic bias ({SYSTEMATIC_FLOOR:g} in ln p); none at a range bound",
    }


def diagnose(measured, maneuver=None, rig=None, discretization="baseline", candidates=None, workers=2,
             seed=0, source=None, progress=None):
    """Diagnose a measured trajectory table against the nominal model.

    Parameters
    ----------
    measured : pandas.DataFrame
        Measured trajectory table (docs/conventions.md), any clock: aligned to the
        simulation from the rope lengths.
    maneuver : Maneuver, optional
        The reel table of the recording (dig maneuver by default).
    rig : Rig, optional
    discretization : str or dict
        Of every simulation (``baseline`` by default).
    candidates : sequence of str, optional
        Mechanism names; every one in ``MECHANISMS`` by default.
    workers : int or Executor
        Where the simulations run: a number of local processes, or an
        ``Executor`` (``compare.executor_from``: local processes or a Dask
        cluster). Results do not depend on it.
    seed : int
        Seeds the null test's surrogates.
    source : dict, optional
        Where the table came from (``load_recording``), copied to the JSON.
    progress : callable, optional
        Receives one-line progress notes.

    Returns
    -------
    Diagnosis
        ``doc`` holds: ``schema``; ``verdict`` (a mechanism name, "none" or
        "unexplained"); ``reason``; ``mismatch`` (significant channel-window
        entries of the nominal model, largest ``score`` first: ``channel``,
        ``window``, ``t_start``, ``t_end``, ``score`` (structured RMS over
        its threshold), ``rms``, ``frequency_hz``, ...); ``mismatch_after``
        (the same for the verdict's model); ``hypotheses`` ranked by held-out
        improvement, best first: ``name``, ``parameters`` (docs/interfaces.md units),
        ``main_parameter``, ``uncertainty``, ``rms_before`` and
        ``rms_after`` (held-out RMS residual in units of the measurement
        noise, 1 = noise), ``improvement`` (held-out chi2 drop),
        ``threshold``, ``score`` (improvement / threshold), ``significant``,
        ``signature_match``, ``explained_fraction``, ``rms_channels`` (SI,
        all data, before/after); ``second_mechanism`` (when a mechanism is
        named: every other candidate fitted on top of it, ``_second_round``;
        else None); ``skipped`` (candidates the simulator
        cannot run); ``free_decay`` (measured, nominal and fitted frequency,
        damping, envelope per channel); ``metrics`` (RMS and peak error,
        Sprague-Geers C, ISO/TS 18571 rating over the free decay, nominal
        ``before`` and fitted ``after``); ``null_test``; ``channels`` (noise,
        offset per channel); ``alignment``; ``settings``; ``timing``.

    Raises
    ------
    ValueError
        A table of another rig, a maneuver the rope lengths do not follow,
        no free decay.
    """
    started = _time.perf_counter()
    note = progress or (lambda msg: None)
    rig = load_rig() if rig is None else rig
    maneuver = dig_maneuver() if maneuver is None else maneuver
    check_table(measured, "measured table")
    channels = _check_channels(measured)
    t_meas = np.asarray(measured["time"], float)
    step = float(np.median(np.diff(t_meas)))
    if np.max(np.abs(np.diff(t_meas) - step)) > 0.01 * step:
        raise ValueError("the measured table's time is not uniformly sampled")
    rate = round(1.0 / step, 6)
    t0 = float(maneuver.time[0])

    # Nominal run, long enough for any clock offset searched.
    record = float(t_meas[-1] - t_meas[0])
    note("simulating the nominal model")
    nominal_run = simulate(rig, maneuver, discretization, [], duration=record + MAX_OFFSET, rate_hz=rate)
    nominal_table = nominal_run.table
    estimate = align_with_maneuver(measured, nominal_table, rig)
    check_maneuver(measured, estimate, rig, rope_bias_allowance(rig, nominal_table))
    offset = float(estimate["offset"])
    t_al = t_meas - offset
    keep = (t_al >= t0 - 1e-9) & (t_al <= float(nominal_run.time[-1]) + 1e-9)
    time = t_al[keep]
    if time.size < 16:
        raise ValueError("the recording does not overlap the maneuver in time")
    M = np.column_stack([np.asarray(measured[c], float)[keep] for c in channels])
    t_stop, stop_method = reels_stop_time(measured, nominal_table, offset)
    if t_stop is None:
        raise ValueError("cannot tell when the reels stop; the free decay cannot be found")
    if time[-1] - t_stop < MIN_DECAY_S:
        raise ValueError(f"the recording ends {max(time[-1] - t_stop, 0.0):.2f} s after the reels stop; a diagnosis "
                         f"needs a free decay of at least {MIN_DECAY_S:g} s (more than one swing)")
    duration = float(time[-1] - t0) + 1.0 / rate
    sigma = np.array([noise_level(M[:, j], channel_kind(c)) for j, c in enumerate(channels)])
    problem = Problem(time, M, sigma, t_stop)
    ctx = {"rig": rig, "maneuver": maneuver, "discretization": discretization, "duration": duration,
           "rate_hz": rate, "initial_state": nominal_run.states[0], "time": time, "channels": channels,
           "nominal_dt": float(nominal_run.dt), "parameters": tuple(rig.tolerances),
           # The recording was reconstructed with this rig's geometry (``channels_on``).
           "reported_rig": rig}
    nominal_sim = np.column_stack([np.interp(time, nominal_run.time, np.asarray(nominal_table[c], float))
                                   for c in channels])

    # 1. Locate (the nominal model as the user gave it).
    dt = float(time[1] - time[0])
    width = max(3, int(round(LOWPASS_S / dt)) | 1)
    windows = time_windows(maneuver, t_stop, float(time[-1]))
    plain_eval = problem.evaluate(nominal_sim)
    r_nominal = problem.residual(nominal_sim, plain_eval["nuisance"])
    located_nominal = locate_mismatch(time, r_nominal, channels, sigma, windows)
    b0, shift0, _ = plain_eval["nuisance"]

    # 2. The model's own numerical error, then updating within the rig's tolerances.
    note("estimating the model's own numerical error (finer discretization, half time step)")
    error_directions, model_error_block = model_error(problem, ctx, nominal_sim, workers=workers)
    model_error_sims = 2
    update = None
    plain_problem, nominal_ctx = problem, ctx
    if ctx["parameters"]:
        note(f"updating {len(ctx['parameters'])} rig parameters within their tolerances")
        update = update_model(problem, ctx, nominal_sim, error_directions, workers=workers, progress=note)
        # The finer model's difference depends on the parameters (a few percent
        # on a frequency moves its phase drift): estimated again at the updated
        # rig, and updating resumed with it (on a recording simulated at the
        # next finer level, chi2 fell from 1.5 to 1.04 times the noise).
        note("estimating the model's own numerical error again at the updated rig")
        error_directions, model_error_block = model_error(
            problem, dict(ctx, rig=update["rig"], maneuver=update["maneuver"], initial_state=update["initial_state"]),
            update["sim"], workers=workers)
        model_error_block["rig"] = "updated"
        model_error_sims += 2
        update = update_model(problem, ctx, nominal_sim, error_directions, workers=workers, progress=note,
                              start=update)
        ctx = dict(ctx, rig=update["rig"], maneuver=update["maneuver"], initial_state=update["initial_state"])
        base_sim = update["sim"]
        tol = np.array([p.tolerance for p in ctx["parameters"]])
        problem = problem.with_regressors(
            [*update["sensitivities"], *error_directions],
            prior_precision=np.r_[1.0 / tol**2, np.zeros(len(error_directions))],
            prior_mean=np.r_[-update["coords"], np.zeros(len(error_directions))], shift_center=update["shift"])
    else:
        base_sim = nominal_sim
        problem = problem.with_regressors(error_directions)
    nominal_eval = problem.evaluate(base_sim)
    r0 = problem.residual(base_sim, nominal_eval["nuisance"])
    # A mismatch the finer model also shows is the model's own error, not missing physics.
    located = mark_model_error(locate_mismatch(time, r0, channels, sigma, windows), time, error_directions,
                               channels)
    structured_before = [e for e in located if e["significant"] and not e["within_model_error"]]

    # 2-3. Rank and fit.
    cands = candidate_list(candidates)
    skipped, runnable = [], []
    for c in cands:
        why = unavailable_reason(c, rig, maneuver, discretization)
        if why:
            skipped.append({"name": c["name"], "reason": why})
            continue
        c["searched"] = affordable_range(c, rig, maneuver, discretization)
        runnable.append(c)
    note(f"fitting {len(runnable)} candidate mechanisms ({', '.join(c['name'] for c in runnable)})")
    points = fit_candidates(problem, ctx, runnable, base_sim, workers=workers, progress=note)
    scored = {c["name"]: score_candidate(problem, c, points[c["name"]]) for c in runnable}
    joints = {}
    if update is not None and scored:
        # Updating ran before any mechanism, so the parameters took up what
        # they could of a real one (a sheave's inertia read as cluster mass):
        # on top of the updated rig its score is too low. The lead among the
        # candidates that could be named (off the bounds of their range) is
        # refitted jointly with the parameters: one at a bound would spend
        # the budget on a dead end. Refitting the runner-up too cost 70-135
        # simulations on each of six realistic recordings and changed no
        # verdict (docs/diagnosis.md).
        eligible = sorted((c for c in runnable if scored[c["name"]]["value"] > 0
                           and scored[c["name"]]["improvement"] > 0 and not scored[c["name"]]["at_bound"]),
                          key=lambda c: -scored[c["name"]]["improvement"])
        # The candidate a parameter change imitates best lost most to
        # updating: refitted jointly as well, when it is not the lead.
        span = {c["name"]: parameter_span_share(problem, scored[c["name"]]["sim"] - base_sim, update)
                for c in eligible}
        if span:
            note("share of each candidate's signature a parameter change reproduces: "
                 + ", ".join(f"{n} {v:.2f}" for n, v in span.items()))
        refit = eligible[:1]
        imitated = [c for c in eligible[1:] if span[c["name"]] >= SPAN_REFIT]
        if imitated:
            refit.append(max(imitated, key=lambda c: span[c["name"]]))
        for lead in refit:
            s = scored[lead["name"]]
            note(f"refitting {lead['name']} and the rig parameters together")
            joint = joint_refit(plain_problem, nominal_ctx, update,
                                make_mechanism(lead["name"], **{lead["main"]: s["value"]}), error_directions,
                                workers=workers, progress=note, value_range=lead["searched"])
            if joint is None:
                continue
            joints[lead["name"]] = joint
            value = float(joint["mechanism"].parameters[lead["main"]])
            points[lead["name"]].append((value, joint["sim"], problem.evaluate(joint["sim"])))
            # The profile's curvature comes from the search on one rig; the
            # joint point sits on another and would bend the parabola.
            profile = s["profile"]
            scored[lead["name"]] = score_candidate(problem, lead, points[lead["name"]])
            scored[lead["name"]]["profile"] = profile
            scored[lead["name"]]["n_simulations"] += joint["n_simulations"] - 1

    # 4. Null test: surrogates of the best model's residual.
    best_name = min(scored, key=lambda n: scored[n]["evaluation"]["full"]) if scored else None
    best_res = r0 if best_name is None or scored[best_name]["value"] == 0 else problem.residual(
        scored[best_name]["sim"], scored[best_name]["evaluation"]["nuisance"])
    signatures = [s["signature_sim"] - base_sim for s in scored.values() if s["signature_sim"] is not None]
    threshold, q = null_threshold(problem, best_res, signatures, seed=seed)
    z = np.where(problem.valid, best_res, 0.0) / sigma
    tau = autocorrelation_time(z)
    chi_min = min([s["evaluation"]["full"] for s in scored.values()] + [nominal_eval["full"]])
    kappa = max(1.0, chi_min / problem.n_weighted) * float(np.average(tau, weights=(z**2).sum(0) + 1e-12))
    # The model-error budget: what the updated model leaves above noise
    # (chi2 beyond its expectation) holds what updating could not reach -
    # degenerate parameter pairs, nonlinearity, the finer model's error
    # beyond its fitted direction. A mechanism must explain a real share of
    # it, not a sliver that any smooth signature would absorb. A small
    # excess is mostly the measurement's own (MODEL_ERROR_FULL).
    excess = max(0.0, nominal_eval["full"] - problem.n_weighted)
    share = model_error_share(excess, problem.n_weighted) if update is not None else 0.0
    allowance = share * excess
    noise_threshold, threshold = threshold, max(threshold, allowance)

    e_before = _structure_energy(r0, channels, sigma, width)
    hypotheses, fitted_series, residuals = [], {}, {}
    for c in runnable:
        s = scored[c["name"]]
        main = c["main"]
        value = s["value"]
        params = dict(make_mechanism(c["name"]).parameters)
        params[main] = value
        if s["value"] > 0:
            res = problem.residual(s["sim"], s["evaluation"]["nuisance"])
            frac = 1.0 - _structure_energy(res, channels, sigma, width) / e_before if e_before > 0 else 0.0
            sig_match = signature_match(problem, r0, s["sim"] - base_sim)
            band = band_improvement(problem, r0, res)
            residuals[c["name"]] = res
            fitted_series[c["name"]] = M - res
        else:
            frac, sig_match, band = 0.0, 0.0, {"resolved": 0.0, "resolved_share": 0.0}
        uncertainty = _uncertainty(s, main, kappa)
        confounders = (nuisance_correlation(problem, s["sim"] - base_sim, update)
                       if update is not None and s["value"] > 0 else [])
        rms_ch = {}
        for j, ch in enumerate(channels):
            before = r0[:, j]
            after = residuals[c["name"]][:, j] if c["name"] in residuals else before
            rms_ch[ch] = {"before": float(np.sqrt(np.nanmean(before**2))),
                          "after": float(np.sqrt(np.nanmean(after**2)))}
        n_w = problem.n_weighted
        # Evidence only where the model does not resolve the motion is not
        # evidence (``_band``).
        beyond = bool(s["improvement"] > threshold and value > 0)
        resolved_ok = band["resolved"] >= RESOLVED_MIN * threshold
        hypotheses.append({
            "name": c["name"],
            "main_parameter": main,
            "parameters": params,
            "uncertainty": uncertainty,
            "range": list(c["range"]),
            "searched_range": list(c["searched"]),
            "rms_before": math.sqrt(s["heldout_before"] / n_w),
            "rms_after": math.sqrt(s["heldout_after"] / n_w),
            "improvement": s["improvement"],
            "threshold": threshold,
            "score": s["improvement"] / threshold,
            "significant": beyond and resolved_ok,
            "unresolved": beyond and not resolved_ok,
            "resolved_share": band["resolved_share"],
            "resolved_improvement": band["resolved"],
            "signature_match": sig_match,
            "nuisance_correlation": confounders,
            "parameter_span_share": (parameter_span_share(problem, s["sim"] - base_sim, update)
                                     if update is not None and s["value"] > 0 else 0.0),
            "explained_fraction": frac,
            "at_bound": s["at_bound"],
            "time_shift_s": float(s["evaluation"]["nuisance"][1]),
            "n_simulations": s["n_simulations"],
            "n_failed": s["n_failed"],
            "rms_channels": rms_ch,
            "profile": [{"value": v, "chi2": ch} for v, ch in s["profile"]],
            "chi2_nominal": nominal_eval["full"],
        })
    for h in hypotheses:
        h["leftover_share"] = leftover_share(h)
    hypotheses.sort(key=lambda h: -h["improvement"])
    for k, h in enumerate(sorted(hypotheses, key=lambda h: -h["signature_match"])):
        h["signature_rank"] = k + 1
    sig = [h for h in hypotheses if h["significant"]]
    structured_after, after_name, located_after = structured_before, None, located
    if sig:
        after_name = sig[0]["name"]
        located_after = mark_model_error(locate_mismatch(time, residuals[after_name], channels, sigma, windows),
                                         time, error_directions, channels)
        structured_after = [e for e in located_after if e["significant"] and not e["within_model_error"]]
    # Constant offsets left by the best model (a mechanism can shift the
    # mean pose, e.g. rope held in a pulley): beyond calibration accuracy,
    # the geometry differs. Rope-length offsets were judged against the reel
    # table (check_maneuver).
    b_ref = scored[after_name]["evaluation"]["nuisance"][0] if after_name else nominal_eval["nuisance"][0]
    offsets = {c: float(b) for c, b in zip(channels, b_ref)}
    if update is not None:
        # Offsets the updated parameters leave (offsets with their prior):
        # beyond OFFSET_FINDING a finding; beyond OFFSET_LIMIT times
        # DIFFERENT_RIG no parameter within tolerance comes near: another rig.
        left = update["block"]["offsets_left"]
        if after_name in joints:
            # A mechanism can shift the mean pose (rope held in a ring): the
            # offsets left are those of the joint refit with it.
            left = joints[after_name]["offsets"]
        judged = {c: left[c] for c in channels if channel_kind(c) in OFFSET_LIMIT}
        limit = {c: DIFFERENT_RIG * OFFSET_LIMIT[channel_kind(c)] for c in judged}
    else:
        judged = {c: offsets[c] for c in channels if channel_kind(c) in OFFSET_LIMIT}
        limit = {c: OFFSET_LIMIT[channel_kind(c)] for c in judged}
    too_far = [c for c in judged if abs(judged[c]) > limit[c]]
    offsets_note = None
    if too_far:
        offsets_note = ("constant offsets beyond what calibration " + ("and the rig's tolerances " if update else "")
                        + "explain on " + ", ".join(f"{c} ({judged[c]:+.3g})" for c in too_far)
                        + ": the rig geometry or the calibration differs from the model, so no dynamic mechanism "
                        "can be trusted")
    updates = _significant_updates(update)
    verdict, reason = decide(hypotheses, threshold, structured_before, structured_after,
                             offsets_ok=not too_far, offsets_note=offsets_note, updates=updates)
    findings = [c for c in channels if update is not None and c in left
                and abs(left[c]) > OFFSET_FINDING.get(channel_kind(c), math.inf)]
    if findings and not too_far:
        reason += ("; finding: constant offsets no parameter within tolerance explains on "
                   + ", ".join(f"{c} ({left[c]:+.3g})" for c in findings))
    second = None
    if verdict in scored:
        note(f"fitting the other candidates on top of {verdict}")
        named = next(h for h in hypotheses if h["name"] == verdict)
        second_ctx, second_problem, base_sim = ctx, problem, scored[verdict]["sim"]
        if verdict in joints:
            # The named fit sits on the jointly refitted rig: the others are
            # fitted on that rig too. Against the joint fit from the updated
            # rig, each had to beat the parameters' shifts as well as the
            # mechanism (at the low level a sheave's inertia under aero drag
            # scored 0, though strong on its own). The linearised parameter
            # freedom stays, its prior centred as the joint rig's shifts say.
            joint = joints[verdict]
            second_ctx = dict(ctx, rig=joint["rig"], maneuver=joint["maneuver"],
                              initial_state=joint["initial_state"])
            second_problem = problem.with_regressors(
                problem.regressors, prior_precision=problem.prior_precision,
                prior_mean=np.r_[-joint["coords"], np.zeros(len(error_directions))])
            main = named["main_parameter"]
            base_sim = joint["sim"]
            named = dict(named, parameters=dict(named["parameters"],
                                                **{main: float(joint["mechanism"].parameters[main])}))
        # What the named model leaves above noise holds its own error (the
        # updated rig's nonlinearity, the discretization): a second
        # mechanism must explain a good part of it, not a slice any smooth
        # signature would take (on `dragline run`'s recording, friction
        # alone in its truth, a sheave inertia took 24 % of it and beat the
        # noise threshold 4.6 times; the inertia hidden under aero drag in
        # tests/test_diagnose.py takes 64 %).
        # (Its own name: the JSON's model_error_allowance is the first round's.)
        second_allowance = 0.0
        if update is not None:
            named_excess = second_problem.evaluate(base_sim)["full"] - second_problem.n_weighted
            second_allowance = SECOND_EXCESS_SHARE * max(0.0, named_excess)
        second = second_round(second_problem, second_ctx, runnable, named, base_sim,
                              workers=workers, seed=seed, progress=note, allowance=second_allowance)
        also = [h for h in second["candidates"] if h["significant"]]
        if also:
            h = also[0]
            (k, v), = h["parameters"].items()
            reason += (f"; on top of it, {h['name']} ({k}={v:.3g}) also improves held-out data, {h['score']:.1f} "
                       "times what noise alone gives: a second mechanism may be at work")
    shown = verdict if verdict in fitted_series else after_name
    decay = _free_decay_section(time, channels, M, M - r_nominal, fitted_series.get(shown), shown, t_stop,
                                updated=M - r0 if update is not None else None)
    metrics = _before_after_metrics(time, channels, M, M - r_nominal, fitted_series.get(shown), shown, t_stop)

    doc = {
        "schema": SCHEMA,
        "verdict": verdict,
        "reason": reason,
        "mismatch": [e for e in located_nominal if e["significant"]][:MAX_MISMATCH_ENTRIES],
        "mismatch_updated": structured_before[:MAX_MISMATCH_ENTRIES],
        "calibration": _calibration_doc(update, joints, nominal_ctx, after_name),
        "model_error": model_error_block,
        "mismatch_after": {"model": after_name or ("updated" if update else "nominal"),
                           "entries": structured_after[:MAX_MISMATCH_ENTRIES]},
        "hypotheses": hypotheses,
        "second_mechanism": second,
        "skipped": skipped,
        "free_decay": decay,
        "metrics": metrics,
        "null_test": {"threshold": threshold, "noise_threshold": noise_threshold, "surrogate_quantile": q, "quantile": NULL_QUANTILE,
                      "n_surrogates": NULL_SURROGATES, "min_improvement": MIN_IMPROVEMENT,
                      "dispersion_kappa": kappa, "model_error_allowance": allowance,
                      "excess_chi2_updated": excess, "model_error_share": share},
        "channels": {c: {"noise": float(sigma[j]), "offset": offsets[c], "offset_nominal": float(b0[j]),
                         "structure_threshold": structure_threshold(c, sigma[j], width)}
                     for j, c in enumerate(channels)},
        "windows": [{"window": w, "t_start": a, "t_end": b} for w, a, b in windows],
        "alignment": {"time_offset": offset, "time_shift_nominal": float(shift0),
                      "ropes": estimate["ropes"], "reels_stop": float(t_stop), "reels_stop_method": stop_method},
        "source": source or {},
        "settings": {"discretization": discretization if isinstance(discretization, str) else dict(discretization),
                     "candidates": [c["name"] for c in cands], "decay_weight": DECAY_WEIGHT,
                     "block_s": BLOCK_S, "lowpass_s": LOWPASS_S, "rate_hz": rate,
                     "resolved_hz": RESOLVED_HZ, "resolved_min": RESOLVED_MIN},
        "executor": as_executor(workers).describe(),
        "timing": {"seconds": _time.perf_counter() - started,
                   "simulations": 1 + sum(h["n_simulations"] for h in hypotheses)
                   + (second["n_simulations"] if second else 0) + model_error_sims
                   + (update["n_simulations"] if update else 0)},
    }
    fitted = {name: fitted_series[name] for name in fitted_series}
    return Diagnosis(doc=json_ready(doc), time=time, channels=channels, measured=M, nominal=M - r_nominal,
                     updated=M - r0 if update is not None else None, fitted=fitted,
                     located={"before": json_ready(located), "after": json_ready(located_after)})


def _calibration_doc(update, joints, ctx, named=None):
    """The JSON ``calibration`` block, with the candidates' joint refits when they ran.

    ``joint_refit`` is the named candidate's (else the first refitted);
    ``joint_refits`` lists every one.
    """
    if update is None:
        return {"parameters": [], "method": "the rig states no tolerances: nothing updated"}
    block = dict(update["block"])
    entries = {name: {
        "mechanism": name,
        "parameters": dict(joint["mechanism"].parameters),
        "shift_in_tolerances": {p.name: float(x / p.tolerance) for p, x in zip(ctx["parameters"], joint["coords"])},
        "history": joint["history"],
        "n_simulations": joint["n_simulations"],
    } for name, joint in joints.items()}
    if entries:
        block["joint_refit"] = entries.get(named) or next(iter(entries.values()))
        block["joint_refits"] = list(entries.values())
    return block


def _significant_updates(update, min_shift=2.0, most=4):
    """The largest updates a lab would notice: identifiable, beyond one tolerance and ``min_shift`` posterior sd."""
    if update is None:
        return []
    moved = [e for e in update["block"]["parameters"]
             if e["identifiable"] and abs(e["shift_in_tolerances"]) > 1.0
             and abs(e["coordinate"]) > min_shift * e["coordinate_sd"]]
    moved.sort(key=lambda e: -abs(e["shift_in_tolerances"]))
    return [e["description"] for e in moved[:most]]


def diagnose_path(path, maneuver=None, rig=None, calibration=None, discretization="baseline", candidates=None,
                  workers=2, seed=0, progress=None, between=None):
    """:func:`load_recording` then :func:`diagnose`: what ``dragline diagnose`` runs."""
    started = _time.perf_counter()
    rig = load_rig() if rig is None else rig
    table, man, source = load_recording(path, maneuver, rig, calibration, progress, between)
    loaded = _time.perf_counter() - started
    try:
        result = diagnose(table, man, rig, discretization, candidates, workers, seed, source, progress)
    except (StaticsError, SimulationError):
        raise  # about the rig or the maneuver, not the recording
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise ValueError(f"{path}: {exc}") from None  # the checks of diagnose() are about the recording
    result.doc["timing"]["load_seconds"] = loaded
    result.doc["timing"]["total_seconds"] = _time.perf_counter() - started
    return result


def write_diagnosis_json(path, doc):
    """Write the diagnosis JSON atomically (strict JSON, no NaN)."""
    write_json(path, doc)


def write_diagnosis_report(path, diagnosis):
    """Write the diagnosis PDF (see ``_diagnose_report``)."""
    from ._report import write_report_pdf

    write_report_pdf(path, diagnosis)
