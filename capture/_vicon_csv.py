"""VICON-style CSV exports: read any section, write 3D marker trajectories.

Layout of one section, as VICON Nexus writes it::

    Trajectories                                  section name
    100                                           rate (Hz); older: ``100,Hz``
    ,,bucket:alpha,,,bucket:beta,,                one name per group of columns
    Frame,Sub Frame,X,Y,Z,X,Y,Z                   header
    ,,mm,mm,mm,mm,mm,mm                           units (optional)
    1,0,209.331,1219.74,1780.67,,,                data; empty cell = not seen

Sections (``Devices``, ``Trajectories``, ``Model Outputs``, ...) follow one
another, separated by a blank (all-delimiter) line. Variants accepted:
leading blank lines or a metadata preamble (``Title``, ``Date:`` ...) before
the first section, upper-case names, a ``Field #`` header with no
``Sub Frame`` column and no units line (VICON Workstation), names without a
subject prefix or unlabeled ``*111``, ``;`` as delimiter (VICON Tracker;
a decimal comma is then accepted too), CRLF line endings, a UTF-8 BOM and
trailing empty columns.

Column naming: every data column belongs to the name most recently given on
the names line (its *group*, e.g. ``bucket:alpha`` or ``Imported AMTI ...
- Force``) and carries the header cell (its *component*, e.g. ``X``); the
column is called ``group.component`` (``bucket:alpha.X``), or just the
component when no name precedes it. Values are kept in the file's units
inside :class:`ViconSection`; :func:`marker_trajectories` converts positions
to metres.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ._atomic import atomic_file

__all__ = [
    "ViconSection",
    "ViconExport",
    "read_vicon_csv",
    "marker_trajectories",
    "write_vicon_csv",
    "summarize_vicon_csv",
]

# Names a user would only ever mean as a section: a missing rate line after
# one of these is an error, not a preamble line to skip.
_KNOWN_SECTIONS = {"trajectories", "devices", "model outputs", "joints", "segments"}
_HEADER_FIRST = {"frame", "field #", "field#", "field"}
_SUB_FRAME = {"sub frame", "subframe", "sub-frame"}
_METRES_PER_UNIT = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
# The largest frame or sub-frame number taken: a day at 10 kHz is 8.6e8.
MAX_FRAME = 10**9


@dataclass(eq=False)
class ViconSection:
    """One section of a VICON CSV export.

    Attributes
    ----------
    name : str
        Section name as written in the file, e.g. ``'Trajectories'``.
    rate_hz : float
        Sample rate of this section (Hz); a Devices section usually runs at a
        multiple of the frame rate, the multiple being its sub-frames.
    frame : ndarray of int, shape (N,)
    sub_frame : ndarray of int, shape (N,)
        Zeros when the file has no ``Sub Frame`` column.
    columns : list of str
        ``group.component`` per data column (see the module docstring).
    units : list of str or None
        Unit per data column as written (``'mm'``, ``'N'``, ``'deg'``; ``''``
        where the cell is empty), or None when the section has no units line.
    data : ndarray of float, shape (N, C)
        Values in the file's units; NaN for empty cells.
    groups : list of str
        Names-line label owning each column (``''`` when none).
    components : list of str
        Header cell of each column (``'X'``, ``'Fz'``, ...).
    """

    name: str
    rate_hz: float
    frame: np.ndarray
    sub_frame: np.ndarray
    columns: list
    units: list | None
    data: np.ndarray
    groups: list = field(default_factory=list)
    components: list = field(default_factory=list)


@dataclass(eq=False)
class ViconExport:
    """A parsed VICON CSV file.

    Attributes
    ----------
    sections : dict of str to ViconSection
        Keyed by the lower-cased section name (``'trajectories'``,
        ``'devices'``, ``'model outputs'``), in file order.
    path : str
    notes : list of str
        What the reader skipped and why: a section other than Trajectories
        it could not parse, columns of the Trajectories section that are not
        marker positions (derivatives, counts, magnitudes).
    events : list of dict
        The Events section's rows: ``subject``, ``context``, ``name``,
        ``time_s``, ``description``, in file order.
    """

    sections: dict
    path: str
    notes: list = field(default_factory=list)
    events: list = field(default_factory=list)

    @property
    def trajectories(self):
        """The Trajectories section, or None when the file has none."""
        return self.sections.get("trajectories")


class _Lines:
    """The file's lines split into cells, with 1-based line numbers for errors."""

    def __init__(self, path, text, delimiter):
        self.path = path
        self.delimiter = delimiter
        self.rows = [[c.strip().strip('"').strip() for c in line.split(delimiter)]
                     for line in text.split("\n")]

    def fail(self, index, problem):
        raise ValueError(f"{self.path}: line {index + 1}: {problem}")

    def blank(self, i):
        return not any(self.rows[i])

    def number(self, cell):
        if self.delimiter == ";":
            cell = cell.replace(",", ".")
        value = float(cell)
        if not math.isfinite(value):  # a gap is an empty cell; inf or nan written out is not a position
            raise ValueError(f"not finite: {cell}")
        return value

    def rate(self, i):
        """Rate (Hz) if line i is a rate line (``100``, ``100,Hz``), else None."""
        if i >= len(self.rows):
            return None
        cells = [c for c in self.rows[i] if c]
        if not cells or not self.rows[i][0] or len(cells) > 2:
            return None
        if len(cells) == 2 and cells[1].lower() != "hz":
            return None
        head = cells[0]
        if head.lower().endswith("hz"):
            head = head[:-2].strip()
        try:
            return self.number(head)
        except ValueError:
            return None

    def section_start(self, i):
        """True if line i is a section name line followed by a rate line."""
        cells = self.rows[i]
        if not cells[0] or any(cells[1:]):
            return False
        try:
            self.number(cells[0])
            return False
        except ValueError:
            pass
        return self.rate(i + 1) is not None


