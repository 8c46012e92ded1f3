"""Labelled 3D marker files of other labs (C3D, TRC) as one small record.

A VICON-style CSV, a C3D file and a TRC file all hold the same thing for
this tool: labelled marker positions at a fixed rate. Each reader returns a
:class:`MarkerFile` in metres with NaN where a marker was not seen, so the
reconstruction reads every format alike (``reconstruct_marker_file``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

__all__ = ["MarkerFile", "METRES_PER_UNIT", "metres_per_unit", "event_frame", "between_events"]

METRES_PER_UNIT = {"mm": 1e-3, "cm": 1e-2, "dm": 1e-1, "m": 1.0, "millimeters": 1e-3, "meters": 1.0}
# A day at 10 kHz: beyond, a frame index is nonsense (and an int64 product overflows).
MAX_FRAMES = 10**9


def metres_per_unit(unit, where):
    """Scale from a file's length unit to metres; one-line ValueError naming ``where`` otherwise."""
    key = (unit or "").strip().lower()
    if key not in METRES_PER_UNIT:
        raise ValueError(f"{where}: length unit '{unit}' is not one of mm, cm, dm, m")
    return METRES_PER_UNIT[key]


@dataclass(eq=False)
class MarkerFile:
    """Labelled marker trajectories read from a file.

    Attributes
    ----------
    path : str
    format : str
        ``"c3d"`` or ``"trc"``.
    names : list of str
        Marker labels as in the file (``'bucket:alpha'``, ``'RHip'``).
    positions : ndarray, shape (frames, markers, 3)
        Positions (m); NaN in all three where the marker was not seen.
    rate_hz : float
        Frame rate (Hz).
    first_frame : int
        Number of the first frame in the file's own counting.
    units : str
        The file's length unit, as written.
    analog : dict
        ``channels`` (labels), ``rate_hz``, ``units``, ``frames`` of the
        analog data the file also holds (empty lists and 0 if none).
    info : dict
        Anything else worth showing (manufacturer, software, header fields).
    events : list of dict
        Labelled times the file holds (a VICON CSV's Events section, a C3D's
        EVENT group): ``name``, ``context``, ``subject``, ``time_s`` (s from
        the capture's start, where frame 1 is 0 s), ``description``.
    """

    path: str
    format: str
    names: list
    positions: np.ndarray
    rate_hz: float
    first_frame: int = 1
    units: str = "mm"
    analog: dict = field(default_factory=lambda: {"channels": [], "rate_hz": 0.0, "units": [], "frames": 0})
    info: dict = field(default_factory=dict)
    events: list = field(default_factory=list)

    @property
    def frames(self):
        return int(self.positions.shape[0])

    def summary(self):
        """JSON-able description: rate, frames, markers with their seen fraction, analog channels."""
        seen = np.isfinite(self.positions).all(axis=-1)
        return {"path": self.path, "format": self.format, "rate_hz": self.rate_hz, "frames": self.frames,
                "first_frame": self.first_frame, "duration_s": self.frames / self.rate_hz if self.rate_hz else None,
                "units": self.units, "markers": list(self.names),
                "seen_fraction": {n: float(seen[:, k].mean()) if self.frames else 0.0
                                  for k, n in enumerate(self.names)},
                "analog": dict(self.analog), "info": dict(self.info), "events": [dict(e) for e in self.events]}


MARKER_FILE_EXTENSIONS = (".csv", ".c3d", ".trc")
# Frame numbers may skip rows (gaps filled with NaN), up to this: span <= factor x rows + missing rows.
MAX_SPAN_FACTOR = 2
MAX_MISSING_ROWS = 10_000


def frame_span(path, frames, lines=None):
    """Frames from the first to the last number, checked against the rows the file holds.

    A span far beyond the rows is a typo in a frame number (and would fill
    memory with NaN frames): refused, naming the biggest jump (and its line,
    when ``lines`` gives each row's).
    """
    frames = np.asarray(frames)
    span = int(frames[-1] - frames[0]) + 1
    if span > MAX_SPAN_FACTOR * len(frames) + MAX_MISSING_ROWS:
        k = int(np.argmax(np.diff(frames))) + 1
        where = f"line {lines[k]}: " if lines is not None else ""
        raise ValueError(f"{path}: {where}frame {frames[k]} after frame {frames[k - 1]}: the frame numbers span "
                         f"{span} frames for {len(frames)} rows (a typo in a frame number?)")
    return span


