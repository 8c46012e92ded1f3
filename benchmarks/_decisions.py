"""The verdict's constants calibrated on kept diagnoses: ``dragline bench decisions``.

The rules ``decide`` applies after the null test (a signature a parameter
change makes, the share of the structure explained, the residual a named
mechanism may leave) read four constants (``DecisionRules``). Each is
calibrated here on recorded cases whose truth is known - the kept
diagnoses of earlier runs of the trusted-verdict set, reduced to what
``decide`` reads (``decision_records``) - never on the fresh seed a figure
is reported on. A verdict can change only where a constant crosses one of
the cases' own statistics, so every interval between two neighbouring
statistics is tried at its middle: the calibration is exact for the
records, not a grid's.

The criterion, fixed before it was run: fewest false names first (a
mechanism named on a recording with nothing added or with physics no
candidate expresses), then most right verdicts (``_discovery``'s rule: the
hidden mechanism named with its parameter within ``RIGHT_WITHIN``, "none"
where nothing was added, "none" or "unexplained" out of the menu). The
constant's calibrated value is the middle of the widest interval that
meets it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os

from dragline.compare import (
    SECOND_EXCESS_SHARE,
    DecisionRules,
    rethresholded,
    seconds_of_document,
    verdict_of_document,
)

from ._discovery import verdict_right
from ._intervals import calibrate_error_along, interval_summary_lines, load_interval_records

__all__ = ["decision_records", "write_decision_records", "calibrate_decisions", "summary_lines", "RECORDS"]

RECORDS = os.path.join(os.path.dirname(__file__), "data", "decision_records.json")
"""The committed calibration records: the trusted-verdict set's seeds 92 and 94 (docs/diagnosis.md)."""
PAIR_RECORDS = os.path.join(os.path.dirname(__file__), "data", "pair_records.json")
"""The committed two-mechanism records (``_pairs``), which bound ``SECOND_EXCESS_SHARE`` from above."""
ANOTHER_RIG_RECORDS = os.path.join(os.path.dirname(__file__), "data", "another_rig_records.json")
"""The committed another-rig records (``_another_rig``, seed 620), which calibrate ``DecisionRules.different_rig``."""

# The model-error share and its full excess in force for documents written before their null test named them.
MODEL_ERROR_SHARE_BEFORE_KEY = 0.25
MODEL_ERROR_FULL_BEFORE_KEY = 0.5
_HYPOTHESIS_KEYS = ("name", "main_parameter", "parameters", "improvement", "significant", "unresolved",
                    "resolved_improvement", "at_bound", "score", "explained_fraction", "rms_before", "rms_after",
                    "leftover_share", "credit_at_joint_rig", "leads", "nuisance_correlation")
_MISMATCH_KEYS = ("channel", "window", "t_start", "t_end")


def _short(entries):
    """Entries whose floats only the verdict's reason prints, at four digits."""
    return [{k: float(f"{v:.4g}") if isinstance(v, float) else v for k, v in e.items()} for e in entries]


def _hypothesis(h):
    out = {k: h[k] for k in _HYPOTHESIS_KEYS if k in h}
    if "leads" in out:  # rule 4 reads each lead's ``consistent``; its figures go into the reason
        out["leads"] = dict(zip(out["leads"], _short(out["leads"].values())))
    if "nuisance_correlation" in out:
        out["nuisance_correlation"] = _short(out["nuisance_correlation"])
    return out


def _n_weighted(doc):
    """The noise expectation (weighted samples) of a document written before its null test kept it.

    Each held-out RMS (in noise sigmas) is sqrt(held-out chi2 / it), and the
    improvement is the two chi2s' gap; where no candidate moved the held-out
    chi2, an unsaturated budget gives it (share excess^2 / (full n)). A
    saturated one bounds it only (at most excess / full); no candidate
    improving, the verdict is the same at any such value, and the bound is
    kept.
    """
    for h in doc["hypotheses"]:
        gap = h.get("rms_before", 0.0) ** 2 - h.get("rms_after", 0.0) ** 2
        if h.get("improvement") and abs(gap) > 1e-9:
            return float(h["improvement"] / gap)
    null = doc["null_test"]
    excess, allowance = null.get("excess_chi2_updated"), null.get("model_error_allowance")
    if not excess or not allowance:
        return None
    share = null.get("model_error_share_at_full", MODEL_ERROR_SHARE_BEFORE_KEY)
    full = null.get("model_error_full", MODEL_ERROR_FULL_BEFORE_KEY)
    if allowance < share * excess * (1.0 - 1e-9):
        return float(share * excess**2 / (full * allowance))
    return float(excess / full)


