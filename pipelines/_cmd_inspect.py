"""``dragline inspect``: say what a capture file holds.

Reads a session directory or MCAP file, a VICON CSV export, a C3D or TRC
marker file, a trajectory
or maneuver table (CSV with a ``time`` column) or a ``cameras.json``, and
prints sections, rates, subjects and markers, frames, gap counts and
channels; ``--json`` prints the same as one JSON object with a ``kind``.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd
from dragline.capture import (
    camera_centre,
    is_c3d,
    is_trc,
    json_text,
    load_cameras,
    read_marker_file,
    read_session,
    session_file,
    summarize_mcap,
    summarize_vicon_csv,
)
from dragline.compare import read_trajectory_table
from dragline.simulate import read_maneuver_csv

_MCAP_MAGIC = b"\x89MCAP0\r\n"


def add_parser(sub):
    p = sub.add_parser("inspect", help="print what a capture file holds",
                       description="Print what a file holds: a session directory or MCAP file, a VICON CSV "
                                   "export, a C3D or TRC marker file, a trajectory or maneuver table, or "
                                   "cameras.json.")
    p.add_argument("file", metavar="FILE",
                   help="session directory, .mcap, VICON .csv, .c3d, .trc, table .csv or cameras.json")
    p.add_argument("--json", action="store_true", help="print a JSON object for scripts")


# ------------------------------------------------------------------ gathering

def _runs(missing):
    edges = np.diff(np.r_[0, missing.astype(np.int8), 0])
    return np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)


def _gap_table(missing, names):
    """Per marker: frames missing, gap runs, longest run; missing is (frames, markers) bool."""
    out = {}
    for k, name in enumerate(names):
        runs = _runs(missing[:, k])
        out[name] = {"nan_frames": int(missing[:, k].sum()), "gap_runs": int(runs.size),
                     "longest_gap": int(runs.max()) if runs.size else 0}
    return out


def _mcap(path, folder=None):
    summary = summarize_mcap(path)
    out = {"kind": "session" if folder else "mcap", **summary}
    if folder:
        out["folder"] = folder
        out["files"] = sorted(f for f in os.listdir(folder) if not f.startswith("."))
    if summary["session"] is not None:
        session, _ = read_session(path)
        seen = np.isfinite(session.trial).all(axis=-1).sum(axis=0)  # (frames, markers)
        # A 3D marker needs two views: these are the gaps triangulation will leave.
        out["session"]["trial_gaps"] = _gap_table(seen < 2, session.marker_names)
    return out


def _table(path):
    """Summary of a table CSV (a reel table or a trajectory table), read through its schema; None if not a table."""
    try:
        header = pd.read_csv(path, nrows=0)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError):
        return None
    columns = [str(c).strip() for c in header.columns]
    if "time" not in columns:
        return None
    # A maneuver: time, <winch>_length and moving points' .x/.y/.z, nothing else (a trajectory
    # table's channels are <entity>.<quantity>).
    reel_table = any(c.endswith("_length") and "." not in c for c in columns) and all(
        c == "time" or (c.endswith("_length") and "." not in c) or c.endswith((".x", ".y", ".z")) for c in columns)
    # Read as the commands read it: its schema's error (file, column, row) is the answer for a bad table.
    num = read_maneuver_csv(path).to_frame() if reel_table else read_trajectory_table(path)
    frame = num
    t = num["time"].to_numpy(float)
    dt = np.diff(t)
    entities = sorted({c.split(".", 1)[0] for c in frame.columns if "." in c})
    nan = {c: int(num[c].isna().sum()) for c in frame.columns if num[c].isna().any()}
    return {"kind": "table", "path": path, "rows": int(len(frame)), "columns": len(frame.columns),
            "time_start_s": float(t[0]) if len(t) else None, "time_end_s": float(t[-1]) if len(t) else None,
            # A rate only for evenly spaced rows (a maneuver table's are not).
            "rate_hz": (float(1.0 / np.median(dt)) if dt.size and np.median(dt) > 0
                        and np.ptp(dt) <= 1e-6 * np.median(dt) else None),
            "entities": entities, "column_names": list(frame.columns), "nan_values": nan}


def _marker_file(path):
    """Summary of a C3D or TRC file; its first bytes decide (a C3D saved as .dat is still a C3D)."""
    from dragline.capture import read_c3d, read_trc

    markers = read_c3d(path) if is_c3d(path) else read_trc(path) if is_trc(path) else read_marker_file(path)
    summary = markers.summary()
    summary["gaps"] = _gap_table(~np.isfinite(markers.positions).all(axis=-1), markers.names)
    return {"kind": markers.format, **summary}


def _cameras(path):
    cameras = load_cameras(path)
    with open(path) as fh:
        quality = json.load(fh).get("quality")
    return {"kind": "cameras", "path": path,
            "cameras": [{"name": c.name, "image_size": list(c.image_size), "focal_px": float(c.K[0, 0]),
                         "principal_point_px": c.K[:2, 2].tolist(), "dist": c.dist.tolist(),
                         "centre_m": camera_centre(c).tolist()} for c in cameras],
            "quality": quality}


def inspect_path(path):
    """Summary dict of any file ``dragline inspect`` understands; ValueError otherwise."""
    path = os.fspath(path)
    if os.path.isdir(path):
        return _mcap(session_file(path), folder=path)
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such file or directory")
    with open(path, "rb") as fh:
        head = fh.read(len(_MCAP_MAGIC))
    if head == _MCAP_MAGIC:
        return _mcap(path)
    if head.lstrip()[:1] == b"{":
        return _cameras(path)
    if is_c3d(path) or is_trc(path) or path.lower().endswith((".c3d", ".trc")):
        return _marker_file(path)
    try:
        return {"kind": "vicon_csv", **summarize_vicon_csv(path)}
    except ValueError as exc:
        table = _table(path)
        if table is None:
            raise ValueError(f"{path}: not a session, MCAP, VICON CSV, C3D, TRC, table CSV or cameras.json file "
                             f"({' '.join(str(exc).split())})") from None
        return table


# ------------------------------------------------------------------ printing

def _fmt_s(v):
    return "-" if v is None else f"{v:.3f}"


def _mcap_text(s):
    state = ("complete" if not s["truncated"] and not s["lost_chunks"] else
             f"DAMAGED, {len(s['lost_chunks'])} corrupt stretches skipped; lost: {s['lost']}" if not s["truncated"]
             else f"TRUNCATED ({s['error']}); lost: {s['lost']}")
    lines = []
    if s["kind"] == "session":
        lines.append(f"{s['folder']}: session directory; files: {', '.join(s['files'])}")
    lines.append(f"{s['path']}: MCAP, {s['file_bytes']} bytes, {s['chunks']} chunks, "
                 f"{s['messages']} messages ({state})")
    lines.append(f"  {'channel':<22} {'schema':<26} {'messages':>8} {'first s':>8} {'last s':>8} {'rate Hz':>8}")
    for ch in s["channels"]:
        span = (ch["last_time_s"] or 0) - (ch["first_time_s"] or 0)
        rate = f"{(ch['messages'] - 1) / span:.1f}" if ch["messages"] > 1 and span > 0 else "-"
        lines.append(f"  {ch['topic']:<22} {ch['schema']:<26} {ch['messages']:>8} {_fmt_s(ch['first_time_s']):>8} "
                     f"{_fmt_s(ch['last_time_s']):>8} {rate:>8}")
    se = s["session"]
    if se is None:
        return lines
    w, h = se["image_size"]
    lines.append(f"session: {len(se['cameras'])} cameras ({', '.join(se['cameras'])}), {w} x {h} px, "
                 f"nominal focal length {se['nominal_focal_px']:g} px")
    lines.append(f"  recorded: {se['recorded_at'] or 'not dated'}")
    rates = {"lframe": se["wand_rate_hz"] or se["rate_hz"], "wand": se["wand_rate_hz"] or se["rate_hz"],
             "trial": se["rate_hz"]}
    for take in ("lframe", "wand", "trial"):
        n, expected = se["frames"][take], se["frames_expected"][take]
        extra = f" (of {expected} written)" if n != expected else ""
        extra += f", wand length {1000 * se['wand_length']:.1f} mm" if take == "wand" and se["wand_length"] else ""
        lines.append(f"  take {take:<7} {n:>6} frames at {rates[take]:g} Hz{extra}" if n or expected
                     else f"  take {take:<7} not recorded")
    cams = se["cameras"]
    if se["unseen_fraction"]:
        lines.append("  unseen detections (%): " + " ".join(f"{c:>6}" for c in cams))
        for take, frac in se["unseen_fraction"].items():
            lines.append(f"  {take:<21} " + " ".join(f"{100 * frac[c]:6.1f}" for c in cams))
    groups = {}
    for m in se["markers"]:
        subject, _, marker = m.rpartition(".")
        groups.setdefault(subject or "-", []).append(marker)
    lines.append(f"  markers ({len(se['markers'])}): " + "; ".join(f"{g}: {' '.join(ms)}" for g, ms in groups.items()))
    gaps = {m: g for m, g in se.get("trial_gaps", {}).items() if g["nan_frames"]}
    lines.append(f"  trial gaps (frames seen by fewer than two cameras): "
                 f"{len(gaps)} of {len(se['markers'])} markers" + (":" if gaps else ""))
    for m, g in gaps.items():
        lines.append(f"    {m:<24} {g['nan_frames']:>6} frames in {g['gap_runs']} gaps, longest {g['longest_gap']}")
    lines.append(f"  maneuver: {se['maneuver_samples']} rows, columns {', '.join(se['maneuver_columns']) or '-'}")
    for note in se["notes"]:
        lines.append(f"  note: {note}")
    return lines


def _vicon_text(s):
    lines = [f"{s['path']}: VICON CSV, {len(s['sections'])} section(s)",
             f"  {'section':<16} {'rate Hz':>8} {'rows':>7} {'frames':>7} {'first-last':>12} {'columns':>8}  units"]
    for sec in s["sections"]:
        span = f"{sec['first_frame']}-{sec['last_frame']}" if sec["first_frame"] is not None else "-"
        rate = "-" if sec["rate_hz"] is None else f"{sec['rate_hz']:g}"
        lines.append(f"  {sec['name']:<16} {rate:>8} {sec['rows']:>7} {sec['frames']:>7} {span:>12} "
                     f"{sec['columns']:>8}  {', '.join(sec['units'] or []) or '-'}")
    lines += _event_lines(s.get("events", []))
    for note in s.get("notes", []):
        lines.append(f"  note: {note}")
    t = s["trajectories"]
    if t is None:
        lines.append("  no Trajectories section (no 3D markers)")
        return lines
    lines.append(f"trajectories: {t['markers']} markers, {t['frames']} frames at {t['rate_hz']:g} Hz "
                 f"(frames {t['first_frame']}-{t['last_frame']})")
    for sub in t["subjects"]:
        lines.append(f"  subject {sub['name'] or '(none)'}: {' '.join(sub['markers'])}")
    if t["unlabeled"]:
        lines.append(f"  unlabeled: {' '.join(t['unlabeled'])}")
    gaps = {m: g for m, g in t["gaps"].items() if g["nan_frames"]}
    lines.append(f"  gaps: {len(gaps)} of {t['markers']} markers" + (":" if gaps else ""))
    for m, g in gaps.items():
        lines.append(f"    {m:<24} {g['nan_frames']:>6} frames in {g['gap_runs']} gaps, longest {g['longest_gap']}")
    return lines


def _event_lines(events):
    """One line an event, labelled as ``--between`` takes it (CONTEXT:NAME)."""
    return [f"  event {e['time_s']:g} s: {e['context'] + ':' if e['context'] else ''}{e['name']}"
            + (f" (subject {e['subject']})" if e["subject"] else "") for e in events]


def _marker_file_text(s):
    fmt = {"c3d": "C3D", "trc": "TRC"}[s["format"]]
    lines = [f"{s['path']}: {fmt}, {len(s['markers'])} markers, {s['frames']} frames at {s['rate_hz']:g} Hz "
             f"(frames {s['first_frame']}-{s['first_frame'] + s['frames'] - 1}, {_fmt_s(s['duration_s'])} s), "
             f"units {s['units']}"]
    for k, v in s["info"].items():
        lines.append(f"  {'CUT SHORT' if k == 'cut_short' else k}: {v}")
    lines += _event_lines(s.get("events", []))
    groups = {}
    for m in s["markers"]:
        subject, _, marker = m.rpartition(":")
        groups.setdefault(subject or "-", []).append(marker)
    for subject, markers in groups.items():
        lines.append(f"  subject {subject if subject != '-' else '(none)'}: {' '.join(markers)}")
    a = s["analog"]
    if a["channels"]:
        lines.append(f"  analog: {len(a['channels'])} channels at {a['rate_hz']:g} Hz, {a['frames']} samples: "
                     + ", ".join(f"{c} ({u})" if u else c for c, u in zip(a["channels"], a["units"] + [""] * 99)))
    else:
        lines.append("  analog: none")
    gaps = {m: g for m, g in s["gaps"].items() if g["nan_frames"]}
    lines.append(f"  gaps: {len(gaps)} of {len(s['markers'])} markers" + (":" if gaps else ""))
    for m, g in gaps.items():
        lines.append(f"    {m:<24} {g['nan_frames']:>6} frames in {g['gap_runs']} gaps, longest {g['longest_gap']}")
    return lines


def _table_text(s):
    rate = "uneven steps" if s["rate_hz"] is None else f"{s['rate_hz']:g} Hz"
    lines = [f"{s['path']}: table CSV, {s['rows']} rows x {s['columns']} columns, time "
             f"{_fmt_s(s['time_start_s'])}-{_fmt_s(s['time_end_s'])} s, {rate}",
             f"  entities: {', '.join(s['entities'])}" if s["entities"] else
             f"  columns: {', '.join(s['column_names'])}"]
    if s["nan_values"]:
        lines.append("  columns with missing values: " + ", ".join(f"{c} ({n})" for c, n in s["nan_values"].items()))
    return lines


def _cameras_text(s):
    lines = [f"{s['path']}: cameras.json, {len(s['cameras'])} cameras",
             f"  {'camera':<8} {'size':>10} {'focal px':>9} {'k1':>8} {'k2':>8}  centre x, y, z (m)"]
    for c in s["cameras"]:
        x, y, z = c["centre_m"]
        lines.append(f"  {c['name']:<8} {c['image_size'][0]:>4} x {c['image_size'][1]:<4} {c['focal_px']:9.1f} "
                     f"{c['dist'][0]:8.4f} {c['dist'][1]:8.4f}  {x:7.3f} {y:7.3f} {z:7.3f}")
    q = s["quality"]
    if q and "reprojection_rms_px_all" in q:
        lines.append(f"  quality: reprojection RMS {q['reprojection_rms_px_all']:.3f} px, wand length "
                     f"{q.get('wand_length_mean_mm', float('nan')):.2f} +- {q.get('wand_length_std_mm', float('nan')):.2f} mm")
    return lines


_TEXT = {"session": _mcap_text, "mcap": _mcap_text, "vicon_csv": _vicon_text, "table": _table_text,
         "cameras": _cameras_text, "c3d": _marker_file_text, "trc": _marker_file_text}


def run(args):
    summary = inspect_path(args.file)
    if args.json:
        print(json_text(summary, indent=1))
    else:
        print("\n".join(_TEXT[summary["kind"]](summary)))
    return 0
