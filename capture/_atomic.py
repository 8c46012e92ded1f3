"""Outputs written under a temporary name and renamed into place when complete."""

from __future__ import annotations

import os
from contextlib import contextmanager

__all__ = ["atomic_file"]


@contextmanager
def atomic_file(path, suffix=""):
    """Yield a temporary path beside ``path``; on success rename it to ``path``, else remove it.

    The temporary file is in the same folder, so the rename is atomic and a
    reader never sees a half-written file; it is hidden (a leading dot) and
    carries the process id, so two writers never share one. ``suffix`` ends
    its name, for writers that choose the format by extension (``.c3d``).
    The caller opens it with ``open()``, which keeps the user's umask on the
    final file.
    """
    path = os.fspath(path)
    folder, name = os.path.split(os.path.abspath(path))
    tmp = os.path.join(folder, f".{name}.partial-{os.getpid()}{suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
