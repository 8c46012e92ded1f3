"""A trial that begins mid-motion: its start read from its first samples.

A recording cut from a longer flight (a box already turning under its
drones) does not begin at rest, and a model started from its statics
misses the whole swing. ``estimate_start`` reads where each tracked body is
and how it moves at the trial's first instant, as the maneuver's ``start``:

- the coordinates the recording resolves (the body's modes below its
  Nyquist frequency: sway, turn) start where the recording has them, as a
  displacement from the rig's rest pose (``about_rest``): the recording's
  value read with the constant that makes its mean the rest-started
  model's, so a rig whose geometry is a few centimetres off (or updated)
  swings about its own rest pose, not towards the recording's;
- the coordinates it cannot resolve (the stiff modes on the ropes'
  stretch, ``unresolved_coordinates``) are settled by the ropes from there,
  at rest: a height or tilt read from the recording would stretch a cable
  by its error and start a jolt no recording saw;
- each value and rate is that of one damped sinusoid and a constant
  (``matrix_pencil``, five numbers) fitted to the samples within one period
  of the body's slowest resolved mode from the start: near its start each
  channel is ruled by one swing, and on a 10 Hz track of a 1 Hz turn the
  rate at the first sample is then within 2-4 % where a cubic over half a
  period was 26 % off (its slope at the window's end; tests).
A body whose attitude is not tracked starts at the rest pose's attitude,
not turning; a body whose position is not tracked is not held at all.
What is read is a first guess: ``start_parameters`` makes each resolved
coordinate's displacement and rate a parameter of the trial, fitted with
the rig.
"""

from __future__ import annotations

import math

import numpy as np

from .._decay import matrix_pencil
from ...simulate import (
    RigParameter,
    angles_from_matrix,
    body_frequencies,
    body_rates_from_euler_rates,
    body_to_inertial,
    euler_from_matrix,
    matrix_from_angles,
    unresolved_coordinates,
)

__all__ = ["estimate_start", "start_parameters"]

# The matrix pencil's least (``_decay.matrix_pencil``); below it a cubic, with a degree of freedom for the noise.
MIN_SAMPLES = 8
CUBIC_SAMPLES = 5
# The difference over which an attitude's rate is turned into body rates (s): far below any period.
_RATE_STEP_S = 1e-6


def estimate_start(time, measured, nominal_run, rate_hz):
    """The maneuver's ``start`` for the bodies a recording tracks (``Maneuver.start``), and what it was read from.

    Parameters
    ----------
    time : ndarray (n,)
        The recording's samples on the model's clock (s), from the maneuver's start.
    measured : mapping
        Channel -> values (n,) SI: a trajectory table's columns at ``time``.
    nominal_run : SimulationResult
        The model started at rest (its ``states[0]`` the rest pose), recorded over ``time``.
    rate_hz : float
        The recording's rate.

    Returns
    -------
    start : dict
        Body -> ``position``, ``angles`` (displacements from the rest pose),
        ``velocity`` (m/s), ``rates`` (rad/s, body axes), ``settled``,
        ``about_rest``.
    report : dict
        Body -> ``window_s``, ``samples``, ``settled`` and the start in SI
        and degrees, for the JSON.

    Raises
    ------
    ValueError
        When the first samples cannot give a start (too few, or missing).
    """
    model, t0 = nominal_run.model, float(nominal_run.time[0])
    rest = nominal_run.states[0]
    frequencies = body_frequencies(model, rest, t0)
    settled = unresolved_coordinates(model, rest, t0, rate_hz, frequencies)
    modes = frequencies[0]
    table = nominal_run.table
    start, report = {}, {}
    for b, body in enumerate(model.body_names):
        if not all(f"{body}.{q}" in measured for q in "xyz"):
            continue
        resolved = modes[b][(modes[b] > 0) & (modes[b] <= 0.5 * rate_hz)]
        window = 1.0 / float(resolved.min()) if resolved.size else MIN_SAMPLES / rate_hz
        near = np.flatnonzero(np.asarray(time, float) <= t0 + max(window, (MIN_SAMPLES - 0.5) / rate_hz))
        angles_tracked = all(f"{body}.{q}" in measured for q in ("roll", "pitch", "yaw"))
        quantities = ("x", "y", "z", "roll", "pitch", "yaw") if angles_tracked else ("x", "y", "z")
        value, rate, scale = [], [], []
        for q in quantities:
            column = np.asarray(measured[f"{body}.{q}"], float)
            if q in ("roll", "pitch", "yaw"):
                column = np.unwrap(column)
            at, slope = _at_start(time[near] - t0, column[near], f"{body}.{q}")
            sim = np.interp(time, nominal_run.time, np.asarray(table[f"{body}.{q}"], float))
            if q in ("roll", "pitch", "yaw"):
                sim = np.unwrap(sim)
            # The recording's value read with the constant that makes its mean the rest-started model's.
            value.append(at - np.nanmean(column) + np.nanmean(sim) - sim[0])
            rate.append(slope)
            scale.append(_motion_scale(column[near], rate_hz))
        value, rate = np.array(value), np.array(rate)
        keep = settled[body]
        velocity = np.where([q in keep for q in "xyz"], 0.0, rate[:3])
        rates = np.zeros(3)
        angles = np.zeros(3)
        if angles_tracked:
            sequence = model.rig.bodies[body].euler_sequence
            at_rest = np.array(angles_from_matrix(body_to_inertial(*rest[12 * b + 6: 12 * b + 9]), sequence))
            angles = value[3:]
            rates = _body_rates(at_rest + angles, rate[3:], sequence, keep)
        start[body] = {"position": value[:3], "angles": angles, "velocity": velocity, "rates": rates,
                       "settled": keep, "about_rest": True}
        report[body] = {"window_s": window, "samples": int(near.size), "settled": list(keep),
                        "scales": dict(zip(quantities, scale)),
                        "displacement": value[:3], "angles_deg": np.degrees(angles), "velocity": velocity,
                        "rates_deg": np.degrees(rates)}
    return start, report


