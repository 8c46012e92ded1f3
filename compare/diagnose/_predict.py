"""Trials the fit never saw, predicted by the nominal, the updated and the named model.

A diagnosis fitted on some trials of a machine predicts the others
(``predict_held_out``): each held-out trial is aligned as any recording is,
then simulated with the nominal rig, with the rig as the fit updated it, and
with that rig and the named mechanism (the joint refit's, where there was
one). Only each channel's constant offset is fitted on the held-out trial
(its own calibration origin; none on the positions of a tracker that shares
the model's frame): everything else is prediction. The residual is
reported in noise units (1 = the trial's own noise) and per channel in SI.

A trial with parameters of its own (``RigParameter.of_a_trial``: a start
read from its first samples, its anchor tracks' offsets) has them fitted,
for each model, on its *conditioning window* alone - one period of the
slowest motion the recording resolves, the window its start is read over -
and is scored after it: its own nuisance is the trial's, as its offsets
are, but fitting it on the samples being predicted would credit every
model with what that fit absorbs. The shared parameters stay the fit's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ...simulate import SimulationError, StaticsError, apply_parameters, make_mechanism, simulate
from ._hypotheses import channels_on
from ._recording import free_offsets

__all__ = ["held_out_entry", "HeldOut"]


def _models(state):
    """``(label, rig, coords or None, physics)`` of each model that predicts: nominal, updated, named."""
    models = [("nominal", state.rig, None, [])]
    update = state.update
    if update is not None:
        models.append(("updated", update["rig"], update["coords"], []))
    verdict = state.verdict
    if verdict in state.scored:
        if verdict in state.joints:
            joint = state.joints[verdict]
            models.append(("named", joint["rig"], joint["coords"], [joint["mechanism"]]))
        else:
            main = next(h["main_parameter"] for h in state.hypotheses if h["name"] == verdict)
            mechanism = make_mechanism(verdict, **{main: float(state.scored[verdict]["value"])})
            rig, coords = (update["rig"], update["coords"]) if update is not None else (state.rig, None)
            models.append(("named", rig, coords, [mechanism]))
    return models


# Fitting a trial's own parameters on its conditioning window: Jacobians at most (each one simulation per
# parameter, of the window alone).
CONDITION_JACOBIANS = 6


def own_parameters(aligned):
    """The held-out trial's own parameters: its read start's and the rig's per-trial ones (a track's offset)."""
    return tuple(p for p in aligned["ctx"]["parameters"] if p.of_a_trial)


def conditioning_window(aligned):
    """How long (s) a trial's own parameters are fitted from its start: the window its start was read over
    (one period of the slowest resolved motion), else a tenth of the trial; 0 without parameters of its own."""
    if not own_parameters(aligned):
        return 0.0
    start = aligned["alignment"].get("start") or {}
    windows = [entry["window_s"] for entry in start.values() if "window_s" in entry]
    ctx = aligned["ctx"]
    return float(max(windows)) if windows else 0.1 * float(ctx["duration"])


def _conditioned(aligned, window, rig, maneuver, physics, discretization, offset_free, statics_guess):
    """``(rig, maneuver)`` with the trial's own parameters fitted on its first ``window`` s (its conditioning
    window: least squares in noise units, each parameter's tolerance as its prior), for one model."""
    own = own_parameters(aligned)
    ctx = aligned["ctx"]
    time = np.asarray(aligned["time"], float)
    rows = time <= time[0] + window
    measured, noise = aligned["values"][rows], aligned["noise"]
    short = dict(ctx, time=time[rows])
    tol = np.array([p.tolerance for p in own])

    def residual(z):
        r, m = apply_parameters(rig, maneuver, own, z * tol)
        try:
            run = simulate(r, m, discretization, physics, duration=window + 2.0 / ctx["rate_hz"],
                           rate_hz=ctx["rate_hz"], statics_guess=statics_guess)
        except (SimulationError, StaticsError, FloatingPointError):
            return np.full(measured.size + z.size, 1e6)
        e = measured - channels_on(run, short)
        e = e - np.where(offset_free, np.nanmean(e, axis=0), 0.0)
        return np.r_[np.nan_to_num(e / noise).ravel(), z]

    fit = least_squares(residual, np.zeros(len(own)), max_nfev=CONDITION_JACOBIANS, diff_step=1e-3)
    return apply_parameters(rig, maneuver, own, fit.x * tol)


