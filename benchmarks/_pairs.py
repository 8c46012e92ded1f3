"""Two hidden mechanisms at once: ``dragline bench discovery --realism --pairs``.

The verdict names one mechanism; the second round (``_second_round``)
reports another beside it when it explains more than
``SECOND_EXCESS_SHARE`` of what the named model leaves above noise. Cases
with one hidden mechanism or none bound that share from below only (every
second named there is false); these cases, each with two, bound it from
above: the share up to which the hidden second is still named.

Each case is a realistic one (``_discovery._truth_world``: the truth rig
drawn within the tolerances, simulated finer, filmed by the lab) with a
dominant mechanism at ``FIRST_MULTIPLE`` times its detection threshold and
a second at ``SECOND_MULTIPLE`` times its own, for each ordered pair in
``PAIRS`` - fixed before the first run. The diagnosis gets the session
directory alone, as a user's would.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time

from dragline.compare import SECOND_EXCESS_SHARE, as_executor, diagnose_path, seconds_of_document
from dragline.simulate import MECHANISMS, default_maneuver, load_rig, make_mechanism, simulate

from ._discovery import DETECTION_THRESHOLDS, RIGHT_WITHIN, _film, _no_context, _three_digits, _truth_world, keeper

__all__ = ["PAIRS", "pair_cases", "bench_pairs", "second_share", "pair_records", "summary_lines"]

FIRST_MULTIPLE = 20
SECOND_MULTIPLE = 5
# Each candidate dominant once, and the pair the tests hold (a sheave's inertia under air drag).
PAIRS = (("pulley_friction", "pulley_inertia"), ("aero_drag", "chain_link_friction"),
         ("chain_link_friction", "rope_bending_damping"), ("rope_bending_damping", "aero_drag"),
         ("pulley_inertia", "pulley_friction"), ("aero_drag", "pulley_inertia"))


def pair_cases(seed=0):
    """``(first, value, second, value, seed)`` per pair, each at its multiple of its detection threshold."""
    return [(a, _three_digits(FIRST_MULTIPLE * DETECTION_THRESHOLDS[a]),
             b, _three_digits(SECOND_MULTIPLE * DETECTION_THRESHOLDS[b]), seed * 1000 + 500 + k)
            for k, (a, b) in enumerate(PAIRS)]


def second_share(document, name=None):
    """The largest share of the named model's excess at which ``document``'s second round still names
    ``name`` (any second mechanism when None; 0 where it never does): bisection, the names only shrinking
    as the share grows."""

    def named(share):
        seconds = seconds_of_document(document, share)
        return bool(seconds) if name is None else name in seconds

    if not named(0.0):
        return 0.0
    lo, hi = 0.0, 1.0
    while named(hi):
        lo, hi = hi, 2.0 * hi
    while hi - lo > 1e-6 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if named(mid) else (lo, mid)
    return hi


def _fitted(doc, name):
    """The value the diagnosis gives ``name``: the verdict's, or the second round's."""
    for h in [*doc["hypotheses"][:1], *((doc.get("second_mechanism") or {}).get("candidates") or ())]:
        if h["name"] == name:
            return h["parameters"][MECHANISMS[name].main]
    return None


def _run_pair(first, v1, second, v2, seed, workdir=None, keep=False):
    """One blind session with two hidden mechanisms, diagnosed from its directory, scored here."""
    own = workdir is None
    workdir = tempfile.mkdtemp(prefix="dragline-pair-") if own else workdir
    folder = os.path.join(workdir, f"case{seed}")
    machine = load_rig()
    rig, maneuver, discretization, _, _ = _truth_world(None, 0.0, seed)
    physics = [make_mechanism(first, **{MECHANISMS[first].main: v1}),
               make_mechanism(second, **{MECHANISMS[second].main: v2})]
    result = simulate(rig, maneuver, discretization, physics, duration=10.0, rate_hz=200.0)
    _film(result, machine, seed, folder, default_maneuver(machine))
    out = {"truth": first, "value": v1, "second": second, "second_value": v2, "seed": seed}
    t0 = time.perf_counter()
    try:
        doc = diagnose_path(folder, rig=machine, workers=1, seed=seed).doc
    except ValueError as exc:
        out.update(verdict="error", reason=str(exc), diagnosis_seconds=time.perf_counter() - t0)
        return out
    finally:
        shutil.rmtree(workdir if own else folder, ignore_errors=True)
    other = {first: second, second: first}.get(doc["verdict"])
    seconds = seconds_of_document(doc, SECOND_EXCESS_SHARE)
    out.update(verdict=doc["verdict"], reason=doc["reason"], diagnosis_seconds=time.perf_counter() - t0,
               also=seconds, fitted={first: _fitted(doc, first), second: _fitted(doc, second)},
               other=other, other_share=second_share(doc, other) if other else 0.0)
    out["both_named"] = other is not None and other in seconds
    out["both_right"] = out["both_named"] and all(
        out["fitted"][n] is not None and abs(out["fitted"][n] / v - 1.0) <= RIGHT_WITHIN
        for n, v in ((first, v1), (second, v2)))
    if keep:
        out["diagnosis"] = doc
    return out


def bench_pairs(seed=0, workers=2, keep=None, progress=None):
    """Run the two-mechanism cases; ``keep``: a folder for every case's diagnosis (``case<seed>.json``).

    Returns
    -------
    dict
        ``cases`` (per case: both truths, verdict, the second round's
        names at the share in force, both fitted values, the other's
        ``other_share``), ``both_named``, ``both_right`` and
        ``second_share_upper`` (the least ``other_share`` over the cases
        whose verdict is one of the two and whose other is named at some
        share: the share must lie below it for every such second to be
        named), ``timing``.
    """
    executor = as_executor(workers)
    workdir = tempfile.mkdtemp(prefix="dragline-pairs-")
    started = time.perf_counter()

    finished = keeper(keep, progress, _line)
    session = executor.open(_no_context)
    try:
        results = session.map(_run_pair, [(*c, workdir, bool(keep)) for c in pair_cases(seed)], each=finished)
    finally:
        session.close()
        shutil.rmtree(workdir, ignore_errors=True)
    bounded = [r for r in results if r.get("other_share", 0.0) > 0.0]
    upper = min(bounded, key=lambda r: r["other_share"]) if bounded else None
    return {"cases": results, "n_cases": len(results),
            "both_named": sum(bool(r.get("both_named")) for r in results),
            "both_right": sum(bool(r.get("both_right")) for r in results),
            "second_share_in_force": SECOND_EXCESS_SHARE,
            "second_share_upper": upper["other_share"] if upper else None,
            "second_share_upper_set_by": upper["seed"] if upper else None,
            "timing": {"wall_s": time.perf_counter() - started,
                       "diagnosis_s": [r.get("diagnosis_seconds") for r in results]}}


def _line(r):
    fits = ", ".join(f"{n} {v:.3g}" for n, v in (r.get("fitted") or {}).items() if v is not None)
    return (f"{r['truth']}={r['value']:g} + {r['second']}={r['second_value']:g} -> {r['verdict']}"
            f" + {r.get('also') or []} (fitted {fits}; the other named up to share {r.get('other_share', 0):.3g};"
            f" {r.get('diagnosis_seconds', 0):.0f} s)")


def pair_records(report, diagnoses, label):
    """The cases as records ``calibrate_second_share`` reads: ``set``, ``seed``, ``truth``, ``value``,
    ``second``, ``second_value``, ``verdict`` and the ``document`` as ``_decisions`` reduces it."""
    from ._decisions import _document

    records = []
    for case in report["cases"]:
        path = os.path.join(diagnoses, f"case{case['seed']}.json")
        if not os.path.isfile(path):
            continue
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        records.append({"set": label, **{k: case[k] for k in ("seed", "truth", "value", "second", "second_value",
                                                               "verdict")},
                        "document": _document(doc.get("diagnosis", doc))})
    return records


def summary_lines(report):
    lines = [f"{report['n_cases']} cases with two hidden mechanisms: both named {report['both_named']}, both right "
             f"{report['both_right']} (within {RIGHT_WITHIN:.0%}); at the share in force "
             f"({report['second_share_in_force']:g})"]
    if report["second_share_upper"] is not None:
        lines.append(f"  every hidden second is named below share {report['second_share_upper']:.3g} "
                     f"(set by case {report['second_share_upper_set_by']})")
    for r in report["cases"]:
        lines.append("  " + _line(r))
    return lines