def _document(doc):
    """What ``verdict_of_document`` reads of a diagnosis document, and nothing else: of the mismatch left,
    whether there is one, and where it is largest."""
    after = doc.get("mismatch_after") or {}
    second = doc.get("second_mechanism") or {}
    if second.get("candidates"):
        second = {"noise_threshold": second["noise_threshold"], "allowance": second["allowance"],
                  "named_excess": second.get("named_excess"),
                  "candidates": [{k: h[k] for k in ("name", "parameters", "improvement", "resolved_improvement",
                                                    "at_bound")} for h in second["candidates"]]}
    return {
        "hypotheses": [_hypothesis(h) for h in doc["hypotheses"]],
        # The threshold's parts, so that the model-error share and the resolved share can be moved too.
        "null_test": {**{k: doc["null_test"].get(k) for k in ("threshold", "noise_threshold",
                                                               "model_error_allowance", "own_error_chi2",
                                                               "excess_chi2_updated")},
                      "model_error_share_at_full": doc["null_test"].get("model_error_share_at_full",
                                                                        MODEL_ERROR_SHARE_BEFORE_KEY),
                      "model_error_full": doc["null_test"].get("model_error_full", MODEL_ERROR_FULL_BEFORE_KEY),
                      "n_weighted": doc["null_test"].get("n_weighted") or _n_weighted(doc)},
        "settings": {k: v for k, v in doc.get("settings", {}).items() if k == "resolved_min"},
        "mismatch_updated": [{k: e[k] for k in _MISMATCH_KEYS} for e in doc["mismatch_updated"][:1]],
        "mismatch_after": {"entries": [{k: e[k] for k in _MISMATCH_KEYS} for e in after.get("entries", [])[:1]]},
        "offsets_beyond_tolerance": doc.get("offsets_beyond_tolerance"),
        "offsets_judged": doc.get("offsets_judged"),  # judged anew under another ``different_rig``
        "reason": doc["reason"],  # rule 1's text, for a document written before the key above
        "second_mechanism": second or None,
    }


def decision_records(report, diagnoses, label):
    """A discovery run's cases with what ``decide`` read in each, from its kept diagnoses.

    Parameters
    ----------
    report : dict
        ``bench discovery --realism --json``'s figures (its ``realistic`` world's cases).
    diagnoses : str
        The folder ``--keep-diagnoses`` wrote (``case<seed>.json``).
    label : str
        The run's name in the records (say "seed 94, d3ce39b").

    Returns
    -------
    list of dict
        Per case with a kept diagnosis: ``set``, ``seed``, ``truth``,
        ``value``, ``out_of_menu``, ``verdict`` (as the run gave it) and
        ``document``.
    """
    records = []
    for case in report["worlds"]["realistic"]["cases"]:
        path = os.path.join(diagnoses, f"case{case['seed']}.json")
        if not os.path.isfile(path):
            continue  # a case whose diagnosis stopped on an error kept none
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        doc = doc.get("diagnosis", doc)
        records.append({"set": label, "seed": case["seed"], "truth": case["truth"], "value": case["value"],
                        "out_of_menu": bool(case["out_of_menu"]), "verdict": case["verdict"],
                        "document": _document(doc)})
    return records


def write_decision_records(path, records, origin):
    """``records`` as a file ``bench decisions --records`` reads, with the rules they were decided under."""
    data = {"origin": origin, "licence": "MIT, as the repository",
            "rules_in_force": dataclasses.asdict(DecisionRules()), "records": records}
    tmp = f"{path}.tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(data, f, separators=(",", ":"))
    os.replace(tmp, path)


def _judged(record, verdict):
    """(right, false name) of ``verdict`` on ``record``."""
    h = next((h for h in record["document"]["hypotheses"] if h["name"] == verdict), None)
    fitted = None if h is None else h["parameters"][h["main_parameter"]]
    right = verdict_right(record["truth"], record["value"], record["out_of_menu"], verdict, fitted)
    nothing_nameable = record["out_of_menu"] or record["truth"] == "none"
    return right, nothing_nameable and verdict not in ("none", "unexplained")


def _best_significant(hypotheses):
    return next((h["name"] for h in hypotheses if h.get("significant")), None)


def _tally(records, rules):
    """(right, false names, moved): ``moved`` counts the records whose best significant candidate is not their
    diagnosis's own under ``rules`` (their re-decision reads the mismatch the first best left)."""
    right = false = moved = 0
    for record in records:
        r, f = _judged(record, verdict_of_document(record["document"], rules))
        hypotheses, _ = rethresholded(record["document"], rules)
        moved += _best_significant(hypotheses) != _best_significant(record["document"]["hypotheses"])
        right, false = right + r, false + f
    return right, false, moved


