"""Foxglove results: trajectory tables (and markers, ropes) as an MCAP that Foxglove opens.

Per source ``s`` of :func:`write_results` (``measured``, ``simulated``, ...):
``/s/transforms`` (``foxglove.FrameTransforms``: frame ``world`` -> ``s/body``),
``/s/scene`` (``foxglove.SceneUpdate``: a cube per body, a sphere for a body
whose orientation is unknown, a line strip per rope) and ``/s/markers``
(``foxglove.PointCloud``, FLOAT64 x, y, z), JSON-encoded with JSON schemas.
``world`` is the inertial frame of docs/conventions.md unchanged: K (z) points
DOWN. Every transforms message also holds ``world_z_up`` -> ``world``, a half
turn about x: pick ``world_z_up`` as the 3D panel's display frame and the rig
stands right side up (Foxglove's view is z-up). Log times are the tables'
times after the recording's start (``start_ns``, Unix epoch; the current
time when the start is not known), and the summary's ``dragline`` metadata
says which. Chunks are flushed as they fill, like session files (``_mcap_io``).
"""

from __future__ import annotations

import base64
import heapq
import os
import re
import time
from datetime import datetime, timezone

import numpy as np
from scipy.spatial.transform import Rotation

from ..simulate import BODIES, body_to_inertial
from ._mcap_io import CHUNK_SIZE, _atomic_mcap, _json_bytes

__all__ = ["write_results", "quaternion_from_matrix", "FOXGLOVE_SCHEMAS"]


def quaternion_from_matrix(T):
    """Unit quaternion ``(x, y, z, w)`` of a rotation matrix, through scipy's ``Rotation``.

    The quaternion rotates vectors like the matrix: ``T @ v == q v q*``
    (Hamilton convention, Foxglove's). ``w >= 0``.

    Parameters
    ----------
    T : array_like, shape ``S + (3, 3)``

    Returns
    -------
    ndarray, shape ``S + (4,)``
        NaN where ``T`` holds NaN.
    """
    T = np.asarray(T, float)
    m = T.reshape(-1, 3, 3)
    q = np.full((m.shape[0], 4), np.nan)
    ok = np.isfinite(m).all(axis=(1, 2))
    if ok.any():
        q[ok] = Rotation.from_matrix(m[ok]).as_quat(canonical=True)
    return q.reshape(T.shape[:-2] + (4,))


def _obj(title, props):
    return {"title": title, "type": "object", "properties": props}


def _arr(items):
    return {"type": "array", "items": items}