def _residual_rms(measured, sim, noise, offset_free):
    """RMS residual in noise units over every measured sample, and per channel (SI), each channel's mean removed
    where its offset is free (``_recording.free_offsets``)."""
    r = measured - sim
    r = r - np.where(offset_free, np.nanmean(r, axis=0), 0.0)
    z = r / noise
    return float(np.sqrt(np.nanmean(z * z))), [float(np.sqrt(np.nanmean(r[:, j] ** 2))) for j in range(r.shape[1])]


def held_out_entry(state, name, aligned, maneuver):
    """The held-out trial ``name`` (``aligned``: its recording on the model's clock) predicted by every model.

    Returns
    -------
    entry : dict
        ``trial``, ``rows``, ``channels``, ``rms_noise`` (model -> RMS
        residual in the trial's noise units, None where the simulation
        failed), ``rms_channels`` (channel -> model -> RMS, SI), ``named``
        (the mechanism, or None).
    series : HeldOut
        What the report draws.
    """
    ctx = aligned["ctx"]
    # the fit's shared parameters: a fitted trial's own (its start, its tracks' offsets) are not this trial's
    shared = [k for k, p in enumerate(state.ctx["parameters"]) if not p.of_a_trial]
    params = [state.ctx["parameters"][k] for k in shared]
    rms, per_channel, sims = {}, {}, {}
    named = None
    offset_free = free_offsets(aligned["channels"], state.shared_frame)
    window = conditioning_window(aligned)
    scored = np.asarray(aligned["time"], float) > aligned["time"][0] + window if window > 0 else slice(None)
    guess = aligned["nominal_run"].states[0]
    for label, rig, coords, physics in _models(state):
        man = maneuver if coords is None else apply_parameters(state.rig, maneuver, params,
                                                               np.asarray(coords)[shared])[1]
        if label == "named":
            named = physics[0].name
        try:
            if window > 0:
                rig, man = _conditioned(aligned, window, rig, man, physics, state.discretization, offset_free, guess)
            run = simulate(rig, man, state.discretization, physics, duration=ctx["duration"], rate_hz=ctx["rate_hz"],
                           statics_guess=guess)
        except (SimulationError, StaticsError, FloatingPointError):
            rms[label] = None
            continue
        sims[label] = channels_on(run, ctx)
        rms[label], per_channel[label] = _residual_rms(aligned["values"][scored], sims[label][scored],
                                                       aligned["noise"], offset_free)
    series = HeldOut(name=name, time=aligned["time"], channels=list(aligned["channels"]),
                     measured=aligned["values"], predicted=sims, named=named)
    return {"trial": name, "rows": int(aligned["time"].size), "channels": list(aligned["channels"]),
            "conditioning_s": window,
            "rms_noise": rms, "named": named,
            "rms_channels": {ch: {label: values[j] for label, values in per_channel.items()}
                             for j, ch in enumerate(aligned["channels"])},
            "better_than_nominal": {label: (value is not None and rms.get("nominal") is not None
                                            and value < rms["nominal"])
                                    for label, value in rms.items() if label != "nominal"}}, series


@dataclass(frozen=True)
class HeldOut:
    """A held-out trial and its predictions, as the report draws them.

    ``time`` (n,) s on the model's clock; ``measured`` (n, c) SI, NaN where
    not measured; ``predicted``: model label (``nominal``, ``updated``,
    ``named``) -> (n, c), each as simulated (offsets not removed); ``named``:
    the mechanism's name, or None.
    """

    name: str
    time: np.ndarray
    channels: list
    measured: np.ndarray
    predicted: dict
    named: str | None

