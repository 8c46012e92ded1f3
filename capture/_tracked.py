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

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal, Optional, Union

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ._schema_tools import describe_validation_error, fields_markdown

__all__ = ["TrackedPoses", "TrackedMapping", "read_tracked_table", "load_tracked_mapping", "frame_rotation",
           "tracked_mapping_markdown"]

_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
# A sample interval further than this from the median is a jitter or a dropout, said in the report.
JITTER = 0.01
MAX_ROWS = 10_000_000

_Column = Union[Annotated[str, Field(min_length=1)], Annotated[int, Field(ge=0, le=100_000)]]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, frozen=True, extra="forbid")


class TrackedBody(_Strict):
    """A rig body's tracked pose: its reference point's position, and its attitude when tracked."""

    position: list[_Column] = Field(min_length=3, max_length=3, description="x, y, z columns (names or numbers)")
    quaternion: Optional[list[_Column]] = Field(None, min_length=4, max_length=4,
                                                description="attitude columns, in the table's `quaternion` order")


class TrackedPoint(_Strict):
    """A rig point the recording moves (a drone's hook, a trolley): its track is the maneuver's."""

    position: list[_Column] = Field(min_length=3, max_length=3, description="x, y, z columns (names or numbers)")


class TrackedTable(_Strict):
    """How the table is laid out."""

    header: bool = Field(True, description="the first row names the columns; false: columns are numbered from 0")
    time: Optional[_Column] = Field(None, description="the time column; without it, `rate_hz`")
    time_unit: Literal["s", "ms", "us", "ns"] = Field("s", description="unit of the time column")
    rate_hz: Optional[float] = Field(None, gt=0, le=100_000, allow_inf_nan=False,
                                     description="rows per second, for a table without a time column")
    units: Literal["m", "cm", "mm"] = Field("m", description="unit of every position")
    up: Literal["+x", "-x", "+y", "-y", "+z", "-z"] = Field("+z", description="the recording's axis that points up")
    quaternion: Literal["xyzw", "wxyz"] = Field("xyzw", description="the order of every quaternion's columns")

    @model_validator(mode="after")
    def _clock(self):
        if (self.time is None) == (self.rate_hz is None):
            raise ValueError("give the table's clock once: a `time` column or a `rate_hz`")
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
        Body name -> (n, 3, 3) body-to-inertial matrices (bodies with a quaternion only).
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


def _columns(frame, mapping, path):
    """Every column the mapping names, as float arrays, by the mapping's own keys."""
    wanted = [mapping.table.time] if mapping.table.time is not None else []
    for body in mapping.bodies.values():
        wanted += list(body.position) + list(body.quaternion or ())
    for point in mapping.points.values():
        wanted += list(point.position)
    out = {}
    for key in wanted:
        if isinstance(key, int):
            if key >= len(frame.columns):
                raise ValueError(f"{path}: column {key} named by the mapping; the table has {len(frame.columns)}")
            name = frame.columns[key]
        elif not mapping.table.header:
            raise ValueError(f"{path}: the mapping names column {key!r}, but the table has no header: number the "
                             "columns from 0")
        elif key not in frame.columns:
            raise ValueError(f"{path}: no column {key!r} (the mapping names it; the table has "
                             f"{', '.join(map(str, list(frame.columns)[:8]))}{', ...' if len(frame.columns) > 8 else ''})")
        else:
            name = key
        values = pd.to_numeric(frame[name], errors="coerce")
        bad = values.isna() & frame[name].notna()
        if bad.any():
            row = int(np.argmax(bad.to_numpy())) + (2 if mapping.table.header else 1)
            raise ValueError(f"{path}: column {key!r}, row {row} = {frame[name][bad].iloc[0]!r}: expected a number")
        out[key] = values.to_numpy(float)
    return out


