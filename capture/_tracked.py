"""Tables of tracked poses: what motion-capture software exports, read through a declared mapping.

A lab's tracker (OptiTrack Motive, VICON Tracker, a ROS bag flattened to
CSV) writes rigid-body poses over time: positions, often quaternions, in
its own world frame, units and column names. A small TOML mapping says
which columns are which rig body's pose and which rig point's track (the
drone a load hangs from), the frame's up axis, the units, the quaternion
order and the clock (docs/schemas.md, "Tracked-pose mapping"). The result
is in the tool's frame (K down, metres, seconds), each body's attitude a
rotation matrix; making a trajectory table of it (mass centres, the
output Euler angles) needs the rig and is ``reconstruct``'s.

Conventions: the recording's frame is right-handed; its ``up`` axis maps
to -K; a tracked body's local axes are the recording's world axes at the
moment the body was defined (how Motive and VICON Tracker create a rigid
body), so the same rotation takes both to the tool's frames.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal, Optional, Union

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ._clock import recover_clock
from ._marker_file import MAX_MISSING_ROWS, MAX_SPAN_FACTOR
from ._mcap_scan import MAGIC as MCAP_MAGIC
from ._schema_tools import describe_validation_error, fields_markdown

__all__ = ["TrackedPoses", "TrackedMapping", "read_tracked_table", "read_tracked_bag", "load_tracked_mapping",
           "frame_rotation", "tracked_mapping_markdown"]

_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
# A sample interval further than this from the median is a jitter or a dropout, said in the report.
JITTER = 0.01
# A moving point's track (the model's input) is interpolated across holes up to this long (s): a
# drone's or trolley's position is smooth over a few frames; a longer hole stays missing.
MAX_POINT_BRIDGE_S = 0.25
MAX_ROWS = 10_000_000
# A bag of poses this small decodes in megabytes; a MemoryError reading it is a damaged length field.
MAX_HONEST_BAG_BYTES = 256 * 2**20

# Tait-Bryan sequences, as scipy's ``Rotation.from_euler`` reads them: lowercase extrinsic, uppercase intrinsic.
_EULER_SEQUENCES = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")

_Column = Union[Annotated[str, Field(min_length=1)], Annotated[int, Field(ge=0, le=100_000)]]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, frozen=True, extra="forbid")


class TrackedBody(_Strict):
    """A rig body's tracked pose: its reference point's position, and its attitude when tracked."""

    position: Optional[list[_Column]] = Field(None, min_length=3, max_length=3,
                                              description="x, y, z columns (names or numbers), in a table")
    quaternion: Optional[list[_Column]] = Field(None, min_length=4, max_length=4,
                                                description="attitude columns, in the table's `quaternion` order")
    euler: Optional[list[_Column]] = Field(None, min_length=3, max_length=3,
                                           description="attitude as three angle columns, in the order of the "
                                                       "table's `euler` sequence, in its `angle_unit`")
    topic: Optional[Annotated[str, Field(min_length=1)]] = Field(
        None, description="in a ROS 2 bag: its PoseStamped or TransformStamped topic (position and attitude)")

    @model_validator(mode="after")
    def _source(self):
        if (self.position is None) == (self.topic is None):
            raise ValueError("give a tracked pose's source once: `position` columns (a table) or a `topic` (a bag)")
        if self.topic is not None and (self.quaternion is not None or self.euler is not None):
            raise ValueError("a topic carries its own attitude: no `quaternion` or `euler` columns with a `topic`")
        if self.quaternion is not None and self.euler is not None:
            raise ValueError("give a body's attitude once: `quaternion` or `euler` columns, not both")
        return self


class TrackedPoint(_Strict):
    """A rig point the recording moves (a drone's hook, a trolley): its track is the maneuver's."""

    position: Optional[list[_Column]] = Field(None, min_length=3, max_length=3,
                                              description="x, y, z columns (names or numbers), in a table")
    topic: Optional[Annotated[str, Field(min_length=1)]] = Field(None, description="in a ROS 2 bag: its topic")

    @model_validator(mode="after")
    def _source(self):
        if (self.position is None) == (self.topic is None):
            raise ValueError("give a tracked point's source once: `position` columns (a table) or a `topic` (a bag)")
        return self


class TrackedTable(_Strict):
    """How the table is laid out."""

    header: bool = Field(True, description="the first row names the columns; false: columns are numbered from 0")
    time: Optional[_Column] = Field(None, description="the time column; without it, `rate_hz`")
    time_unit: Literal["s", "ms", "us", "ns"] = Field("s", description="unit of the time column")
    rate_hz: Optional[float] = Field(None, gt=0, le=100_000, allow_inf_nan=False,
                                     description="rows per second, for a table without a time column")
    clock: Literal["rows", "motion"] = Field(
        "rows", description="with `rate_hz`: `rows`, every row one period; `motion`, rows at that rate on "
                            "average, each row's time recovered from the tracked motion (a log written on callbacks)")
    units: Literal["m", "cm", "mm"] = Field("m", description="unit of every position")
    up: Literal["+x", "-x", "+y", "-y", "+z", "-z"] = Field("+z", description="the recording's axis that points up")
    quaternion: Literal["xyzw", "wxyz"] = Field("xyzw", description="the order of every quaternion's columns")
    euler: Literal[_EULER_SEQUENCES] = Field(
        "xyz", description="the rotations a body's `euler` angles make, in column order: lowercase about the "
                           "recording's fixed axes (ROS's roll, pitch, yaw is xyz), uppercase about the body's own "
                           "turned axes (ZYX: yaw, pitch, roll)")
    angle_unit: Literal["rad", "deg"] = Field("rad", description="unit of every `euler` angle")
    stamp: Literal["header", "log"] = Field("header", description="in a bag: each message's header stamp, or the "
                                                                 "time the recorder logged it")
    shared_frame: bool = Field(False, description="the bodies and the points are tracked in one frame by one system: "
                                                  "a body's position is measured from the origin the points move "
                                                  "the rig in, so the diagnosis fits it no constant offset")

    @model_validator(mode="after")
    def _clock_needs_rate(self):
        if self.clock != "rows" and self.rate_hz is None:
            raise ValueError(f"`clock = \"{self.clock}\"` times a table's rows from its `rate_hz`: give one")
        return self


class TrackedMapping(_Strict):
    """A tracked-pose table mapped onto a rig."""

    table: TrackedTable = Field(default_factory=TrackedTable, description="the layout, above")
    bodies: dict[str, TrackedBody] = Field(default_factory=dict, description="rig body -> its pose columns")
    points: dict[str, TrackedPoint] = Field(default_factory=dict, description="rig point -> its track's columns")

    @model_validator(mode="after")
    def _something(self):
        if not self.bodies:
            raise ValueError("the mapping names no body: a recording must track one of the rig's bodies")
        if self.table.shared_frame and not self.points:
            raise ValueError("`shared_frame` places the bodies by the points the recording moves the rig with: "
                             "the mapping tracks no point")
        return self


@dataclass(frozen=True)
class TrackedPoses:
    """Poses read from a tracked table, in the tool's frame (K down), metres and seconds.

    Attributes
    ----------
    time : ndarray (n,)
        Uniform, from 0 at the first row (s).
    positions : dict
        Body name -> (n, 3) reference-point positions (m); NaN where not tracked.
    rotations : dict
        Body name -> (n, 3, 3) body-to-inertial matrices (bodies with a tracked attitude only).
    points : dict
        Point name -> (n, 3) positions (m).
    report : dict
        What the reading did: rows, rate, timestamps off the median step,
        rows dropped, frames resampled.
    """

    time: np.ndarray
    positions: dict
    rotations: dict = field(default_factory=dict)
    points: dict = field(default_factory=dict)
    report: dict = field(default_factory=dict)


def frame_rotation(up):
    """The proper rotation taking the recording's frame (``up`` its upward axis) to the tool's (K down)."""
    sign = 1.0 if up[0] == "+" else -1.0
    axis = "xyz".index(up[1])
    down = np.zeros(3)
    down[axis] = -sign  # the recording's downward direction becomes +K
    # The tool's I axis: the recording's x, or its z when x is vertical.
    first = np.zeros(3)
    first["xyz".index("z" if axis == 0 else "x")] = 1.0
    second = np.cross(down, first)  # J = K x I keeps the frame right-handed
    return np.vstack([first, second, down])


def load_tracked_mapping(path):
    """A mapping TOML checked against its schema (ValueError with one line naming the file)."""
    try:
        doc = tomllib.loads(Path(path).read_text())
    except OSError as exc:
        raise ValueError(f"cannot read mapping {path}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise ValueError(f"mapping {path} is not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML ({exc})") from None
    try:
        return TrackedMapping.model_validate(doc)
    except ValidationError as exc:
        where, value, expected = describe_validation_error(exc)
        if exc.errors()[0]["type"] == "value_error" or not where:
            raise ValueError(f"{path}: {where + ': ' if where else ''}{expected}") from None
        raise ValueError(f"{path}: {where} = {value!r}: expected {expected}") from None


def _columns(frame, mapping, path, mapping_name):
    """Every column the mapping names, as float arrays, by the mapping's own keys (errors name the file at fault:
    the table, the mapping ``mapping_name``, or both)."""
    wanted = [mapping.table.time] if mapping.table.time is not None else []
    for entry in (*mapping.bodies.values(), *mapping.points.values()):
        if entry.position is None:
            raise ValueError(f"{mapping_name}: a table's mapping gives `position` columns; `topic` is for a ROS 2 "
                             f"bag (reading {path})")
        wanted += list(entry.position) + list(getattr(entry, "quaternion", None) or ())
        wanted += list(getattr(entry, "euler", None) or ())
    out = {}
    for key in wanted:
        if isinstance(key, int):
            if key >= len(frame.columns):
                raise ValueError(f"{path}: column {key} named by the mapping {mapping_name}; the table has "
                                 f"{len(frame.columns)}")
            name = frame.columns[key]
        elif not mapping.table.header:
            raise ValueError(f"{mapping_name}: the mapping names column {key!r}, but the table {path} has no "
                             "header: number the columns from 0")
        elif key not in frame.columns:
            raise ValueError(f"{path}: no column {key!r} (the mapping {mapping_name} names it; the table has "
                             f"{', '.join(map(str, list(frame.columns)[:8]))}{', ...' if len(frame.columns) > 8 else ''})")
        else:
            name = key
        values = pd.to_numeric(frame[name], errors="coerce")
        bad = (values.isna() & frame[name].notna()) | np.isinf(values.to_numpy(float))
        if bad.any():
            row = int(np.argmax(bad.to_numpy())) + (2 if mapping.table.header else 1)
            raise ValueError(f"{path}: column {key!r}, row {row} = {frame[name][bad].iloc[0]!r}: expected a finite "
                             "number (a gap is an empty cell)")
        out[key] = values.to_numpy(float)
    return out


def read_tracked_table(path, mapping):
    """Read a tracked-pose table (CSV) through ``mapping`` (a ``TrackedMapping`` or its TOML path).

    Every track is put in time order; rows with no time, or a time already
    seen, are dropped; the rest are resampled to a uniform clock at the
    median step (``_resampled``). The report says how many rows were dropped
    and how far the timestamps strayed.

    Raises
    ------
    ValueError
        One line naming the file: unreadable, a column the mapping names
        that the table lacks, a non-number, too few rows.
    """
    mapping_name = "the mapping given in code" if isinstance(mapping, TrackedMapping) else os.fspath(mapping)
    if not isinstance(mapping, TrackedMapping):
        mapping = load_tracked_mapping(mapping)
    if (mapping.table.time is None) == (mapping.table.rate_hz is None):
        raise ValueError(f"{mapping_name}: give the table's clock once in the mapping: a `time` column or a "
                         f"`rate_hz` (reading {path})")
    try:
        frame = pd.read_csv(path, header=0 if mapping.table.header else None, low_memory=False,
                            nrows=MAX_ROWS + 1)
    except FileNotFoundError:
        raise ValueError(f"tracked table {path} does not exist") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, OSError) as exc:
        raise ValueError(f"tracked table {path} cannot be read: {str(exc).splitlines()[0]}") from None
    if len(frame) > MAX_ROWS:
        raise ValueError(f"tracked table {path} has more than {MAX_ROWS} rows")
    if mapping.table.header:
        frame.columns = [str(c).strip() for c in frame.columns]
    columns = _columns(frame, mapping, path, mapping_name)
    if mapping.table.time is None:
        t = np.arange(len(frame)) / mapping.table.rate_hz
        if mapping.table.clock == "motion":
            tracked = [columns[k] for entry in (*mapping.bodies.values(), *mapping.points.values())
                       for k in entry.position]
            t = recover_clock(np.column_stack(tracked) * _UNITS[mapping.table.units], 1.0 / mapping.table.rate_hz)
    else:
        t = columns[mapping.table.time] * _TIME_UNITS[mapping.table.time_unit]

    def track(entry):
        quaternion, euler = getattr(entry, "quaternion", None), getattr(entry, "euler", None)
        q = None if quaternion is None else np.column_stack([columns[k] for k in quaternion])
        if q is not None and mapping.table.quaternion == "wxyz":
            q = q[:, [1, 2, 3, 0]]
        if euler is not None:
            q = _euler_quaternions(np.column_stack([columns[k] for k in euler]), mapping.table)
        return t, np.column_stack([columns[k] for k in entry.position]), q

    tracks = {**{("body", n): track(b) for n, b in mapping.bodies.items()},
              **{("point", n): track(p) for n, p in mapping.points.items()}}
    return _resampled(path, mapping, tracks, rows=len(frame))


def read_tracked_bag(path, mapping):
    """Read the pose topics of a ROS 2 bag (MCAP, CDR) through ``mapping``.

    Each body or point names a ``geometry_msgs`` ``PoseStamped`` or
    ``TransformStamped`` topic (as the VICON and OptiTrack ROS bridges
    publish); messages are decoded by ``mcap-ros2-support`` from the bag's
    own message definitions. Time is each message's header stamp (or the
    recorder's log time, ``table.stamp = "log"``). Every track is then
    resampled to one uniform clock (``_resampled``).
    """
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    mapping_name = "the mapping given in code" if isinstance(mapping, TrackedMapping) else os.fspath(mapping)
    if not isinstance(mapping, TrackedMapping):
        mapping = load_tracked_mapping(mapping)
    entries = {**{("body", n): b for n, b in mapping.bodies.items()}, **{("point", n): p for n, p in mapping.points.items()}}
    for (_, name), entry in entries.items():
        if entry.topic is None:
            raise ValueError(f"{path}: a bag's mapping gives each body and point a `topic` ({name!r} has columns)")
    samples = {key: [] for key in entries}
    by_topic = {}
    for key, entry in entries.items():
        by_topic.setdefault(entry.topic, []).append(key)
    _check_bag_ends(path)
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])  # noqa: SIM117
            for _, channel, message, ros in reader.iter_decoded_messages(topics=list(by_topic)):
                stamp = message.log_time  # integer ns: seconds since 1970 in a float lose 0.2 us
                if mapping.table.stamp == "header":
                    stamp = int(ros.header.stamp.sec) * 10**9 + int(ros.header.stamp.nanosec)
                pose = getattr(ros, "pose", None)
                if pose is not None:
                    p, q = pose.position, pose.orientation
                else:
                    p, q = ros.transform.translation, ros.transform.rotation
                row = (stamp, p.x, p.y, p.z, q.x, q.y, q.z, q.w)
                for key in by_topic[channel.topic]:
                    samples[key].append(row)
    except MemoryError:
        if os.path.getsize(path) > MAX_HONEST_BAG_BYTES:
            raise
        # a bag this small needs megabytes: a length field a damaged byte turned into terabytes
        raise ValueError(f"bag {path} is damaged: a record claims more memory than the machine has") from None
    except Exception as exc:  # noqa: BLE001 - a damaged bag fails inside the decoders (zstd, lz4, CDR) in their own ways
        raise ValueError(f"bag {path} cannot be read as ROS 2 poses: {' '.join(str(exc).split()) or type(exc).__name__}") from None
    tracks = {}
    for key, rows in samples.items():
        if not rows:
            raise ValueError(f"{mapping_name}: bag {path} has no message on the topic it names for {key[0]} "
                             f"{key[1]!r}, {entries[key].topic!r}")
    origin = min(row[0] for rows in samples.values() for row in rows)
    for key, rows in samples.items():
        t = np.array([(row[0] - origin) * 1e-9 for row in rows])
        a = np.array([row[1:] for row in rows], float)
        tracks[key] = (t, a[:, 0:3], a[:, 3:7] if key[0] == "body" else None)
    return _resampled(path, mapping, tracks, rows=sum(len(r) for r in samples.values()))


def _check_bag_ends(path):
    """ValueError unless the bag opens and closes with MCAP's magic bytes: the reader seeks to the footer at the
    end, and a cut bag's last bytes read as a record of any length (10,000 fuzzed cases: a MemoryError)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(MCAP_MAGIC))
            size = fh.seek(0, os.SEEK_END)
            fh.seek(max(0, size - len(MCAP_MAGIC)))
            tail = fh.read(len(MCAP_MAGIC))
    except FileNotFoundError:
        raise ValueError(f"bag {path} does not exist") from None
    if head != MCAP_MAGIC:
        raise ValueError(f"bag {path} is not an MCAP file (bad magic bytes)")
    if tail != MCAP_MAGIC or size < 2 * len(MCAP_MAGIC):
        raise ValueError(f"bag {path} is cut short: it does not end with MCAP's closing magic bytes")


