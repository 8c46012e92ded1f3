"""``dragline bench discovery``: does the diagnosis find physics it cannot see directly?

Blind cases, as ``dragline synth`` makes them: the dig maneuver simulated
with one hidden mechanism (each at magnitudes from barely detectable to
strong) or none at all, filmed by the lab's six cameras with the default
noise, dropouts, ghosts, occlusion and lens distortion, and written as a
session directory (``capture.mcap`` with the wand and L-frame takes, and
``maneuver.csv``). The truth stays in this process; the diagnosis gets the
directory alone and runs as a user's would (``diagnose_path``, which
calibrates, reconstructs and diagnoses). Cases run in parallel processes,
each diagnosis in one.

Figures: a confusion matrix (truth x verdict), the fitted parameter's
relative error and whether the stated 68 % interval covers the truth, the
false-positive rate on the no-physics cases (a mechanism named where there
is none), and per mechanism the smallest magnitude found reliably (named
correctly there and at every larger magnitude tried). The trusted-verdict
set (``verdict_cases``, ``--realism --verdict-set``) adds the false-name
rate's Clopper-Pearson bound, and counts a named mechanism right only
with its parameter within ``RIGHT_WITHIN``.

Magnitudes: from barely detectable to strong, each strictly inside the
searched range and off the fit's log grid (a truth on a grid point or at a
bound would be "found" exactly by construction). The weakest sit near the
null test's threshold: a held-out improvement of a few times what noise
alone gives (measured with the current lab, 0.9 mm marker noise, and the
threshold's floor at 200: sheave inertia 9e-6 kg m^2 scored 5.2 times the
threshold, bending damping 6e-4 N m s/rad 2.9, aero drag cd 0.12 14, near
the bottom of its range; ``LIMIT_CASES`` straddle the edge). Chain-link
and pulley friction are
strong already at the bottom of their plausible ranges (a signal of 160
and 1600 noise sigmas at mu 0.01 and 0.005), so their weakest cases are
the range's bottom, not the detection limit.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
import time

import numpy as np

from dragline.compare import as_executor, diagnose_path, executor_from, write_diagnosis_json
from dragline.lab import lab_for_rig, synthesize_session, write_session_dir
from dragline.simulate import (
    MECHANISMS,
    apply_parameters,
    default_maneuver,
    dig_maneuver,
    draw_parameters,
    load_rig,
    make_mechanism,
    marker_positions,
    mechanism_type,
    simulate,
)

from ._another_rig import ANOTHER_RIG, another_rig_cases, another_rig_entries, another_rig_figures, beyond_bounds
from ._another_rig import summary_lines as another_rig_lines

__all__ = ["MAGNITUDES", "LIMIT_CASES", "REALISTIC_MAGNITUDES", "REALISTIC_LIMIT_CASES", "DETECTION_THRESHOLDS",
           "default_cases", "realistic_cases", "verdict_cases", "creeping", "reels_scaled", "clopper_pearson_upper",
           "bench_discovery", "summary_lines", "bench_command"]

MAGNITUDES = {
    "aero_drag": (0.12, 0.4, 1.6, 5.5),
    "chain_link_friction": (0.015, 0.04, 0.11, 0.3),
    "pulley_friction": (0.0075, 0.02, 0.05, 0.13),
    "pulley_inertia": (9e-6, 3.5e-5, 1.1e-4, 4e-4),
    "rope_bending_damping": (6e-4, 4e-3, 0.02, 0.06),
}
NONE_FRACTION = 0.22
# A named mechanism counts as right with its main parameter within this share of the truth.
RIGHT_WITHIN = 0.25
# Below the list's weakest (``--limits``): where detection fades, around the
# null test's threshold, with a no-physics control.
LIMIT_CASES = (
    ("pulley_inertia", 5e-6, 5001),
    ("pulley_inertia", 7e-6, 5002),
    ("rope_bending_damping", 2e-4, 5003),
    ("rope_bending_damping", 3.5e-4, 5004),
    (None, 0.0, 5005),
)


def default_cases(quick=False, seed=0):
    """The blind cases: ``(mechanism or None, main-parameter value, seed)``.

    Full: every mechanism at its four ``MAGNITUDES`` (a mechanism without
    listed magnitudes gets four log-spaced values over its range) plus
    no-physics cases to make ``NONE_FRACTION`` of the total. Quick: each
    mechanism at its weakest and third magnitude, plus three no-physics
    cases. Seeds differ per case (cameras, wand path, every noise draw).
    """
    cases = []
    for name in sorted(n for n in MECHANISMS if MECHANISMS[n].candidate):
        entry = MECHANISMS[name]
        values = MAGNITUDES.get(name)
        if values is None:
            lo, hi = entry.range
            values = tuple(float(v) for v in np.geomspace(lo, hi, 4))
        if quick:
            values = (values[0], values[2])
        cases += [(name, float(v)) for v in values]
    n_none = 3 if quick else int(math.ceil(NONE_FRACTION * len(cases) / (1 - NONE_FRACTION)))
    cases += [(None, 0.0)] * n_none
    return [(name, value, seed * 1000 + k) for k, (name, value) in enumerate(cases)]


# Realistic magnitudes, from barely detectable to strong. A real rig's
# model errs by itself: on the dig maneuver the baseline model's bucket
# moves 0.05-0.07 mm RMS from the next finer level's, and the model's
# distance from its converged solution is about twice that
# (docs/diagnosis.md). The weakest case of each mechanism moves the bucket
# by about three times that error, 0.2 mm RMS (measured on two drawn truth
# rigs): rope bending damping 0.02 N m s/rad 0.19-0.21 mm, sheave inertia
# 6e-5 kg m^2 0.23 mm, aero drag 0.4 0.18 mm (0.39 on another rig); a test
# holds each above twice the model's own error. The nominal benchmark's second magnitudes,
# bending damping 4e-3 (0.05 mm, the model's own error) and sheave inertia
# 3.5e-5 (0.14 mm), are below that: they are ``REALISTIC_LIMIT_CASES``.
REALISTIC_MAGNITUDES = {
    "aero_drag": (0.4, 1.6, 5.5),
    "chain_link_friction": (0.04, 0.11, 0.3),
    "pulley_friction": (0.02, 0.05, 0.13),
    "pulley_inertia": (6e-5, 1.1e-4, 4e-4),
    "rope_bending_damping": (0.02, 0.04, 0.07),
}
# Below the realistic detection edge (``--realism --limits``), with a no-physics control.
REALISTIC_LIMIT_CASES = (
    ("pulley_inertia", 3.5e-5, 5501, "realistic"),
    ("rope_bending_damping", 4e-3, 5502, "realistic"),
    ("rope_bending_damping", 0.01, 5503, "realistic"),
    (None, 0.0, 5504, "realistic"),
)


def realistic_cases(seed=0, quick=False):
    """The realistic blind cases: ``(truth, value, seed, "realistic")``.

    Every case's truth rig is drawn within the rig's tolerances and
    simulated at a finer discretization than the diagnosis uses
    (``_truth_world``). In the menu: each candidate at its three
    ``REALISTIC_MAGNITUDES``. No added mechanism: ``REALISTIC_NONE`` cases.
    Out of the menu: material damping of every rope and chain
    ``OUT_OF_MENU`` times the table value, and sheave bearing damping (a
    mechanism the simulator has but the candidate list does not). Quick:
    each candidate at one magnitude, one of each out-of-menu effect, two
    without a mechanism.
    """
    cases = []
    for name in sorted(n for n in MECHANISMS if MECHANISMS[n].candidate):
        values = REALISTIC_MAGNITUDES[name]
        cases += [(name, float(v)) for v in (values[1:2] if quick else values)]
    cases += [(n, float(v)) for n, v in (OUT_OF_MENU[1::2] if quick else OUT_OF_MENU)]
    cases += [(None, 0.0)] * (2 if quick else REALISTIC_NONE)
    return [(name, value, seed * 1000 + 500 + k, "realistic") for k, (name, value) in enumerate(cases)]


REALISTIC_NONE = 5
OUT_OF_MENU = (("material_damping", 2.5), ("material_damping", 3.5), ("sheave_bearing_damping", 3e-3),
               ("sheave_bearing_damping", 1e-2))
# The generic law at a site that models each out-of-menu effect, when the diagnosis is asked where (``--candidates
# default,*@*``): a sheave's bearing damping is a law of its own; every rope's material damping scaled is a rope
# type's damping beyond its tolerance (issue 39).
GENERIC_LAW = {"sheave_bearing_damping": "sheave_bearing_damping", "material_damping": "rope_damping_excess"}

# Each candidate's detection threshold on the dig (``dragline bench detection``,
# seed 990100, 2026-11-27): the magnitude at which what it does to the
# recording, less what the rig's parameters within their tolerances and
# the model's error directions can reproduce, weighs as much as the
# model's own numerical error (chi2 49,243). Fixed before the verdict
# benchmark was run; its magnitudes are 2, 5 and 20 times these.
DETECTION_THRESHOLDS = {
    "aero_drag": 0.924,
    "chain_link_friction": 0.00878,
    "pulley_friction": 0.000618,
    "pulley_inertia": 0.000252,
    "rope_bending_damping": 0.0393,
}
THRESHOLD_MULTIPLES = (2, 5, 20)
# Physics no candidate law can express, even a law at a site: cameras out of
# sync (each camera's frames late by a delay drawn in [0, d] s) and rope
# creep (each winch's rope lengthening steadily under load, by this strain
# over the trial); the four ``OUT_OF_MENU`` effects beside them are out of
# today's menu only (a sheave's bearing damping and a rope's damping beyond
# its tolerance are laws of issue 39).
CAMERA_LATENCY_S = (0.001, 0.0025, 0.005)
ROPE_CREEP_STRAIN = (3e-4, 1e-3, 3e-3)
# A third: each winch paying out (1 + s) times the change its reel table
# says (the rope slipping on the drum, or a wound layer the table does not
# count). The dig pays out 1.5 m of hoist rope and hauls in 2.8 m of drag
# rope: 0.1 % is 1.5-2.8 mm, about the markers' noise; 1 % is 15-28 mm,
# under the reel table's check (54 mm). No rig parameter scales a reel (a
# reel's zero shifts it). Added after seed 102, so that ten of the set are
# beyond every law, even a law at a site; fixed before any run.
REEL_SCALE_SHARE = (0.001, 0.002, 0.005, 0.01)
VERDICT_NONE = 20
VERDICT_REPLICATES = 2


def _three_digits(x):
    return float(f"{x:.3g}")


def verdict_cases(seed=0):
    """The trusted-verdict benchmark's 64 cases: ``(truth, value, seed, "realistic")``.

    Each candidate at 2, 5 and 20 times its ``DETECTION_THRESHOLDS``
    (three digits), ``VERDICT_REPLICATES`` times on differently drawn truth
    rigs; ``VERDICT_NONE`` with nothing added; fourteen out of the menu
    (camera latency and rope creep at three magnitudes each, the four
    ``OUT_OF_MENU``, reel scale at four): ten of them beyond every law.
    Every case has its own seed; the reel-scale cases come last, so that
    the other cases of a seed keep the seeds they had before they were
    added.
    """
    cases = []
    for name in sorted(DETECTION_THRESHOLDS):
        for m in THRESHOLD_MULTIPLES:
            cases += [(name, _three_digits(m * DETECTION_THRESHOLDS[name]))] * VERDICT_REPLICATES
    cases += [("camera_latency", d) for d in CAMERA_LATENCY_S]
    cases += [("rope_creep", e) for e in ROPE_CREEP_STRAIN]
    cases += list(OUT_OF_MENU)
    cases += [(None, 0.0)] * VERDICT_NONE
    cases += [("reel_scale", s) for s in REEL_SCALE_SHARE]
    return [(name, float(value), seed * 1000 + 500 + k, "realistic") for k, (name, value) in enumerate(cases)]


# Finer than the diagnosis's baseline: the truth's own discretization.
TRUTH_DISCRETIZATION = "medium"
# The held-out trial's maneuver (``--verdict-set``): the dig's literal
# reading (docs/model.md) - the reels' speeds stepped, not ramped, phase 1
# 2.5 s, the drag 0.48 m/s in phase 3, both reels stopped at 6.5 s - a
# schedule of the same machine the fit never sees, filmed as a second
# session of the same truth rig (its own noise, wand and L-frame takes).
HELD_OUT_MANEUVER = {"phase1_s": 2.5, "phase3_drag_m_s": 0.48, "ramp_s": 0.0}
HELD_OUT_SEED = 10_000_000  # added to the case's seed for the second session's draws


def _truth_world(name, value, seed, effect=True, rig_name=None, maneuver=None):
    """Truth rig, maneuver (with the drawn reel zeros), discretization, physics and drawn coordinates.

    ``effect=False``: the same world without the case's effect (no
    mechanism; the drawn material damping kept), to measure its size.
    ``rig_name``: another machine than the dragline, with its own maneuver.
    ``maneuver``: another maneuver of the machine (the held-out trial's).
    """

    rig = load_rig(rig_name)
    params = rig.tolerances
    coords = draw_parameters(params, np.random.default_rng(seed))
    physics = []
    if effect and name == "material_damping":  # out of the menu: every rope's and chain's damping scaled
        coords = np.array([math.log(value) if p.field == "viscous_damping" else x for p, x in zip(params, coords)])
    elif effect and name is not None and name.startswith(ANOTHER_RIG):  # geometry beyond updating's reach
        coords = beyond_bounds(params, coords, name.partition(":")[2], value)
    elif effect and name is not None and name.partition("@")[0] in MECHANISMS:  # a law, or a law at a site
        physics = [make_mechanism(name, **{mechanism_type(name).main: value})]
    truth_rig, truth_maneuver = apply_parameters(rig, maneuver or default_maneuver(rig), params, coords)
    if effect and name == "rope_creep":
        truth_maneuver = creeping(truth_maneuver, value)
    if effect and name == "reel_scale":
        truth_maneuver = reels_scaled(truth_maneuver, value)
    return truth_rig, truth_maneuver, TRUTH_DISCRETIZATION, physics, coords


def creeping(maneuver, strain, duration=10.0):
    """``maneuver`` with every winch's rope creeping: paid-out length times ``1 + strain (t - t0) / duration``.

    The rope lengthens steadily under load, by ``strain`` of its length over
    the trial (held after it); the maneuver's rows are resampled to 100 Hz
    first so that the kernel's linear interpolation follows the product.
    """
    from dragline.simulate import Maneuver

    t0 = float(maneuver.time[0])
    time = np.union1d(maneuver.time, np.arange(t0, float(maneuver.time[-1]), 0.01))
    grow = 1.0 + strain * np.clip((time - t0) / duration, 0.0, 1.0)
    lengths = {w: np.interp(time, maneuver.time, v) * grow for w, v in maneuver.lengths.items()}
    points = {p: np.column_stack([np.interp(time, maneuver.time, xyz[:, c]) for c in range(3)])
              for p, xyz in maneuver.points.items()}
    return Maneuver(time, lengths, points)


def reels_scaled(maneuver, share):
    """``maneuver`` with every winch paying out ``1 + share`` times the change from its first row.

    A new ``Maneuver``; the points and the clock are kept.
    """
    from dragline.simulate import Maneuver

    lengths = {w: v[0] + (1.0 + share) * (np.asarray(v, float) - v[0]) for w, v in maneuver.lengths.items()}
    return Maneuver(maneuver.time, lengths, dict(maneuver.points))


def _effect_size(result, without):
    """How much the case's effect moves the rig's first body (the dragline's bucket): RMS over the record
    of its position in x and z (mm) and of its pitch (deg).

    ``result`` and ``without``: the truth simulated with and without it.
    A yardstick for "barely detectable": the lab's markers are good to
    about a millimetre.
    """
    a, b = result.table, without.table
    body = next(iter(result.model.rig.bodies))
    d = np.hypot(np.asarray(a[f"{body}.x"]) - np.asarray(b[f"{body}.x"]),
                 np.asarray(a[f"{body}.z"]) - np.asarray(b[f"{body}.z"]))
    p = np.asarray(a[f"{body}.pitch"]) - np.asarray(b[f"{body}.pitch"])
    return {"bucket_mm": float(1000 * np.sqrt(np.mean(d**2))),
            "bucket_pitch_deg": float(np.degrees(np.sqrt(np.mean(p**2))))}


def verdict_right(truth, value, out_of_menu, verdict, fitted=None):
    """Issue 37's rule: the hidden mechanism named with its parameter (``fitted``, the verdict's) within
    ``RIGHT_WITHIN`` of ``value``, not the name alone; "none" where nothing was added; "none" or
    "unexplained" out of the menu (with the update that names the changed parameter, for material damping), or
    the generic law that models it (``GENERIC_LAW``) where the diagnosis was asked for laws at sites."""
    if out_of_menu:
        return verdict in ("none", "unexplained") or modeled(truth, verdict)
    if truth == "none":
        return verdict == "none"
    return verdict == truth and fitted is not None and abs(fitted / value - 1.0) <= RIGHT_WITHIN


def modeled(truth, verdict):
    """Whether ``verdict`` names the generic law that models the out-of-menu effect ``truth``, at any sites."""
    return GENERIC_LAW.get(truth) is not None and str(verdict).partition("@")[0] == GENERIC_LAW[truth]


def _names_a_law(verdict):
    return str(verdict).partition("@")[0] in MECHANISMS


def _film(result, machine, seed, folder, recorded_maneuver, delay_s=None):
    """``result`` filmed by the rig's own lab (the dragline's built-in one, else six cameras about the
    machine's markers) and written as a session directory; ``delay_s``: each camera's frames late by up to
    that (the camera latency case)."""
    lab = lab_for_rig(machine, marker_positions(result)[1], seed)
    delays = None if delay_s is None else np.random.default_rng([seed, 1]).uniform(0.0, delay_s, len(lab.cameras))
    session, _ = synthesize_session(result, lab.cameras, seed=seed, wand_volume=lab.wand_volume,
                                    lframe=lab.lframe, wand_length=lab.wand_length, camera_delay_s=delays,
                                    metadata={"generator": "dragline bench discovery", "rig": machine.name})
    write_session_dir(folder, session, recorded_maneuver)


def _held_out_session(name, value, seed, folder, machine, delay_s):
    """The case's truth on ``HELD_OUT_MANEUVER``, filmed as a second session into ``folder``."""
    second = dig_maneuver(**HELD_OUT_MANEUVER)
    rig, maneuver, discretization, physics, _ = _truth_world(name, value, seed, maneuver=second)
    result = simulate(rig, maneuver, discretization, physics, duration=10.0, rate_hz=200.0)
    _film(result, machine, seed + HELD_OUT_SEED, folder, second, delay_s)


def _run_case(name, value, seed, world="nominal", workdir=None, keep=False, rig_name=None, held_out=False,
              candidates=None):
    """Make one blind session, diagnose it from its directory alone, score it here.

    ``workdir``: where the session is made (a temporary folder of the
    machine that runs the case when None); ``keep``: return the case's
    diagnosis document too (under ``diagnosis``); ``rig_name``: a realistic
    case on another machine (its own maneuver, ``[demo]`` duration and lab);
    ``held_out``: a realistic dragline case also films its truth on a second
    maneuver (``HELD_OUT_MANEUVER``), which the diagnosis predicts without
    fitting it (``held_out`` in the result: each model's RMS residual there).
    """

    own = workdir is None
    workdir = tempfile.mkdtemp(prefix="dragline-case-") if own else workdir
    folder = os.path.join(workdir, f"case{seed}")
    started = time.perf_counter()
    coords = None
    machine = load_rig(rig_name)
    duration = machine.demo["duration"] if rig_name is not None and machine.demo else 10.0
    if world == "realistic":
        rig, maneuver, discretization, physics, coords = _truth_world(name, value, seed, rig_name=rig_name)
        result = simulate(rig, maneuver, discretization, physics, duration=duration, rate_hz=200.0)
        recorded_maneuver = default_maneuver(machine)  # the user's reel table: the drum's zero error is hidden
        without = None if name in (None, "camera_latency") else simulate(
            *_truth_world(name, value, seed, effect=False, rig_name=rig_name)[:4], duration=duration, rate_hz=200.0)
    else:
        physics = [] if name is None else [make_mechanism(name, **{MECHANISMS[name].main: value})]
        result = simulate(physics=physics, duration=10.0, rate_hz=200.0)
        recorded_maneuver = result.model.maneuver
        without = None if name is None else simulate(duration=10.0, rate_hz=200.0)
    effect = {"bucket_mm": 0.0, "bucket_pitch_deg": 0.0} if without is None else _effect_size(result, without)
    delay_s = value if name == "camera_latency" else None  # out of the menu: cameras late by up to ``value`` s
    _film(result, machine, seed, folder, recorded_maneuver, delay_s)
    spare = []
    if held_out and world == "realistic" and rig_name is None:
        spare = [os.path.join(workdir, f"case{seed}_held_out")]
        _held_out_session(name, value, seed, spare[0], machine, delay_s)
    made = time.perf_counter() - started
    out = {"truth": name or "none", "value": value, "seed": seed, "world": world, "synth_seconds": made,
           "effect": effect, "rig": rig_name or "dragline"}
    t0 = time.perf_counter()
    try:
        doc = diagnose_path(folder, rig=machine, workers=1, seed=seed, held_out=spare,
                            candidates=list(candidates) if candidates else None).doc
        if keep:
            out["diagnosis"] = doc  # written by the caller: a Dask worker's disk is not the user's
    except ValueError as exc:
        # A recording of another rig may be refused at the door (its rope lengths off the reel table): it
        # names no mechanism, which is that case's right answer; any other case refused is wrong.
        another = name is not None and name.startswith(ANOTHER_RIG)
        out.update(verdict="error", reason=str(exc), diagnosis_seconds=time.perf_counter() - t0,
                   right=another,
                   out_of_menu=not (name is None or (name in MECHANISMS and MECHANISMS[name].candidate)))
        return out
    finally:
        shutil.rmtree(workdir if own else folder, ignore_errors=True)
        for path in spare:
            shutil.rmtree(path, ignore_errors=True)
    out.update(verdict=doc["verdict"], reason=doc["reason"], diagnosis_seconds=time.perf_counter() - t0,
               load_seconds=doc["timing"].get("load_seconds"), simulations=doc["timing"]["simulations"])
    in_menu = name is None or (name in MECHANISMS and MECHANISMS[name].candidate)
    out["out_of_menu"] = not in_menu
    hyp = {h["name"]: h for h in doc["hypotheses"]}
    fitted = hyp[name]["parameters"][hyp[name]["main_parameter"]] if name in hyp else None
    out["right"] = verdict_right(name or "none", value, not in_menu, doc["verdict"], fitted)
    if not in_menu and name in GENERIC_LAW:
        out["modeled"] = modeled(name, doc["verdict"])
    if coords is not None:
        out["calibration"] = _calibration_errors(doc, coords, machine)
    second = doc.get("second_mechanism") or {}
    out["also"] = [h["name"] for h in second.get("candidates", []) if h["significant"]]
    if fitted is not None:
        h = hyp[name]
        u = h["uncertainty"]

        def covers(key):
            interval = u.get(key)
            return bool(interval and interval[0] <= value <= interval[1])

        out.update(fitted=fitted, relative_error=fitted / value - 1.0 if value else None,
                   interval_68=u.get("interval_68"), covered=covers("interval_68"), covered_95=covers("interval_95"),
                   covered_fixed_rig=covers("interval_68_fixed_rig"),
                   correlations=u.get("correlations"),
                   truth_rank=[x["name"] for x in doc["hypotheses"]].index(name) + 1,
                   truth_score=h["score"])
    if doc.get("held_out"):
        out["held_out"] = doc["held_out"][0]["rms_noise"]
    if world == "realistic":
        out.update(another_rig_entries(doc))
    if doc["hypotheses"]:
        top = doc["hypotheses"][0]
        out.update(top=top["name"], top_score=top["score"], top_improvement=top["improvement"],
                   threshold=doc["null_test"]["threshold"])
    return out


def _calibration_errors(doc, coords, rig):
    """Per rig parameter: truth and estimate in tolerances, identifiable or not."""

    params = rig.tolerances
    entries = {e["parameter"]: e for e in doc.get("calibration", {}).get("parameters", [])}
    out = {}
    for p, x in zip(params, coords):
        e = entries.get(p.name)
        if e is None:
            continue
        out[p.name] = {"truth": float(x / p.tolerance), "estimate": e["shift_in_tolerances"],
                       "identifiable": e["identifiable"]}
    return out


def _no_context():
    """A case needs nothing besides its own arguments."""


def keeper(keep, progress, line):
    """The callback each finished case goes through: its diagnosis document (popped from the result) written
    to ``keep`` as ``case<seed>.json``, and ``line(result)`` given to ``progress``."""

    def finished(result):
        doc = result.pop("diagnosis", None)
        if doc is not None:
            os.makedirs(keep, exist_ok=True)
            write_diagnosis_json(os.path.join(keep, f"case{result['seed']}.json"), doc)
        if progress:
            progress(line(result))

    return finished


def bench_discovery(cases=None, workers=2, seed=0, quick=False, workdir=None, progress=None, keep=None,
                    held_out=False, candidates=None):
    """Run the blind discovery benchmark.

    Parameters
    ----------
    cases : list of (str or None, float, int), optional
        ``(mechanism, value, seed)``; default :func:`default_cases`.
    workers : int or Executor
        Cases run in this many local processes at once (each diagnosis in
        one), or on an ``Executor`` (a Dask cluster: one case per task).
    seed : int
        Base seed of the default cases.
    quick : bool
        The reduced default case list.
    workdir : str, optional
        Where the session directories are made (and removed); a temporary
        folder by default.
    progress : callable, optional
        Called with one line per finished case.
    keep : str, optional
        A folder where every case's ``diagnosis.json`` is kept
        (``case<seed>.json``).
    held_out : bool
        Each realistic dragline case's truth is filmed on a second maneuver
        too, which its diagnosis predicts (``_run_case``).
    candidates : list of str, optional
        What every case's diagnosis tries (``default,*@*``: every law at
        each of its sites too); the diagnosis's default list otherwise.

    Returns
    -------
    dict
        ``cases`` (per case: truth, value, verdict, fitted value, relative
        error, coverage, timings), ``confusion`` (truth -> verdict ->
        count), ``accuracy``, ``false_positive_rate`` (no-physics cases
        given a mechanism name), ``none_correct_rate``, ``parameter_error``
        (per mechanism, over correctly named cases: median and largest
        |relative error|, coverage of the 68 % interval), ``smallest_found``
        (per mechanism), ``timing`` (diagnosis seconds: median, max).
    """
    cases = default_cases(quick, seed) if cases is None else [tuple(c) for c in cases]
    executor = as_executor(workers)
    local = executor.kind == "local"
    own = local and workdir is None
    workdir = tempfile.mkdtemp(prefix="dragline-discovery-") if own else (workdir if local else None)

    finished = keeper(keep, progress, _case_line)
    started = time.perf_counter()
    session = executor.open(_no_context)
    try:
        jobs = [(*c[:3], c[3] if len(c) > 3 else "nominal", workdir, bool(keep), c[4] if len(c) > 4 else None,
                 held_out, tuple(candidates) if candidates else None) for c in cases]
        results = session.map(_run_case, jobs, each=finished)
    finally:
        session.close()
        if own:
            shutil.rmtree(workdir, ignore_errors=True)
    wall = time.perf_counter() - started
    workers = executor.describe()["workers"]
    worlds = sorted({r.get("world", "nominal") for r in results})
    if worlds == ["nominal"]:
        return dict(_summarise(results, wall, workers), executor=executor.describe())
    report = {"n_cases": len(results), "worlds": {}, "executor": executor.describe()}
    for w in worlds:
        mine = [r for r in results if r.get("world", "nominal") == w]
        report["worlds"][w] = _summarise(mine, wall, workers)
        if w == "realistic":
            report["worlds"][w].update(_realistic_figures(mine))
    report["timing"] = {"wall_s": wall, "workers": workers}
    return report


def _realistic_figures(results):
    """The realistic benchmark's headline figures (issue targets beside them)."""
    oom = [r for r in results if r.get("out_of_menu")]
    none = [r for r in results if r["truth"] == "none"]
    named = [r for r in results if not r.get("out_of_menu") and r["truth"] != "none"]
    rel = [abs(r["relative_error"]) for r in named if r["verdict"] == r["truth"] and r.get("relative_error") is not None]
    cal = [abs(e["estimate"] - e["truth"]) for r in results for e in (r.get("calibration") or {}).values()
           if e["identifiable"]]
    damping_named = [r for r in oom if r["truth"] == "material_damping" and r["verdict"] == "none"
                     and "viscous_damping" in r.get("reason", "")]
    nulls = none + oom
    # a name on a case without a candidate's physics, unless it is the generic law that models it (``modeled``)
    false = sum(_names_a_law(r["verdict"]) and not r.get("modeled") for r in nulls)
    another = None
    if any(r["truth"].startswith(ANOTHER_RIG) for r in results):
        another = another_rig_figures(results)
    return {
        "another_rig": another,
        "held_out_trial": _held_out_figures(results),
        "right_rate": float(np.mean([r["right"] for r in results])) if results else None,
        "n_right": sum(bool(r["right"]) for r in results),
        "right_rule": f"the hidden mechanism named with its parameter within {RIGHT_WITHIN:.0%}; \"none\" where "
                      "nothing was added; \"none\" or \"unexplained\" out of the menu",
        # Every case without a candidate's physics (none and out of the menu) that got a mechanism's name.
        "false_names": false,
        "n_false_name_chances": len(nulls),
        "false_name_rate": false / len(nulls) if nulls else None,
        "false_name_rate_upper_95": clopper_pearson_upper(false, len(nulls)),
        "none_named_a_mechanism": sum(_names_a_law(r["verdict"]) for r in none),
        "n_none": len(none),
        "out_of_menu_wrong_name_rate": (float(np.mean([_names_a_law(r["verdict"]) and not r.get("modeled")
                                                       for r in oom])) if oom else None),
        "n_out_of_menu": len(oom),
        # issue 39: an out-of-menu effect modeled by its generic law, where the diagnosis was asked for sites
        "out_of_menu_modeled": sum(bool(r.get("modeled")) for r in oom),
        "material_damping_named_in_update": len(damping_named),
        "median_mechanism_relative_error": float(np.median(rel)) if rel else None,
        "calibration_error_in_tolerances_median": float(np.median(cal)) if cal else None,
        "calibration_error_in_tolerances_p90": float(np.quantile(cal, 0.9)) if cal else None,
        "targets": {"right_rate": ">= 0.90", "none_named_a_mechanism": "0",
                    "out_of_menu_wrong_name_rate": "<= 0.05", "median_mechanism_relative_error": "<= 0.25",
                    "diagnosis_s": "<= 300"},
    }


def _held_out_figures(results):
    """How each verdict's model predicts the held-out trial (another maneuver, never fitted): per kind of
    verdict, the cases where the named model beats the updated one and the updated the nominal, and the
    median RMS residuals (noise units). None when no case had one."""
    have = [r for r in results if (r.get("held_out") or {}).get("nominal") is not None]
    if not have:
        return None

    def better(rows, a, b):
        pairs = [(r["held_out"].get(a), r["held_out"].get(b)) for r in rows]
        return sum(1 for x, y in pairs if x is not None and y is not None and x < y)

    def median(rows, label):
        values = [r["held_out"][label] for r in rows if r["held_out"].get(label) is not None]
        return float(np.median(values)) if values else None

    groups = {"right_named": [r for r in have if r["verdict"] in MECHANISMS and r["right"]],
              "wrong_named": [r for r in have if r["verdict"] in MECHANISMS and not r["right"]],
              "none_or_unexplained": [r for r in have if r["verdict"] not in MECHANISMS]}
    return {name: {"n": len(rows), "named_beats_updated": better(rows, "named", "updated"),
                   "updated_beats_nominal": better(rows, "updated", "nominal"),
                   "median_rms": {label: median(rows, label) for label in ("nominal", "updated", "named")}}
            for name, rows in groups.items()}


def _case_line(r):
    fit = f" fitted {r['fitted']:.3g}" if r.get("fitted") is not None and r["verdict"] == r["truth"] else ""
    world = " [realistic]" if r.get("world") == "realistic" else ""
    size = r.get("effect") or {}
    effect = (f", effect {size['bucket_mm']:.2g} mm / {size['bucket_pitch_deg']:.2g} deg"
              if r["truth"] != "none" and size else "")
    return (f"{r['truth']}={r['value']:g}{world} -> {r['verdict']}{fit} ({r.get('diagnosis_seconds', 0):.0f} s"
            f"{effect})")


def _summarise(results, wall, workers):
    truths = sorted({r["truth"] for r in results})
    verdicts = sorted({r["verdict"] for r in results} | set(truths) | {"unexplained"})
    confusion = {t: {v: 0 for v in verdicts} for t in truths}
    for r in results:
        confusion[r["truth"]][r["verdict"]] += 1
    right = [r.get("right", r["verdict"] == r["truth"]) for r in results]
    none_cases = [r for r in results if r["truth"] == "none"]
    named_wrong = [r for r in none_cases if r["verdict"] not in ("none", "unexplained", "error")]
    errors = {}
    smallest = {}
    for name in truths:
        if name == "none":
            continue
        mine = [r for r in results if r["truth"] == name]
        good = [r for r in mine if r["verdict"] == name and r.get("relative_error") is not None]
        rel = [abs(r["relative_error"]) for r in good]
        errors[name] = {
            "n_named": len(good),
            "n_cases": len(mine),
            "median_abs_relative_error": float(np.median(rel)) if rel else None,
            "max_abs_relative_error": float(max(rel)) if rel else None,
            "coverage_68": float(np.mean([r["covered"] for r in good])) if good else None,
            "coverage_95": float(np.mean([r.get("covered_95", False) for r in good])) if good else None,
            # the interval as stated before the rig's parameters were freed in it (``stated_uncertainty``)
            "coverage_68_fixed_rig": float(np.mean([r.get("covered_fixed_rig", False) for r in good])) if good else None,
        }
        found = None
        for value in sorted({r["value"] for r in mine}, reverse=True):
            if all(r["verdict"] == name for r in mine if r["value"] == value):
                found = value
            else:
                break
        smallest[name] = found
        if found is not None:
            errors[name]["median_abs_relative_error_reliable"] = float(np.median(
                [abs(r["relative_error"]) for r in good if r["value"] >= found]))
    reliable = [abs(r["relative_error"]) for r in results if r["truth"] != "none" and r["verdict"] == r["truth"]
                and r.get("relative_error") is not None and smallest.get(r["truth"]) is not None
                and r["value"] >= smallest[r["truth"]]]
    secs = [r["diagnosis_seconds"] for r in results]
    named = [r for r in results if r["verdict"] in MECHANISMS]
    return {
        "n_cases": len(results),
        "cases": results,
        "confusion": confusion,
        "accuracy": float(np.mean(right)) if results else None,
        "false_positive_rate": len(named_wrong) / len(none_cases) if none_cases else None,
        "none_correct_rate": (float(np.mean([r["verdict"] == "none" for r in none_cases])) if none_cases else None),
        "parameter_error": errors,
        # Every case holds one mechanism at most: a second one reported
        # beside a verdict is a false alarm.
        "second_mechanism_false_rate": (float(np.mean([bool(r.get("also")) for r in named]))
                                        if named else None),
        # The figure: correctly named cases at or above each
        # mechanism's smallest reliably found magnitude.
        "median_abs_relative_error_reliable": float(np.median(reliable)) if reliable else None,
        "smallest_found": smallest,
        "coverage": _coverage(results),
        "timing": {"diagnosis_median_s": float(np.median(secs)) if secs else None,
                   "diagnosis_max_s": float(max(secs)) if secs else None,
                   "wall_s": wall, "workers": workers,
                   "note": "diagnosis_seconds includes calibration and reconstruction of the session; "
                           "cases ran concurrently, so each shared the machine"},
    }


def clopper_pearson_upper(k, n, confidence=0.95):
    """One-sided exact (Clopper-Pearson) upper bound of a proportion k / n at ``confidence``; None without cases.

    The p at which k or fewer successes in n have probability
    ``1 - confidence``: with none in n, ``1 - (1 - confidence)**(1/n)``.
    """
    from scipy.stats import beta

    if n == 0:
        return None
    return 1.0 if k >= n else float(beta.ppf(confidence, k + 1, n - k))


def wilson_interval(k, n, confidence=0.90):
    """Wilson's score interval for a proportion k / n (two-sided, ``confidence``)."""
    from scipy.stats import norm

    if n == 0:
        return None
    z = float(norm.ppf(0.5 + confidence / 2.0))
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return [centre - half, centre + half]


def _coverage(results):
    """How often the stated intervals held the truth, over the correctly named cases, with 90 % Wilson intervals."""
    good = [r for r in results if r.get("relative_error") is not None and r["verdict"] == r["truth"]]
    out = {"n_named": len(good)}
    for key, label in (("covered", "68"), ("covered_95", "95"), ("covered_fixed_rig", "68_fixed_rig")):
        k = sum(bool(r.get(key)) for r in good)
        out[label] = {"covered": k, "rate": k / len(good) if good else None, "wilson_90": wilson_interval(k, len(good))}
    return out


def summary_lines(report):
    """Human-readable lines: the confusion matrix and the headline figures."""
    if "worlds" in report:
        lines = []
        for w, sub in report["worlds"].items():
            lines.append(f"== {w} cases ==")
            lines += summary_lines(sub)
            if w == "realistic":
                lines.append(
                    f"realistic: right {sub['n_right']} of {sub['n_cases']} ({_fmt(sub['right_rate'])}); false names "
                    f"{sub['false_names']} of {sub['n_false_name_chances']} (95 % upper bound "
                    f"{_fmt(sub['false_name_rate_upper_95'])}); mechanism named on {sub['none_named_a_mechanism']} of "
                    f"{sub['n_none']} no-mechanism cases; wrong names on out-of-menu cases "
                    f"{_fmt(sub['out_of_menu_wrong_name_rate'])} of {sub['n_out_of_menu']}; median mechanism error "
                    f"{_fmt(sub['median_mechanism_relative_error'])}; calibrated parameters off by a median "
                    f"{_fmt(sub['calibration_error_in_tolerances_median'])} tolerances (identifiable ones)")
                if sub.get("another_rig"):
                    lines += another_rig_lines(sub["another_rig"])
                for kind, h in (sub.get("held_out_trial") or {}).items():
                    m = h["median_rms"]
                    lines.append(f"held-out trial (another maneuver), {kind.replace('_', ' ')}: {h['n']} cases; the "
                                 f"named model beats the updated on {h['named_beats_updated']}, the updated the "
                                 f"nominal on {h['updated_beats_nominal']}; median RMS nominal {_fmt(m['nominal'])}, "
                                 f"updated {_fmt(m['updated'])}, named {_fmt(m['named'])} (noise units)")
        return lines
    conf = report["confusion"]
    cols = sorted({v for row in conf.values() for v in row})
    width = max([len(c) for c in cols] + [10])
    lines = ["truth \\ verdict".ljust(24) + "".join(c[:width].rjust(width + 1) for c in cols)]
    for t, row in conf.items():
        lines.append(t.ljust(24) + "".join(str(row.get(c, 0)).rjust(width + 1) for c in cols))
    lines.append(f"accuracy {report['accuracy']:.2f} over {report['n_cases']} cases; false-positive rate on "
                 f"no-physics cases {_fmt(report['false_positive_rate'])}")
    for name, e in report["parameter_error"].items():
        lines.append(f"{name}: named {e['n_named']}/{e['n_cases']}, |relative error| median "
                     f"{_fmt(e['median_abs_relative_error'])} max {_fmt(e['max_abs_relative_error'])}, 68% interval "
                     f"covers truth {_fmt(e['coverage_68'])}; smallest found reliably "
                     f"{_fmt(report['smallest_found'].get(name))}")
    lines.append(f"second mechanism reported beside a named one (each case holds one at most): "
                 f"{_fmt(report['second_mechanism_false_rate'])} of named cases")
    lines.append("median |relative error| of correctly named cases at or above the smallest magnitude "
                 f"found reliably: {_fmt(report['median_abs_relative_error_reliable'])}")
    cov = report.get("coverage")
    if cov and cov["n_named"]:
        lines.append("intervals holding the truth over the " + str(cov["n_named"]) + " correctly named: " + ", ".join(
            f"{label} {cov[label]['covered']} (90 % Wilson {_fmt(cov[label]['wilson_90'][0])}-"
            f"{_fmt(cov[label]['wilson_90'][1])})" for label in ("68", "95", "68_fixed_rig")))
    t = report["timing"]
    lines.append(f"diagnosis time per case (load + fit, {t['workers']} cases at once): median "
                 f"{_fmt(t['diagnosis_median_s'])} s, max {_fmt(t['diagnosis_max_s'])} s")
    return lines


def _fmt(x):
    return "-" if x is None else f"{x:.3g}"


def bench_command(args):
    """``dragline bench discovery``: returns (report, summary lines) like the other benches.

    Reads ``args.seed`` and, when the bench command has them, ``args.rig``
    (with ``args.realism``: another machine's cases, ``_machine_cases``), ``args.quick``,
    ``args.limits`` (the ``LIMIT_CASES`` instead; with ``args.realism``
    the ``REALISTIC_LIMIT_CASES``), ``args.verdict_set`` (with
    ``args.realism``: ``verdict_cases``), ``args.pairs`` (with
    ``args.realism``: two hidden mechanisms, ``_pairs``), ``args.sites`` (with
    ``args.realism``: one law at one site, ``_site_cases``), ``args.another_rig`` (with
    ``args.realism``: geometry beyond updating's reach, ``_another_rig``), ``args.workers``,
    ``args.scheduler`` (a Dask cluster; also ``DRAGLINE_SCHEDULER``),
    ``args.keep_diagnoses`` and ``args.candidates`` (what every case's
    diagnosis tries).
    """
    import sys

    if getattr(args, "realism", False) and getattr(args, "pairs", False):
        return _pairs_command(args)
    if getattr(args, "realism", False) and getattr(args, "sites", False):
        from ._site_cases import bench_sites
        from ._site_cases import summary_lines as site_summary_lines

        report = bench_sites(seed=args.seed, workers=executor_from(getattr(args, "workers", 2) or 2,
                                                                   getattr(args, "scheduler", None)),
                             keep=getattr(args, "keep_diagnoses", None), rig_name=getattr(args, "rig", None),
                             progress=lambda line: print(line, file=sys.stderr))
        return report, site_summary_lines(report)
    cases, derivation, held_out = None, None, False
    if getattr(args, "limits", False):
        cases = REALISTIC_LIMIT_CASES if getattr(args, "realism", False) else LIMIT_CASES
    elif getattr(args, "realism", False) and getattr(args, "rig", None):
        from ._machine_cases import machine_cases

        derivation = {}
        cases = machine_cases(args.rig, args.seed, derivation)
        for name, how in derivation.items():
            print(f"{name}: model error {how['model_error_mm']:.3g} mm, effect at {how['plausible'][-1]:g} "
                  f"{how['effect_at_top_mm']:.3g} mm: " + ("no case (below the edge)" if how["values"] is None else
                                                          "cases at " + ", ".join(f"{v:.3g}" for v in how["values"])),
                  file=sys.stderr)
    elif getattr(args, "realism", False) and getattr(args, "another_rig", False):
        cases = another_rig_cases(args.seed)
    elif getattr(args, "realism", False) and getattr(args, "verdict_set", False):
        cases = verdict_cases(args.seed)
        held_out = True
    elif getattr(args, "realism", False):
        cases = realistic_cases(args.seed, quick=bool(getattr(args, "quick", False)))
    candidates = [n.strip() for n in (getattr(args, "candidates", None) or "").split(",") if n.strip()] or None
    if candidates:
        from dragline.compare.diagnose import candidate_list

        candidate_list(candidates, load_rig(getattr(args, "rig", None)))  # unknown names: exit 2 before any work
    report = bench_discovery(cases=cases,
                             workers=executor_from(getattr(args, "workers", 2) or 2, getattr(args, "scheduler", None)),
                             seed=args.seed,
                             quick=bool(getattr(args, "quick", False)),
                             progress=lambda line: print(line, file=sys.stderr),
                             keep=getattr(args, "keep_diagnoses", None), held_out=held_out,
                             candidates=candidates)
    if derivation:
        report["magnitudes"] = derivation
    keep = getattr(args, "keep_diagnoses", None)
    if keep and "realistic" in report.get("worlds", {}):
        # What the verdict's rules read in each case, for ``bench decisions --records`` to calibrate on.
        from ._decisions import decision_records, write_decision_records

        label = f"seed {args.seed}" + (f", {args.rig}" if getattr(args, "rig", None) else "")
        write_decision_records(os.path.join(keep, "decision_records.json"), decision_records(report, keep, label),
                               origin=f"dragline bench discovery --realism, {label}")
    return report, summary_lines(report)


def _pairs_command(args):
    """``bench discovery --realism --pairs``: the two-mechanism cases, and their records beside the kept
    diagnoses (``pair_records.json``, for ``bench decisions``)."""
    import json
    import sys

    from ._pairs import bench_pairs, pair_records
    from ._pairs import summary_lines as pair_summary_lines

    keep = getattr(args, "keep_diagnoses", None)
    report = bench_pairs(seed=args.seed, workers=executor_from(getattr(args, "workers", 2) or 2,
                                                               getattr(args, "scheduler", None)),
                         keep=keep, progress=lambda line: print(line, file=sys.stderr))
    if keep:
        data = {"origin": f"dragline bench discovery --realism --pairs --seed {args.seed}",
                "licence": "MIT, as the repository", "records": pair_records(report, keep, f"seed {args.seed}")}
        path = os.path.join(keep, "pair_records.json")
        with open(f"{path}.tmp", "w", encoding="utf-8") as f:
            json.dump(data, f, separators=(",", ":"))
        os.replace(f"{path}.tmp", path)
    return report, pair_summary_lines(report)