def _decode(path):
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if b"\x00" in raw:
        raise ValueError(f"{path}: line 1: binary data, not a VICON CSV text export")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        # Nexus on Windows writes subject names in the ANSI code page.
        text = raw.decode("cp1252", errors="replace")
    return text.replace("\r\n", "\n").replace("\r", "\n")


def _sniff_delimiter(text):
    head = [line for line in text[:1 << 16].split("\n") if line.strip()][:12]
    semis = sum(line.count(";") for line in head)
    commas = sum(line.count(",") for line in head)
    return ";" if semis > commas else ","


def read_vicon_csv(path):
    """Read every section of a VICON-style CSV export.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    ViconExport

    Raises
    ------
    ValueError
        One line naming the file and line: not a VICON CSV, no section,
        a row with a different number of cells than the header, a
        non-numeric data cell, a duplicated section.
    """
    path = os.fspath(path)
    text = _decode(path)
    lines = _Lines(path, text, _sniff_delimiter(text))
    n = len(lines.rows)
    first = next((i for i in range(n) if not lines.blank(i)), None)
    if first is None:
        raise ValueError(f"{path}: line 1: empty file, not a VICON CSV export")

    # Anything before the first section is a preamble (Workstation writes
    # Title/Date/Notes lines there); a known section name without a rate
    # line is a broken file, not a preamble.
    i = first
    while i < n and not lines.section_start(i) and not _events_start(lines, i):
        if lines.rows[i][0].lower() in _KNOWN_SECTIONS and not any(lines.rows[i][1:]):
            lines.fail(i + 1, f"section '{lines.rows[i][0]}' is not followed by a rate line "
                              "(e.g. '100' or '100,Hz')")
        i += 1
    if i >= n:
        lines.fail(first, "no VICON section found (expected a name line such as "
                          "'Trajectories' followed by a rate line)")

    sections, notes, events = {}, [], []
    while i < n:
        if lines.blank(i):
            i += 1
            continue
        if _events_start(lines, i):
            i = _read_events(lines, i, events, notes)
            continue
        if not lines.section_start(i):
            if not sections:  # before any section: not a VICON export
                lines.fail(i, "expected a section name line (e.g. 'Trajectories') "
                              f"followed by a rate line, found '{lines.delimiter.join(lines.rows[i])[:60]}'")
            # After a section, a block of another shape: not ours to read, and not a reason to refuse.
            end = _block_end(lines, i)
            notes.append(f"skipped lines {i + 1}-{end}: not a section this reader knows "
                         f"('{lines.delimiter.join(lines.rows[i])[:40]}')")
            i = end
            continue
        start = i
        name = lines.rows[i][0]
        if name.lower() in sections:
            lines.fail(start, f"section '{name}' appears twice")
        try:
            section, i = _read_section(lines, i)
        except ValueError as exc:
            if name.lower() == "trajectories":
                raise
            # Nexus writes Joints, Segments and Model Outputs sections the
            # trajectories do not need; one the reader cannot parse is skipped.
            i = _block_end(lines, start + 2)
            notes.append(f"skipped section '{name}' (lines {start + 1}-{i}): {str(exc).split(': ', 1)[-1]}")
            continue
        sections[name.lower()] = section
    export = ViconExport(sections=sections, path=path, notes=notes, events=events)
    if export.trajectories is not None:
        try:
            notes.extend(_marker_layout(export.trajectories, path)[2])
        except ValueError:
            pass  # said by marker_trajectories, when markers are asked for
    return export


