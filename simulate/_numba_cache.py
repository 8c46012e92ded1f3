"""Numba's on-disk cache, keyed on the simulator's sources.

Numba checks a cached function against its own file's time stamp only, not
the files it calls into (numba issue #1833, open since 2016): the
integrators in ``_tracked`` and ``_verlet`` inline the right-hand side of
``_kernel``, so after an edit or an upgrade that changes ``_kernel`` alone
they would load yesterday's machine code and run the old physics without a
word. Here the cache lives in a folder named by a hash of every source file
of this package: any change to any of them starts a fresh cache.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import time
from pathlib import Path

import numba

__all__ = ["source_key", "use_source_keyed_cache"]

# Caches of older sources are removed once this old (s): a process still
# running the old sources a day after an upgrade is not expected.
STALE_AFTER_S = 86400.0


def source_key(package_dir):
    """A hex digest of every ``.py`` file under ``package_dir`` (names and contents)."""
    digest = hashlib.sha256()
    root = Path(package_dir)
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()[:16]


def use_source_keyed_cache(package_dir):
    """Point numba's cache at a folder named by ``source_key(package_dir)``; return it.

    Call before the package's compiled modules are imported (numba picks a
    function's cache folder when it is decorated). A cache folder the user
    chose (``NUMBA_CACHE_DIR``) is left alone, and None is returned. The
    folder is ``__pycache__/numba-KEY`` beside the sources where they are
    writable, else under the user's cache folder (``XDG_CACHE_HOME`` or
    ``~/.cache``) as ``dragline/numba-KEY``; sibling folders of other keys
    untouched for a day are removed.
    """
    if os.environ.get("NUMBA_CACHE_DIR") or numba.config.CACHE_DIR:
        return None
    name = f"numba-{source_key(package_dir)}"
    if os.access(package_dir, os.W_OK):
        parent = Path(package_dir) / "__pycache__"
    else:
        parent = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "dragline"
    folder = parent / name
    numba.config.CACHE_DIR = str(folder)
    _remove_stale(parent, name)
    return folder


def _remove_stale(parent, keep):
    try:
        entries = list(parent.glob("numba-*"))
    except OSError:
        return
    now = time.time()
    for entry in entries:
        try:
            if entry.name != keep and entry.is_dir() and now - entry.stat().st_mtime > STALE_AFTER_S:
                shutil.rmtree(entry, ignore_errors=True)
        except OSError:
            pass  # another process removed it first
