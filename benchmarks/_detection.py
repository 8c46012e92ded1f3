"""``dragline bench detection``: each candidate's detection threshold on this maneuver, from the truth model.

The trusted-verdict benchmark's magnitudes are multiples (2x, 5x, 20x) of
a threshold fixed before the run, not values placed after misses. The
threshold is the magnitude at which what the mechanism does to the
recording, less what a change of the rig's parameters can reproduce,
weighs as much as the model's own numerical error - the bar a
mechanism's improvement must clear (``own_error_chi2``, the binding
threshold on 17 of the 19 no-physics recordings of the calibration set,
docs/diagnosis.md section 5); ``compare.detection_thresholds`` computes it.

Measured on one session of the nominal rig with nothing added, simulated
at the truth's finer level and filmed by the lab, with its own seed, kept
apart from every evaluation seed. Each candidate's threshold is sought
from a hundredth of its range's bottom to its top.
"""

from __future__ import annotations

import shutil
import tempfile

from dragline.compare import detection_thresholds
from dragline.lab import lab_for_rig, synthesize_session, write_session_dir
from dragline.simulate import MECHANISMS, default_maneuver, load_rig, marker_positions, mechanism_type, simulate

from ._discovery import THRESHOLD_MULTIPLES, TRUTH_DISCRETIZATION

__all__ = ["DETECTION_SEED", "bench_detection", "summary_lines"]

# A seed no evaluation draws from (evaluation seeds are seed * 1000 + 500 + k).
DETECTION_SEED = 990_100


def _session(folder, seed, rig, duration=10.0):
    """A session of the nominal rig, nothing added, the truth at the finer level, as the lab films it."""
    result = simulate(rig, default_maneuver(rig), TRUTH_DISCRETIZATION, [], duration=duration, rate_hz=200.0)
    lab = lab_for_rig(rig, marker_positions(result)[1], seed)
    session, _ = synthesize_session(result, lab.cameras, seed=seed, wand_volume=lab.wand_volume,
                                    lframe=lab.lframe, wand_length=lab.wand_length)
    write_session_dir(folder, session, default_maneuver(rig))


def bench_detection(seed=DETECTION_SEED, candidates=None, workers=2, progress=None, rig_name=None):
    """Each candidate's detection threshold on the rig's maneuver (the dragline's dig; ``rig_name``: another
    built-in machine's, over its ``[demo]`` duration).

    Returns
    -------
    dict
        ``own_error_chi2`` (the target), ``seed``, and per candidate
        ``threshold`` (its main parameter's value), ``status``, ``main``,
        ``range`` and ``multiples`` (2x, 5x, 20x the threshold).
    """
    rig = load_rig(rig_name)
    duration = rig.demo["duration"] if rig_name is not None and rig.demo else 10.0
    names = candidates or sorted(n for n in MECHANISMS if MECHANISMS[n].candidate)
    kinds = {n: mechanism_type(n) for n in names}  # a law, or a law at a site (LAW@SITE)
    sought = {n: (k.main, (k.range[0] / 100.0, k.range[1])) for n, k in kinds.items()}
    folder = tempfile.mkdtemp(prefix="dragline-detection-")
    try:
        _session(f"{folder}/session", seed, rig, duration)
        found = detection_thresholds(f"{folder}/session", rig, sought, workers=workers, progress=progress)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    out = {"seed": seed, "rig": rig_name or "dragline", "own_error_chi2": found["own_error_chi2"], "candidates": {}}
    for name, c in found["candidates"].items():
        p = c["threshold"]
        out["candidates"][name] = dict(c, main=kinds[name].main, range=list(kinds[name].range),
                                       multiples={f"{m}x": m * p for m in THRESHOLD_MULTIPLES})
    return out


def summary_lines(report):
    """Lines for the terminal: the target and each candidate's threshold with its multiples."""
    lines = [f"detection thresholds on {report.get('rig', 'dragline')}'s maneuver (own error chi2 "
             f"{report['own_error_chi2']:.4g}, seed {report['seed']}):"]
    for name, c in report["candidates"].items():
        m = c["multiples"]
        lines.append(f"  {name}: {c['main']} = {c['threshold']:.3g} ({c['status']}; range {c['range'][0]:g}-"
                     f"{c['range'][1]:g}); 2x {m['2x']:.3g}, 5x {m['5x']:.3g}, 20x {m['20x']:.3g}")
    return lines