def _block_end(lines, i):
    """Index of the first blank line or section start after line i (or the end)."""
    n = len(lines.rows)
    k = i + 1
    while k < n and not lines.blank(k) and not lines.section_start(k) and not _events_start(lines, k):
        k += 1
    return k


def _events_start(lines, i):
    """True if line i names an Events section (its rate line optional)."""
    cells = lines.rows[i]
    if cells[0].lower() != "events" or any(cells[1:]):
        return False
    k = i + 1 if lines.rate(i + 1) is None else i + 2
    return k < len(lines.rows) and [c.lower() for c in lines.rows[k][:1]] == ["subject"]


def _read_events(lines, i, events, notes):
    """Rows of an Events section (Subject, Context, Name, Time (s), Description) into ``events``."""
    k = i + 1 if lines.rate(i + 1) is None else i + 2
    header = [c.lower() for c in lines.rows[k]]
    col = {key: next((j for j, c in enumerate(header) if c.startswith(key)), None)
           for key in ("subject", "context", "name", "time", "description")}
    k += 1
    while k < len(lines.rows) and not lines.blank(k) and not lines.section_start(k):
        cells = lines.rows[k] + [""] * len(header)
        try:
            time_s = lines.number(cells[col["time"]]) if col["time"] is not None else math.nan
        except ValueError:
            notes.append(f"skipped event on line {k + 1}: time '{cells[col['time']]}' is not a number")
            k += 1
            continue
        events.append({("time_s" if key == "time" else key): (time_s if key == "time" else cells[j] if j is not None else "")
                       for key, j in col.items()})
        k += 1
    return k


