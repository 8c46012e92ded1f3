"""The stated interval's two calibrated constants, from kept diagnoses (part of ``dragline bench decisions``).

A named mechanism's stated uncertainty (``_summary.stated_uncertainty``,
in ln p) is the largest of its profile curvature, half its folds' spread,
its marginal with the rig free and a floor, with the part of the model's
own error that lies along its signature, ``s sqrt(E / D)`` (``E`` the
model's own error's chi2, ``D`` the candidate's held-out improvement), in
quadrature. The floor (now the search's resolution ``REFINE_XATOL``; it
was 0.05 before this calibration) and ``s`` (``ERROR_ALONG_SIGNATURE``) are
calibrated here on recorded cases whose truth is known - the correctly
named cases of earlier runs of the trusted-verdict set - never on the
fresh seed a figure is reported on.

The criterion, fixed before it was run: maximum likelihood, each case's
error ln(fitted / truth) normal with mean 0 and the stated variance, over
both constants at once; each one's 95 % interval from its profile
likelihood (chi2 with one degree of freedom, 1.92 below the maximum). A case whose joint refit ended at the edge of the span it was
then held to (exp(+-0.4) about the first fit, removed in 72297fa after
those runs) is left out: that bias had another cause, since removed.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from dragline.compare.diagnose._hypotheses import REFINE_XATOL
from dragline.compare.diagnose._summary import ERROR_ALONG_SIGNATURE

__all__ = ["interval_records", "calibrate_error_along", "interval_summary_lines", "load_interval_records",
           "INTERVAL_RECORDS"]

INTERVAL_RECORDS = os.path.join(os.path.dirname(__file__), "data", "interval_records.json")
"""The committed records: the correctly named cases of the trusted-verdict set's seeds 92, 94, 96 and 100."""

# The joint refit's old span about its first fit (ln p), and how near its edge a fit counts as held there.
OLD_SPAN = 0.4
AT_EDGE = 0.01
# One degree of freedom: the profile likelihood's 95 % interval lies within this of its maximum.
PROFILE_DROP = 0.5 * 3.841


def _first_fit(hypothesis):
    """The lowest point of the candidate's searched profile: its fit on the updated rig, before the joint refit."""
    return min(hypothesis["profile"], key=lambda p: p["chi2"])["value"]


def interval_records(report, diagnoses, label, span_until=False):
    """A discovery run's correctly named cases with what the stated interval is made of.

    Parameters
    ----------
    report : dict
        ``bench discovery --realism --json``'s figures.
    diagnoses : str
        The folder ``--keep-diagnoses`` wrote.
    label : str
        The run's name in the records.
    span_until : bool
        The run's code still held the joint refit to its span: a case held
        at its edge is marked ``excluded``.

    Returns
    -------
    list of dict
        ``set``, ``seed``, ``truth``, ``value``, ``fitted``, the stated
        interval's parts (ln p): ``profile_relative``, ``fold_spread``,
        ``marginal_relative`` (0 where the diagnosis had none), and
        ``own_error_chi2``, ``improvement`` and ``excluded`` (None or why).
    """
    records = []
    for case in report["worlds"]["realistic"]["cases"]:
        path = os.path.join(diagnoses, f"case{case['seed']}.json")
        if case["truth"] == "none" or case["verdict"] != case["truth"] or not os.path.isfile(path):
            continue
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        doc = doc.get("diagnosis", doc)
        h = next(h for h in doc["hypotheses"] if h["name"] == case["truth"])
        u = h.get("uncertainty") or {}
        if u.get("relative") is None:
            continue  # at a range bound: no interval stated
        fitted = h["parameters"][h["main_parameter"]]
        folds = [v for v in u["fold_values"] if v > 0]
        held = span_until and abs(abs(math.log(fitted / _first_fit(h))) - OLD_SPAN) < AT_EDGE
        records.append({"set": label, "seed": case["seed"], "truth": case["truth"], "value": case["value"],
                        "fitted": fitted, "profile_relative": u["profile_relative"],
                        "fold_spread": abs(math.log(folds[0] / folds[1])) / 2 if len(folds) == 2 else 0.0,
                        "marginal_relative": u.get("marginal_relative") or 0.0,
                        "own_error_chi2": doc["null_test"]["own_error_chi2"], "improvement": h["improvement"],
                        "excluded": "held at the joint refit's old span edge" if held else None})
    return records