_NUM = {"type": "number"}
_STR = {"type": "string"}
_TIME = {"title": "time", "type": "object", "properties": {
    "sec": {"type": "integer", "minimum": 0},
    "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_DURATION = {"title": "duration", "type": "object", "properties": {
    "sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_VEC3 = _obj("foxglove.Vector3", {k: _NUM for k in "xyz"})
_QUAT = _obj("foxglove.Quaternion", {k: _NUM for k in "xyzw"})
_POSE = _obj("foxglove.Pose", {"position": _VEC3, "orientation": _QUAT})
_COLOR = _obj("foxglove.Color", {k: _NUM for k in "rgba"})
_SHAPE = {"pose": _POSE, "size": _VEC3, "color": _COLOR}
_LINE = _obj("foxglove.LinePrimitive", {
    "type": {"title": "foxglove.LineType", "oneOf": [
        {"title": "LINE_STRIP", "const": 0}, {"title": "LINE_LOOP", "const": 1},
        {"title": "LINE_LIST", "const": 2}]},
    "pose": _POSE, "thickness": _NUM, "scale_invariant": {"type": "boolean"},
    "points": _arr(_obj("foxglove.Point3", {k: _NUM for k in "xyz"})),
    "color": _COLOR, "colors": _arr(_COLOR), "indices": _arr({"type": "integer", "minimum": 0})})
# Primitive kinds this writer leaves empty are named but not spelled out.
_ENTITY = _obj("foxglove.SceneEntity", {
    "timestamp": _TIME, "frame_id": _STR, "id": _STR, "lifetime": _DURATION,
    "frame_locked": {"type": "boolean"},
    "metadata": _arr(_obj("foxglove.KeyValuePair", {"key": _STR, "value": _STR})),
    "arrows": _arr({"title": "foxglove.ArrowPrimitive", "type": "object"}),
    "cubes": _arr(_obj("foxglove.CubePrimitive", _SHAPE)),
    "spheres": _arr(_obj("foxglove.SpherePrimitive", _SHAPE)),
    "cylinders": _arr({"title": "foxglove.CylinderPrimitive", "type": "object"}),
    "lines": _arr(_LINE),
    "triangles": _arr({"title": "foxglove.TriangleListPrimitive", "type": "object"}),
    "texts": _arr({"title": "foxglove.TextPrimitive", "type": "object"}),
    "models": _arr({"title": "foxglove.ModelPrimitive", "type": "object"})})
FOXGLOVE_SCHEMAS = {
    "foxglove.FrameTransforms": _obj("foxglove.FrameTransforms", {"transforms": _arr(
        _obj("foxglove.FrameTransform", {
            "timestamp": _TIME, "parent_frame_id": _STR, "child_frame_id": _STR,
            "translation": _VEC3, "rotation": _QUAT}))}),
    "foxglove.SceneUpdate": _obj("foxglove.SceneUpdate", {
        "deletions": _arr(_obj("foxglove.SceneEntityDeletion", {
            "timestamp": _TIME,
            "type": {"title": "foxglove.SceneEntityDeletionType", "oneOf": [
                {"title": "MATCHING_ID", "const": 0}, {"title": "ALL", "const": 1}]},
            "id": _STR})),
        "entities": _arr(_ENTITY)}),
    "foxglove.PointCloud": _obj("foxglove.PointCloud", {
        "timestamp": _TIME, "frame_id": _STR, "pose": _POSE,
        "point_stride": {"type": "integer", "minimum": 0},
        "fields": _arr(_obj("foxglove.PackedElementField", {
            "name": _STR, "offset": {"type": "integer", "minimum": 0},
            "type": {"title": "foxglove.NumericType", "type": "integer"}})),
        "data": {"type": "string", "contentEncoding": "base64"}}),
}

WORLD_FRAME = "world"
# Display frame: world turned half a turn about x (x kept, y and z reversed), so z is up.
Z_UP_FRAME = "world_z_up"
_HALF_TURN_X = {"x": 1.0, "y": 0.0, "z": 0.0, "w": 0.0}
# Bucket: 0.381 x 0.203 x 0.152 m (paper section 3.1); the other bodies are drawn small.
BODY_SIZE = {"bucket": (0.381, 0.203, 0.152)}
_SMALL = (0.05, 0.05, 0.05)
_PALETTE = {"measured": (0.12, 0.47, 0.71), "simulated": (1.0, 0.50, 0.05)}
_EXTRA_COLORS = [(0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.58, 0.40, 0.74)]
_FLOAT64 = 8  # foxglove.NumericType
_ROPE_THICKNESS = 0.01  # m


def _stamp(ns):
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _xyz(v):
    return {"x": v[0], "y": v[1], "z": v[2]}


def _pose(position, quat=(0.0, 0.0, 0.0, 1.0)):
    return {"position": _xyz(position),
            "orientation": {"x": quat[0], "y": quat[1], "z": quat[2], "w": quat[3]}}


def _rgba(rgb, a):
    return {"r": rgb[0], "g": rgb[1], "b": rgb[2], "a": a}


def _entity(stamp, entity_id, cubes=(), spheres=(), lines=()):
    return {"timestamp": stamp, "frame_id": WORLD_FRAME, "id": entity_id,
            "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False, "metadata": [],
            "arrows": [], "cubes": list(cubes), "spheres": list(spheres), "cylinders": [],
            "lines": list(lines), "triangles": [], "texts": [], "models": []}


def _table_ns(source, table):
    if "time" not in table.columns:
        raise ValueError(f"table {source!r} has no 'time' column")
    t = np.asarray(table["time"], float)
    if not np.isfinite(t).all() or (t < 0).any() or (np.diff(t) < 0).any():
        raise ValueError(f"table {source!r}: time must be finite, >= 0 and non-decreasing")
    return [int(round(v * 1e9)) for v in t]


def _body_poses(table, body):
    """Positions (frames, 3) and quaternions (frames, 4); quaternion NaN where unknown."""
    pos = np.column_stack([np.asarray(table[f"{body}.{k}"], float) for k in "xyz"])
    if all(f"{body}.{k}" in table.columns for k in ("roll", "pitch", "yaw")):
        T = body_to_inertial(*(np.asarray(table[f"{body}.{k}"], float)
                               for k in ("roll", "pitch", "yaw")))
        quat = quaternion_from_matrix(T)
    else:
        quat = np.full((len(table), 4), np.nan)
    return pos, quat


def _split_rope_keys(ropes, sources):
    out = {}
    for key, pts in (ropes or {}).items():
        source, _, name = str(key).rpartition("/")
        if not source and len(sources) == 1:
            source = sources[0]
        if source not in sources:
            raise ValueError(f"rope {key!r}: name it '<source>/<rope>' with a source of the tables")
        out.setdefault(source, {})[name] = pts
    return out


def _frames_array(what, arr, n):
    arr = np.asarray(arr, float)
    if arr.ndim != 3 or arr.shape[0] != n or arr.shape[2] != 3:
        raise ValueError(f"{what} has shape {arr.shape}, expected ({n}, points, 3)")
    return arr


def _source_data(source, table, markers, ropes):
    """Validate one source: log times (ns), body poses, markers and ropes as arrays."""
    times = _table_ns(source, table)
    n = len(times)
    bodies = [b for b in BODIES if all(f"{b}.{k}" in table.columns for k in "xyz")]
    return {"times": times,
            "poses": {b: _body_poses(table, b) for b in bodies},
            "markers": None if markers is None else _frames_array(
                f"markers[{source!r}]", markers, n),
            "ropes": {k: _frames_array(f"rope {source}/{k}", v, n)
                      for k, v in (ropes or {}).items()}}


def _source_messages(source, data, color, channels, origin_ns):
    """Yield (log_time_ns, channel_id, payload) for one source, in time order, from ``origin_ns``."""
    poses, markers, ropes = data["poses"], data["markers"], data["ropes"]
    bodies = list(poses)
    for i, ns in enumerate(data["times"]):
        ns = origin_ns + ns
        stamp = _stamp(ns)
        transforms = [{"timestamp": stamp, "parent_frame_id": Z_UP_FRAME, "child_frame_id": WORLD_FRAME,
                       "translation": _xyz((0.0, 0.0, 0.0)), "rotation": dict(_HALF_TURN_X)}]
        entities, deletions = [], []
        for body in bodies:
            pos, quat = poses[body][0][i].tolist(), poses[body][1][i].tolist()
            eid = f"{source}/{body}"
            if not np.isfinite(pos).all():
                deletions.append({"timestamp": stamp, "type": 0, "id": eid})
            elif np.isfinite(quat).all():
                transforms.append({"timestamp": stamp, "parent_frame_id": WORLD_FRAME,
                                   "child_frame_id": eid, "translation": _xyz(pos),
                                   "rotation": dict(zip("xyzw", quat))})
                cube = {"pose": _pose(pos, quat), "size": _xyz(BODY_SIZE.get(body, _SMALL)),
                        "color": _rgba(color, 0.8)}
                entities.append(_entity(stamp, eid, cubes=[cube]))
            else:  # orientation unknown (e.g. a two-marker body): a sphere claims none
                sphere = {"pose": _pose(pos), "size": _xyz(_SMALL), "color": _rgba(color, 0.8)}
                entities.append(_entity(stamp, eid, spheres=[sphere]))
        for name, pts in ropes.items():
            eid = f"{source}/{name}"
            ok = pts[i][np.isfinite(pts[i]).all(axis=1)].tolist()
            if len(ok) < 2:
                deletions.append({"timestamp": stamp, "type": 0, "id": eid})
                continue
            line = {"type": 0, "pose": _pose((0.0, 0.0, 0.0)), "thickness": _ROPE_THICKNESS,
                    "scale_invariant": False, "points": [_xyz(p) for p in ok],
                    "color": _rgba(color, 1.0), "colors": [], "indices": []}
            entities.append(_entity(stamp, eid, lines=[line]))
        yield ns, channels["transforms"], _json_bytes({"transforms": transforms})
        yield ns, channels["scene"], _json_bytes({"deletions": deletions, "entities": entities})
        if markers is not None:
            seen = markers[i][np.isfinite(markers[i]).all(axis=1)]
            cloud = {"timestamp": stamp, "frame_id": WORLD_FRAME, "pose": _pose((0.0, 0.0, 0.0)),
                     "point_stride": 24,
                     "fields": [{"name": k, "offset": 8 * j, "type": _FLOAT64}
                                for j, k in enumerate("xyz")],
                     "data": base64.b64encode(seen.astype("<f8").tobytes()).decode()}
            yield ns, channels["markers"], _json_bytes(cloud)


def write_results(path, tables, markers=None, ropes=None, chunk_size=CHUNK_SIZE, start_ns=None):
    """Write trajectory tables (and markers, ropes) as a Foxglove-ready MCAP, atomically.

    Parameters
    ----------
    path : str or path-like
    tables : dict of str -> pandas.DataFrame
        Trajectory tables by source (``measured``, ``simulated``, ...), see
        ``dragline.simulate.trajectory_columns``. Bodies need ``x y z`` (m);
        ``roll pitch yaw`` (rad) make them cubes with a frame transform.
    markers : dict of str -> ndarray, shape (frames, markers, 3), optional
        3D markers (m) by source, one row per row of that source's table;
        NaN markers are left out of the point cloud.
    ropes : dict of str -> ndarray, shape (frames, points, 3), optional
        Rope points (m) by ``"<source>/<rope>"`` (the bare rope name when
        there is one table), drawn as line strips.
    chunk_size : int
        Chunk size (bytes).
    start_ns : int, optional
        When the recording started (ns since the Unix epoch): a table's time
        t is logged at ``start_ns + t``. The current time when None (the
        start is not known); the metadata says which.

    Returns
    -------
    str
        The path written.
    """
    path = os.fspath(path)
    if not tables:
        raise ValueError("write_results needs at least one trajectory table")
    sources = [str(s) for s in tables]
    for s in sources:
        if not re.fullmatch(r"[A-Za-z0-9_]+", s):
            raise ValueError(f"source name {s!r} must be letters, digits or '_'")
    for s in markers or {}:
        if s not in tables:
            raise ValueError(f"markers for {s!r}, which has no table")
    rope_sets = _split_rope_keys(ropes, sources)
    colors = {s: _PALETTE.get(s) or _EXTRA_COLORS[i % len(_EXTRA_COLORS)]
              for i, s in enumerate(sources)}
    data = {s: _source_data(s, tables[s], (markers or {}).get(s), rope_sets.get(s))
            for s in sources}

    known = start_ns is not None
    if known and not (isinstance(start_ns, (int, np.integer)) and 0 <= start_ns < 2**63 - 10**15):
        raise ValueError(f"start_ns must be a non-negative integer (ns since the Unix epoch), got {start_ns!r}")
    origin = int(start_ns) if known else time.time_ns()

    def fill(writer):
        writer.add_metadata("dragline", {
            "format": "dragline.results/1",
            "world_frame": "inertial frame: origin on the ground below the machine, "
                           "z (K) points down, m and rad",
            "display_frame": f"{Z_UP_FRAME}: world turned half a turn about x, z up; pick it in the 3D panel",
            "log_time_origin": datetime.fromtimestamp(origin / 1e9, timezone.utc).isoformat(),
            "log_time_origin_source": "the recording's start" if known else
                                      "the time this file was written (the recording's start is not known)"})
        schema_ids = {name: writer.register_schema(name, "jsonschema", _json_bytes(schema))
                      for name, schema in FOXGLOVE_SCHEMAS.items()}
        streams = []
        for s in sources:
            channels = {
                "transforms": writer.register_channel(
                    f"/{s}/transforms", "json", schema_ids["foxglove.FrameTransforms"]),
                "scene": writer.register_channel(
                    f"/{s}/scene", "json", schema_ids["foxglove.SceneUpdate"])}
            if data[s]["markers"] is not None:
                channels["markers"] = writer.register_channel(
                    f"/{s}/markers", "json", schema_ids["foxglove.PointCloud"])
            streams.append(_source_messages(s, data[s], colors[s], channels, origin))
        # Sources interleave in log-time order so that players stream them together.
        for ns, channel, payload in heapq.merge(*streams, key=lambda m: m[0]):
            writer.add_message(channel, ns, payload, ns)

    _atomic_mcap(path, fill, chunk_size)
    return path