def _read_section(lines, i):
    """Parse the section starting at line i; return it and the next line index."""
    rows, n = lines.rows, len(lines.rows)
    name = rows[i][0]
    rate = lines.rate(i + 1)
    if not (math.isfinite(rate) and rate > 0):
        lines.fail(i + 1, f"section '{name}' has rate {rate}, expected a positive number")
    i += 2

    def is_header(k):
        return k < n and rows[k][0].lower() in _HEADER_FIRST

    names = []
    if not is_header(i):
        # The names line; an all-empty one reads as blank, so look past it.
        if i < n and not rows[i][0] and is_header(i + 1):
            names = rows[i]
            i += 1
        else:
            lines.fail(i, f"section '{name}': expected the names line and a "
                          "'Frame,Sub Frame,...' or 'Field #,...' header")
    header = rows[i]
    n_index = 2 if len(header) > 1 and header[1].lower() in _SUB_FRAME else 1
    width = len(header)
    while width > n_index and not header[width - 1]:
        width -= 1
    components = header[n_index:width]
    if not components:
        lines.fail(i, f"section '{name}': header has no data columns")
    if "" in components:
        lines.fail(i, f"section '{name}': empty header cell in column "
                      f"{n_index + components.index('') + 1}")
    if any(names[:n_index]) or any(names[width:]):
        lines.fail(i - 1, f"section '{name}': names line does not line up with the header")
    groups, current = [], ""
    for c in range(n_index, width):
        if c < len(names) and names[c]:
            current = names[c]
        groups.append(current)
    columns = [f"{g}.{c}" if g else c for g, c in zip(groups, components)]
    i += 1

    units = None
    if i < n and not lines.blank(i) and not rows[i][0]:
        cells = rows[i]
        if any(cells[:n_index]) or any(cells[width:]):
            lines.fail(i, f"section '{name}': units line does not line up with the header")
        units = (cells[n_index:width] + [""] * width)[: width - n_index]
        i += 1

    frames, subs, values = [], [], []
    while i < n and not lines.blank(i) and not lines.section_start(i):
        cells = rows[i]
        if len(cells) < width or any(cells[width:]):
            found = len(cells) if len(cells) < width else max(
                k + 1 for k, c in enumerate(cells) if c)
            lines.fail(i, f"section '{name}': row has {found} cells, header has {width}")
        frames.append(_index_cell(lines, i, cells[0], "frame"))
        subs.append(_index_cell(lines, i, cells[1], "sub frame") if n_index == 2 else 0)
        try:
            values.append([lines.number(c) if c else math.nan for c in cells[n_index:width]])
        except ValueError:
            bad = next(k for k, c in enumerate(cells[n_index:width], n_index)
                       if c and not _is_number(lines, c))
            lines.fail(i, f"section '{name}': value '{cells[bad]}' in column {bad + 1} "
                          f"({columns[bad - n_index]}) is not a finite number (a gap is an empty cell)")
        i += 1
    section = ViconSection(
        name=name,
        rate_hz=float(rate),
        frame=np.array(frames, dtype=np.int64),
        sub_frame=np.array(subs, dtype=np.int64),
        columns=columns,
        units=units,
        data=np.array(values, dtype=float).reshape(len(values), len(columns)),
        groups=groups,
        components=components,
    )
    return section, i


def _is_number(lines, cell):
    try:
        lines.number(cell)
        return True
    except ValueError:
        return False


def _index_cell(lines, i, cell, what):
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value == int(value)):
        lines.fail(i, f"{what} '{cell}' is not an integer")
    if not 0 <= value <= MAX_FRAME:  # a day at 10 kHz; beyond, an int64 index overflows
        lines.fail(i, f"{what} '{cell}' is outside 0 to {MAX_FRAME:.0e}")
    return int(value)


def _split_marker(name):
    """``'bucket:alpha'`` -> ``('bucket', 'alpha')``; no prefix -> ``(None, name)``."""
    subject, sep, marker = name.rpartition(":")
    return (subject, marker) if sep and subject else (None, name)


def _marker_layout(section, where):
    """Marker groups of a Trajectories section, their X, Y, Z columns, and notes on what is not a position.

    A group without X, Y and Z columns (``Trajectory Count``, a magnitude)
    is not a marker; derivative columns (``X'``, ``Y''``: velocity and
    acceleration) and any other component beside a marker's X, Y, Z are
    left out, with a note. A marker whose positions appear twice is an error.
    """
    order, found, extra = [], {}, {}
    for c, (g, comp) in enumerate(zip(section.groups, section.components)):
        if not g:
            raise ValueError(f"{where}: Trajectories data column {c + 1} ({comp}) "
                             "has no marker name on the names line")
        key = comp.upper().replace(" ", "")
        if key in ("X", "Y", "Z"):
            if g in found and key in found[g]:
                raise ValueError(f"{where}: marker '{g}' appears twice on the names line")
            if g not in found:
                order.append(g)
                found[g] = {}
            found[g][key] = c
        else:
            extra.setdefault(g, []).append(comp)
    notes = []
    markers = []
    for g in order:
        missing = [a for a in "XYZ" if a not in found[g]]
        if missing:
            raise ValueError(f"{where}: marker '{g}' has no {'/'.join(missing)} column")
        markers.append(g)
    not_markers = [g for g in extra if g not in found]
    derivative = sorted({comp for g in extra if g in found for comp in extra[g] if comp.endswith("'")})
    other = sorted({comp for g in extra if g in found for comp in extra[g] if not comp.endswith("'")})
    if not_markers:
        notes.append("Trajectories: columns that are not markers left out: " + ", ".join(not_markers))
    if derivative:
        notes.append("Trajectories: derivative columns left out (velocity, acceleration): " + ", ".join(derivative))
    if other:
        notes.append("Trajectories: other marker columns left out: " + ", ".join(other))
    idx = np.array([[found[g][a] for a in "XYZ"] for g in markers], dtype=int).reshape(len(markers), 3)
    return markers, idx, notes


