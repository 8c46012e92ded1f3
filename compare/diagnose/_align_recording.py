"""The diagnosis's first step: the recording put on the model's clock.

``align_recording`` runs the nominal model, ties the recording's clock to
the maneuver (by the recorded rope lengths where the rig has winches,
else from the recording's first sample), cuts it to the maneuver, keeps
the channels that move, and estimates each channel's noise. Several trials
are each aligned alone and stacked side by side (``_trials``); a trial that
starts mid-swing starts from its first samples (``_start``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...simulate import simulate
from .._align import MAX_OFFSET, check_table, maneuver_stop_time, reels_stop_time
from .._compare import channel_kind
from ._problem import Problem
from ._locate import LOWPASS_S, noise_level, time_windows
from ._recording import (
    MIN_DECAY_S,
    load_recording,
    align_with_maneuver,
    check_channels,
    check_maneuver,
    free_offsets,
    measured_rope_channels,
    moving_channels,
    rope_bias_allowance,
)
from ._scale import machine_scale
from ._start import estimate_start, start_parameters
from ._state import DiagnosisState, Recording, _note
from ._trials import SEPARATOR, each_trials_own

__all__ = ["align_recording", "aligned_path"]


def align_recording(state, clock_table=None):
    """The nominal run, the recording on its clock, the channels and their noise, the fitting problem.

    Several trials (``state.trial_names``): each aligned as one would be, then
    stacked side by side (``_trials``). ``clock_table``: the trajectory
    table whose rope lengths the recording's clock is read against (one
    trial; the nominal model's by default; ``recording_floor`` reads it
    against the filmed truth's).
    """
    held = []
    for name, measured, maneuver in state.held_out:
        # Checked before any fit: a held-out trial the model cannot read fails now, not after the diagnosis.
        try:
            held.append(_aligned_trial(state, measured, maneuver))
        except ValueError as exc:
            raise ValueError(f"held-out trial {name}: {exc}") from None
    state = replace(state, held_aligned=held)
    if state.trial_names is None:
        one = _aligned_trial(state, state.measured, state.maneuver, clock_table=clock_table)
        recording = Recording(time=one["time"], channels=one["channels"], values=one["values"], noise=one["noise"],
                              rate_hz=one["rate"], t_stop=one["t_stop"], stop_method=one["stop_method"],
                              offset=one["offset"], alignment=one["alignment"], windows=one["windows"],
                              lowpass_width=one["lowpass_width"], scale=one["scale"])
        ctx = one["ctx"]
        problem = Problem(one["time"], one["values"], one["noise"], one["t_stop"],
                          offset_free=free_offsets(one["channels"], state.shared_frame))
        return replace(state, recording=recording, nominal_run=one["nominal_run"], nominal_sim=one["nominal_sim"],
                       plain_problem=problem, nominal_ctx=ctx, problem=problem, ctx=ctx)
    trials = []
    for name, measured, maneuver in zip(state.trial_names, state.measured, state.maneuver):
        try:
            trials.append(_aligned_trial(state, measured, maneuver, rate=trials[0]["rate"] if trials else None))
        except ValueError as exc:
            raise ValueError(f"trial {name}: {exc}") from None
    return _stacked(state, trials)


def aligned_path(path, rig, workers=1, progress=None, clock_table=None):
    """The first step on the one recording at ``path`` (``load_recording``), at the baseline level, with the
    diagnosis's defaults: what a caller that weighs something else against the recording starts from."""
    table, maneuver, source = load_recording(path, rig=rig)
    state = DiagnosisState(measured=table, rig=rig, maneuver=maneuver, discretization="baseline",
                           candidate_names=None, workers=workers, seed=0, source=source, note=progress,
                           started=0.0, trial_names=None, held_out=())
    return align_recording(state, clock_table=clock_table)


