"""Foxglove results: trajectory tables (and markers, ropes) as an MCAP that Foxglove opens.

Per source ``s`` of :func:`write_results` (``measured``, ``simulated``, ...):
``/s/transforms`` (``foxglove.FrameTransforms``: frame ``world`` -> ``s/body``),
``/s/scene`` (``foxglove.SceneUpdate``: a cube per body, a sphere for a body
whose orientation is unknown, a line strip per rope) and ``/s/markers``
(``foxglove.PointCloud``, FLOAT64 x, y, z). The messages are built and
written by Foxglove's own SDK (``foxglove-sdk``): its message classes and
schemas are Foxglove's, protobuf-encoded, so the file follows the official
schemas by construction and follows them as they evolve (docs/interfaces.md
says why the SDK rather than JSON messages with carried JSON schemas: the
file is smaller and written several times faster).
``world`` is the inertial frame of docs/conventions.md unchanged: K (z) points
DOWN. Every transforms message also holds ``world_z_up`` -> ``world``, a half
turn about x: pick ``world_z_up`` as the 3D panel's display frame and the rig
stands right side up (Foxglove's view is z-up). Log times are the tables'
times after the recording's start (``start_ns``, Unix epoch; the current
time when the start is not known), and the summary's ``dragline`` metadata
says which.
"""

from __future__ import annotations

import heapq
import os
import re
import time
from datetime import datetime, timezone

import numpy as np
from scipy.spatial.transform import Rotation

from ..capture import MCAP_CHUNK_SIZE as CHUNK_SIZE
from ..capture import atomic_file
from ..simulate import BODIES, body_to_inertial
from ._paper import BODY_SIZES

__all__ = ["write_results", "quaternion_from_matrix"]


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


WORLD_FRAME = "world"
# Display frame: world turned half a turn about x (x kept, y and z reversed), so z is up.
Z_UP_FRAME = "world_z_up"
_HALF_TURN_X = (1.0, 0.0, 0.0, 0.0)  # x, y, z, w
_SMALL = (0.05, 0.05, 0.05)
_PALETTE = {"measured": (0.12, 0.47, 0.71), "simulated": (1.0, 0.50, 0.05)}
_EXTRA_COLORS = [(0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.58, 0.40, 0.74)]
_ROPE_THICKNESS = 0.01  # m


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


def _source_messages(fm, source, data, color, channels, origin_ns, sizes):
    """Yield (log_time_ns, channel, message) for one source, in time order, from ``origin_ns``.

    ``fm`` is ``foxglove.messages``; ``channels`` maps ``transforms``,
    ``scene`` (and ``markers``) to the SDK's channels.
    """
    poses, markers, ropes = data["poses"], data["markers"], data["ropes"]
    bodies = list(poses)
    origin = fm.Pose(position=fm.Vector3(x=0.0, y=0.0, z=0.0), orientation=fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
    fields = [fm.PackedElementField(name=k, offset=8 * j, type=fm.PackedElementFieldNumericType.Float64)
              for j, k in enumerate("xyz")]

    def pose(position, q):
        return fm.Pose(position=fm.Vector3(x=position[0], y=position[1], z=position[2]),
                       orientation=fm.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))

    def vec(v):
        return fm.Vector3(x=v[0], y=v[1], z=v[2])

    def rgba(a):
        return fm.Color(r=color[0], g=color[1], b=color[2], a=a)

    for i, ns in enumerate(data["times"]):
        ns = origin_ns + ns
        stamp = fm.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)
        transforms = [fm.FrameTransform(timestamp=stamp, parent_frame_id=Z_UP_FRAME, child_frame_id=WORLD_FRAME,
                                        translation=vec((0.0, 0.0, 0.0)),
                                        rotation=fm.Quaternion(x=_HALF_TURN_X[0], y=_HALF_TURN_X[1],
                                                               z=_HALF_TURN_X[2], w=_HALF_TURN_X[3]))]
        entities, deletions = [], []
        for body in bodies:
            pos, q = poses[body][0][i].tolist(), poses[body][1][i].tolist()
            eid = f"{source}/{body}"
            if not np.isfinite(pos).all():
                deletions.append(fm.SceneEntityDeletion(timestamp=stamp, type=fm.SceneEntityDeletionType.MatchingId,
                                                        id=eid))
            elif np.isfinite(q).all():
                transforms.append(fm.FrameTransform(timestamp=stamp, parent_frame_id=WORLD_FRAME, child_frame_id=eid,
                                                    translation=vec(pos),
                                                    rotation=fm.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])))
                cube = fm.CubePrimitive(pose=pose(pos, q), size=vec(sizes.get(body, _SMALL)), color=rgba(0.8))
                entities.append(fm.SceneEntity(timestamp=stamp, frame_id=WORLD_FRAME, id=eid, cubes=[cube]))
            else:  # orientation unknown (e.g. a two-marker body): a sphere claims none
                sphere = fm.SpherePrimitive(pose=pose(pos, (0.0, 0.0, 0.0, 1.0)), size=vec(_SMALL), color=rgba(0.8))
                entities.append(fm.SceneEntity(timestamp=stamp, frame_id=WORLD_FRAME, id=eid, spheres=[sphere]))
        for name, pts in ropes.items():
            eid = f"{source}/{name}"
            ok = pts[i][np.isfinite(pts[i]).all(axis=1)].tolist()
            if len(ok) < 2:
                deletions.append(fm.SceneEntityDeletion(timestamp=stamp, type=fm.SceneEntityDeletionType.MatchingId,
                                                        id=eid))
                continue
            line = fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineStrip, pose=origin, thickness=_ROPE_THICKNESS,
                                    points=[fm.Point3(x=p[0], y=p[1], z=p[2]) for p in ok], color=rgba(1.0))
            entities.append(fm.SceneEntity(timestamp=stamp, frame_id=WORLD_FRAME, id=eid, lines=[line]))
        yield ns, channels["transforms"], fm.FrameTransforms(transforms=transforms)
        yield ns, channels["scene"], fm.SceneUpdate(deletions=deletions, entities=entities)
        if markers is not None:
            seen = markers[i][np.isfinite(markers[i]).all(axis=1)]
            yield ns, channels["markers"], fm.PointCloud(timestamp=stamp, frame_id=WORLD_FRAME, pose=origin,
                                                         point_stride=24, fields=fields,
                                                         data=seen.astype("<f8").tobytes())


