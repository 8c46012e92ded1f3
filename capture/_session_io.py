"""Session directories: created complete or not at all.

A session directory (docs/interfaces.md) holds ``capture.mcap`` and ``maneuver.csv``
(the reel table the trial ran, the same table the MCAP's session info
carries), and may hold a VICON-style ``markers.csv``. Directories are
written under a temporary sibling name and renamed into place when every
file is in them, so a crash never leaves a half-made session under its
final name.
"""

from __future__ import annotations

import os
import shutil

from dataclasses import dataclass

from ._marker_file import MARKER_FILE_EXTENSIONS
from ._mcap_io import SESSION_FILE

__all__ = ["SESSION_FILE", "MANEUVER_FILE", "SESSION_FILES", "OUTPUT_MARKER", "session_file", "check_directory_target",
           "atomic_directory", "mark_output", "RecordingInput", "resolve_recording"]

MANEUVER_FILE = "maneuver.csv"
#: Every file a command may read from a session directory.
SESSION_FILES = (SESSION_FILE, MANEUVER_FILE, "markers.csv")
#: Left in every folder dragline writes: ``--force`` replaces only a folder
#: that holds it, never one the user made.
OUTPUT_MARKER = ".dragline-output"


def mark_output(folder, command):
    """Leave the marker that lets ``--force`` replace ``folder`` later."""
    with open(os.path.join(folder, OUTPUT_MARKER), "w") as fh:
        fh.write(f"written by dragline {command}; --force may replace this folder\n")


def session_file(path):
    """The ``capture.mcap`` of a session directory, or the MCAP file itself.

    Raises
    ------
    ValueError
        If neither a session directory holding ``capture.mcap`` nor a file
        exists there.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        inner = os.path.join(path, SESSION_FILE)
        if not os.path.isfile(inner):
            raise ValueError(f"{path}: not a session directory (no {SESSION_FILE} in it)")
        return inner
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such session directory or MCAP file")
    return path


@dataclass(frozen=True)
class RecordingInput:
    """What a recording path holds (``resolve_recording``).

    Attributes
    ----------
    kind : str
        ``session`` (an MCAP capture session), ``markers`` (3D markers: a
        VICON CSV, C3D or TRC file) or ``table`` (a trajectory table CSV).
    file : str
        The file to read.
    directory : str or None
        The session directory given, if a directory was given (it may hold
        ``cameras.json`` and ``maneuver.csv``).
    folder : str
        The folder the input lives in: the directory given, or the file's.
    """

    kind: str
    file: str
    directory: str | None
    folder: str


def _is_trajectory_table(path):
    """A CSV whose header has ``time`` and ``<entity>.<quantity>`` names (a VICON export has neither)."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            names = [c.strip() for c in fh.readline().split(",")]
    except OSError:
        return False
    return "time" in names and any("." in n for n in names)


def resolve_recording(path, tables=False):
    """The one way every command tells what a recording path is.

    Parameters
    ----------
    path : str or path-like
        A session directory (``capture.mcap``, or without one ``markers.csv``),
        a ``.mcap`` session file, a marker file (``.csv`` VICON export,
        ``.c3d``, ``.trc``) or, with ``tables``, a trajectory table CSV.
    tables : bool
        Whether a trajectory table is a recording here (``diagnose`` and
        ``compare`` take one; ``reconstruct`` and ``run`` make one).

    Returns
    -------
    RecordingInput

    Raises
    ------
    ValueError
        No such path, a directory without a session, an unknown extension.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        for kind, name in (("session", SESSION_FILE), ("markers", "markers.csv")):
            if os.path.isfile(os.path.join(path, name)):
                return RecordingInput(kind, os.path.join(path, name), path, path)
        raise ValueError(f"{path}: session directory holds neither {SESSION_FILE} nor markers.csv")
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such file or directory")
    folder = os.path.dirname(os.path.abspath(path))
    ext = os.path.splitext(path)[1].lower()
    if ext == ".mcap":
        return RecordingInput("session", path, None, folder)
    if ext == ".csv" and tables and _is_trajectory_table(path):
        return RecordingInput("table", path, None, folder)
    if ext in MARKER_FILE_EXTENSIONS:
        return RecordingInput("markers", path, None, folder)
    table = ", a trajectory table" if tables else ""
    raise ValueError(f"{path}: expected a session directory, a .mcap session file{table} or a marker file "
                     "(.csv VICON export, .c3d, .trc)")


def check_directory_target(path, overwrite=False):
    """Fail early (``ValueError``) when directory ``path`` cannot be created or replaced."""
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise ValueError(f"output folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise ValueError(f"output folder {parent} is not writable")
    if os.path.lexists(path):
        if not os.path.isdir(path):
            raise ValueError(f"{path} exists and is not a directory")
        entries = os.listdir(path)
        if entries and not overwrite:
            raise ValueError(f"{path} exists and is not empty (choose another name, or --force to replace it)")
        if entries and OUTPUT_MARKER not in entries:
            raise ValueError(f"{path} was not written by dragline (no {OUTPUT_MARKER} in it); --force replaces only "
                             "a folder dragline wrote: remove it yourself or choose another name")


def atomic_directory(path, fill, overwrite=False, command="synth"):
    """Create directory ``path`` complete: ``fill(tmp_dir)`` writes into a sibling, then it is renamed.

    Parameters
    ----------
    path : str or path-like
        The directory to create. An empty directory there is replaced; a
        non-empty one only with ``overwrite`` (it is removed once the new one
        is in place).
    fill : callable
        ``fill(tmp_dir)`` writes every file.
    overwrite : bool
    command : str
        The command named in the folder's marker (``OUTPUT_MARKER``).

    Returns
    -------
    str
        ``path``.

    Raises
    ------
    ValueError
        If the parent folder is missing or read-only, or ``path`` is a file
        or a non-empty directory without ``overwrite`` or not written by
        dragline.
    """
    path = os.path.abspath(os.fspath(path))
    check_directory_target(path, overwrite)
    parent, name = os.path.split(path)
    tmp = os.path.join(parent, f".{name}.tmp{os.getpid()}")
    old = os.path.join(parent, f".{name}.old{os.getpid()}")
    if os.path.lexists(tmp):
        shutil.rmtree(tmp)
    os.mkdir(tmp)
    try:
        fill(tmp)
        mark_output(tmp, command)
        moved = os.path.isdir(path) and bool(os.listdir(path))
        if moved:
            os.rename(path, old)
        elif os.path.isdir(path):
            os.rmdir(path)
        try:
            os.rename(tmp, path)
        except BaseException:
            if moved:  # put the old directory back rather than lose both
                os.rename(old, path)
            raise
        if moved:
            shutil.rmtree(old)
    finally:
        if os.path.lexists(tmp):
            shutil.rmtree(tmp)
    return path
