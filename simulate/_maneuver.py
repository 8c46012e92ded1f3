"""Maneuvers: what the winches pay out, and where moving points go, against time.

A maneuver is a table: ``time`` (s), one ``<winch>_length`` column (m) per
winch of the rig (the rope it has paid out), and optionally ``<point>.x,
<point>.y, <point>.z`` columns (m) that move one of the rig's fixed points
(a trolley on its rail, a boom tip, the drone a load hangs from). Rows are
linearly interpolated (seed paper section 2.3) and held at the last row
after it ends. Which columns a rig needs is checked when the maneuver
meets it (``_model.assemble``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..capture import atomic_file
from ._maneuver_schema import LENGTH_SUFFIX, MAX_ROWS, check_maneuver_columns

__all__ = ["Maneuver", "default_maneuver", "maneuver_from_table", "read_maneuver_csv", "write_maneuver_csv"]


@dataclass(frozen=True)
class Maneuver:
    """A maneuver table.

    Attributes
    ----------
    time : ndarray, shape (K,)
        Strictly increasing (s).
    lengths : dict
        Winch name -> rope paid out (m, positive), shape (K,).
    points : dict
        Point name -> its position (m), shape (K, 3).
    source : str
        The file it was read from ("" when built in code): errors name it.
    start : dict, optional
        The trial's own start, as ``simulate``'s ``release`` (body ->
        ``position``, ``angles``, ``velocity``, ``rates``, ``settled``,
        ``about_rest``): a recording that begins mid-motion
        (``compare.diagnose._start``). It replaces the rig's release; None:
        the rig's own start. Not compared: two maneuvers with the same
        tables are equal whatever their starts.
    """

    time: np.ndarray
    lengths: dict = field(default_factory=dict)
    points: dict = field(default_factory=dict)
    source: str = field(default="", compare=False)
    start: dict | None = field(default=None, compare=False)

    def described(self):
        """How an error names it: ``maneuver file PATH``, or ``the maneuver``."""
        return f"maneuver file {self.source}" if self.source else "the maneuver"

    def __post_init__(self):
        time = np.array(self.time, float).reshape(-1)
        time.setflags(write=False)
        object.__setattr__(self, "time", time)
        n = time.size
        if n == 0:
            raise ValueError("maneuver table is empty")
        if not np.isfinite(time).all():
            raise ValueError("maneuver column 'time' has missing or non-finite values")
        if n > 1 and np.any(np.diff(time) <= 0):
            i = int(np.argmax(np.diff(time) <= 0)) + 1
            raise ValueError(f"maneuver time is not strictly increasing at row {i + 1}")
        lengths = {}
        for winch, values in dict(self.lengths).items():
            arr = np.array(values, float).reshape(-1)
            column = f"{winch}{LENGTH_SUFFIX}"
            if arr.size != n:
                raise ValueError("maneuver columns have different lengths")
            if not np.isfinite(arr).all():
                raise ValueError(f"maneuver column {column!r} has missing or non-finite values")
            if np.any(arr <= 0):
                raise ValueError(f"maneuver {column} must be positive (row {int(np.argmax(arr <= 0)) + 1})")
            arr.setflags(write=False)
            lengths[winch] = arr
        object.__setattr__(self, "lengths", lengths)
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
        """Each winch's interpolated length at times ``t`` (m): winch name -> array shaped like ``t``."""
        t = np.asarray(t, float)
        return {winch: np.interp(t, self.time, values) for winch, values in self.lengths.items()}

    def to_frame(self):
        cols = {"time": self.time}
        cols.update({f"{winch}{LENGTH_SUFFIX}": values for winch, values in self.lengths.items()})
        for name, xyz in self.points.items():
            for k, axis in enumerate("xyz"):
                cols[f"{name}.{axis}"] = xyz[:, k]
        return pd.DataFrame(cols)


def default_maneuver(rig):
    """The rig's own maneuver (its file's ``maneuver``): a CSV it names, or a built-in generator's (the dig).

    A rig that names none drives nothing when it has no winch (time alone),
    and runs the dig, as files written for the dragline did, when it has.
    """
    from ._dig import BUILT_IN_MANEUVERS

    if rig.maneuver is None and not rig.winches:
        return Maneuver([0.0])
    if rig.maneuver is None or rig.maneuver in BUILT_IN_MANEUVERS:
        return BUILT_IN_MANEUVERS[rig.maneuver or "dig"]()
    return read_maneuver_csv(rig.maneuver)


def read_maneuver_csv(path):
    """Read a maneuver CSV (``time``, ``<winch>_length`` columns, optional ``<point>.x/.y/.z``).

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
    if "time" not in frame.columns:
        raise ValueError(f"maneuver file {path} lacks column(s) time")
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
    return maneuver_from_table({c: num[c] for c in frame.columns}, path)


def maneuver_from_table(table, path):
    """A Maneuver from flat columns (``time``, ``<winch>_length``, ``<point>.x/.y/.z``), as a CSV or a session holds them.

    Raises
    ------
    ValueError
        One line naming ``path``, the column and the row.
    """
    point_names = sorted({c.rsplit(".", 1)[0] for c in table if c.endswith((".x", ".y", ".z"))})
    for name in point_names:
        if not all(f"{name}.{a}" in table for a in "xyz"):
            raise ValueError(f"maneuver file {path}: point {name!r} needs .x, .y and .z columns")
    point_columns = {f"{n}.{a}" for n in point_names for a in "xyz"}
    columns = {c: np.asarray(v, float).tolist() for c, v in table.items() if c not in point_columns}
    columns["points"] = {name: np.column_stack([np.asarray(table[f"{name}.{a}"], float) for a in "xyz"]).tolist()
                         for name in point_names}
    return maneuver_from_columns(columns, path)


def maneuver_from_columns(columns, path):
    """A Maneuver from its columns (``time``, ``<winch>_length`` lists, ``points``), checked against the schema.

    Raises
    ------
    ValueError
        One line naming ``path``, the column and the row.
    """
    check_maneuver_columns(columns, path)
    lengths = {c[: -len(LENGTH_SUFFIX)]: columns[c] for c in columns if c.endswith(LENGTH_SUFFIX)}
    points = {name: np.asarray(xyz, float) for name, xyz in columns.get("points", {}).items()}
    try:
        return Maneuver(columns["time"], lengths, points, source=str(path))
    except ValueError as exc:
        raise ValueError(f"maneuver file {path}: {exc}") from None


def write_maneuver_csv(path, maneuver):
    """Write a maneuver table as CSV (atomic: temporary name, then rename)."""

    with atomic_file(path) as tmp:
        maneuver.to_frame().to_csv(tmp, index=False, float_format="%.9g")
