"""Strict JSON for everything the tool writes.

Python's ``json`` writes ``NaN`` and ``Infinity`` by default, which a
browser's ``JSON.parse`` and every strict parser refuse. A non-finite number
is written as ``null`` (a quantity the tool could not determine); numpy
scalars and arrays become plain numbers and lists.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from ._atomic import atomic_file

__all__ = ["json_ready", "json_text", "write_json"]


def json_ready(obj):
    """Return ``obj`` with numpy values as Python ones and non-finite floats as None.

    Dictionary keys become strings, tuples lists and paths strings. ``obj`` is
    not modified.
    """
    if isinstance(obj, dict):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_ready(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if math.isfinite(x) else None
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return obj


def json_text(obj, indent=1, separators=None):
    """Strict JSON text of ``obj`` (see `json_ready`); never ``NaN`` or ``Infinity``."""
    return json.dumps(json_ready(obj), indent=indent, separators=separators, allow_nan=False)


def write_json(path, doc, indent=1):
    """Write ``doc`` as strict JSON under a temporary name, then rename it into place."""
    text = json_text(doc, indent=indent) + "\n"
    with atomic_file(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