def marker_trajectories(export, subject=None):
    """3D marker positions of the Trajectories section, in metres.

    Parameters
    ----------
    export : ViconExport
    subject : str, optional
        Keep only the markers named ``subject:...``.

    Returns
    -------
    names : list of str
        Marker names as in the file (``'bucket:alpha'``, ``'LFHD'``, ``'*111'``).
    positions : ndarray, shape (frames, markers, 3)
        Positions (m), converted from the units line (mm, cm or m; mm when
        the file has no units line). NaN where the marker was not seen; a
        point missing any coordinate is NaN in all three.

    Raises
    ------
    ValueError
        No Trajectories section, a marker without X/Y/Z columns, an unknown
        length unit, or no marker of `subject`.
    """
    section = export.trajectories
    if section is None:
        raise ValueError(f"{export.path}: no Trajectories section "
                         f"(sections: {', '.join(s.name for s in export.sections.values())})")
    names, idx, _ = _marker_layout(section, export.path)
    if subject is not None:
        keep = [k for k, m in enumerate(names) if _split_marker(m)[0] == subject]
        if not keep:
            subjects = sorted({_split_marker(m)[0] or "(none)" for m in names})
            raise ValueError(f"{export.path}: no markers of subject '{subject}' "
                             f"(subjects: {', '.join(subjects)})")
        names, idx = [names[k] for k in keep], idx[keep]
    scale = np.empty(idx.shape)
    for k, cols in enumerate(idx):
        for a, c in enumerate(cols):
            unit = (section.units[c] if section.units is not None else "") or "mm"
            if unit.lower() not in _METRES_PER_UNIT:
                raise ValueError(f"{export.path}: marker '{names[k]}' has unit '{unit}', "
                                 f"expected one of {', '.join(_METRES_PER_UNIT)}")
            scale[k, a] = _METRES_PER_UNIT[unit.lower()]
    positions = section.data[:, idx] * scale
    positions[np.isnan(positions).any(axis=-1)] = np.nan
    return list(names), positions


def _format_rate(rate_hz):
    return str(int(rate_hz)) if float(rate_hz).is_integer() else repr(float(rate_hz))


def write_vicon_csv(path, marker_names, positions, rate_hz, first_frame=1, decimals=5):
    """Write 3D marker positions as a VICON Nexus Trajectories CSV.

    The file holds one ``Trajectories`` section: rate line, names line, the
    ``Frame,Sub Frame,X,Y,Z,...`` header, a ``mm`` units line, then one row
    per frame (Sub Frame 0) in millimetres with `decimals` decimals and an
    empty cell wherever the position is NaN. Lines end with ``\\n``. The file
    is written under a temporary name and renamed when complete.

    Parameters
    ----------
    path : str or path-like
    marker_names : sequence of str
        One per marker, e.g. ``'bucket:alpha'``.
    positions : array_like, shape (frames, markers, 3)
        Positions (m); NaN where not seen.
    rate_hz : float
        Frame rate (Hz).
    first_frame : int
        Number of the first frame.
    decimals : int
        Decimals written (mm).
    """
    path = os.fspath(path)
    positions = np.asarray(positions, dtype=float)
    names = [str(m) for m in marker_names]
    if positions.ndim != 3 or positions.shape[2] != 3:
        raise ValueError(f"positions must have shape (frames, markers, 3), got {positions.shape}")
    if len(names) != positions.shape[1]:
        raise ValueError(f"{len(names)} marker names for {positions.shape[1]} markers")
    for m in names:
        if not m or any(ch in m for ch in ",;\"\r\n") or m != m.strip():
            raise ValueError(f"marker name {m!r} is empty or contains a delimiter, quote, "
                             "newline or surrounding spaces")
    if len(set(names)) != len(names):
        raise ValueError("marker names are not unique")
    if np.isinf(positions).any():
        raise ValueError("positions contain infinite values")
    rate_hz = float(rate_hz)
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be a positive number, got {rate_hz}")
    if int(decimals) != decimals or decimals < 0:
        raise ValueError(f"decimals must be a non-negative integer, got {decimals}")
    if int(first_frame) != first_frame:
        raise ValueError(f"first_frame must be an integer, got {first_frame}")

    n_frames, n_markers, _ = positions.shape
    fmt = f"{{:.{int(decimals)}f}}"
    mm = positions.reshape(n_frames, 3 * n_markers) * 1000.0
    out = ["Trajectories", _format_rate(rate_hz),
           ",".join(["", ""] + [c for m in names for c in (m, "", "")]),
           ",".join(["Frame", "Sub Frame"] + ["X", "Y", "Z"] * n_markers),
           ",".join(["", ""] + ["mm"] * 3 * n_markers)]
    for f, row in enumerate(mm):
        cells = ["" if math.isnan(v) else fmt.format(v) for v in row.tolist()]
        out.append(",".join([str(int(first_frame) + f), "0"] + cells))
    with atomic_file(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write("\n".join(out) + "\n")


def _run_lengths(missing):
    """Lengths of the runs of consecutive True values in a 1-D bool array."""
    edges = np.diff(np.r_[0, missing.astype(np.int8), 0])
    return np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)