def start_parameters(start, report, trial=None):
    """Each resolved coordinate of a read ``start`` as a parameter the updating fits with the rig
    (``RigParameter``, kind ``start``): its displacement and its rate, nominal where it was read.

    Its tolerance is the motion's own size over the window it was read in
    (the channel's spread about its mean; its rate's RMS): a start is
    known to within that before any fit, and the fit decides. The turn's
    rate is the body rate about the same axis (r for yaw), as near a level
    pose.
    """
    out = []
    prefix = "start." + (f"{trial}." if trial is not None else "")
    for body, pose in start.items():
        scales = report[body]["scales"]
        for k, q in enumerate(("x", "y", "z", "roll", "pitch", "yaw")):
            if q in pose["settled"] or q not in scales:
                continue
            place, speed = scales[q]
            angle = k >= 3
            key, moving, j = ("angles", "rates", k - 3) if angle else ("position", "velocity", k)
            # a channel that did not move at all (no noise either) is known where it was read: not fitted
            if place > 0:
                out.append(RigParameter(f"{prefix}{body}.{q}", "start", (body,), f"{key}.{j}", float(pose[key][j]),
                                        "linear", place, "rad" if angle else "m", trial))
            if speed > 0:
                out.append(RigParameter(f"{prefix}{body}.{q}_rate", "start", (body,), f"{moving}.{j}",
                                        float(pose[moving][j]), "linear", speed, "rad/s" if angle else "m/s", trial))
    return tuple(out)


def _motion_scale(values, rate_hz):
    """The size of a channel's motion over a window: (its spread about its mean, its rate's RMS)."""
    v = values[np.isfinite(values)]
    spread = float(np.sqrt(np.mean((v - v.mean()) ** 2)))
    speed = float(np.sqrt(np.mean(np.diff(v) ** 2))) * rate_hz
    return spread, speed


def _at_start(t, values, channel):
    """The value and rate at t = 0 of one damped sinusoid and a constant fitted to ``values`` at ``t`` (s) from 0;
    of a cubic where a sample is missing or there are too few for the pencil."""
    ok = np.isfinite(values)
    if ok.all() and ok.size >= MIN_SAMPLES:
        modes = matrix_pencil(values, float(t[1] - t[0]), n_modes=1, offset=True)
        if modes:
            value = sum(m["amplitude"] * math.cos(m["phase"]) for m in modes)
            rate = sum(-m["amplitude"] * (m["decay_rate"] * math.cos(m["phase"])
                                          + 2 * math.pi * m["frequency_hz"] * math.sin(m["phase"])) for m in modes)
            return float(value), float(rate)
    if ok.sum() < CUBIC_SAMPLES:
        raise ValueError(f"its first samples cannot start the trial: {channel} has {int(ok.sum())} measured "
                         f"samples at the start where a start needs {CUBIC_SAMPLES}")
    c = np.polynomial.polynomial.polyfit(t[ok], values[ok], 3)
    return float(c[0]), float(c[1])


def _body_rates(angles, angle_rates, sequence, settled):
    """Body-axis rates (rad/s) of a body turning at ``angle_rates`` through ``angles`` (its output ``sequence``),
    with Eq. 11's rates of its ``settled`` angles taken out (those modes start at rest)."""
    now = np.array(euler_from_matrix(matrix_from_angles(*angles, sequence)))
    later = np.array(euler_from_matrix(matrix_from_angles(*(angles + _RATE_STEP_S * angle_rates), sequence)))
    turning = np.angle(np.exp(1j * (later - now))) / _RATE_STEP_S
    for k, q in enumerate(("roll", "pitch", "yaw")):
        if q in settled:
            turning[k] = 0.0
    return np.array(body_rates_from_euler_rates(now[0], now[2], *turning), float)
