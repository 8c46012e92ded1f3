"""Maneuvers: what the winches pay out, and where moving points go, against time.

A maneuver is a table: ``time`` (s), one ``<winch>_length`` column (m) per
winch of the rig (the rope it has paid out), and optionally ``<point>.x,
<point>.y, <point>.z`` columns (m) that move one of the rig's fixed points
(a trolley on its rail, a boom tip, the drone a load hangs from). Rows are
linearly interpolated (seed paper section 2.3) and held at the last row
after it ends. Which columns a rig needs is checked when the maneuver
meets it (``_simulate.check_reel_table``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..capture import atomic_file
from ._maneuver_schema import LENGTH_SUFFIX, MAX_ROWS, check_maneuver_columns

__all__ = ["Maneuver", "dig_maneuver", "default_maneuver", "maneuver_from_table", "read_maneuver_csv",
           "write_maneuver_csv"]


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
    """

    time: np.ndarray
    lengths: dict = field(default_factory=dict)
    points: dict = field(default_factory=dict)

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
    """The rig's own maneuver (its file's ``maneuver``): a CSV it names, else the built-in dig maneuver."""
    name = getattr(rig, "maneuver", None)
    if name is None or name == "dig":
        return dig_maneuver()
    return read_maneuver_csv(name)


# The text's reading fitted to the paper's published poses and peak table
# (tools/identify_paper_rig.py; docs/model.md, "The dig maneuver").
DIG_PHASE1_S = 2.4312
DIG_PHASE3_DRAG_M_S = 0.4214
DIG_RAMP_S = 0.0119
REEL_SPEED_LIMIT = 1.3  # m/s (seed paper, section 3.1)


def dig_maneuver(phase1_s=DIG_PHASE1_S, phase3_drag_m_s=DIG_PHASE3_DRAG_M_S, ramp_s=DIG_RAMP_S, step_s=0.005):
    """The seed paper's dig maneuver (section 4), read as docs/model.md says.

    What the text fixes: hoist 8.6 -> 10.1 m and drag 4.2 -> 1.4 m; phase 1
    with the hoist paying out at 0.36 m/s and the drag winding in at 0.30
    m/s; phase 2, 1 s, the hoist still and the drag at 0.61 m/s; phase 3,
    2 s; phase 4, 1 s, the hoist still; then both reels stop. Its phase-1
    duration and phase-3 drag speed do not add up with the rest, so they are
    free: the phase-3 hoist speed and the phase-4 drag speed follow from the
    end lengths. The defaults are the reading fitted to the paper's peak
    table; ``phase1_s=2.5, phase3_drag_m_s=0.48, ramp_s=0`` is the literal
    reading (phase 3 hoist 0.30 m/s, phase 4 drag 0.48 m/s, stop at 6.5 s).

    Parameters
    ----------
    phase1_s : float
        Phase 1's duration (s).
    phase3_drag_m_s : float
        The drag's winding speed in phase 3 (m/s).
    ramp_s : float
        Each change of reel speed is spread over this time (s; a motor
        cannot step): the lengths are their moving average over the last
        ``ramp_s``, so the start and end lengths are kept. 0: speed steps.
    step_s : float
        Table spacing (s) where ``ramp_s`` > 0 (with steps, the phase edges
        alone are exact).

    Raises
    ------
    ValueError
        When a derived speed is negative or above the reels' 1.3 m/s.
    """
    hoist3 = (10.1 - 8.6 - 0.36 * phase1_s) / 2.0
    drag4 = 4.2 - 1.4 - 0.30 * phase1_s - 0.61 - 2.0 * phase3_drag_m_s
    for what, speed in (("phase-3 hoist", hoist3), ("phase-3 drag", phase3_drag_m_s), ("phase-4 drag", drag4)):
        if not 0.0 <= speed <= REEL_SPEED_LIMIT:
            raise ValueError(f"this dig reading needs a {what} speed of {speed:.3g} m/s, "
                             f"outside 0-{REEL_SPEED_LIMIT} m/s")
    if not (phase1_s > 0 and ramp_s >= 0 and step_s > 0):
        raise ValueError("the dig's phase-1 duration and table step must be positive and its ramp not negative")
    phases = [(phase1_s, 0.36, -0.30), (1.0, 0.0, -0.61), (2.0, hoist3, -phase3_drag_m_s), (1.0, 0.0, -drag4)]
    edges = np.cumsum([0.0] + [p[0] for p in phases])
    if ramp_s == 0:
        time_s = edges
    else:
        knots = np.append(edges, edges[-1] + ramp_s)  # every phase edge, and the last ramp's end
        grid = np.arange(0.0, knots[-1], step_s)
        time_s = np.union1d(grid[np.min(np.abs(grid[:, None] - knots[None, :]), axis=1) > 1e-6], knots)
    lengths = []
    for column, start in ((1, 8.6), (2, 4.2)):
        at_edges = start + np.concatenate([[0.0], np.cumsum([p[0] * p[column] for p in phases])])
        if ramp_s == 0:
            lengths.append(at_edges)
        else:
            lengths.append((_integral(time_s, edges, at_edges) - _integral(time_s - ramp_s, edges, at_edges)) / ramp_s)
    return Maneuver(time_s, {"hoist": lengths[0], "drag": lengths[1]})


def _integral(t, knots, values):
    """The exact integral up to ``t`` of piecewise-linear ``values``, held outside the knots."""
    pad = 1.0 + max(knots[0] - np.min(t), np.max(t) - knots[-1], 0.0)
    knots = np.concatenate([[knots[0] - pad], knots, [knots[-1] + pad]])
    values = np.concatenate([[values[0]], values, [values[-1]]])
    at_knots = np.concatenate([[0.0], np.cumsum(0.5 * (values[1:] + values[:-1]) * np.diff(knots))])
    i = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2)
    return at_knots[i] + (t - knots[i]) * 0.5 * (values[i] + np.interp(t, knots, values))


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
        return Maneuver(columns["time"], lengths, points)
    except ValueError as exc:
        raise ValueError(f"maneuver file {path}: {exc}") from None


def write_maneuver_csv(path, maneuver):
    """Write a maneuver table as CSV (atomic: temporary name, then rename)."""

    with atomic_file(path) as tmp:
        maneuver.to_frame().to_csv(tmp, index=False, float_format="%.9g")
