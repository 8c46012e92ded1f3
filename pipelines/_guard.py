"""Outputs never touch inputs.

Every command names its inputs and its outputs here before it writes or
removes anything. An output is refused (exit 2) when it is an input, or a
folder that holds one, or when two outputs collide. Paths are compared
after resolving symbolic links, and existing files also by device and inode,
so a link or a hard link to an input is caught too.

``--force`` is checked elsewhere (``capture.check_directory_target``): it
replaces only a folder that holds the marker file dragline leaves in every
folder it writes.
"""

from __future__ import annotations

import os

from dragline.capture import SESSION_FILES

__all__ = ["guard_outputs", "session_inputs"]


def session_inputs(path, extra=()):
    """The paths a command reads from a session directory, MCAP or export.

    Parameters
    ----------
    path : str or None
        A session directory, a file, or None (the built-in session).
    extra : tuple of str
        Other file names the command reads from a session directory (for
        example ``cameras.json``).

    Returns
    -------
    list of str
        ``path`` itself and, for a directory, the session files in it.
    """
    if not path:
        return []
    paths = [path]
    if os.path.isdir(path):
        paths += [os.path.join(path, name) for name in (*SESSION_FILES, *extra)]
    return paths


def guard_outputs(inputs, files=(), folders=()):
    """Refuse outputs that would replace, remove or hold an input.

    Parameters
    ----------
    inputs : iterable of str or None
        Every path the command reads (files or folders); None, missing paths
        and the built-in name ``dig`` are skipped.
    files : iterable of str or None
        Output files.
    folders : iterable of str or None
        Output folders (replaced whole with ``--force``).

    Raises
    ------
    ValueError
        Naming the output and the input it would touch.
    """
    read = [(p, _real(p), _identity(p)) for p in inputs if p and p != "dig" and os.path.lexists(p)]
    outputs = [(p, _real(p)) for p in (*files, *folders) if p]
    for path, real in outputs:
        ident = _identity(path)
        for name, inp, inp_ident in read:
            if real == inp or (ident is not None and ident == inp_ident):
                raise ValueError(f"{path}: is an input of this command ({name}); an output never replaces an input")
            if _inside(inp, real):
                raise ValueError(f"{path}: holds the input {name}; an output folder never holds an input "
                                 "(choose another output name)")
    for i, (a, real_a) in enumerate(outputs):
        for b, real_b in outputs[i + 1:]:
            if real_a == real_b:
                raise ValueError(f"{a} and {b}: two outputs name the same path")
            if _inside(real_a, real_b) or _inside(real_b, real_a):
                raise ValueError(f"{a} and {b}: one output lies inside the other")


def _real(path):
    return os.path.realpath(os.path.abspath(os.fspath(path)))


def _identity(path):
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _inside(path, folder):
    """True when ``path`` lies strictly inside ``folder`` (both resolved)."""
    return path.startswith(folder.rstrip(os.sep) + os.sep)
