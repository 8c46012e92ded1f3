"""Leave one trial out: every trial predicted by a diagnosis fitted on all the others.

Of several trials of one machine, each in turn is left out: the others are
diagnosed together (``_trials``) and the one left out is predicted
(``_predict``). What comes back says whether the diagnosis can be trusted
on this machine: how often the verdict is the same, how far each shared
parameter moves between splits against its stated uncertainty, and how
often the updated model (and the named one) predicts a trial it never saw
better than the nominal model (than the updated one).
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["leave_one_out", "split_summary"]


def leave_one_out(measured, maneuvers, names, progress=None, on_split=None, **settings):
    """Diagnose every trial but one together and predict the one left out, for each trial.

    Parameters
    ----------
    measured, maneuvers : list
        The trials' trajectory tables and maneuvers.
    names : list of str
    progress : callable, optional
        One line per split.
    on_split : callable, optional
        Called with each split's ``Diagnosis`` (a figure of it, say).
    **settings
        ``diagnose``'s other arguments (``rig``, ``discretization``,
        ``candidates``, ``workers``, ``seed``).

    Returns
    -------
    dict
        ``split_summary`` of the splits.
    """
    from ._diagnose import diagnose

    note = progress or (lambda line: None)
    if len(measured) < 2:
        raise ValueError(f"leaving one trial out needs at least two trials, got {len(measured)}")
    splits = []
    for k, held in enumerate(names):
        fitted = [n for n in names if n != held]
        tables = [t for j, t in enumerate(measured) if j != k]
        mans = [m for j, m in enumerate(maneuvers) if j != k]
        started = time.perf_counter()
        try:
            result = diagnose(tables if len(tables) > 1 else tables[0], mans if len(mans) > 1 else mans[0],
                              trial_names=fitted if len(fitted) > 1 else None,
                              held_out=[(held, measured[k], maneuvers[k])], **settings)
        except ValueError as exc:
            splits.append({"held_out": held, "fitted": fitted, "verdict": "error", "reason": str(exc)})
            note(f"without {held}: error: {exc}")
            continue
        if on_split is not None:
            on_split(result)
        doc = result.doc
        (predicted,) = doc["held_out"]
        splits.append({"held_out": held, "fitted": fitted, "verdict": doc["verdict"], "reason": doc["reason"],
                       "parameters": {e["parameter"]: {"estimate": e["estimate"], "uncertainty": e["uncertainty"],
                                                       "shift_in_tolerances": e["shift_in_tolerances"],
                                                       "identifiable": e["identifiable"]}
                                      for e in doc["calibration"]["parameters"]},
                       "held_out_rms_noise": predicted["rms_noise"],
                       "held_out_rms_channels": predicted["rms_channels"],
                       "seconds": time.perf_counter() - started})
        rms = predicted["rms_noise"]
        note(f"without {held}: {doc['verdict']}; held-out RMS (noise units) "
             + ", ".join(f"{m} {v:.3g}" for m, v in rms.items() if v is not None)
             + f" ({time.perf_counter() - started:.0f} s)")
    return split_summary(splits)


def _share(pairs):
    pairs = [(a, b) for a, b in pairs if a is not None and b is not None]
    return float(np.mean([a < b for a, b in pairs])) if pairs else None


def split_summary(splits):
    """What the splits say together.

    Returns
    -------
    dict
        ``splits``; ``verdicts`` (verdict -> count) and
        ``verdict_agreement`` (the most common verdict's share);
        ``parameters`` (per parameter: min, median, max and standard
        deviation of the estimates over splits, the median stated
        uncertainty, ``n``); ``updated_better_share`` and
        ``named_better_share`` (splits where the updated model predicts the
        trial left out better than the nominal one, and the named model
        better than the updated one, among splits that name one).
    """
    done = [s for s in splits if s["verdict"] != "error"]
    verdicts = {}
    for s in splits:
        verdicts[s["verdict"]] = verdicts.get(s["verdict"], 0) + 1
    spread = {}
    for s in done:
        for name, e in s["parameters"].items():
            spread.setdefault(name, []).append((e["estimate"], e["uncertainty"]))
    parameters = {k: {"min": float(min(e for e, _ in v)), "median": float(np.median([e for e, _ in v])),
                      "max": float(max(e for e, _ in v)), "sd": float(np.std([e for e, _ in v])),
                      "median_uncertainty": float(np.median([u for _, u in v])), "n": len(v)}
                  for k, v in spread.items()}
    rms = [s["held_out_rms_noise"] for s in done]
    return {"splits": splits, "verdicts": verdicts,
            "verdict_agreement": max(verdicts.values()) / len(splits) if splits else None,
            "parameters": parameters,
            "updated_better_share": _share([(r.get("updated"), r.get("nominal")) for r in rms]),
            "named_better_share": _share([(r.get("named"), r.get("updated")) for r in rms if "named" in r]),
            "note": "each split fits every trial but one together (shared rig and mechanism parameters, each "
                    "trial its own offsets) and predicts the one left out"}