def _stacked(state, trials):
    """Several aligned trials as one recording and one simulation context (``_trials``)."""
    first, names = trials[0], state.trial_names
    n = max(t["time"].size for t in trials)
    dt = 1.0 / first["rate"]
    time = first["time"][0] + dt * np.arange(n)
    channels, columns, c = [], [], 0
    for name, t in zip(names, trials):
        channels += [f"{name}{SEPARATOR}{ch}" for ch in t["channels"]]
        columns.append(np.arange(c, c + len(t["channels"])))
        c += len(t["channels"])
    values, nominal_sim = np.full((n, c), np.nan), np.empty((n, c))
    for t, cols in zip(trials, columns):
        rows = t["time"].size
        values[:rows, cols] = t["values"]
        nominal_sim[:rows, cols] = t["nominal_sim"]
        nominal_sim[rows:, cols] = t["nominal_sim"][-1]
    noise = np.concatenate([t["noise"] for t in trials])
    t_stops = np.concatenate([np.full(len(t["channels"]), t["t_stop"] - t["time"][0] + time[0]) for t in trials])
    # The windows where a mismatch is located are the first trial's phases, with the earliest stop.
    t_stop = float(t_stops.min())
    recording = Recording(
        time=time, channels=channels, values=values, noise=noise, rate_hz=first["rate"], t_stop=t_stop,
        stop_method=first["stop_method"], offset=first["offset"], alignment=first["alignment"],
        windows=time_windows(state.maneuver[0], t_stop, float(time[-1])), lowpass_width=first["lowpass_width"],
        scale=first["scale"],
        trials=[{"name": name, "channels": list(t["channels"]), "rows": int(t["time"].size),
                 "time_offset": t["offset"], "reels_stop": t["t_stop"], "reels_stop_method": t["stop_method"],
                 "reels_stop_stacked": float(t["t_stop"] - t["time"][0] + time[0]), "ropes": t["alignment"]["ropes"],
                 **({"start": t["alignment"]["start"]} if "start" in t["alignment"] else {})}
                for name, t in zip(names, trials)])
    # each trial's start read from its recording is that trial's to fit
    starts = tuple(p for name, t in zip(names, trials) if "start" in t["alignment"]
                   for p in start_parameters(t["ctx"]["maneuver"].start, t["alignment"]["start"], name))
    ctx = dict(first["ctx"], maneuver=tuple(t["ctx"]["maneuver"] for t in trials), channels=channels, time=time,
               parameters=each_trials_own(state.rig.tolerances, names) + starts,
               initial_state=tuple(t["nominal_run"].states[0] for t in trials),
               schedules=tuple(t["ctx"]["schedules"][0] for t in trials),
               trials=tuple({"name": name, "time": t["time"], "channels": t["channels"], "rows": t["time"].size,
                             "duration": t["ctx"]["duration"], "columns": cols}
                            for name, t, cols in zip(names, trials, columns)))
    problem = Problem(time, values, noise, t_stops, offset_free=free_offsets(channels, state.shared_frame))
    return replace(state, recording=recording, nominal_run=first["nominal_run"], nominal_sim=nominal_sim,
                   plain_problem=problem, nominal_ctx=ctx, problem=problem, ctx=ctx)


def _cut(schedule, records):
    """A run's step schedule (``SimulationResult.schedule``) for its first ``records`` record intervals (rounded)."""
    if schedule is None:
        return None
    n = int(round(records))
    return schedule[0][:n], schedule[1][:n]


def _aligned_trial(state, measured, maneuver, rate=None, clock_table=None):
    """One recording on the model's clock: its channels, noise, nominal run and simulation context.

    ``rate``: the rate (Hz) every trial is read at; a table sampled at another
    rate is resampled to it, from its own first sample. ``clock_table``:
    the table whose rope lengths give the clock (the nominal run's by
    default).
    """
    rig = state.rig
    check_table(measured, "measured table")
    channels = check_channels(measured, rig)
    t_meas = np.asarray(measured["time"], float)
    step = float(np.median(np.diff(t_meas)))
    if np.max(np.abs(np.diff(t_meas) - step)) > 0.01 * step:
        raise ValueError("the measured table's time is not uniformly sampled")
    if rate is not None and abs(step * rate - 1.0) > 1e-6:  # within 1 ppm: the same rate, rounded
        measured = _resampled(measured, rate)
        t_meas = np.asarray(measured["time"], float)
    else:
        rate = round(1.0 / step, 6)
    t0 = float(maneuver.time[0])

    # Long enough for any clock offset searched.
    record = float(t_meas[-1] - t_meas[0])
    _note(state, "simulating the nominal model")
    nominal_run = simulate(rig, maneuver, state.discretization, [], duration=record + MAX_OFFSET, rate_hz=rate)
    nominal_table = nominal_run.table
    clock = nominal_table if clock_table is None else clock_table
    offset, estimate, t_stop, stop_method = _clock(measured, clock, rig, maneuver)
    if rig.winches and not estimate.get("ropes"):
        _note(state, "the recording measures no rope length: its first sample is taken as the maneuver's "
                     "start (no clock offset is estimated)")
    t_al = t_meas - offset
    keep = (t_al >= t0 - 1e-9) & (t_al <= float(nominal_run.time[-1]) + 1e-9)
    time = t_al[keep]
    if time.size < 16:
        raise ValueError("the recording does not overlap the maneuver in time")
    if state.start_from_recording:
        maneuver, nominal_run, estimate = _started(state, measured, keep, time, maneuver, nominal_run, estimate,
                                                        rate)
        nominal_table = nominal_run.table
    if time[-1] - t_stop < MIN_DECAY_S:
        if rig.winches:
            raise ValueError(f"the recording ends {max(time[-1] - t_stop, 0.0):.2f} s after the maneuver stops; a "
                             f"diagnosis needs a free decay of at least {MIN_DECAY_S:g} s (more than one swing)")
        # A machine driven by a measured track to the end (a load under a flying drone) has no free
        # decay: the whole recording is judged as its forced response, on held-out blocks as ever.
        _note(state, "the maneuver's points move to the recording's end: no free decay, the forced response "
                     "is judged")
    values = np.column_stack([np.asarray(measured[c], float)[keep] for c in channels])
    scale = machine_scale(rig, maneuver)
    sigma = np.array([noise_level(values[:, j], channel_kind(c), scale) for j, c in enumerate(channels)])
    nominal_sim = np.column_stack([np.interp(time, nominal_run.time, np.asarray(nominal_table[c], float))
                                   for c in channels])
    # In a shared frame a still position is compared too: its level is the rig's geometry (no offset takes it).
    pinned = ~free_offsets(channels, state.shared_frame)
    moved = set(moving_channels(channels, nominal_sim, sigma))
    moving = [c for c, kept in zip(channels, pinned) if kept or c in moved]
    if len(moving) < len(channels):
        # C order, as column_stack gives: a strided copy sums in another order (last-bit differences).
        cols = [channels.index(c) for c in moving]
        channels, values, sigma, nominal_sim = (moving, np.ascontiguousarray(values[:, cols]), sigma[cols],
                                                np.ascontiguousarray(nominal_sim[:, cols]))
    duration = float(time[-1] - t0) + 1.0 / rate
    dt = float(time[1] - time[0])
    ctx = {"rig": rig, "maneuver": maneuver, "discretization": state.discretization, "duration": duration,
           "rate_hz": rate, "initial_state": nominal_run.states[0], "time": time, "channels": channels,
           "nominal_dt": float(nominal_run.dt), "schedules": (_cut(nominal_run.schedule, duration * rate),),
           "parameters": tuple(rig.tolerances) + (start_parameters(maneuver.start, estimate["start"])
                                                  if "start" in estimate else ()),
           # The recording was reconstructed with this rig's geometry (``channels_on``).
           "reported_rig": rig, "scale": scale}
    return {"time": time, "channels": channels, "values": values, "noise": sigma, "rate": rate, "t_stop": t_stop,
            "stop_method": stop_method, "offset": offset, "alignment": estimate, "scale": scale,
            "windows": time_windows(maneuver, t_stop, float(time[-1])),
            "lowpass_width": scale.lowpass_width(LOWPASS_S, dt), "nominal_run": nominal_run,
            "nominal_sim": nominal_sim, "ctx": ctx}


