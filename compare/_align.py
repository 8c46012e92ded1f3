"""Putting a measured and a simulated trajectory table on one time base.

The simulation's clock starts when the maneuver starts; a capture's clock
starts whenever the cameras did. Both sides carry the hoist and drag rope
lengths, so the offset between the clocks is estimated from them
(:func:`estimate_time_offset`), reported, and removed by shifting the
measured clock (:func:`align_tables`). Time offsets follow one convention
everywhere: ``offset = t_measured - t_simulated`` of the same event, so a
positive offset means the measurement started earlier (its events come
later on its own clock), and measured time ``t`` maps to ``t - offset`` on
the simulation's clock.

Tables are pandas DataFrames with a ``time`` column (s) and the docs/conventions.md
channels; functions never modify their inputs.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..simulate import MAX_TABLE_ROWS as MAX_ROWS
from ..simulate import check_trajectory_columns, trajectory_columns

__all__ = [
    "read_trajectory_table",
    "channel_status",
    "estimate_time_offset",
    "align_tables",
    "reels_stop_time",
    "maneuver_stop_time",
]

# Default largest |offset| searched (s), further capped at a quarter of the
# shorter record so that most of the maneuver always overlaps.
MAX_OFFSET = 3.0
# Reel stop from rope-length rates: the rate is the least-squares slope over
# this window (s); it spans most of a swing period (~1.5 s in the dig
# maneuver), which attenuates the swing's rate below the reeling rate.
RATE_WINDOW = 1.0
# A rope counts as reeling while its smoothed rate exceeds this fraction of
# its largest smoothed rate.
RATE_FRACTION = 0.5


def read_trajectory_table(path, side="trajectory"):
    """Read a trajectory-table CSV (docs/conventions.md) and check its time column.

    Parameters
    ----------
    path : str or path-like
    side : str
        Word used in error messages ("measured", "simulated").

    Returns
    -------
    pandas.DataFrame
        Numeric columns; non-numeric cells become NaN.

    Raises
    ------
    ValueError
        Missing or unreadable file, or a table its schema refuses
        (``simulate._table_schema``, docs/schemas.md): no ``time`` column,
        non-finite or non-increasing times, fewer than 3 rows, a cell that
        is not a number, infinity. One line naming the file, the column and
        the row.
    """
    try:
        # low_memory=False: one type per column for the whole file, so a
        # mixed column (a Nexus export offered as a table) warns of nothing.
        frame = pd.read_csv(path, low_memory=False)
    except FileNotFoundError:
        raise ValueError(f"{side} table {path} does not exist") from None
    except IsADirectoryError:
        raise ValueError(f"{side} table {path} is a directory, not a CSV file") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, OSError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ValueError(f"{side} table {path} cannot be read: {first}") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    what = f"{side} table {path}"
    if "time" not in frame.columns:
        raise ValueError(f"{what} has no 'time' column")
    if len(frame.columns) != len(set(frame.columns)):
        dup = next(c for c in frame.columns if list(frame.columns).count(c) > 1)
        raise ValueError(f"{what}: column {dup!r} appears twice")
    if len(frame) > MAX_ROWS:
        raise ValueError(f"{what} has {len(frame)} rows; at most {MAX_ROWS} are read")
    numeric = {}
    for c in frame.columns:
        values = pd.to_numeric(frame[c], errors="coerce")
        bad = values.isna() & frame[c].notna()
        if bad.any():  # a cell that is not a number is an error, never a silent gap
            row = int(np.argmax(bad.to_numpy()))
            raise ValueError(f"{what}: column {c}, row {row + 2} = {frame[c].iloc[row]!r}: expected a number")
        numeric[c] = values.to_numpy(float)
    check_trajectory_columns({"time": numeric["time"].tolist(),
                              "channels": {c: [None if np.isnan(v) else v for v in numeric[c].tolist()]
                                           for c in frame.columns if c != "time"}}, what)
    return pd.DataFrame(numeric, columns=list(frame.columns))


def check_table(table, what):
    """Raise ValueError unless ``table`` has a usable ``time`` column."""
    if "time" not in table.columns:
        raise ValueError(f"{what} has no 'time' column")
    t = np.asarray(table["time"], dtype=float)
    if t.size < 3:
        raise ValueError(f"{what} has {t.size} rows; need at least 3")
    if not np.all(np.isfinite(t)):
        raise ValueError(f"{what}: time has missing or non-finite values (row {int(np.argmin(np.isfinite(t))) + 1})")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"{what}: time is not strictly increasing (row {int(np.argmax(np.diff(t) <= 0)) + 2})")


def channel_status(measured, simulated, channels=None):
    """Which channels both tables can be compared on, and why the others cannot.

    Parameters
    ----------
    measured, simulated : pandas.DataFrame
    channels : sequence of str, optional
        Channels to consider; default every docs/conventions.md channel.

    Returns
    -------
    usable : list of str
        Channels with finite samples in both tables, in the given order.
    missing : dict
        Channel -> one-line reason, for the others.
    """
    channels = trajectory_columns()[1:] if channels is None else list(channels)
    usable, missing = [], {}
    for ch in channels:
        in_m, in_s = ch in measured.columns, ch in simulated.columns
        if not in_m and not in_s:
            missing[ch] = "in neither table"
        elif not in_m:
            missing[ch] = "not in the measured table"
        elif not in_s:
            missing[ch] = "not in the simulated table"
        elif not np.isfinite(np.asarray(measured[ch], float)).any():
            missing[ch] = "no finite samples in the measured table"
        elif not np.isfinite(np.asarray(simulated[ch], float)).any():
            missing[ch] = "no finite samples in the simulated table"
        else:
            usable.append(ch)
    return usable, missing


def _interp(x, t, y):
    """Linear interpolation of y(t) at x; NaN outside [t0, t1] and next to NaN samples.

    A query that falls exactly on a sample takes that sample alone, so a gap
    does not spread onto its finite neighbours.
    """
    x = np.asarray(x, float)
    j = np.clip(np.searchsorted(t, x, side="right") - 1, 0, t.size - 2)
    w = (x - t[j]) / (t[j + 1] - t[j])
    left, right = y[j], y[j + 1]
    out = np.where(w == 0.0, left, np.where(w == 1.0, right, left + w * (right - left)))
    out = np.where((w > 0.0) & (w < 1.0) & ~(np.isfinite(left) & np.isfinite(right)), np.nan, out)
    out[(x < t[0]) | (x > t[-1])] = np.nan
    return out


def _step(t):
    """Typical sample interval (s), rounded to 1 ns so equal rates give equal steps."""
    return round(float(np.median(np.diff(t))), 9)


def _offset_cost(offset, t_m, ropes_m, t_s, ropes_s):
    """Normalised rope-length mismatch at a trial offset, and per-rope details.

    Each rope's lengths are compared after removing their means over the
    overlap (a constant bias between how the two sides measure a rope length
    does not shift the clocks); the squared difference is divided by the
    two variances so that a shift that leaves only a flat stretch
    overlapping is not rewarded.
    """
    num = den = 0.0
    details = []
    for ym, ys in zip(ropes_m, ropes_s):
        ys_at = _interp(t_m - offset, t_s, ys)
        ok = np.isfinite(ym) & np.isfinite(ys_at)
        if np.count_nonzero(ok) < 3:
            details.append(None)
            continue
        a, b = ym[ok], ys_at[ok]
        d = (a - a.mean()) - (b - b.mean())
        num += float(np.mean(d * d))
        den += float(np.var(a) + np.var(b))
        details.append((float(np.sqrt(np.mean(d * d))), float(a.mean() - b.mean()), int(a.size)))
    cost = num / den if den > 0.0 else math.inf
    return cost, details


def estimate_time_offset(measured, simulated, max_offset=None):
    """Offset between the measured and the simulated clocks, from rope lengths.

    Searches ``offset`` in [-max_offset, max_offset] on a grid of the finer
    sample interval, minimising the normalised mismatch of the mean-removed
    hoist and drag rope lengths (measured at ``t``, simulated at
    ``t - offset``), then refines it by a parabola through the best grid
    point and its neighbours.

    Parameters
    ----------
    measured, simulated : pandas.DataFrame
        Trajectory tables with ``time`` and rope-length channels.
    max_offset : float, optional
        Largest |offset| searched (s); default ``MAX_OFFSET`` capped at a
        quarter of the shorter record.

    Returns
    -------
    dict
        ``offset`` (s, ``t_measured - t_simulated``; 0.0 when it cannot be
        estimated), ``estimated`` (bool), ``reason`` (why not, else None),
        ``channels`` (rope channels used), ``search_range`` (s),
        ``at_search_edge`` (bool: the best offset is at the range's end, so
        the true one may lie outside), ``cost`` and ``cost_at_zero``
        (normalised mismatch, 0 = identical shapes), and per rope
        ``ropes[channel]``: ``residual_rms`` (m, after removing the mean
        difference) and ``bias`` (m, measured minus simulated mean).
    """
    t_m = np.asarray(measured["time"], float)
    t_s = np.asarray(simulated["time"], float)
    duration = min(t_m[-1] - t_m[0], t_s[-1] - t_s[0])
    limit = min(MAX_OFFSET, 0.25 * duration) if max_offset is None else float(max_offset)
    if not limit >= 0.0:
        raise ValueError(f"max_offset must be non-negative, got {max_offset}")
    ropes = [c for c in simulated.columns if c.endswith(".length") and not c.endswith(".reel_length")]
    usable, _ = channel_status(measured, simulated, ropes)
    result = {
        "offset": 0.0,
        "estimated": False,
        "reason": None,
        "channels": usable,
        "search_range": [-float(limit), float(limit)],
        "at_search_edge": False,
        "cost": None,
        "cost_at_zero": None,
        "ropes": {},
    }
    if not usable:
        result["reason"] = "no rope-length channel with finite samples in both tables"
        return result
    ropes_m = [np.asarray(measured[c], float) for c in usable]
    ropes_s = [np.asarray(simulated[c], float) for c in usable]
    step = min(_step(t_m), _step(t_s))
    k = int(math.floor(limit / step + 1e-9))
    grid = np.arange(-k, k + 1) * step
    costs = np.array([_offset_cost(o, t_m, ropes_m, t_s, ropes_s)[0] for o in grid])
    if not np.isfinite(costs).any():
        result["reason"] = "the rope lengths do not overlap in time, or do not change, at any offset searched"
        return result
    i = int(np.nanargmin(np.where(np.isfinite(costs), costs, np.nan)))
    best = float(grid[i])
    if 0 < i < grid.size - 1 and np.all(np.isfinite(costs[i - 1 : i + 2])):
        c0, c1, c2 = costs[i - 1 : i + 2]
        curvature = c0 - 2.0 * c1 + c2
        if curvature > 0.0:
            best += step * float(np.clip(0.5 * (c0 - c2) / curvature, -0.5, 0.5))
    cost, details = _offset_cost(best, t_m, ropes_m, t_s, ropes_s)
    zero_cost, _ = _offset_cost(0.0, t_m, ropes_m, t_s, ropes_s)
    result.update(
        offset=best,
        estimated=True,
        at_search_edge=bool(k > 0 and i in (0, grid.size - 1)),
        cost=cost,
        cost_at_zero=zero_cost if math.isfinite(zero_cost) else None,
    )
    for ch, det in zip(usable, details):
        if det is not None:
            result["ropes"][ch] = {"residual_rms": det[0], "bias": det[1], "n_samples": det[2]}
    return result


def align_tables(measured, simulated, time_offset=0.0, channels=None):
    """Resample both tables onto one uniform time base on the simulation's clock.

    The measured clock is shifted by ``-time_offset``; the common base runs
    over the overlap of the two records with the coarser of the two sample
    intervals, starting at the later start. Values are linearly
    interpolated; a sample next to a NaN is NaN (no gap is filled).

    Parameters
    ----------
    measured, simulated : pandas.DataFrame
    time_offset : float
        ``t_measured - t_simulated`` (s), see the module docstring.
    channels : sequence of str, optional
        Columns to resample (default: every column other than ``time`` that
        is in both tables).

    Returns
    -------
    time : ndarray, shape (n,)
        Common time base (s, simulation clock).
    measured_aligned, simulated_aligned : pandas.DataFrame
        ``time`` plus the channels, on the common base.

    Raises
    ------
    ValueError
        The records do not overlap by at least three common samples.
    """
    t_m = np.asarray(measured["time"], float) - float(time_offset)
    t_s = np.asarray(simulated["time"], float)
    if channels is None:
        channels = [c for c in simulated.columns if c != "time" and c in measured.columns]
    step = max(_step(t_m), _step(t_s))
    start, end = max(t_m[0], t_s[0]), min(t_m[-1], t_s[-1])
    n = int(math.floor((end - start) / step + 1e-6)) + 1 if end > start else 0
    if n < 3:
        raise ValueError(
            f"measured ({t_m[0]:.3f} to {t_m[-1]:.3f} s after removing a {time_offset:+.3f} s offset) "
            f"and simulated ({t_s[0]:.3f} to {t_s[-1]:.3f} s) tables do not overlap in time"
        )
    time = start + np.arange(n) * step
    out = []
    for table, t in ((measured, t_m), (simulated, t_s)):
        cols = {"time": time}
        for ch in channels:
            cols[ch] = _interp(time, t, np.asarray(table[ch], float)) if ch in table.columns else np.full(n, np.nan)
        out.append(pd.DataFrame(cols))
    return time, out[0], out[1]


def _reel_columns_stop(table):
    """Last time any ``<rope>.reel_length`` column (a winch's length) changes, or None."""
    cols = [c for c in table.columns if c.endswith(".reel_length")]
    if not cols:
        return None
    columns = [np.asarray(table[c], float) for c in cols]
    if not all(np.isfinite(y).all() for y in columns):
        return None
    return _last_change(np.asarray(table["time"], float), columns)


def _last_change(t, columns):
    """The last time (s) any of ``columns`` (arrays over ``t``) changes beyond rounding; ``t[0]`` if none does."""
    last = float(t[0])
    for y in columns:
        scale = max(1.0, float(np.max(np.abs(y))))
        moving = np.flatnonzero(np.abs(np.diff(y)) > 1e-9 * scale)
        if moving.size:
            last = max(last, float(t[moving[-1] + 1]))
    return last


def _rate_stop(table):
    """Reel stop from the rope lengths' smoothed rates, or None."""
    t = np.asarray(table["time"], float)
    step = _step(t)
    half = max(1, int(round(0.5 * RATE_WINDOW / step)))
    stops = []
    for c in table.columns:
        if not c.endswith(".length") or c.endswith(".reel_length"):
            continue
        y = np.asarray(table[c], float)
        ok = np.isfinite(y)
        if np.count_nonzero(ok) < 2 * half + 2:
            continue
        grid = np.arange(t[ok][0], t[ok][-1] + 0.5 * step, step)
        yg = np.interp(grid, t[ok], y[ok])
        # Least-squares slope over a centred window of 2 * half + 1 samples.
        k = np.arange(-half, half + 1) * step
        kernel = k[::-1] / np.sum(k * k)
        rate = np.convolve(yg, kernel, mode="valid")
        centre = grid[half : grid.size - half]
        speed = np.abs(rate)
        peak = float(np.max(speed))
        if peak == 0.0:
            continue
        last = int(np.flatnonzero(speed > RATE_FRACTION * peak)[-1])
        # The smoothed rate falls as a ramp over one window after the stop,
        # so the stop is where it crosses half the reeling rate that held a
        # window earlier (the last phase need not be the fastest one).
        before = max(0, last - 2 * half)
        level = float(speed[before])
        window = speed[before : last + 2 * half + 1]
        above = np.flatnonzero(window > RATE_FRACTION * level)
        if level == 0.0 or above.size == 0:
            stops.append(float(centre[last]))
            continue
        i = before + int(above[-1])
        if i + 1 < speed.size:
            # Linear interpolation of the crossing between samples i and i + 1.
            a, b = speed[i] - RATE_FRACTION * level, speed[i + 1] - RATE_FRACTION * level
            stops.append(float(centre[i] + step * a / (a - b)) if a != b else float(centre[i]))
        else:
            stops.append(float(centre[i]))
    return max(stops) if stops else None


def maneuver_stop_time(maneuver):
    """The last time (s) any winch's length or moving point of a maneuver changes; its start if none does."""
    columns = list(maneuver.lengths.values()) + [xyz[:, k] for xyz in maneuver.points.values() for k in range(3)]
    return _last_change(np.asarray(maneuver.time, float), columns)


def reels_stop_time(measured, simulated, time_offset=0.0):
    """When every winch stops, on the simulation's clock.

    Tried in this order: the ``<rope>.reel_length`` columns of the
    simulated table (the winch lengths the model was driven by), the same
    columns in the measured table,
    then the rope lengths' rates - measured first, as the measurement sees
    the real reels - where a rope counts as reeling while the least-squares
    slope of its length over ``RATE_WINDOW`` exceeds ``RATE_FRACTION`` of
    its largest value (accurate to about 0.1 s; the rope's swing after the
    stop is what limits it).

    Parameters
    ----------
    measured, simulated : pandas.DataFrame
    time_offset : float
        ``t_measured - t_simulated`` (s).

    Returns
    -------
    time : float or None
        Stop time (s, simulation clock); None when no method applies.
    method : str
        Which source gave it.
    """
    stop = _reel_columns_stop(simulated)
    if stop is not None:
        return stop, "reel_length columns of the simulated table"
    stop = _reel_columns_stop(measured)
    if stop is not None:
        return stop - time_offset, "reel_length columns of the measured table"
    stop = _rate_stop(measured)
    if stop is not None:
        return stop - time_offset, "rope-length rates of the measured table"
    stop = _rate_stop(simulated)
    if stop is not None:
        return stop, "rope-length rates of the simulated table"
    return None, "no reel_length or rope-length channel"