def _columns(records):
    used = [r for r in records if not r["excluded"]]
    err = np.array([math.log(r["fitted"] / r["value"]) for r in used])
    parts = np.array([[r["profile_relative"], r["fold_spread"], r["marginal_relative"], REFINE_XATOL] for r in used])
    term = np.array([math.sqrt(r["own_error_chi2"] / r["improvement"]) for r in used])
    return err, parts, term


def _sd(floor, s, parts, term):
    return np.hypot(np.maximum(parts.max(axis=1), floor), s * term)


def _negative_log_likelihoods(floor, alongs, err, parts, term):
    """The negative log-likelihood at ``floor`` for each share in ``alongs`` (k,)."""
    base = np.maximum(parts.max(axis=1), floor)
    var = base[None, :] ** 2 + (np.asarray(alongs)[:, None] * term[None, :]) ** 2
    return 0.5 * np.sum(np.log(var) + err[None, :] ** 2 / var, axis=1)


def _coverage(floor, s, columns, z):
    err, parts, term = columns
    return float(np.mean(np.abs(err) <= z * _sd(floor, s, parts, term)))


def calibrate_error_along(records, floor=REFINE_XATOL, along=ERROR_ALONG_SIGNATURE,
                          floors=np.linspace(0.0, 0.1, 101), alongs=np.linspace(0.0, 0.5, 501)):
    """The floor and ``s`` by maximum likelihood on ``records`` (over the grids), each one's profile interval,
    and the coverage they give.

    Returns
    -------
    dict
        ``n_cases``, ``n_excluded``, ``sets``, per constant (``floor``,
        ``along``) its ``value`` in force, ``calibrated``, ``interval_95``
        and ``in_interval`` (a floor below the resolution ``REFINE_XATOL``
        is the resolution), and ``coverage_68`` / ``coverage_95`` over the
        records with the values in force and with the calibrated ones.
    """
    columns = _columns(records)
    nll = np.array([_negative_log_likelihoods(f, alongs, *columns) for f in floors])
    i, j = np.unravel_index(int(np.argmin(nll)), nll.shape)
    out = {"n_cases": int(columns[0].size), "n_excluded": sum(1 for r in records if r["excluded"]),
           "sets": sorted({r["set"] for r in records}), "constants": {}}
    for name, value, grid, profile in (("floor", floor, floors, nll.min(axis=1)),
                                       ("along", along, alongs, nll.min(axis=0))):
        inside = grid[profile <= profile.min() + PROFILE_DROP]
        lo, hi = float(max(inside.min(), REFINE_XATOL if name == "floor" else 0.0)), float(inside.max())
        best = float(grid[i if name == "floor" else j])
        out["constants"][name] = {"value": value, "calibrated": max(best, REFINE_XATOL) if name == "floor" else best,
                                  "interval_95": [lo, hi],
                                  "in_interval": lo <= max(value, REFINE_XATOL if name == "floor" else value) <= hi}
    fc, sc = (out["constants"][k]["calibrated"] for k in ("floor", "along"))
    for label, (f, s) in (("in_force", (floor, along)), ("calibrated", (fc, sc))):
        out[label] = {"coverage_68": _coverage(f, s, columns, 1.0), "coverage_95": _coverage(f, s, columns, 1.96)}
    return out


def interval_summary_lines(report):
    lines = [f"intervals: {report['n_cases']} correctly named cases ({report['n_excluded']} left out), "
             f"maximum likelihood:"]
    for name, c in report["constants"].items():
        lo, hi = c["interval_95"]
        lines.append(f"  {name} = {c['value']:g}: calibrated {c['calibrated']:.3g} (95 % profile interval "
                     f"{lo:.3g}-{hi:.3g})" + ("" if c["in_interval"] else "  (the value in force is outside)"))
    now, cal = report["in_force"], report["calibrated"]
    lines.append(f"  the 68 % / 95 % intervals cover {now['coverage_68']:.2f} / {now['coverage_95']:.2f} of them "
                 f"({cal['coverage_68']:.2f} / {cal['coverage_95']:.2f} calibrated)")
    return lines


def load_interval_records(path=INTERVAL_RECORDS):
    """The records in ``path`` (``interval_records``' list), or ValueError naming the file."""
    with open(path, encoding="utf-8") as f:
        try:
            return json.load(f)["records"]
        except (ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{path}: not an interval records file ({exc!r})") from None