def read_marker_file(path):
    """Labelled 3D markers from a VICON-style CSV, a C3D or a TRC file (by extension).

    Frame numbers the file skips become frames with every marker unseen, so
    row ``i`` of ``positions`` is always frame ``first_frame + i``.

    Returns
    -------
    MarkerFile

    Raises
    ------
    ValueError
        One line starting with the path, as the format's reader words it.
    """
    import os

    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext == ".c3d":
        from ._c3d import read_c3d

        return read_c3d(path)
    if ext == ".trc":
        from ._trc import read_trc

        return read_trc(path)
    from ._vicon_csv import marker_trajectories, read_vicon_csv

    export = read_vicon_csv(path)
    names, positions = marker_trajectories(export)
    frame = export.trajectories.frame
    if frame.size == 0:
        raise ValueError(f"{path}: the Trajectories section has no frames")
    if np.any(np.diff(frame) <= 0):
        raise ValueError(f"{path}: frame numbers are not increasing")
    full = np.full((frame_span(path, frame),) + positions.shape[1:], np.nan)
    full[frame - frame[0]] = positions
    return MarkerFile(path=path, format="vicon_csv", names=names, positions=full,
                      rate_hz=float(export.trajectories.rate_hz), first_frame=int(frame[0]),
                      events=[dict(e) for e in export.events])


def event_frame(markers, time_s):
    """The row of ``markers.positions`` at an event's time (s from the capture's start).

    Nexus and C3D count frames from 1 at 0 s, so frame ``1 + round(t rate)``;
    a file that starts later (``first_frame`` > 1) is offset by that.
    """
    return int(round(time_s * markers.rate_hz)) + 1 - markers.first_frame


def _find_event(markers, label, after=None):
    """The first event named ``label`` (``NAME`` or ``CONTEXT:NAME``) at or after row ``after``."""
    for event in sorted(markers.events, key=lambda e: e["time_s"]):
        names = {event["name"], f"{event['context']}:{event['name']}"}
        if label in names and (after is None or event_frame(markers, event["time_s"]) > after):
            return event
    held = sorted({(f"{e['context']}:" if e["context"] else "") + e["name"] for e in markers.events})
    what = "after the start event" if after is not None else "in the file"
    raise ValueError(f"{markers.path}: no event '{label}' {what} (events: {', '.join(held) or 'none'})")


def between_events(markers, start, end):
    """The trial cut from one labelled event to the next: frames from ``start`` to ``end``, both kept.

    Parameters
    ----------
    markers : MarkerFile
    start, end : str
        Event labels, ``NAME`` or ``CONTEXT:NAME`` (``"General:Dig Start"``);
        the first ``start`` in the file, then the first ``end`` after it.

    Returns
    -------
    MarkerFile
        A new record (``markers`` is not modified) whose first row is the
        start event's frame; ``info["cut"]`` says which events and frames.

    Raises
    ------
    ValueError
        One line starting with the path: an event not in the file (the
        file's events named), or one outside its frames.
    """
    first = _find_event(markers, start)
    i0 = event_frame(markers, first["time_s"])
    last = _find_event(markers, end, after=i0)
    i1 = event_frame(markers, last["time_s"])
    for event, row in ((first, i0), (last, i1)):
        if not 0 <= row < markers.frames:
            raise ValueError(f"{markers.path}: event '{event['name']}' at {event['time_s']:g} s is frame "
                             f"{row + markers.first_frame}, outside the file's frames {markers.first_frame}-"
                             f"{markers.first_frame + markers.frames - 1}")
    cut = {"start": start, "end": end, "start_s": first["time_s"], "end_s": last["time_s"],
           "frames": [i0 + markers.first_frame, i1 + markers.first_frame]}
    return dataclasses.replace(markers, positions=markers.positions[i0:i1 + 1].copy(),
                               first_frame=markers.first_frame + i0, info={**markers.info, "cut": cut},
                               events=[dict(e) for e in markers.events])