def _resampled(path, mapping, tracks, rows):
    """Tracks (("body" or "point", name) -> (time s, xyz, quaternion xyzw or None)) on one uniform clock, in
    the tool's frame.

    The clock runs at the first body's median step over the time every
    track covers. A track's rows without a time, or repeating one, are
    dropped; across a gap of more than 3.5 steps nothing is made up, except
    in a point's track (the model's input) up to ``MAX_POINT_BRIDGE_S``.
    """
    cleaned, dropped = {}, 0
    for key, (t, xyz, q) in tracks.items():
        usable = np.flatnonzero(np.isfinite(t) & np.all(np.isfinite(xyz), axis=1))
        order = usable[np.argsort(t[usable], kind="stable")]
        keep = order[np.r_[True, np.diff(t[order]) > 0]]
        dropped += t.size - keep.size
        if keep.size < 4:
            raise ValueError(f"{path}: {key[0]} {key[1]!r} has {keep.size} samples with a usable time; a recording "
                             "needs more")
        cleaned[key] = (t[keep], xyz[keep], None if q is None else q[keep])
    first = next(iter(cleaned.values()))[0]
    step = float(np.median(np.diff(first)))
    start = max(v[0][0] for v in cleaned.values())
    end = min(v[0][-1] for v in cleaned.values())
    if not end - start > 3 * step:
        raise ValueError(f"{path}: the tracks do not overlap in time")
    span = (end - start) / step
    if not span <= MAX_SPAN_FACTOR * rows + MAX_MISSING_ROWS:  # a marker file's frame numbers are held the same
        # A damaged timestamp once made a 2-second bag span 1.9e11 steps (1.9 TiB of clock).
        raise ValueError(f"{path}: the timestamps span {end - start:.6g} s at a median step of {step:.3g} s, "
                         f"{span:.3g} steps for {rows} samples: a timestamp is wrong")
    time = start + np.arange(int(np.floor((end - start) / step + 1e-9)) + 1) * step
    R = frame_rotation(mapping.table.up)
    scale = _UNITS[mapping.table.units]
    gaps = bridged = off_step = 0
    out = {"body": {}, "point": {}, "rotation": {}}
    for (kind, name), (t, xyz, q) in cleaned.items():
        intervals = np.diff(t)
        off_step += int(np.count_nonzero(np.abs(intervals - step) > JITTER * step))
        # A point's track is the model's input: a short hole in it is bridged (a drone's hook moves
        # smoothly over a few frames), a body's stays missing (it is what the model is judged on).
        limit = max(3.5 * step, MAX_POINT_BRIDGE_S) if kind == "point" else 3.5 * step
        holes = np.flatnonzero(intervals > limit)
        gaps += holes.size
        bridged += int(np.count_nonzero((intervals > 3.5 * step) & (intervals <= limit)))
        margin = JITTER * step  # a sample at a kept row's own time is data, whatever its rounding
        missing = np.zeros(time.size, bool)
        for k in holes:
            missing |= (time > t[k] + margin) & (time < t[k + 1] - margin)

        def resample(values, t=t, missing=missing):
            values = np.interp(time, t, values)
            values[missing] = np.nan
            return values

        out[kind][name] = np.column_stack([resample(xyz[:, k]) for k in range(3)]) * scale @ R.T
        if q is not None:
            out["rotation"][name] = R @ _quaternion_matrices(_resample_quaternions(q, resample)) @ R.T
    report = {"rows": int(rows), "rows_dropped": int(dropped), "rate_hz": 1.0 / step, "samples": int(time.size),
              "off_step": off_step, "gaps": gaps, "point_gaps_bridged": bridged, "start_time_s": float(start),
              "shared_frame": mapping.table.shared_frame}
    return TrackedPoses(time=time - start, positions=out["body"], rotations=out["rotation"], points=out["point"],
                        report=report)