def _statistics(records, field, base):
    """The values of the cases' own statistic that ``field``'s constant is compared with (the other
    constants at ``base``)."""
    values = set()
    for record in records:
        doc = record["document"]
        if field == "model_error_share":  # where the scaled budget crosses a gain the threshold is compared with
            null = doc["null_test"]
            if not null.get("model_error_allowance"):
                continue
            per_share = null["model_error_allowance"] / null["model_error_share_at_full"]
            for h in doc["hypotheses"]:
                credit = (h.get("credit_at_joint_rig") or {}).get("credit")
                for x in (h["improvement"], h.get("resolved_improvement", 0.0) / base.resolved_min, credit):
                    if x is not None and x > 0:
                        values.add(float(x / per_share))
            continue
        if field == "model_error_full":  # where the unsaturated budget crosses a gain, and where it saturates
            null = doc["null_test"]
            excess, n_w = null.get("excess_chi2_updated"), null.get("n_weighted")
            if not null.get("model_error_allowance") or not excess or not n_w:
                continue
            values.add(float(excess / n_w))
            for h in doc["hypotheses"]:
                credit = (h.get("credit_at_joint_rig") or {}).get("credit")
                for x in (h["improvement"], h.get("resolved_improvement", 0.0) / base.resolved_min, credit):
                    if x is not None and x > 0:
                        values.add(float(base.model_error_share * excess**2 / (x * n_w)))
            continue
        if field == "different_rig":  # where the factor crosses an offset left after updating
            judged = doc.get("offsets_judged") or {}
            if judged.get("after_updating"):
                values.update(abs(offset) / limit for offset, limit in judged["channels"].values())
            continue
        if field == "resolved_min":
            _, threshold = rethresholded(doc, base)
            values.update(float(h["resolved_improvement"] / threshold) for h in doc["hypotheses"]
                          if h.get("resolved_improvement") is not None)
            continue
        for h in doc["hypotheses"]:
            if field == "confounded":
                values.update(abs(e["correlation"]) for e in h.get("nuisance_correlation") or ())
            else:
                key = {"explained_min": "explained_fraction", "adequate_rms": "rms_after",
                       "leftover_share": "leftover_share"}[field]
                if h.get(key) is not None:
                    values.add(float(h[key]))
    return sorted(values)


def _scan(records, field, base):
    """Every interval between neighbouring statistics, tried at its middle: [(lo, hi, right, false, moved)]."""
    stats = _statistics(records, field, base)
    edges = [-math.inf, *stats, math.inf]
    rows = []
    for lo, hi in zip(edges, edges[1:]):
        if math.isinf(lo) and math.isinf(hi):
            probe = getattr(base, field)
        elif math.isinf(lo):
            probe = hi - max(abs(hi), 1.0)
        elif math.isinf(hi):
            probe = lo + max(abs(lo), 1.0)
        else:
            probe = 0.5 * (lo + hi)
        rows.append((lo, hi, *_tally(records, dataclasses.replace(base, **{field: probe}))))
    return rows


def calibrate_decisions(records, rules=None):
    """Each of ``DecisionRules``' constants calibrated on ``records``, the others held at ``rules``.

    Returns
    -------
    dict
        ``n_cases``, ``sets``, ``criterion``, ``current`` (right and false
        names under ``rules``), and per constant its ``value``, the best
        ``right`` and ``false_names``, the ``intervals`` that reach them
        (merged where neighbouring), the widest one's middle
        (``calibrated``; an unbounded interval has none), ``in_interval``
        (whether the value in force lies in one) and ``best_changed`` (the
        most records, over those intervals, whose best significant
        candidate is another than their diagnosis's: their re-decision
        reads the mismatch the first best left, so the figure is exact
        only where it is 0).
    """
    rules = rules or DecisionRules()
    right, false, _ = _tally(records, rules)
    out = {"n_cases": len(records), "sets": sorted({r["set"] for r in records}),
           "criterion": "fewest false names, then most right verdicts",
           "current": {"right": right, "false_names": false}, "constants": {}}
    for field in (f.name for f in dataclasses.fields(DecisionRules)):
        rows = _scan(records, field, rules)
        best = min((f, -r) for _, _, r, f, _ in rows)
        merged, moved = [], 0
        for lo, hi, r, f, m in rows:
            if (f, -r) != best:
                continue
            moved = max(moved, m)
            if merged and merged[-1][1] == lo:
                merged[-1][1] = hi
            else:
                merged.append([lo, hi])
        widest = max(merged, key=lambda iv: iv[1] - iv[0])
        value = getattr(rules, field)
        out["constants"][field] = {
            "value": value, "right": -best[1], "false_names": best[0],
            "intervals": [[None if math.isinf(a) else a, None if math.isinf(b) else b] for a, b in merged],
            "calibrated": None if any(map(math.isinf, widest)) else 0.5 * (widest[0] + widest[1]),
            "in_interval": any(a < value < b for a, b in merged),
            "best_changed": moved,
        }
    return out


