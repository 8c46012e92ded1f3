"""Writing results: strict JSON, atomically (temporary name, then rename)."""

from __future__ import annotations

import json
import os

__all__ = ["write_json"]


def write_json(path, doc):
    """Write ``doc`` as strict JSON (no NaN) under a temporary name, then rename.

    Raises
    ------
    ValueError
        If ``doc`` holds NaN or infinity (which strict JSON cannot carry).
    """
    path = os.fspath(path)
    text = json.dumps(doc, indent=1, allow_nan=False) + "\n"
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
