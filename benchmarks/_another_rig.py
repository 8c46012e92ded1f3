"""Recordings of another rig: ``dragline bench discovery --realism --another-rig``.

The rule that a recording is of another rig (``DIFFERENT_RIG``: a constant
offset, left after updating, that many times the calibration's accuracy)
must fire on a rig whose geometry lies beyond what updating may move, and
on no rig within its tolerances. Both kinds of case are made here, from
fresh truth rigs simulated finer than the diagnosis:

- **another rig**: each kind of geometric parameter (a fixed point's
  coordinates, a body's mass centre, a winch's reel zero), all of its
  parameters at once, set to ``ANOTHER_RIG_BOUNDS`` times the updating's
  bound (``BOUND_TOLERANCES`` tolerances), on the side the truth rig's own
  draw put it; the right verdict names no mechanism (a recording refused
  at the door, its rope lengths off the reel table, names none either);
- **within tolerance**: every candidate at ``ANOTHER_RIG_WITHIN`` times its
  detection threshold (a mechanism shifts the mean pose) and
  ``ANOTHER_RIG_NONE`` with nothing added.

The cases, magnitudes and the criterion below were fixed before the first
run. Each case records the largest offset the rule judged, as a multiple
of the calibration's accuracy (``offset_ratio``), and, where the rule
fired, the verdict without it. The factor is bounded from below by the
within-tolerance cases (it must exceed every ratio they reach) and from
above by the another-rig cases that without the rule would name a
mechanism (it must lie below each of their ratios).
"""

from __future__ import annotations

import math

import numpy as np

from dragline.compare import BOUND_TOLERANCES, DecisionRules, verdict_of_document
from dragline.simulate import MECHANISMS

__all__ = ["ANOTHER_RIG", "ANOTHER_RIG_KINDS", "ANOTHER_RIG_BOUNDS", "another_rig_cases", "beyond_bounds",
           "another_rig_entries", "another_rig_figures", "summary_lines"]

ANOTHER_RIG = "another_rig:"
ANOTHER_RIG_KINDS = ("fixed_point", "cg", "reel_zero")
# 1.5: just beyond updating's reach (half a bound left over); 6: far beyond it.
ANOTHER_RIG_BOUNDS = (1.5, 3.0, 6.0)
ANOTHER_RIG_WITHIN = 5
ANOTHER_RIG_NONE = 5


def another_rig_cases(seed=0):
    """The cases: ``(truth, value, seed, "realistic")``; an another-rig truth is ``"another_rig:KIND"`` with
    its multiple of the updating's bound as the value."""
    from ._discovery import DETECTION_THRESHOLDS, _three_digits

    cases = [(ANOTHER_RIG + kind, m) for kind in ANOTHER_RIG_KINDS for m in ANOTHER_RIG_BOUNDS]
    cases += [(name, _three_digits(ANOTHER_RIG_WITHIN * t)) for name, t in sorted(DETECTION_THRESHOLDS.items())]
    cases += [(None, 0.0)] * ANOTHER_RIG_NONE
    return [(name, float(value), seed * 1000 + 700 + k, "realistic") for k, (name, value) in enumerate(cases)]


def beyond_bounds(parameters, coordinates, kind, bounds):
    """``coordinates`` with every parameter of ``kind`` at ``bounds`` times the updating's bound.

    Parameters
    ----------
    parameters : sequence of RigParameter
    coordinates : ndarray (k,)
        The truth rig's drawn coordinates (tolerance units times the
        tolerance); the sign of each sets its side (positive where zero).
    kind : str
        ``RigParameter.kind``: "fixed_point", "cg" or "reel_zero".
    bounds : float

    Returns
    -------
    ndarray (k,)
        A new array; a ``ValueError`` where the rig has no parameter of that kind.
    """
    out = np.array(coordinates, float)
    hits = [i for i, p in enumerate(parameters) if p.kind == kind]
    if not hits:
        raise ValueError(f"the rig has no {kind} parameter to move")
    for i in hits:
        side = 1.0 if out[i] >= 0.0 else -1.0
        out[i] = side * bounds * BOUND_TOLERANCES * parameters[i].tolerance
    return out