def calibrate_second_share(records, share=SECOND_EXCESS_SHARE, pairs=()):
    """``SECOND_EXCESS_SHARE`` between records where every second is false and records where it is true.

    ``records`` (one hidden mechanism or none) bound the share from below:
    the least share at which none of them shows a second mechanism
    (``lowest``, with the case that sets it, ``set_by``). ``pairs``
    (``_pairs.pair_records``: two hidden, the verdict naming one) bound it
    from above: the least share up to which every such record still names
    the other (``highest``, ``highest_set_by``); a record whose other is
    named at no share bounds nothing (``never_named``).
    """
    from ._pairs import second_share

    flips = {record["seed"]: second_share(record["document"]) for record in records}
    set_by = max(flips, key=flips.get) if flips else None
    lowest = flips.get(set_by, 0.0)
    others = {}
    for r in pairs:
        other = {r["truth"]: r["second"], r["second"]: r["truth"]}.get(r["verdict"])
        if other is not None:
            others[r["seed"]] = second_share(r["document"], other)
    named = {seed: s for seed, s in others.items() if s > 0.0}
    high_by = min(named, key=named.get) if named else None
    highest = named.get(high_by, math.inf)
    return {"value": share, "lowest": lowest, "set_by": set_by, "n_records": len(records),
            "false_seconds": sum(bool(seconds_of_document(r["document"], share)) for r in records),
            "n_pairs": len(pairs), "n_pairs_named": len(others),
            "highest": None if math.isinf(highest) else highest, "highest_set_by": high_by,
            "never_named": sorted(seed for seed, s in others.items() if s == 0.0),
            "missed_seconds": sum(1 for s in named.values() if s <= share),
            "in_interval": lowest < share < highest}


def summary_lines(report):
    cur = report["current"]
    lines = [f"{report['n_cases']} cases ({', '.join(report['sets'])}): {cur['right']} right, "
             f"{cur['false_names']} false names with the constants in force"]
    for field, c in report["constants"].items():
        spans = ", ".join(f"{'-inf' if a is None else f'{a:.3g}'} to {'inf' if b is None else f'{b:.3g}'}"
                          for a, b in c["intervals"])
        lines.append(f"  {field} = {c['value']:g}: best {c['right']} right, {c['false_names']} false names for "
                     f"values in {spans}" + ("" if c["in_interval"] else "  (the value in force is outside)"))
    second = report.get("second_excess_share")
    if second is not None:
        lines.append(f"  second_excess_share = {second['value']:g}: {second['false_seconds']} false second mechanisms; "
                     f"none from {second['lowest']:.3g} up (set by case {second['set_by']})")
        if second.get("highest") is not None:
            lines.append(f"    and {second['missed_seconds']} missed of the hidden seconds of the "
                         f"{second['n_pairs_named']} two-mechanism cases (of {second['n_pairs']}) whose verdict named "
                         f"one of the two; every one "
                         f"named below {second['highest']:.3g} (set by case "
                         f"{second['highest_set_by']}; named at no share: {second['never_named'] or 'none'})"
                         + ("" if second["in_interval"] else "  (the value in force is outside)"))
    return lines


def bench_command(args):
    """``dragline bench decisions [--records FILE ...]``: the calibration on the committed or given records, and
    the stated interval's constants on the committed interval records (``_intervals``)."""
    records = []
    for path in args.records or [RECORDS]:
        with open(path, encoding="utf-8") as f:
            try:
                records.extend(json.load(f)["records"])
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"{path}: not a decision records file ({exc!r})") from None
    report = calibrate_decisions(records)
    pairs = []
    if os.path.isfile(PAIR_RECORDS):
        with open(PAIR_RECORDS, encoding="utf-8") as f:
            pairs = json.load(f)["records"]
    report["second_excess_share"] = calibrate_second_share(records, pairs=pairs)
    lines = summary_lines(report)
    with open(ANOTHER_RIG_RECORDS, encoding="utf-8") as f:
        another = calibrate_decisions(json.load(f)["records"])
    report["different_rig"] = dict(another["constants"]["different_rig"], n_cases=another["n_cases"])
    lines += ["another-rig records (seed 620):"] + summary_lines(
        dict(another, constants={"different_rig": report["different_rig"]}))
    report["intervals"] = calibrate_error_along(load_interval_records())
    return report, lines + interval_summary_lines(report["intervals"])
