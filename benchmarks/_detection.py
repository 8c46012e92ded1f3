"""``dragline bench detection``: each candidate's detection threshold on this maneuver, from the truth model.

The realistic benchmark's magnitudes are multiples (2x, 5x, 20x) of a
threshold fixed before the run, not values placed after misses. The
threshold is the magnitude at which what the mechanism does to the
recording, less what a change of the rig's parameters can reproduce,
weighs as much as the model's own numerical error - the bar a
mechanism's improvement must clear (``own_error_chi2``, the binding
threshold on 17 of the 19 no-physics recordings of the calibration set,
docs/diagnosis.md section 5).

Measured on one session of the nominal rig with nothing added, simulated
at the truth's finer level and filmed by the lab (its own seed, kept apart
from every evaluation seed): the diagnosis's own steps up to the updating
give the channels, their noise, the updated model, the parameters'
sensitivities and the model's error directions. A candidate's signature at
``p`` is its simulation on the updated rig minus the updated model's; its
weight is the chi2 of what is left after the best fit of every parameter
sensitivity, every error direction and each channel's offset
(``_unabsorbed_chi2``). ``p`` at which that weight equals the model's own
error weight is found by bisection in ln p; a signature grows with its
parameter, so the weight is taken as monotone and the bracket checked.
"""

from __future__ import annotations

import math
import shutil
import tempfile

import numpy as np
from scipy.optimize import lsq_linear

from dragline.compare.diagnose._hypotheses import simulate_channels
from dragline.compare.diagnose._recording import load_recording
from dragline.compare.diagnose._state import DiagnosisState
from dragline.compare.diagnose._steps import align_recording, locate_nominal, own_error_weight, update_rig
from dragline.compare.diagnose._updating import ERROR_AMPLITUDE_SD
from dragline.lab import lab_for_rig, synthesize_session, write_session_dir
from dragline.simulate import MECHANISMS, default_maneuver, load_rig, marker_positions, simulate

__all__ = ["DETECTION_SEED", "bench_detection", "threshold_crossing", "summary_lines"]

# A seed no evaluation draws from (evaluation seeds are seed * 1000 + 500 + k).
DETECTION_SEED = 990_100
TRUTH_DISCRETIZATION = "medium"
# Bisection to this resolution in ln p (1 %): finer than any benchmark needs.
XTOL = 0.01


def threshold_crossing(weight, target, lo, hi, xtol=XTOL, grid=9):
    """The p in [lo, hi] at which ``weight(p)`` reaches ``target``, by bisection in ln p.

    ``weight`` is taken as increasing. A log grid of ``grid`` points finds
    the bracket first. Returns ``(p, status)``: status ``"found"``,
    ``"below range"`` (the weight already exceeds the target at ``lo``:
    p = lo) or ``"above range"`` (never reached: p = hi).
    """
    points = np.geomspace(lo, hi, grid)
    values = [weight(p) for p in points]
    if values[0] >= target:
        return float(lo), "below range"
    above = [k for k, v in enumerate(values) if v >= target]
    if not above:
        return float(hi), "above range"
    k = above[0]
    a, b = math.log(points[k - 1]), math.log(points[k])
    while b - a > xtol:
        mid = 0.5 * (a + b)
        if weight(math.exp(mid)) >= target:
            b = mid
        else:
            a = mid
    return float(math.exp(0.5 * (a + b))), "found"


def _unabsorbed_chi2(problem, signature, columns, precision, bounds):
    """What ``signature`` (n, c) still weighs after the rig's best answer to it.

    The chi2 of the signature less its fit by ``columns`` and each
    channel's offset, plus the fit's prior cost: a column ``k``'s
    coefficient costs ``precision[k] * a_k**2`` and stays within
    ``bounds[k]`` - the parameters within their tolerances, the error
    directions within their amplitude bounds, as the updating and the
    joint refit hold them. A weak signature is absorbed almost whole, a
    strong one cannot be.
    """
    W, valid = problem.W, problem.valid

    def centred(x):
        x = np.where(valid, x, 0.0)
        return ((x - (W * x).sum(0) / np.maximum(W.sum(0), 1e-300)) * np.sqrt(W)).ravel()

    g = centred(signature)
    if not columns:
        return float(g @ g)
    J = np.column_stack([centred(c) for c in columns])
    A = np.vstack([J, np.diag(np.sqrt(precision))])
    fit = lsq_linear(A, np.r_[g, np.zeros(len(columns))], bounds=(bounds[:, 0], bounds[:, 1]))
    left = g - J @ fit.x
    return float(left @ left + precision @ fit.x**2)


