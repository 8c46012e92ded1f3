"""MCAP capture sessions in and out, and summaries for inspection.

Foxglove results files are written by ``compare.write_results``.

Session file (``capture.mcap`` in a session directory)
------------------------------------------------------
JSON messages (message encoding ``json``) with JSON schemas (``jsonschema``):

``/session/info`` (``dragline.SessionInfo``, one message, log time 0)
    ``{"format": "dragline.session/1", "rate_hz", "camera_names",
    "image_size": [w, h], "nominal_focal_px", "marker_names",
    "wand_rate_hz", "wand_length", "lframe_points", "maneuver": {col: [...]},
    "metadata": {...}, "recorded_ns", "takes": {take: {"topic", "frames",
    "markers", "rate_hz", "start_ns"}}}`` for the takes ``lframe``, ``wand``,
    ``trial``. ``recorded_ns`` (optional, null when not known): when the
    trial's first frame was recorded, ns since the Unix epoch; the log times
    themselves run from the session's own zero.
``/calibration/lframe``, ``/calibration/wand``, ``/trial/centroids``
    (``dragline.Centroids2D``) one message per frame:
    ``{"frame": i, "points": [[[u, v] | null per marker] per camera]}`` (px);
    a NaN coordinate is ``null``, a point with both NaN is ``null``.

The takes lie one after another on one clock: the L-frame take starts at 0,
the wand take 1 s after it ends, the trial 1 s after that; frame ``i`` of a
take is logged at ``start_ns + round(i * 1e9 / rate_hz)``. The L-frame take
is static and is timed at ``wand_rate_hz`` (``rate_hz`` if there is none).
Floats are written with ``repr`` so every float64 round-trips exactly.

Messages go into zstd chunks of ``chunk_size`` bytes, each written to the file
as soon as it is full, info and calibration first. A recording cut short (a
crash, a partial copy) therefore keeps every complete chunk, and
:func:`read_session` recovers them: a take cut short comes back *shorter*
(only the frames received, never padded with NaN frames that would read as
"not seen"), a take with no frame left comes back as ``None`` (the trial as a
zero-frame array), and the report says what was lost. A corrupt chunk in the
middle loses that chunk alone (``_mcap_scan``): its frames come back NaN.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

import numpy as np
from mcap.records import Channel, Message, Schema
from mcap.writer import CompressionType, Writer

from ._atomic import atomic_file
from ._mcap_scan import MAGIC as _MAGIC
from ._mcap_scan import scan_records
from ._session_schema import SESSION_FORMAT, check_session_info
from ._strict_json import json_text


__all__ = [
    "CaptureSession",
    "write_session",
    "read_session",
    "summarize_mcap",
]

SESSION_FILE = "capture.mcap"
INFO_TOPIC = "/session/info"
TAKES = {  # take -> (topic, markers per frame or None for the trial's own)
    "lframe": ("/calibration/lframe", 4),
    "wand": ("/calibration/wand", 2),
    "trial": ("/trial/centroids", None),
}
CHUNK_SIZE = 256 * 1024
_TAKE_GAP_NS = 1_000_000_000
# Words that would reveal the generating physics (docs/interfaces.md); metadata is checked for them.
_TRUTH_WORDS = ("truth", "physics", "mechanism", "chain_link_friction", "pulley_friction",
                "pulley_inertia", "rope_bending_damping", "aero_drag")


@dataclass(eq=False)
class CaptureSession:
    """Everything a session's ``capture.mcap`` holds.

    Attributes
    ----------
    rate_hz : float
        Trial frame rate (Hz).
    camera_names : list of str
    image_size : tuple of int
        (width, height) in px, shared by all cameras.
    nominal_focal_px : float
        The lens focal length the vendor quotes, in px: the only intrinsics hint.
    marker_names : list of str
        Trial markers, e.g. ``"bucket.alpha"``.
    trial : ndarray, shape (cameras, frames, markers, 2)
        Marker centroids (px), NaN where not seen.
    wand : ndarray, shape (cameras, wand_frames, 2, 2), or None
        The two wand markers' centroids (px).
    wand_rate_hz, wand_length : float or None
        Wand take rate (Hz) and marker separation (m).
    lframe : ndarray, shape (cameras, lframe_frames, 4, 2), or None
        The four static L-frame markers' centroids (px).
    lframe_points : ndarray, shape (4, 3), or None
        Known L-frame marker positions in the inertial frame (m).
    maneuver : dict of str -> ndarray
        The maneuver, columns ``time`` (s), ``<winch>_length`` (m), ``<point>.x/.y/.z`` (m).
    metadata : dict
        Free-form JSON-able notes; must never reveal the generating physics.
    recorded_ns : int or None
        When the trial's first frame was recorded (ns since the Unix epoch),
        None when not known: results are dated from it.
    """

    rate_hz: float
    camera_names: list
    image_size: tuple
    nominal_focal_px: float
    marker_names: list
    trial: np.ndarray
    wand: np.ndarray | None = None
    wand_rate_hz: float | None = None
    wand_length: float | None = None
    lframe: np.ndarray | None = None
    lframe_points: np.ndarray | None = None
    maneuver: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    recorded_ns: int | None = None


# ----------------------------------------------------------------- file plumbing

class _FlushingFile:
    """Write-through stream: each chunk the Writer finishes reaches the OS at once."""

    def __init__(self, fh):
        self._fh = fh

    def write(self, data):
        n = self._fh.write(data)
        self._fh.flush()
        return n

    def tell(self):
        return self._fh.tell()


def _atomic_mcap(path, fill, chunk_size):
    """Write an MCAP file through ``fill(writer)`` under a temporary name, then rename."""
    with atomic_file(path) as tmp, open(tmp, "wb") as fh:
        writer = Writer(_FlushingFile(fh), chunk_size=chunk_size, compression=CompressionType.ZSTD)
        writer.start(profile="", library="dragline")
        fill(writer)
        writer.finish()
        fh.flush()
        os.fsync(fh.fileno())


def _json_bytes(obj):
    return json_text(obj, indent=None, separators=(",", ":")).encode()


def _nullable(values):
    """float list -> JSON list with NaN as null."""
    return [None if v != v else v for v in values]


def _scan(path, on_message):
    """Read every complete record of an MCAP file, surviving a cut or a corrupt chunk.

    ``on_message(channel, schema, message)`` is called in file order. Returns the
    scan report: byte counts, whether the footer was reached, the first error,
    and per-channel statistics.
    """
    size = os.path.getsize(path)
    schemas, channels, stats = {}, {}, {}
    report = {"file_bytes": size, "bytes_recovered": 0, "complete": False,
              "data_complete": False, "error": None, "chunks": 0, "messages": 0, "lost_chunks": []}

    def take(record):
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Message):
            ch = channels.get(record.channel_id)
            if ch is None and report["lost_chunks"]:  # its channel record was in a lost chunk
                report["orphaned_messages"] = report.get("orphaned_messages", 0) + 1
                return
            if ch is None:
                raise ValueError(f"{path}: message on unknown channel {record.channel_id}")
            st = stats.setdefault(ch.id, {"messages": 0, "first": record.log_time,
                                          "last": record.log_time})
            st["messages"] += 1
            st["first"] = min(st["first"], record.log_time)
            st["last"] = max(st["last"], record.log_time)
            report["messages"] += 1
            on_message(ch, schemas.get(ch.schema_id), record)

    with open(path, "rb") as fh:
        if fh.read(len(_MAGIC)) != _MAGIC:
            raise ValueError(f"{path}: not an MCAP file (bad magic bytes)")
        report["bytes_recovered"] = len(_MAGIC)
        scan_records(fh, size, take, report)
    for entry in report["lost_chunks"]:
        by_id = entry.pop("messages_by_channel_id")
        entry["messages"] = (None if by_id is None else
                             {channels[i].topic if i in channels else f"channel {i}": n for i, n in by_id.items()})
    report["channels"] = [
        {"topic": ch.topic,
         "schema": schemas[ch.schema_id].name if ch.schema_id in schemas else "",
         "schema_encoding": schemas[ch.schema_id].encoding if ch.schema_id in schemas else "",
         "message_encoding": ch.message_encoding,
         "messages": stats.get(ch.id, {}).get("messages", 0),
         "first_log_time_ns": stats.get(ch.id, {}).get("first"),
         "last_log_time_ns": stats.get(ch.id, {}).get("last")}
        for ch in channels.values()]
    return report


def _lost_chunk_text(entry):
    """One line for a damaged stretch of the file: where, when, what, why."""
    t1, t2 = entry["first_log_time_ns"], entry["last_log_time_ns"]
    when = ("log time unknown" if t1 is None and t2 is None else
            f"log time {'?' if t1 is None else f'{t1 / 1e9:.3f}'}-{'?' if t2 is None else f'{t2 / 1e9:.3f}'} s")
    what = ("" if not entry["messages"] else
            "; " + ", ".join(f"{topic} {n} messages" for topic, n in sorted(entry["messages"].items())))
    return f"bytes {entry['from_byte']}-{entry['to_byte']} ({when}{what}: {entry['reason']})"


def _lost_text(scan, cut_text="messages after the last complete chunk"):
    """What the scan could not read, beyond frames (which the session report counts).

    ``cut_text`` describes a data section cut short (nothing when false).
    """
    lost = [f"corrupt stretch skipped, {_lost_chunk_text(e)}" for e in scan["lost_chunks"]]
    if scan.get("orphaned_messages"):
        lost.append(f"{scan['orphaned_messages']} messages whose channel was defined in a lost chunk")
    if scan["data_complete"] and not scan["complete"]:
        lost.append("no messages (all recovered); only the file's summary/footer is incomplete")
    elif not scan["complete"] and cut_text:
        lost.append(cut_text)
    return lost


def _frame_ranges(numbers):
    """'3-7, 12' for the sorted frame numbers [3, 4, 5, 6, 7, 12]."""
    out, start = [], None
    for i, n in enumerate(numbers):
        if start is None:
            start = n
        if i + 1 == len(numbers) or numbers[i + 1] != n + 1:
            out.append(f"{start}" if start == n else f"{start}-{n}")
            start = None
    return ", ".join(out)


# ----------------------------------------------------------------- session files

_NUM_OR_NULL = {"type": ["number", "null"]}
_CENTROIDS_SCHEMA = {
    "title": "dragline.Centroids2D",
    "description": "Marker centroids of one frame (px); null where not seen",
    "type": "object",
    "properties": {
        "frame": {"type": "integer", "minimum": 0},
        "points": {"type": "array", "description": "per camera", "items": {
            "type": "array", "description": "per marker", "items": {
                "type": ["array", "null"], "items": _NUM_OR_NULL,
                "minItems": 2, "maxItems": 2}}},
    },
}
_INFO_SCHEMA = {
    "title": "dragline.SessionInfo",
    "description": "Rates, names, sizes, calibration constants and maneuver of a session",
    "type": "object",
    "properties": {
        "format": {"type": "string"},
        "rate_hz": {"type": "number"},
        "camera_names": {"type": "array", "items": {"type": "string"}},
        "image_size": {"type": "array", "items": {"type": "integer"}},
        "nominal_focal_px": {"type": "number"},
        "marker_names": {"type": "array", "items": {"type": "string"}},
        "wand_rate_hz": _NUM_OR_NULL,
        "wand_length": _NUM_OR_NULL,
        "lframe_points": {"type": ["array", "null"]},
        "maneuver": {"type": "object"},
        "metadata": {"type": "object"},
        "recorded_ns": {"type": ["integer", "null"], "minimum": 0},
        "takes": {"type": "object"},
    },
}


def _session_file(path):
    return os.path.join(path, SESSION_FILE) if os.path.isdir(path) else str(path)


def _check_truth_free(obj, where="metadata"):
    if isinstance(obj, dict):
        for key, value in obj.items():
            if any(w in str(key).lower() for w in _TRUTH_WORDS):
                raise ValueError(f"{where} key {key!r} would reveal the generating physics")
            _check_truth_free(value, f"{where}.{key}")
    elif isinstance(obj, (list, tuple)):
        for value in obj:
            _check_truth_free(value, where)
    elif isinstance(obj, str) and any(w in obj.lower() for w in _TRUTH_WORDS[3:]):
        raise ValueError(f"{where} names a physics mechanism ({obj!r})")


def _check_points(name, arr, n_cams, n_markers):
    if arr is None:
        return None
    arr = np.asarray(arr, float)
    if arr.ndim != 4 or arr.shape[0] != n_cams or arr.shape[2:] != (n_markers, 2):
        raise ValueError(f"{name} has shape {arr.shape}, expected "
                         f"({n_cams}, frames, {n_markers}, 2)")
    if np.isinf(arr).any():
        raise ValueError(f"{name} holds infinite pixel coordinates")
    return arr


def _positive(name, value, required=True):
    if value is None and not required:
        return None
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be positive, got {value}")
    return value


def _names(name, values):
    values = [str(v) for v in values]
    if not values or len(set(values)) != len(values) or not all(values):
        raise ValueError(f"{name} must be unique non-empty names, got {values}")
    return values


def _session_info(session):
    """Validate a session; return (info dict, {take: array or None})."""
    cams = _names("camera_names", session.camera_names)
    markers = _names("marker_names", session.marker_names)
    size = tuple(session.image_size)
    try:
        ok = len(size) == 2 and all(float(v) == int(v) and int(v) > 0 for v in size)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"image_size must be (width, height) in px, got {session.image_size}")
    rate = _positive("rate_hz", session.rate_hz)
    wand_rate = _positive("wand_rate_hz", session.wand_rate_hz, required=False)
    arrays = {"trial": _check_points("trial", session.trial, len(cams), len(markers)),
              "wand": _check_points("wand", session.wand, len(cams), 2),
              "lframe": _check_points("lframe", session.lframe, len(cams), 4)}
    wand_length = _positive("wand_length", session.wand_length, required=arrays["wand"] is not None)
    lpts = session.lframe_points
    if lpts is not None:
        lpts = np.asarray(lpts, float)
        if lpts.shape != (4, 3) or not np.isfinite(lpts).all():
            raise ValueError("lframe_points must be 4 finite (x, y, z) in m, "
                             f"got shape {lpts.shape}")
    elif arrays["lframe"] is not None:
        raise ValueError("an L-frame take needs lframe_points (4, 3) in m")
    maneuver = {}
    for col, values in (session.maneuver or {}).items():
        values = np.asarray(values, float)
        if values.ndim != 1 or np.isinf(values).any():
            raise ValueError(f"maneuver column {col!r} must be a 1-D finite float array")
        maneuver[str(col)] = _nullable(values.tolist())
    if len({len(v) for v in maneuver.values()}) > 1:
        raise ValueError("maneuver columns differ in length")
    metadata = dict(session.metadata or {})
    _check_truth_free(metadata)
    try:
        _json_bytes(metadata)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"metadata is not JSON-able: {exc}") from None

    takes, start = {}, 0
    take_rates = {"lframe": wand_rate or rate, "wand": wand_rate or rate, "trial": rate}
    for take, (topic, k) in TAKES.items():
        arr = arrays[take]
        n = 0 if arr is None else arr.shape[1]
        takes[take] = {"topic": topic, "frames": n, "markers": k or len(markers),
                       "rate_hz": take_rates[take], "start_ns": start}
        if n:
            start = _frame_ns(takes[take], n - 1) + _TAKE_GAP_NS
    info = {"format": SESSION_FORMAT, "rate_hz": rate, "camera_names": cams,
            "image_size": [int(v) for v in size],
            "nominal_focal_px": _positive("nominal_focal_px", session.nominal_focal_px),
            "marker_names": markers, "wand_rate_hz": wand_rate, "wand_length": wand_length,
            "lframe_points": None if lpts is None else lpts.tolist(),
            "maneuver": maneuver, "metadata": metadata, "recorded_ns": _recorded_ns(session.recorded_ns),
            "takes": takes}
    return info, arrays


def _recorded_ns(value):
    if value is None:
        return None
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not 0 <= value < 2**63:
        raise ValueError(f"recorded_ns must be a non-negative integer (ns since the Unix epoch) or None, got {value!r}")
    return int(value)


def _frame_ns(take, i):
    return take["start_ns"] + int(round(i * 1e9 / take["rate_hz"]))


def _points_json(frame):
    """(cameras, markers, 2) -> nested lists, NaN as null, an unseen point as null."""
    return [[None if (u != u and v != v) else [None if u != u else u, None if v != v else v]
             for u, v in cam] for cam in frame.tolist()]


def write_session(path, session, chunk_size=CHUNK_SIZE):
    """Write a capture session to an MCAP file, atomically.

    Parameters
    ----------
    path : str or path-like
        The file, or an existing session directory (``capture.mcap`` inside it).
    session : CaptureSession
    chunk_size : int
        Chunk size (bytes); a crash mid-write loses at most one chunk.

    Returns
    -------
    str
        The path written.

    Raises
    ------
    ValueError
        If the session is inconsistent (shapes, names, rates) or its metadata
        would reveal the generating physics.
    """
    path = _session_file(os.fspath(path))
    info, arrays = _session_info(session)

    def fill(writer):
        info_schema = writer.register_schema(_INFO_SCHEMA["title"], "jsonschema",
                                             _json_bytes(_INFO_SCHEMA))
        pts_schema = writer.register_schema(_CENTROIDS_SCHEMA["title"], "jsonschema",
                                            _json_bytes(_CENTROIDS_SCHEMA))
        info_ch = writer.register_channel(INFO_TOPIC, "json", info_schema)
        take_ch = {take: writer.register_channel(topic, "json", pts_schema)
                   for take, (topic, _) in TAKES.items()}
        writer.add_message(info_ch, 0, _json_bytes(info), 0)
        for take in TAKES:  # in time order, calibration first
            arr = arrays[take]
            for i in range(info["takes"][take]["frames"]):
                t = _frame_ns(info["takes"][take], i)
                msg = {"frame": i, "points": _points_json(arr[:, i])}
                writer.add_message(take_ch[take], t, _json_bytes(msg), t, sequence=i)

    _atomic_mcap(path, fill, chunk_size)
    return path


def _read_session_file(path):
    """One pass over a session file: (info or None, {take: {frame: array}}, scan report)."""
    state = {"info": None, "frames": {take: {} for take in TAKES}}
    topics = {topic: take for take, (topic, _) in TAKES.items()}

    def on_message(channel, schema, message):
        if channel.topic == INFO_TOPIC and state["info"] is None:
            try:
                state["info"] = json.loads(message.data)
            except json.JSONDecodeError as exc:
                raise ValueError(f"{path}: the session info message ({INFO_TOPIC}) is not JSON: {exc.msg} at "
                                 f"character {exc.pos} of {len(message.data)}") from None
            except UnicodeDecodeError as exc:
                raise ValueError(f"{path}: the session info message ({INFO_TOPIC}) is not UTF-8 text "
                                 f"(byte {exc.start})") from None
        elif channel.topic in topics and channel.message_encoding == "json":
            try:
                msg = json.loads(message.data)
                points = [[(None, None) if p is None else p for p in cam]
                          for cam in msg["points"]]
                frame = int(msg["frame"])
                state["frames"][topics[channel.topic]][frame] = np.array(points, float)
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"{path}: malformed {channel.topic} message "
                                 f"({type(exc).__name__}: {exc})".splitlines()[0]) from None

    scan = _scan(path, on_message)
    return state["info"], state["frames"], scan


def _assemble(path, info, frames, scan):
    """Arrays and report from what one scan recovered (the info checked against its schema first)."""
    check_session_info(info, path)
    n_cams = len(info["camera_names"])
    arrays, counts, expected, lost, notes = {}, {}, {}, [], []
    for take in TAKES:
        spec = info["takes"][take]
        got = frames[take]
        n = max(got) + 1 if got else 0
        if n > spec["frames"] or (got and min(got) < 0):
            raise ValueError(f"{path}: {spec['topic']} frame numbers run outside "
                             f"0-{spec['frames'] - 1}")
        arr = np.full((n_cams, n, spec["markers"], 2), np.nan)
        for i, pts in got.items():
            if pts.shape != (n_cams, spec["markers"], 2):
                raise ValueError(f"{path}: {spec['topic']} frame {i} has shape {pts.shape}, "
                                 f"expected ({n_cams}, {spec['markers']}, 2)")
            arr[:, i] = pts
        counts[take], expected[take] = n, spec["frames"]
        if n < spec["frames"]:
            lost.append(f"{take} frames {n}-{spec['frames'] - 1} "
                        f"({spec['frames'] - n} of {spec['frames']})")
        if n > len(got):
            missing = [i for i in range(n) if i not in got]
            notes.append(f"{take}: {len(missing)} frames missing inside the take (NaN): frames "
                         f"{_frame_ranges(missing)}")
        if spec["frames"] == 0:
            notes.append(f"{take}: not recorded in this session")
        arrays[take] = arr if (n or take == "trial") else None
    # Frames lost at a take's end already say what a cut lost; the scan adds
    # corrupt stretches and an incomplete summary.
    frames_lost = bool(lost)
    lost.extend(_lost_text(scan, cut_text=not frames_lost and "the end of the data section; no frames lost"))
    report = {"path": path, "truncated": not scan["complete"], "lost_chunks": scan["lost_chunks"],
              "lost": "; ".join(lost) if lost else "nothing",
              "error": scan["error"], "file_bytes": scan["file_bytes"],
              "bytes_recovered": scan["bytes_recovered"], "chunks": scan["chunks"],
              "messages": scan["messages"], "frames": counts, "frames_expected": expected,
              "missing_takes": [t for t in TAKES if t != "trial" and arrays[t] is None],
              "notes": notes}
    return arrays, report


def read_session(path):
    """Read a capture session, recovering what it can from a truncated file.

    Parameters
    ----------
    path : str or path-like
        ``capture.mcap`` or a session directory holding it.

    Returns
    -------
    session : CaptureSession
        A take cut short is shorter than written (frames received only); a
        calibration take with no frames is ``None``.
    report : dict
        ``truncated`` (bool), ``lost`` (what was lost, ``"nothing"`` if
        nothing), ``error``, ``frames`` and ``frames_expected`` per take,
        ``missing_takes`` (calibration takes that came back ``None``),
        ``notes``, byte, chunk and message counts.

    Raises
    ------
    ValueError
        If the file is missing, is not MCAP, or has no session info.
    """
    path = _session_file(os.fspath(path))
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such session file")
    info, frames, scan = _read_session_file(path)
    if info is None:
        raise ValueError(f"{path}: no session info ({INFO_TOPIC} missing or lost)")
    arrays, report = _assemble(path, info, frames, scan)
    # The schema's optional fields may be absent (a fuzzed session without
    # wand_rate_hz was a KeyError): read with its defaults.
    maneuver = {k: np.array(v, dtype=float) for k, v in info.get("maneuver", {}).items()}
    lpts = info.get("lframe_points")
    session = CaptureSession(
        rate_hz=info["rate_hz"], camera_names=list(info["camera_names"]),
        image_size=tuple(info["image_size"]), nominal_focal_px=info["nominal_focal_px"],
        marker_names=list(info["marker_names"]), trial=arrays["trial"],
        wand=arrays["wand"], wand_rate_hz=info.get("wand_rate_hz"),
        wand_length=info.get("wand_length"), lframe=arrays["lframe"],
        lframe_points=None if lpts is None else np.array(lpts, float),
        maneuver=maneuver, metadata=info.get("metadata", {}), recorded_ns=info.get("recorded_ns"))
    return session, report


# ----------------------------------------------------------------- inspection

def _iso(ns):
    """ISO 8601 (UTC) of ns since the Unix epoch, or None."""
    from datetime import datetime, timezone

    return None if ns is None else datetime.fromtimestamp(ns / 1e9, timezone.utc).isoformat()


def summarize_mcap(path):
    """JSON-able summary of any MCAP file, with session details for session files.

    Parameters
    ----------
    path : str or path-like
        An MCAP file or a session directory.

    Returns
    -------
    dict
        ``path``, ``file_bytes``, ``truncated``, ``error``, ``channels`` (topic,
        schema, encodings, message count, first/last log time in ns and s) and,
        for a session file, ``session``: cameras, markers, image size, rates,
        wand length, frames and expected frames per take, the unseen (NaN)
        fraction per take and camera, the maneuver columns, and ``lost``.
    """
    path = _session_file(os.fspath(path))
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such file")
    info, frames, scan = _read_session_file(path)
    for ch in scan["channels"]:
        for k in ("first", "last"):
            ns = ch[f"{k}_log_time_ns"]
            ch[f"{k}_time_s"] = None if ns is None else ns / 1e9
    out = {"path": path, "file_bytes": scan["file_bytes"], "truncated": not scan["complete"],
           "error": scan["error"], "bytes_recovered": scan["bytes_recovered"],
           "chunks": scan["chunks"], "messages": scan["messages"],
           "channels": scan["channels"], "session": None,
           "lost_chunks": scan["lost_chunks"], "lost": "; ".join(_lost_text(scan)) or "nothing"}
    if info is not None:
        arrays, report = _assemble(path, info, frames, scan)
        unseen = {}
        for take, arr in arrays.items():
            if arr is not None and arr.shape[1]:
                frac = np.isnan(arr).any(axis=-1).mean(axis=(1, 2))
                unseen[take] = dict(zip(info["camera_names"], frac.tolist()))
        out["lost"] = report["lost"]
        out["session"] = {
            "cameras": info["camera_names"], "markers": info["marker_names"],
            "image_size": info["image_size"], "nominal_focal_px": info["nominal_focal_px"],
            "rate_hz": info["rate_hz"], "wand_rate_hz": info.get("wand_rate_hz"),
            "wand_length": info.get("wand_length"), "recorded_ns": info.get("recorded_ns"),
            "recorded_at": _iso(info.get("recorded_ns")), "frames": report["frames"],
            "frames_expected": report["frames_expected"], "unseen_fraction": unseen,
            "missing_takes": report["missing_takes"], "notes": report["notes"],
            "maneuver_columns": sorted(info.get("maneuver", {})),
            "maneuver_samples": len(next(iter(info.get("maneuver", {}).values()), []))}
    return out
