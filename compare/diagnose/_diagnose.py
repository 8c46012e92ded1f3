"""``dragline diagnose``: what physics does the nominal model leave out?

``diagnose`` runs the steps of ``_steps.STEPS`` over one ``DiagnosisState``
(``_state``): the recording aligned with the maneuver, where the nominal
model misses, the model's own error and the rig updated within its
tolerances, each candidate mechanism fitted and scored on held-out data,
the verdict by the rules of ``_decide``, and a second mechanism on top of a
named one; ``docs/diagnosis.md`` states the method. The document and the
series the report draws are then read off the final state.

Only the motion is read: from a session, the calibration takes and the
trial's centroids (``capture.mcap``) and the reel table; nothing else the
directory holds is opened (``_recording``). Bad input (a different rig's
markers, a reel table that the recorded rope lengths do not follow, a
recording without a free decay) raises ``ValueError`` with one line.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...capture import json_ready, write_json
from ...simulate import SimulationError, StaticsError, default_maneuver, load_rig
from .._executor import as_executor
from .._machine_figure import picture_at
from ._band import RESOLVED_HZ, RESOLVED_MIN
from ._decide import MODEL_ERROR_FULL, MODEL_ERROR_SHARE
from ._null import MIN_IMPROVEMENT, NULL_QUANTILE, NULL_SURROGATES
from ._problem import BLOCK_S, DECAY_WEIGHT
from ._leave_one_out import leave_one_out as _leave_one_out
from ._locate import LOWPASS_S, structure_threshold
from ._recording import load_recording
from ._state import DiagnosisState
from ._steps import STEPS, hypotheses_simulations
from ._trials import SEPARATOR, split_channel
from ._summary import before_after_metrics, calibration_doc, free_decay_section, report_channels

__all__ = ["Diagnosis", "diagnose", "diagnose_path", "draw_held_out", "load_recording", "write_diagnosis_json",
           "write_diagnosis_report"]

SCHEMA = "dragline.diagnosis/1"
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
    overlay_channels : list of str
        The channels the report draws measured against the models.
    machine : MachinePicture or None
        The nominal rig at the nominal run's start, drawn on the report's first page.
    held_out : list of HeldOut
        The trials the fit never saw, with each model's prediction (``_predict``).
    """

    doc: dict
    time: np.ndarray
    channels: list
    measured: np.ndarray
    nominal: np.ndarray
    updated: np.ndarray | None = None
    fitted: dict = field(default_factory=dict)
    located: dict = field(default_factory=dict)
    overlay_channels: list = field(default_factory=list)
    machine: object = None
    held_out: list = field(default_factory=list)



