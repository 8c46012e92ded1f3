"""``dragline bench real --data DIR``: the diagnosis on real flights, and each flight's update tried on the others.

The data are the Stormlord slung-load flights (``docs/real-recordings.md``):
``DIR/rosbag_NN/dataset.csv`` with the bag's ``metadata.yaml`` beside it,
as the repository's ``data_combined_system`` folder holds them. For each
flight: its mean row rate from the metadata (``/payload/world_pose``
messages over the bag's duration), its first ``TRIAL_ROWS`` rows (the
hover the flight starts from, with the load at rest, then the first moves:
a trial that starts at rest, as the model does), read through the
dataset's mapping with the clock recovered from the motion, and diagnosed
from that file alone.

Then every flight's updated rig predicts every other flight, which it never
saw: the load's position error (m, RMS over the trial, per-channel means
removed as the diagnosis removes offsets) of the nominal rig and of the
rig updated on another flight. Not yet: fits that share parameters over
several flights (issue 36).
"""

from __future__ import annotations

import itertools
import re
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["bench_real", "summary_lines", "TRIAL_ROWS"]

TRIAL_ROWS = 900
_HERE = Path(__file__).resolve().parent / "real"
RIG = _HERE / "stormlord.toml"
MAPPING = _HERE / "stormlord_mapping.toml"
_CHANNELS = ("load.x", "load.y", "load.z")


def find_flights(data):
    """``(name, dataset.csv, metadata.yaml)`` of every flight folder under ``data``, in name order."""
    data = Path(data)
    if not data.is_dir():
        raise ValueError(f"{data}: no such folder (the Stormlord repository's data_combined_system)")
    flights = []
    for folder in sorted(p for p in data.iterdir() if p.is_dir()):
        csv, meta = folder / "dataset.csv", folder / "metadata.yaml"
        if csv.is_file() and meta.is_file():
            flights.append((folder.name, csv, meta))
    if not flights:
        raise ValueError(f"{data}: no flight folder with a dataset.csv and a metadata.yaml")
    return flights


def row_rate(metadata, topic="/payload/world_pose"):
    """Rows per second of a flight's log: ``topic``'s message count over the bag's duration (rosbag2
    ``metadata.yaml``)."""
    text = Path(metadata).read_text()
    duration = re.search(r"duration:\s*\n\s*nanoseconds:\s*(\d+)", text)
    block = text.split(f"name: {topic}\n", 1)
    count = re.search(r"message_count:\s*(\d+)", block[1]) if len(block) == 2 else None
    if duration is None or count is None:
        raise ValueError(f"{metadata}: no bag duration or no {topic} message count")
    return int(count.group(1)) / (int(duration.group(1)) * 1e-9)


def _trial(csv, rows, folder):
    """The flight's first ``rows`` rows as a file of their own (the log is read as it is, only cut)."""
    with open(csv) as src:
        lines = list(itertools.islice(src, rows))
    path = Path(folder) / f"{Path(csv).parent.name}.csv"
    path.write_text("".join(lines))
    return path


def _mapping_at(rate):
    from dragline.capture import load_tracked_mapping

    mapping = load_tracked_mapping(MAPPING)
    return mapping.model_copy(update={"table": mapping.table.model_copy(update={"rate_hz": float(rate)})})


def _updated_rig(rig, doc):
    """The rig with the diagnosis's updated parameters (its ``calibration`` coordinates)."""
    from dragline.simulate import apply_parameters, default_maneuver

    coords = {e["parameter"]: e["coordinate"] for e in doc["calibration"]["parameters"]}
    values = [float(coords.get(p.name, 0.0)) for p in rig.tolerances]
    return apply_parameters(rig, default_maneuver(rig), rig.tolerances, values)[0]


def _prediction_error(rig, table, maneuver):
    """RMS (m) over the trial of the load's position error, each channel's mean removed."""
    from dragline.simulate import simulate

    time_ = np.asarray(table["time"], float)
    run = simulate(rig, maneuver, duration=float(time_[-1] - maneuver.time[0]) + 0.01, rate_hz=100.0)
    errors = []
    for ch in _CHANNELS:
        e = np.interp(time_, run.time, np.asarray(run.table[ch], float)) - np.asarray(table[ch], float)
        e = e[np.isfinite(e)]
        errors.append(e - e.mean())
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))