def another_rig_entries(doc):
    """What a case records of its diagnosis for this rule: ``offset_ratio`` (the largest judged offset over
    the calibration's accuracy, after updating; None without tolerances), ``offset_rule`` (whether it fired)
    and, where it did, ``verdict_without_offset_rule``."""
    judged = doc.get("offsets_judged") or {}
    ratio = None
    if judged.get("after_updating") and judged.get("channels"):
        ratio = max(abs(offset) / limit for offset, limit in judged["channels"].values())
    fired = bool(doc.get("offsets_beyond_tolerance"))
    out = {"offset_ratio": ratio, "offset_rule": fired}
    if fired:
        out["verdict_without_offset_rule"] = verdict_of_document(doc, DecisionRules(different_rig=math.inf))
    return out


def another_rig_figures(results):
    """The rule's figures over a run's cases: how many another-rig cases named no mechanism, how often the
    rule fired within tolerance, and the factor's bounds from below and above (None where no case sets one)."""
    another = [r for r in results if r["truth"].startswith(ANOTHER_RIG)]
    within = [r for r in results if not r["truth"].startswith(ANOTHER_RIG)]
    below = {r["seed"]: r["offset_ratio"] for r in within if r.get("offset_ratio") is not None}
    above = {r["seed"]: r["offset_ratio"] for r in another if r.get("offset_ratio") is not None
             and r.get("verdict_without_offset_rule", r["verdict"]) in MECHANISMS}
    low_by = max(below, key=below.get) if below else None
    high_by = min(above, key=above.get) if above else None
    return {
        "n_another_rig": len(another),
        "another_rig_right": sum(bool(r["right"]) for r in another),
        "another_rig_named_a_mechanism": sum(r["verdict"] in MECHANISMS for r in another),
        "another_rig_offsets_said": sum("constant offsets" in r.get("reason", "") for r in another),
        "another_rig_rule_fired": sum(bool(r.get("offset_rule")) for r in another),
        # Refused at the door: the recorded rope lengths off the reel table beyond its tolerance.
        "another_rig_refused": sum(r["verdict"] == "error" for r in another),
        "n_within_tolerance": len(within),
        "within_tolerance_rule_fired": sum(bool(r.get("offset_rule")) for r in within),
        "factor_in_force": DecisionRules().different_rig,
        "lowest": below.get(low_by), "lowest_set_by": low_by,
        "highest": above.get(high_by), "highest_set_by": high_by,
        "ratios": {str(r["seed"]): {"truth": r["truth"], "value": r["value"], "offset_ratio": r.get("offset_ratio"),
                                    "verdict": r["verdict"],
                                    "without_rule": r.get("verdict_without_offset_rule", r["verdict"])}
                   for r in results},
    }


def summary_lines(figures):
    """The rule's figures in words."""
    f = figures

    def fmt(x):
        return "-" if x is None else f"{x:.3g}"

    return [
        f"another rig: {f['another_rig_right']} of {f['n_another_rig']} named no mechanism "
        f"({f['another_rig_named_a_mechanism']} named one); the offsets were said on {f['another_rig_offsets_said']}, "
        f"the rule fired on {f['another_rig_rule_fired']}, {f['another_rig_refused']} refused at the door",
        f"within tolerance: the rule fired on {f['within_tolerance_rule_fired']} of {f['n_within_tolerance']}",
        f"DIFFERENT_RIG ({fmt(f['factor_in_force'])} in force): from below {fmt(f['lowest'])} (case "
        f"{f['lowest_set_by']}), from above {fmt(f['highest'])} (case {f['highest_set_by']})",
    ]
