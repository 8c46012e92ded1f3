"""The command-line fuzzer (tools/fuzz_inputs.py) on a few seeded cases.

The full run (10,000 cases, docs/schemas.md) is too long for CI; this keeps
the harness and the door checks honest on a sample: every case must end
refused with its file or option named, accepted with strict JSON, or past
the door of a long command - no traceback, hang, memory blow-up or
accepted nonsense.
"""

from __future__ import annotations

import importlib.util

from conftest import REPO


def _fuzzer():
    spec = importlib.util.spec_from_file_location("fuzz_inputs", REPO / "tools" / "fuzz_inputs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_seeded_sample_of_broken_inputs_ends_well():
    result = _fuzzer().run(24, 3, workers=2, limit=60.0, keep_failures=False)
    counts = result["counts"]
    assert sum(counts.values()) == 24
    assert set(counts) <= {"refused", "accepted", "running"}, result["failures"]
    assert counts.get("refused", 0) >= 10  # most broken inputs are refused at the door
