"""Session folders of the synthetic lab: ``capture.mcap`` and ``maneuver.csv``, written whole.

The folder's layout is capture's (docs/interfaces.md); what fills it here is
a synthetic session and the reel table its trial ran.
"""

from __future__ import annotations

import os

from ..capture import MANEUVER_FILE, SESSION_FILE, atomic_directory, write_session
from ..simulate import write_maneuver_csv

__all__ = ["write_session_dir"]


def write_session_dir(path, session, maneuver=None, overwrite=False):
    """Write a session directory (``capture.mcap``, ``maneuver.csv``) atomically.

    Parameters
    ----------
    path : str or path-like
    session : CaptureSession
    maneuver : Maneuver, optional
        Written as ``maneuver.csv`` (``write_maneuver_csv``); none if None.
    overwrite : bool
        Replace a non-empty directory at ``path``.

    Returns
    -------
    str
        The directory written.
    """
    def fill(tmp):
        write_session(os.path.join(tmp, SESSION_FILE), session)
        if maneuver is not None:
            write_maneuver_csv(os.path.join(tmp, MANEUVER_FILE), maneuver)

    return atomic_directory(path, fill, overwrite)