def _clock(columns, mapping, n, path):
    """Raw sample times (s) from the time column or the rate, and the rows whose time is usable."""
    if mapping.table.time is None:
        return np.arange(n) / mapping.table.rate_hz
    t = columns[mapping.table.time] * _TIME_UNITS[mapping.table.time_unit]
    if not np.isfinite(t).any():
        raise ValueError(f"{path}: the time column {mapping.table.time!r} holds no number")
    return t


def read_tracked_table(path, mapping):
    """Read a tracked-pose table through ``mapping`` (a ``TrackedMapping`` or its TOML path).

    Rows are put in time order; rows with no time, or a time already seen,
    are dropped; the rest are resampled to a uniform clock at the median
    step (linear for positions, normalized linear blend for quaternions),
    leaving NaN across any gap of more than three steps. The report says
    how many rows were dropped and how far the timestamps strayed.

    Raises
    ------
    ValueError
        One line naming the file: unreadable, a column the mapping names
        that the table lacks, a non-number, too few rows.
    """
    if not isinstance(mapping, TrackedMapping):
        mapping = load_tracked_mapping(mapping)
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
    columns = _columns(frame, mapping, path)
    t_raw = _clock(columns, mapping, len(frame), path)
    usable = np.isfinite(t_raw)
    order = np.argsort(t_raw[usable], kind="stable")
    rows = np.flatnonzero(usable)[order]
    t_sorted = t_raw[rows]
    first = np.r_[True, np.diff(t_sorted) > 0]
    rows, t_sorted = rows[first], t_sorted[first]
    if rows.size < 4:
        raise ValueError(f"tracked table {path} has {rows.size} rows with a usable time; a recording needs more")
    step = float(np.median(np.diff(t_sorted)))
    time = np.arange(int(np.floor((t_sorted[-1] - t_sorted[0]) / step + 1e-9)) + 1) * step
    rel = t_sorted - t_sorted[0]
    gaps = np.diff(rel) > 3.5 * step
    report = {"rows": int(len(frame)), "rows_used": int(rows.size), "rows_dropped": int(len(frame) - rows.size),
              "rate_hz": 1.0 / step, "samples": int(time.size),
              "off_step": int(np.count_nonzero(np.abs(np.diff(rel) - step) > JITTER * step)),
              "gaps": int(np.count_nonzero(gaps)), "start_time_s": float(t_sorted[0])}
    R = frame_rotation(mapping.table.up)
    scale = _UNITS[mapping.table.units]

    def resample(values):
        out = np.interp(time, rel, values)
        if gaps.any():  # nothing is made up across a dropout
            for k in np.flatnonzero(gaps):
                margin = JITTER * step  # a sample at a kept row's own time is data, whatever its rounding
                out[(time > rel[k] + margin) & (time < rel[k + 1] - margin)] = np.nan
        return out

    def track(keys):
        xyz = np.column_stack([resample(columns[k][rows]) for k in keys]) * scale
        return xyz @ R.T

    positions = {name: track(body.position) for name, body in mapping.bodies.items()}
    rotations = {}
    for name, body in mapping.bodies.items():
        if body.quaternion is None:
            continue
        q = np.column_stack([columns[k][rows] for k in body.quaternion])
        if mapping.table.quaternion == "wxyz":
            q = q[:, [1, 2, 3, 0]]
        rotations[name] = R @ _quaternion_matrices(_resample_quaternions(q, rel, time, resample)) @ R.T
    points = {name: track(point.position) for name, point in mapping.points.items()}
    return TrackedPoses(time=time, positions=positions, rotations=rotations, points=points, report=report)


def _resample_quaternions(q, rel, time, resample):
    """Quaternions (x, y, z, w) on the uniform clock: signs made continuous, each component interpolated, renormalized."""
    q = np.array(q, float)
    for k in range(1, len(q)):
        if np.all(np.isfinite(q[k])) and np.all(np.isfinite(q[k - 1])) and np.dot(q[k], q[k - 1]) < 0:
            q[k:] *= -1.0
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
