"""TRC marker files (OpenSim, Pose2Sim, Mokka, Cortex) in and out.

The layout (tab-separated)::

    PathFileType  4  (X/Y/Z)  name.trc
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    60        60          12         21          m      60            0                   12
    Frame#  Time  RHip        RKnee ...
                  X1  Y1  Z1  X2  Y2  Z2 ...
    1       0.016 ...

then one row per frame; a blank line after the header is allowed. A marker
not seen in a frame is empty cells (or NaN); a row may stop early, which
leaves the markers after its end unseen. Frame numbers skipped are frames
with every marker unseen, as in the VICON reader, so the clock stays true.
"""

from __future__ import annotations

import math
import os

import numpy as np

from ._atomic import atomic_file
from ._marker_file import MAX_FRAMES, MarkerFile, frame_span, metres_per_unit

__all__ = ["read_trc", "write_trc", "is_trc"]

_HEADER_KEYS = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units")


def is_trc(path):
    """True when ``path`` starts with a TRC header line."""
    try:
        with open(path, "rb") as fh:
            return fh.read(12) == b"PathFileType"
    except OSError:
        return False


def _cells(line):
    return line.rstrip("\r\n").split("\t")


def _fail(path, lineno, message):
    raise ValueError(f"{path}: line {lineno}: {message}")


def _number(path, lineno, cell, what):
    try:
        value = float(cell)
    except ValueError:
        _fail(path, lineno, f"{what} '{cell[:20]}' is not a number")
    if math.isinf(value):
        _fail(path, lineno, f"{what} is infinite")
    return value


def read_trc(path):
    """Read a TRC file.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    MarkerFile
        Positions in metres (from the Units field), NaN where not seen.

    Raises
    ------
    ValueError
        One line naming the path and line: not a TRC file, a header field
        missing or out of range, a marker name missing or repeated, a cell
        that is not a number, frame numbers not increasing, a row longer
        than the header says.
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8-sig", errors="strict") as fh:
            lines = fh.read().splitlines()
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a TRC file (not UTF-8 text)") from None
    if not lines or not lines[0].startswith("PathFileType"):
        raise ValueError(f"{path}: not a TRC file (no PathFileType line)")
    if len(lines) < 5:
        raise ValueError(f"{path}: the TRC header is cut short ({len(lines)} lines, 5 needed)")
    keys, values = _cells(lines[1]), _cells(lines[2])
    fields = dict(zip((k.strip() for k in keys), (v.strip() for v in values)))
    missing = [k for k in _HEADER_KEYS if k not in fields]
    if missing:
        _fail(path, 2, f"header field {missing[0]} missing")
    rate = _number(path, 3, fields["DataRate"], "DataRate")
    if not rate > 0 or math.isnan(rate):
        _fail(path, 3, f"DataRate {fields['DataRate']} must be positive")
    n_markers = _number(path, 3, fields["NumMarkers"], "NumMarkers")
    if not (n_markers == int(n_markers) and 1 <= n_markers <= 100_000):
        _fail(path, 3, f"NumMarkers {fields['NumMarkers']} must be a whole number from 1")
    n_markers = int(n_markers)
    units = fields["Units"]
    scale = metres_per_unit(units, f"{path}: line 3: Units")
    name_cells = _cells(lines[3])
    if len(name_cells) < 2 or name_cells[0].strip() != "Frame#":
        _fail(path, 4, "the names line must start with Frame# and Time")
    names = [c.strip() for c in name_cells[2:] if c.strip()]
    if len(names) != n_markers:
        _fail(path, 4, f"{len(names)} marker names for NumMarkers {n_markers}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        _fail(path, 4, f"marker '{dup[0]}' appears twice")
    width = 2 + 3 * n_markers
    frames, rows, row_lines = [], [], []
    for lineno, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        cells = _cells(line)
        while cells and not cells[-1].strip():  # trailing tabs: unseen markers at the row's end
            cells.pop()
        if len(cells) > width:
            _fail(path, lineno, f"{len(cells)} cells, more than Frame#, Time and {n_markers} markers x 3")
        frame = _number(path, lineno, cells[0], "frame number")
        if len(cells) > 1 and cells[1].strip() and not math.isfinite(_number(path, lineno, cells[1], "time")):
            _fail(path, lineno, f"time '{cells[1]}' is not a finite number")
        if not (math.isfinite(frame) and frame == int(frame) and 0 <= frame <= MAX_FRAMES):
            _fail(path, lineno, f"frame number '{cells[0]}' is not a whole number from 0 to {MAX_FRAMES:.0e}")
        if frames and frame <= frames[-1]:
            _fail(path, lineno, f"frame number {int(frame)} does not follow {frames[-1]}")
        row = np.full(3 * n_markers, np.nan)
        for k, cell in enumerate(cells[2:]):
            if cell.strip():
                row[k] = _number(path, lineno, cell, "coordinate")
        frames.append(int(frame))
        rows.append(row)
        row_lines.append(lineno)
    if not rows:
        raise ValueError(f"{path}: the TRC file has no frames")
    frames = np.array(frames)
    n = frame_span(path, frames, row_lines)
    positions = np.full((n, n_markers, 3), np.nan)
    positions[frames - frames[0]] = np.array(rows).reshape(-1, n_markers, 3) * scale
    positions[np.isnan(positions).any(axis=-1)] = np.nan
    info = {k: fields[k] for k in ("CameraRate", "NumFrames", "OrigDataRate", "OrigDataStartFrame",
                                    "OrigNumFrames") if k in fields}
    return MarkerFile(path=path, format="trc", names=names, positions=positions, rate_hz=rate,
                      first_frame=int(frames[0]), units=units, info=info)


def write_trc(path, marker_names, positions, rate_hz, first_frame=1, units="mm"):
    """Write labelled 3D markers as a TRC file.

    Parameters
    ----------
    path : str or path-like
        Written under a temporary name and renamed when complete.
    marker_names : sequence of str
    positions : ndarray, shape (frames, markers, 3)
        Positions (m); NaN is written as empty cells.
    rate_hz : float
    first_frame : int
    units : {"mm", "m"}
    """
    path = os.fspath(path)
    p = np.asarray(positions, dtype=float)
    names = [str(n) for n in marker_names]
    if p.ndim != 3 or p.shape[1:] != (len(names), 3):
        raise ValueError(f"positions must have shape (frames, {len(names)}, 3), got {p.shape}")
    p = p / metres_per_unit(units, "write_trc")
    n = p.shape[0]
    rate = repr(float(rate_hz)) if not float(rate_hz).is_integer() else str(int(rate_hz))
    out = [f"PathFileType\t4\t(X/Y/Z)\t{os.path.basename(path)}",
           "\t".join(("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
                      "OrigDataStartFrame", "OrigNumFrames")),
           "\t".join((rate, rate, str(n), str(len(names)), units, rate, str(first_frame), str(n))),
           "\t".join(["Frame#", "Time"] + [f"{m}\t\t" for m in names]).rstrip("\t"),
           "\t".join(["", ""] + [f"X{k}\tY{k}\tZ{k}" for k in range(1, len(names) + 1)]),
           ""]
    for i in range(n):
        cells = [str(first_frame + i), repr(i / float(rate_hz))]
        cells += ["" if not math.isfinite(v) else repr(float(v)) for v in p[i].ravel()]
        out.append("\t".join(cells))
    with atomic_file(path) as tmp, open(tmp, "w", encoding="utf-8", newline="\n") as fh:
        fh.write("\n".join(out) + "\n")
    return path