def _euler_quaternions(angles, table):
    """Quaternions (x, y, z, w) of rows of three angles in ``table.euler``'s sequence; NaN where an angle is."""
    from scipy.spatial.transform import Rotation

    q = np.full((angles.shape[0], 4), np.nan)
    whole = np.isfinite(angles).all(axis=1)
    if whole.any():
        q[whole] = Rotation.from_euler(table.euler, angles[whole], degrees=table.angle_unit == "deg").as_quat()
    return q


def _resample_quaternions(q, resample):
    """Quaternions (x, y, z, w) on the uniform clock: signs made continuous, each component interpolated, renormalized."""
    q = np.array(q, float)
    dots = np.einsum("ij,ij->i", q[1:], q[:-1])
    q = q * np.r_[1.0, np.cumprod(np.where(dots < 0, -1.0, 1.0))][:, None]  # q and -q are one attitude
    out = np.column_stack([resample(q[:, k]) for k in range(4)])
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return out / norm


def _quaternion_matrices(q):
    """Rotation matrices (n, 3, 3) of unit quaternions (x, y, z, w); NaN where a quaternion is."""
    x, y, z, w = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def tracked_mapping_markdown():
    """The mapping schema as Markdown tables (``docs/schemas.md`` holds this text)."""
    header = ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    blocks = []
    for model, prefix in ((TrackedMapping, ""), (TrackedTable, "table."), (TrackedBody, "bodies.NAME."),
                          (TrackedPoint, "points.NAME.")):
        blocks.append(header + fields_markdown(model, prefix))
    return "\n\n".join("\n".join(b) for b in blocks) + "\n"