def write_results(path, tables, markers=None, ropes=None, chunk_size=CHUNK_SIZE, start_ns=None, body_sizes=None):
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
    body_sizes : dict of str -> (3,), optional
        Each body's box (m, the rig's ``size``); default the paper's bucket,
        every other body drawn small.

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
    sizes = BODY_SIZES if body_sizes is None else {k: tuple(float(x) for x in v) for k, v in body_sizes.items()}

    known = start_ns is not None
    if known and not (isinstance(start_ns, (int, np.integer)) and 0 <= start_ns < 2**63 - 10**15):
        raise ValueError(f"start_ns must be a non-negative integer (ns since the Unix epoch), got {start_ns!r}")
    origin = int(start_ns) if known else time.time_ns()

    import foxglove
    from foxglove import channels as fc
    from foxglove import messages as fm
    from foxglove.mcap import MCAPCompression, MCAPWriteOptions

    # A context of its own: nothing logged elsewhere in the process reaches this file.
    context = foxglove.Context()
    options = MCAPWriteOptions(compression=MCAPCompression.Zstd, chunk_size=chunk_size)
    with atomic_file(path) as tmp, open(tmp, "wb") as fh:
        writer = foxglove.open_mcap(fh, context=context, writer_options=options)
        writer.write_metadata("dragline", {
            "format": "dragline.results/2",
            "world_frame": "inertial frame: origin on the ground below the machine, "
                           "z (K) points down, m and rad",
            "display_frame": f"{Z_UP_FRAME}: world turned half a turn about x, z up; pick it in the 3D panel",
            "log_time_origin": datetime.fromtimestamp(origin / 1e9, timezone.utc).isoformat(),
            "log_time_origin_source": "the recording's start" if known else
                                      "the time this file was written (the recording's start is not known)"})
        streams = []
        for s in sources:
            channels = {"transforms": fc.FrameTransformsChannel(f"/{s}/transforms", context=context),
                        "scene": fc.SceneUpdateChannel(f"/{s}/scene", context=context)}
            if data[s]["markers"] is not None:
                channels["markers"] = fc.PointCloudChannel(f"/{s}/markers", context=context)
            streams.append(_source_messages(fm, s, data[s], colors[s], channels, origin, sizes))
        # Sources interleave in log-time order so that players stream them together.
        for ns, channel, message in heapq.merge(*streams, key=lambda m: m[0]):
            channel.log(message, log_time=ns)
        writer.close()
        fh.flush()
        os.fsync(fh.fileno())
    return path