def _session(folder, seed, rig):
    """A session of the nominal rig, nothing added, the truth at the finer level, as the lab films it."""
    result = simulate(rig, default_maneuver(rig), TRUTH_DISCRETIZATION, [], duration=10.0, rate_hz=200.0)
    lab = lab_for_rig(rig, marker_positions(result)[1], seed)
    session, _ = synthesize_session(result, lab.cameras, seed=seed, wand_volume=lab.wand_volume,
                                    lframe=lab.lframe, wand_length=lab.wand_length)
    write_session_dir(folder, session, default_maneuver(rig))


def _updated_state(folder, rig, workers, progress):
    table, maneuver, source = load_recording(folder, rig=rig)
    state = DiagnosisState(measured=table, rig=rig, maneuver=maneuver, discretization="baseline",
                           candidate_names=None, workers=workers, seed=0, source=source, note=progress,
                           started=0.0, trial_names=None, held_out=())
    for step in (align_recording, locate_nominal, update_rig):
        state = step(state)
    return state


def bench_detection(seed=DETECTION_SEED, candidates=None, workers=2, progress=None):
    """Each candidate's detection threshold on the rig's maneuver (the dragline's dig).

    Returns
    -------
    dict
        ``own_error_chi2`` (the target), ``seed``, and per candidate
        ``threshold`` (its main parameter's value), ``status``, ``range``
        and ``multiples`` (2x, 5x, 20x the threshold).
    """
    rig = load_rig()
    folder = tempfile.mkdtemp(prefix="dragline-detection-")
    try:
        _session(f"{folder}/session", seed, rig)
        state = _updated_state(f"{folder}/session", rig, workers, progress)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    target = own_error_weight(state.model_error_block)
    columns = [*state.update["sensitivities"], *state.error_directions]
    tol = np.array([p.tolerance for p in state.ctx["parameters"]])
    precision = np.r_[tol**-2.0, np.full(len(state.error_directions), ERROR_AMPLITUDE_SD**-2.0)]
    bound = state.error_directions.amplitude_bounds()[:, 1]
    bounds = np.vstack([np.tile([-np.inf, np.inf], (len(tol), 1)), np.column_stack([-bound, bound])])
    names = candidates or sorted(n for n in MECHANISMS if MECHANISMS[n].candidate)
    out = {"seed": seed, "own_error_chi2": target, "candidates": {}}
    for name in names:
        kind = MECHANISMS[name]
        lo, hi = kind.range

        def weight(p, name=name, main=kind.main):
            sim = simulate_channels(name, main, p, ctx=state.ctx)
            return math.inf if sim is None else _unabsorbed_chi2(state.problem, sim - state.base_sim, columns,
                                                                   precision, bounds)

        p, status = threshold_crossing(weight, target, lo / 100.0, hi)
        out["candidates"][name] = {"threshold": p, "status": status, "main": kind.main, "range": [lo, hi],
                                   "multiples": {f"{m}x": m * p for m in (2, 5, 20)}}
        if progress:
            progress(f"{name}: {kind.main} = {p:.3g} ({status})")
    return out


def summary_lines(report):
    """Lines for the terminal: the target and each candidate's threshold with its multiples."""
    lines = [f"detection thresholds on the dig (own error chi2 {report['own_error_chi2']:.4g}, seed {report['seed']}):"]
    for name, c in report["candidates"].items():
        m = c["multiples"]
        lines.append(f"  {name}: {c['main']} = {c['threshold']:.3g} ({c['status']}; range {c['range'][0]:g}-"
                     f"{c['range'][1]:g}); 2x {m['2x']:.3g}, 5x {m['5x']:.3g}, 20x {m['20x']:.3g}")
    return lines