def summarize_vicon_csv(path):
    """A JSON-serialisable overview of a VICON CSV export (for ``dragline inspect``).

    Returns
    -------
    dict
        ``{"path", "sections": [{"name", "rate_hz", "rows", "frames",
        "first_frame", "last_frame", "columns", "units"}...],
        "trajectories": None or {"rate_hz", "frames", "first_frame",
        "last_frame", "markers", "subjects": [{"name", "markers"}...],
        "unlabeled": [...], "gaps": {marker: {"nan_frames", "gap_runs",
        "longest_gap"}}}}``. ``frames`` counts distinct frame numbers (a
        Devices section has several rows, its sub-frames, per frame); a
        subject ``name`` is None for markers without a ``Subject:`` prefix;
        ``unlabeled`` lists ``*``-named markers; gaps count NaN frames;
        ``notes``: what the reader skipped (``ViconExport.notes``);
        ``events``: the Events section's labelled times.
    """
    export = read_vicon_csv(path)
    summary = {"path": export.path, "sections": [], "trajectories": None, "notes": list(export.notes),
               "events": [dict(e) for e in export.events]}
    for s in export.sections.values():
        summary["sections"].append({
            "name": s.name,
            "rate_hz": s.rate_hz,
            "rows": int(len(s.frame)),
            "frames": int(len(np.unique(s.frame))),
            "first_frame": int(s.frame[0]) if len(s.frame) else None,
            "last_frame": int(s.frame[-1]) if len(s.frame) else None,
            "columns": len(s.columns),
            "units": sorted(set(s.units) - {""}) if s.units is not None else None,
        })
    if export.trajectories is None:
        return summary
    section = export.trajectories
    names, positions = marker_trajectories(export)
    subjects = {}
    for m in names:
        subject, marker = _split_marker(m)
        subjects.setdefault(subject, []).append(marker)
    gaps = {}
    for k, m in enumerate(names):
        missing = np.isnan(positions[:, k, 0])
        runs = _run_lengths(missing)
        gaps[m] = {"nan_frames": int(missing.sum()),
                   "gap_runs": int(runs.size),
                   "longest_gap": int(runs.max()) if runs.size else 0}
    summary["trajectories"] = {
        "rate_hz": section.rate_hz,
        "frames": int(len(section.frame)),
        "first_frame": int(section.frame[0]) if len(section.frame) else None,
        "last_frame": int(section.frame[-1]) if len(section.frame) else None,
        "markers": len(names),
        "subjects": [{"name": s, "markers": ms} for s, ms in subjects.items()],
        "unlabeled": [m for m in names if _split_marker(m)[1].startswith("*")],
        "gaps": gaps,
    }
    return summary
