"""Writing results: strict JSON (non-finite numbers as null), atomically."""

from __future__ import annotations

from dragline.capture._strict_json import write_json

__all__ = ["write_json"]