def diagnose(measured, maneuver=None, rig=None, discretization="baseline", candidates=None, workers=2,
             seed=0, source=None, progress=None, trial_names=None, held_out=(), leave_one_out=False,
             shared_frame=False, start_from_recording=False):
    """Diagnose a measured trajectory table against the nominal model.

    Parameters
    ----------
    measured : pandas.DataFrame or list of them
        Measured trajectory table (docs/conventions.md), any clock: aligned to the
        simulation from the rope lengths. A list: several trials of the
        machine, fitted together (``_trials``): the rig's parameters and a
        mechanism's are shared, each trial keeps its own offsets and clock.
    maneuver : Maneuver or list of them, optional
        The maneuver of the recording (the rig's own by default: the dig for
        the built-in rig); one per trial for several.
    trial_names : sequence of str, optional
        The trials' names (``trial 1``, ... by default); no name may hold "/".
    held_out : sequence of (str, DataFrame, Maneuver)
        Trials the fit never sees, predicted at the end by the nominal, the
        updated and the named model (the document's ``held_out``).
    leave_one_out : bool
        With several trials: each in turn left out, the others diagnosed
        together and it predicted (``_leave_one_out``; the document's
        ``leave_one_out``), after the diagnosis of them all.
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
    shared_frame : bool
        The recording's positions are measured in the frame the rig is
        driven in (a tracker's body beside the points it moves: the
        mapping's ``shared_frame``): no free constant offset on them, in the
        fit or in a held-out trial's prediction (``free_offsets``).
    start_from_recording : bool
        Each trial (a held-out one too) starts where its first samples have
        the tracked bodies, moving as they move there (``_start``): a
        recording cut from the middle of a motion. Else the maneuver's or
        the rig's own start (its statics, or its release).

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
    rig = load_rig() if rig is None else rig
    measured, maneuver, trial_names = _trials_of(measured, maneuver, rig, trial_names)
    held_out = tuple((str(name), table, default_maneuver(rig) if man is None else man)
                     for name, table, man in held_out)
    if leave_one_out and trial_names is None:
        raise ValueError("leaving one trial out needs several trials")
    state = DiagnosisState(measured=measured, rig=rig, maneuver=maneuver, discretization=discretization,
                           candidate_names=candidates, workers=workers, seed=seed, source=source, note=progress,
                           started=_time.perf_counter(), trial_names=trial_names, held_out=held_out,
                           shared_frame=bool(shared_frame), start_from_recording=bool(start_from_recording))
    for step in STEPS:
        state = step(state)
    result = diagnosis_of(state)
    if leave_one_out:
        split = _leave_one_out(measured, maneuver, list(trial_names), progress=progress, rig=rig,
                               discretization=discretization, candidates=candidates, workers=workers, seed=seed,
                               shared_frame=shared_frame, start_from_recording=start_from_recording)
        result.doc["leave_one_out"] = json_ready(split)
        result.doc["timing"]["seconds"] = _time.perf_counter() - state.started
    return result


def _trials_of(measured, maneuver, rig, names):
    """``(measured, maneuver, trial names or None)``: one recording as itself, several as lists."""
    if not isinstance(measured, (list, tuple)):
        return measured, default_maneuver(rig) if maneuver is None else maneuver, None
    n = len(measured)
    maneuvers = list(maneuver) if isinstance(maneuver, (list, tuple)) else [maneuver] * n
    names = [f"trial {k + 1}" for k in range(n)] if names is None else [str(x) for x in names]
    if n == 0 or len(maneuvers) != n or len(names) != n:
        raise ValueError(f"{n} trials need as many maneuvers and names ({len(maneuvers)} and {len(names)} given)")
    if len(set(names)) < n or any(SEPARATOR in x for x in names):
        raise ValueError(f"trial names must be distinct and hold no {SEPARATOR!r}: {names}")
    maneuvers = [default_maneuver(rig) if m is None else m for m in maneuvers]
    if n == 1:
        return measured[0], maneuvers[0], None
    return list(measured), maneuvers, tuple(names)


def _trial_sections(rec, channels, measured, nominal, fitted, shown, updated, decay_channels):
    """The free decay and the metrics, each trial over its own stop (one recording: over its stop)."""
    if not rec.trials:
        return (free_decay_section(rec.time, channels, measured, nominal, fitted, shown, rec.t_stop, updated=updated,
                                   decay_channels=decay_channels),
                before_after_metrics(rec.time, channels, measured, nominal, fitted, shown, rec.t_stop))
    decay, metrics = None, None
    for trial in rec.trials:
        cols = [j for j, c in enumerate(channels) if split_channel(c)[0] == trial["name"]]
        rows = slice(0, trial["rows"])

        def part(a):
            return None if a is None else a[rows][:, cols]

        names = [channels[j] for j in cols]
        stop = trial["reels_stop_stacked"]
        d = free_decay_section(rec.time[rows], names, part(measured), part(nominal), part(fitted), shown, stop,
                               updated=part(updated), decay_channels=[c for c in decay_channels if c in names])
        m = before_after_metrics(rec.time[rows], names, part(measured), part(nominal), part(fitted), shown, stop)
        if decay is None:
            decay, metrics = d, m
        else:
            decay["channels"].update(d["channels"])
            metrics["channels"].update(m["channels"])
    return decay, metrics


def diagnosis_of(state):
    """The ``Diagnosis`` (document and series) of a state every step has run on."""
    rec, update, null = state.recording, state.update, state.null
    time, channels, measured = rec.time, rec.channels, rec.values
    nominal, r0 = measured - state.r_nominal, state.r_base
    shown = state.verdict if state.verdict in state.fitted_series else state.after_name
    fitted = state.fitted_series.get(shown)
    updated = measured - r0 if update is not None else None
    second = state.second
    b0, shift0, _ = state.nominal_nuisance
    discretization = state.discretization
    decay, metrics = _trial_sections(rec, channels, measured, nominal, fitted, shown, updated,
                                     report_channels(state.rig, channels, "decay_channels"))
    doc = {
        "schema": SCHEMA,
        "verdict": state.verdict,
        "reason": state.reason,
        "alike_laws": list(state.alike_laws),
        "mismatch": [e for e in state.located_nominal if e["significant"]][:MAX_MISMATCH_ENTRIES],
        "mismatch_updated": state.structured_before[:MAX_MISMATCH_ENTRIES],
        "calibration": calibration_doc(update, state.joints, state.nominal_ctx, state.after_name),
        "model_error": state.model_error_block,
        "mismatch_after": {"model": state.after_name or ("updated" if update else "nominal"),
                           "entries": state.structured_after[:MAX_MISMATCH_ENTRIES]},
        "offsets_beyond_tolerance": list(state.too_far),
        "offsets_judged": state.offsets_judged,
        "hypotheses": state.hypotheses,
        "second_mechanism": second,
        "updated_again": state.superseded,
        "skipped": state.skipped,
        "sites": state.site_groups,
        "site_screen": state.site_screen,
        "site_split": state.site_split,
        "free_decay": decay,
        "metrics": metrics,
        "null_test": {"threshold": null.threshold, "noise_threshold": null.noise_threshold,
                      "surrogate_quantile": null.surrogate_quantile, "quantile": NULL_QUANTILE,
                      "n_surrogates": NULL_SURROGATES, "min_improvement": MIN_IMPROVEMENT,
                      "dispersion_kappa": null.kappa, "model_error_allowance": null.allowance,
                      "own_error_chi2": null.own_error,
                      "excess_chi2_updated": null.excess, "model_error_share": null.share,
                      "model_error_share_at_full": MODEL_ERROR_SHARE, "model_error_full": MODEL_ERROR_FULL,
                      "n_weighted": null.n_weighted},
        "channels": {c: {"noise": float(rec.noise[j]), "offset": state.offsets[c], "offset_nominal": float(b0[j]),
                         "offset_free": bool(state.problem.offset_free[j]),
                         "structure_threshold": structure_threshold(c, rec.noise[j], rec.lowpass_width,
                                                                    rec.scale)}
                     for j, c in enumerate(channels)},
        "windows": [{"window": w, "t_start": a, "t_end": b} for w, a, b in rec.windows],
        "alignment": {"time_offset": rec.offset, "time_shift_nominal": float(shift0),
                      "ropes": rec.alignment["ropes"], "reels_stop": float(rec.t_stop),
                      "reels_stop_method": rec.stop_method,
                      **({"start": rec.alignment["start"]} if "start" in rec.alignment else {})},
        "trials": rec.trials,
        "held_out": state.predictions,
        "source": state.source or {},
        "settings": {"discretization": discretization if isinstance(discretization, str) else dict(discretization),
                     "candidates": [c["name"] for c in state.candidates], "decay_weight": DECAY_WEIGHT,
                     "shared_frame": state.shared_frame, "start_from_recording": state.start_from_recording,
                     "block_s": BLOCK_S, "lowpass_s": LOWPASS_S * rec.scale.time, "rate_hz": rec.rate_hz,
                     "machine_scale": {"swing_hz": rec.scale.swing_hz, "length": rec.scale.length,
                                       "time": rec.scale.time},
                     "resolved_hz": RESOLVED_HZ, "resolved_min": RESOLVED_MIN},
        "executor": as_executor(state.workers).describe(),
        "timing": {"seconds": _time.perf_counter() - state.started,
                   "simulations": 1 + hypotheses_simulations(state.hypotheses)
                   + (second["n_simulations"] if second else 0) + state.model_error_sims
                   + (update["n_simulations"] if update else 0)
                   + (state.superseded["n_simulations"] if state.superseded else 0)},
    }
    return Diagnosis(doc=json_ready(doc), time=time, channels=channels, measured=measured, nominal=nominal,
                     updated=updated, fitted=dict(state.fitted_series),
                     located={"before": json_ready(state.located), "after": json_ready(state.located_after)},
                     overlay_channels=report_channels(state.rig, channels, "overlay_channels"),
                     machine=picture_at(state.nominal_run.model, state.nominal_run.states[0],
                                        float(state.nominal_run.time[0])),
                     held_out=list(state.predicted_series))


def diagnose_path(path, maneuver=None, rig=None, calibration=None, discretization="baseline", candidates=None,
                  workers=2, seed=0, progress=None, between=None, mapping=None, held_out=(), leave_one_out=False,
                  start_from_recording=False):
    """:func:`load_recording` then :func:`diagnose`: what ``dragline diagnose`` runs.

    ``path`` may be a list: several trials of the machine, fitted together;
    ``held_out`` lists recordings the fit never sees, predicted at the end;
    ``leave_one_out`` leaves each of several in turn out (``diagnose``).
    Each is read as ``path`` is (same maneuver option, calibration, cut and
    mapping); a trial's name is its file's stem.
    """
    started = _time.perf_counter()
    rig = load_rig() if rig is None else rig
    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    names = trial_names_of([*paths, *held_out])
    loaded_all = [load_recording(p, maneuver, rig, calibration, progress, between, mapping)
                  for p in [*paths, *held_out]]
    fitted, predicted = loaded_all[:len(paths)], loaded_all[len(paths):]
    loaded = _time.perf_counter() - started
    by_name = dict(zip(names, [*paths, *held_out]))
    if len(paths) == 1:
        table, man, source = fitted[0]
        args = (table, man)
    else:
        source = {"trials": [{"trial": name, **src} for name, (_, _, src) in zip(names, fitted)]}
        args = ([t for t, _, _ in fitted], [m for _, m, _ in fitted])
    spare = [(name, t, m) for name, (t, m, _) in zip(names[len(paths):], predicted)]
    try:
        result = diagnose(*args, rig, discretization, candidates, workers, seed, source, progress,
                          trial_names=names[:len(paths)] if len(paths) > 1 else None, held_out=spare,
                          leave_one_out=leave_one_out, start_from_recording=start_from_recording,
                          shared_frame=any(src.get("tracked", {}).get("shared_frame", False)
                                           for _, _, src in loaded_all))
    except (StaticsError, SimulationError):
        raise  # about the rig or the maneuver, not the recording
    except ValueError as exc:
        message = str(exc)
        for name, p in by_name.items():
            for lead in (f"trial {name}: ", f"held-out trial {name}: "):
                if message.startswith(lead):
                    raise ValueError(f"{p}: {message[len(lead):]}") from None
        if any(str(p) in message for p in by_name.values()):
            raise
        raise ValueError(f"{paths[0] if len(paths) == 1 else ', '.join(map(str, paths))}: {message}") from None
    result.doc["timing"]["load_seconds"] = loaded
    result.doc["timing"]["total_seconds"] = _time.perf_counter() - started
    return result


def trial_names_of(paths):
    """A distinct name per recording: its file's stem, with its folder's name where stems repeat."""
    stems = [Path(p).stem for p in paths]
    if len(set(stems)) < len(stems):
        stems = [f"{Path(p).resolve().parent.name}-{Path(p).stem}" for p in paths]
    if len(set(stems)) < len(stems):
        stems = [f"{k + 1}-{s}" for k, s in enumerate(stems)]
    return [s.replace(SEPARATOR, "-") for s in stems]


def write_diagnosis_json(path, doc):
    """Write the diagnosis JSON atomically (strict JSON, no NaN)."""
    write_json(path, doc)


def draw_held_out(fig, held, entry):
    """Draw a held-out trial (``Diagnosis.held_out[k]``, its JSON entry ``doc["held_out"][k]``) against each model's
    prediction on a matplotlib ``Figure``: the report's page, for a figure of one's own."""
    from ._report import draw_held_out as draw

    draw(fig, held, entry)


def write_diagnosis_report(path, diagnosis):
    """Write the diagnosis PDF (see ``_diagnose_report``)."""
    from ._report import write_report_pdf

    write_report_pdf(path, diagnosis)
