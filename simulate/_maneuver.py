"""Maneuvers: reel tables of hoist and drag rope length against time.

A maneuver is a table (``time``, ``hoist_length``, ``drag_length``; s, m, m),
linearly interpolated (seed paper section 2.3) and held at its last row
after it ends. Users supply one as a CSV file with those three columns, and
optionally ``<point>.x, <point>.y, <point>.z`` columns (m) that move one of
the rig's fixed points (the boom pulley, a reel) through the maneuver.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..capture import atomic_file
from ._maneuver_schema import MAX_ROWS, check_maneuver_columns

__all__ = ["Maneuver", "dig_maneuver", "read_maneuver_csv", "write_maneuver_csv"]


@dataclass(frozen=True)
class Maneuver:
    """A reel table.

    Attributes
    ----------
    time : ndarray, shape (K,)
        Strictly increasing (s).
    hoist_length, drag_length : ndarray, shape (K,)
        Rope paid out from each reel (m), positive.
    """

    time: np.ndarray
    hoist_length: np.ndarray
    drag_length: np.ndarray
    points: dict = field(default_factory=dict)

    def __post_init__(self):
        cols = {}
        for name in ("time", "hoist_length", "drag_length"):
            arr = np.array(getattr(self, name), float).reshape(-1)
            arr.setflags(write=False)
            cols[name] = arr
            object.__setattr__(self, name, arr)
        n = cols["time"].size
        if n == 0:
            raise ValueError("maneuver table is empty")
        if any(c.size != n for c in cols.values()):
            raise ValueError("maneuver columns have different lengths")
        for name, c in cols.items():
            if not np.isfinite(c).all():
                raise ValueError(f"maneuver column {name!r} has missing or non-finite values")
        if n > 1 and np.any(np.diff(cols["time"]) <= 0):
            i = int(np.argmax(np.diff(cols["time"]) <= 0)) + 1
            raise ValueError(f"maneuver time is not strictly increasing at row {i + 1}")
        for name in ("hoist_length", "drag_length"):
            if np.any(cols[name] <= 0):
                raise ValueError(f"maneuver {name} must be positive (row {int(np.argmax(cols[name] <= 0)) + 1})")
        points = {}
        for name, xyz in dict(self.points).items():
            arr = np.array(xyz, float)
            if arr.shape != (n, 3) or not np.isfinite(arr).all():
                raise ValueError(f"maneuver point {name!r} needs finite x, y, z on every row")
            arr.setflags(write=False)
            points[name] = arr
        object.__setattr__(self, "points", points)

    @property
    def end_time(self):
        """Time of the last row (s)."""
        return float(self.time[-1])

    def lengths_at(self, t):
        """Interpolated (hoist, drag) lengths at times ``t`` (m)."""
        t = np.asarray(t, float)
        return (np.interp(t, self.time, self.hoist_length), np.interp(t, self.time, self.drag_length))

    def to_frame(self):
        cols = {"time": self.time, "hoist_length": self.hoist_length, "drag_length": self.drag_length}
        for name, xyz in self.points.items():
            for k, axis in enumerate("xyz"):
                cols[f"{name}.{axis}"] = xyz[:, k]
        return pd.DataFrame(cols)


def dig_maneuver():
    """The seed paper's dig maneuver (section 4, as read in docs/model.md).

    Phase 1, 2.5 s: hoist pays out 0.36 m/s, drag winds in 0.30 m/s; phase 2,
    1 s: hoist still, drag 0.61 m/s; phase 3, 2 s: hoist 0.30 m/s, drag
    0.48 m/s; phase 4, 1 s: hoist still, drag 0.48 m/s; both stop at 6.5 s.
    Hoist 8.6 -> 10.1 m, drag 4.2 -> 1.41 m.
    """
    durations = [2.5, 1.0, 2.0, 1.0]
    hoist_rate = [0.36, 0.0, 0.30, 0.0]
    drag_rate = [-0.30, -0.61, -0.48, -0.48]
    t, h, d = [0.0], [8.6], [4.2]
    for dur, vh, vd in zip(durations, hoist_rate, drag_rate):
        t.append(t[-1] + dur)
        h.append(h[-1] + vh * dur)
        d.append(d[-1] + vd * dur)
    return Maneuver(np.array(t), np.array(h), np.array(d))


def read_maneuver_csv(path):
    """Read a maneuver CSV (columns ``time, hoist_length, drag_length``).

    Raises
    ------
    ValueError
        One line naming the file and what is wrong with it (the schema is
        ``_maneuver_schema``, docs/schemas.md).
    """
    try:
        frame = pd.read_csv(path, low_memory=False)  # one type per column: no DtypeWarning on odd files
    except FileNotFoundError:
        raise ValueError(f"maneuver file {path} does not exist") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, OSError) as exc:
        raise ValueError(f"maneuver file {path} cannot be read: {str(exc).splitlines()[0]}") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    missing = [c for c in ("time", "hoist_length", "drag_length") if c not in frame.columns]
    if missing:
        raise ValueError(f"maneuver file {path} lacks column(s) {', '.join(missing)}")
    point_names = sorted({c.rsplit(".", 1)[0] for c in frame.columns if c.endswith((".x", ".y", ".z"))})
    for name in point_names:
        if not all(f"{name}.{a}" in frame.columns for a in "xyz"):
            raise ValueError(f"maneuver file {path}: point {name!r} needs .x, .y and .z columns")
    if len(frame) == 0:
        raise ValueError(f"maneuver file {path} is empty (a header and no rows)")
    if len(frame) > MAX_ROWS:
        raise ValueError(f"maneuver file {path} has {len(frame)} rows; at most {MAX_ROWS} are read")
    num = {}
    for c in frame.columns:
        values = pd.to_numeric(frame[c], errors="coerce")
        bad = values.isna() & frame[c].notna()
        if bad.any():
            row = int(np.argmax(bad.to_numpy()))
            raise ValueError(f"maneuver file {path}: column {c}, row {row + 2} = {frame[c].iloc[row]!r}: "
                             "expected a number")
        num[c] = values.to_numpy(float)
    columns = {c: num[c].tolist() for c in ("time", "hoist_length", "drag_length")}
    columns["points"] = {name: np.column_stack([num[f"{name}.{a}"] for a in "xyz"]).tolist() for name in point_names}
    known = {"time", "hoist_length", "drag_length"} | {f"{n}.{a}" for n in point_names for a in "xyz"}
    columns.update({c: num[c].tolist() for c in frame.columns if c not in known})  # refused by the schema
    return maneuver_from_columns(columns, path)


def maneuver_from_columns(columns, path):
    """A Maneuver from its columns (``_maneuver_schema.ManeuverColumns`` layout), checked against the schema.

    Raises
    ------
    ValueError
        One line naming ``path``, the column and the row.
    """
    check_maneuver_columns(columns, path)
    points = {name: np.asarray(xyz, float) for name, xyz in columns.get("points", {}).items()}
    try:
        return Maneuver(columns["time"], columns["hoist_length"], columns["drag_length"], points)
    except ValueError as exc:
        raise ValueError(f"maneuver file {path}: {exc}") from None


def write_maneuver_csv(path, maneuver):
    """Write a maneuver table as CSV (atomic: temporary name, then rename)."""

    with atomic_file(path) as tmp:
        maneuver.to_frame().to_csv(tmp, index=False, float_format="%.9g")