def bench_real(data, rows=TRIAL_ROWS, progress=None):
    """Diagnose each flight under ``data`` and predict each flight with every other flight's update.

    Returns
    -------
    dict
        ``flights`` (per flight: rate, verdict, reason, updated parameters
        with uncertainty, seconds), ``verdicts`` (verdict -> count),
        ``parameters`` (per parameter: the estimates' min, median, max over
        flights), ``predictions`` (per pair: the held-out flight's error
        for the nominal rig and for the rig updated on the other flight),
        ``updated_better_share`` (pairs where the update predicts better).
    """
    from dragline.capture import read_tracked_table
    from dragline.compare import diagnose_path
    from dragline.reconstruct import tracked_trajectory
    from dragline.simulate import load_rig

    note = progress or (lambda line: None)
    rig = load_rig(RIG)
    flights, trials = [], {}
    with tempfile.TemporaryDirectory(prefix="dragline-real-") as tmp:
        for name, csv, meta in find_flights(data):
            rate = row_rate(meta)
            mapping = _mapping_at(rate)
            path = _trial(csv, rows, tmp)
            started = time.perf_counter()
            try:
                doc = diagnose_path(path, rig=rig, mapping=mapping, workers=2).doc
            except ValueError as exc:
                flights.append({"flight": name, "rate_hz": rate, "verdict": "error", "reason": str(exc)})
                note(f"{name}: error: {exc}")
                continue
            table, maneuver = tracked_trajectory(read_tracked_table(path, mapping), rig)
            trials[name] = (table, maneuver, _updated_rig(rig, doc))
            params = {e["parameter"]: {"estimate": e["estimate"], "uncertainty": e["uncertainty"],
                                       "shift_in_tolerances": e["shift_in_tolerances"],
                                       "identifiable": e["identifiable"]}
                      for e in doc["calibration"]["parameters"]}
            flights.append({"flight": name, "rate_hz": rate, "rows": rows, "verdict": doc["verdict"],
                            "reason": doc["reason"], "parameters": params,
                            "seconds": time.perf_counter() - started})
            note(f"{name}: {doc['verdict']} ({time.perf_counter() - started:.0f} s)")
    predictions = []
    for held, (table, maneuver, _) in trials.items():
        nominal = _prediction_error(rig, table, maneuver)
        for source, (_, _, updated) in trials.items():
            if source == held:
                continue
            predictions.append({"held_out": held, "updated_on": source, "nominal_m": nominal,
                                "updated_m": _prediction_error(updated, table, maneuver)})
    return _summary(flights, predictions)


def _summary(flights, predictions):
    verdicts = {}
    for f in flights:
        verdicts[f["verdict"]] = verdicts.get(f["verdict"], 0) + 1
    spread = {}
    for f in flights:
        for name, e in (f.get("parameters") or {}).items():
            spread.setdefault(name, []).append(e["estimate"])
    parameters = {k: {"min": float(min(v)), "median": float(np.median(v)), "max": float(max(v)), "n": len(v)}
                  for k, v in spread.items()}
    better = [p["updated_m"] < p["nominal_m"] for p in predictions]
    return {"flights": flights, "verdicts": verdicts, "parameters": parameters, "predictions": predictions,
            "updated_better_share": float(np.mean(better)) if better else None,
            "note": "each flight's first rows diagnosed alone; no parameter is shared between flights yet"}


def summary_lines(report):
    lines = [f"{f['flight']}: {f['verdict']} at {f['rate_hz']:.2f} rows/s" for f in report["flights"]]
    lines.append("verdicts: " + ", ".join(f"{k} {v}" for k, v in report["verdicts"].items()))
    for name, s in report["parameters"].items():
        lines.append(f"{name}: {s['min']:.4g} .. {s['median']:.4g} .. {s['max']:.4g} over {s['n']} flights")
    share = report["updated_better_share"]
    if share is not None:
        nominal = np.median([p["nominal_m"] for p in report["predictions"]])
        updated = np.median([p["updated_m"] for p in report["predictions"]])
        lines.append(f"a flight's update predicts another flight better than the nominal rig in "
                     f"{100 * share:.0f} % of {len(report['predictions'])} pairs (median error {nominal:.3f} m "
                     f"nominal, {updated:.3f} m updated)")
    return lines


def bench_command(args):
    """``dragline bench real --data DIR``."""
    import sys

    if not getattr(args, "data", None):
        raise ValueError("bench real needs --data DIR: the flights' folder (docs/real-recordings.md)")
    report = bench_real(args.data, progress=lambda line: print(line, file=sys.stderr))
    return report, summary_lines(report)

