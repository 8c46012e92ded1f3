"""Outputs are written under a temporary name and renamed when complete (capture.atomic_file)."""

import os

import pytest

from dragline.capture import atomic_file, write_json


def test_a_complete_write_replaces_the_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "out.json"
    target.write_text("old")
    with atomic_file(target) as tmp:
        assert os.path.dirname(tmp) == str(tmp_path) and os.path.basename(tmp).startswith(".out.json.partial-")
        with open(tmp, "w") as fh:
            fh.write("new")
        assert target.read_text() == "old"  # a reader sees the old file until the rename
    assert target.read_text() == "new"
    assert sorted(os.listdir(tmp_path)) == ["out.json"]


def test_a_failed_write_keeps_the_old_file_and_removes_the_temporary(tmp_path):
    target = tmp_path / "out.json"
    target.write_text('{"kept": 1}')
    with pytest.raises(RuntimeError):
        with atomic_file(target) as tmp, open(tmp, "w") as fh:
            fh.write("half")
            raise RuntimeError("stopped half way")
    assert target.read_text() == '{"kept": 1}'
    assert sorted(os.listdir(tmp_path)) == ["out.json"]


def test_write_json_goes_through_it(tmp_path):
    target = tmp_path / "doc.json"
    write_json(target, {"a": float("nan")})
    assert target.read_text() == '{\n "a": null\n}\n'  # strict JSON: NaN is null
    assert sorted(os.listdir(tmp_path)) == ["doc.json"]