def _resampled(measured, rate):
    """A uniformly sampled table at ``rate`` (Hz) from its own first sample, each column interpolated linearly."""
    t = np.asarray(measured["time"], float)
    new = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * rate + 1e-9)) + 1) / rate
    out = {"time": new}
    for c in measured.columns:
        if c != "time":
            out[c] = np.interp(new, t, np.asarray(measured[c], float), left=np.nan, right=np.nan)
    return measured.__class__(out)


def _started(state, measured, keep, time, maneuver, nominal_run, estimate, rate):
    """The trial started where its first samples have the tracked bodies (``_start``): the maneuver with its
    ``start``, the nominal run from it, and the alignment's entry saying what the start was read from."""
    t0 = float(maneuver.time[0])
    if time[0] - t0 > 0.5 / rate:
        raise ValueError(f"the recording starts {time[0] - t0:.3f} s after the maneuver; a start read from the "
                         "recording needs its first sample at the maneuver's start")
    columns = {c: np.asarray(measured[c], float)[keep] for c in measured.columns if c != "time"}
    start, report = estimate_start(time, columns, nominal_run, rate)
    if not start:
        raise ValueError("a start read from the recording needs a tracked body (its x, y and z)")
    _note(state, "the trial starts where its first samples have " + ", ".join(start))
    maneuver = replace(maneuver, start=start)
    run = simulate(state.rig, maneuver, state.discretization, [], duration=float(nominal_run.time[-1] - t0),
                   rate_hz=rate)
    return maneuver, run, dict(estimate, start=report)


def _clock(measured, nominal_table, rig, maneuver):
    """The recording's clock offset (recording minus model, s), its estimate, and when the maneuver stops.

    A rig with winches: the offset from the recorded rope lengths against
    the model's, which must follow the maneuver (``check_maneuver``), the
    stop from the winches. Without winches, or without a rope length the
    recording measured (a crane's vertical hoist rope, which the markers'
    plane fit cannot measure): the recording starts with the maneuver (a
    release, or a point's measured track that starts the recording), and the
    maneuver stops when its last winch or point does; the JSON says so.
    """
    t0 = float(maneuver.time[0])
    if not rig.winches or not measured_rope_channels(measured, rig):
        why = "the rig has no winch" if not rig.winches else "the recording measures no rope length"
        offset = float(np.asarray(measured["time"], float)[0]) - t0
        estimate = {"offset": offset, "estimated": True, "ropes": {},
                    "method": f"the recording's first sample is the maneuver's start ({why})"}
        return offset, estimate, maneuver_stop_time(maneuver), f"the maneuver table's last change ({why})"
    estimate = align_with_maneuver(measured, nominal_table, rig)
    check_maneuver(measured, estimate, rig, rope_bias_allowance(rig, nominal_table))
    offset = float(estimate["offset"])
    t_stop, stop_method = reels_stop_time(measured, nominal_table, offset)
    if t_stop is None:
        raise ValueError("cannot tell when the reels stop; the free decay cannot be found")
    return offset, estimate, t_stop, stop_method
