"""No output option of any command can remove or change an input.

Each case below destroyed its own input before the guard existed (the
bad-input issue lists them). Every one must now exit 2 with one line, and
leave every file in the working folder byte for byte as it was.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import pytest

from conftest import REPO, synthetic_table
from dragline.capture import OUTPUT_MARKER
from dragline.pipelines.cli import main
from dragline.simulate import dig_maneuver, write_maneuver_csv, write_trajectory_csv

SAMPLE = REPO / "samples" / "dig_sample"


@pytest.fixture()
def proj(tmp_path):
    """A user's project folder: a session, its calibration, tables, notes."""
    import numpy as np

    proj = tmp_path / "proj"
    shutil.copytree(SAMPLE, proj / "sess")
    (proj / "notes.txt").write_text("lab notebook\n")
    (proj / "cams.json").write_text("{}\n")
    write_maneuver_csv(proj / "m.csv", dig_maneuver())
    t = np.arange(0.0, 2.0, 0.005)
    write_trajectory_csv(proj / "A.csv", synthetic_table(t))
    write_trajectory_csv(proj / "B.csv", synthetic_table(t))
    return proj


def _snapshot(folder):
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(Path(folder).rglob("*")) if p.is_file()}


CASES = [
    ["run", "{p}/sess", "--out", "{p}/sess", "--force"],
    ["run", "{p}/sess", "--out", "{p}", "--force"],
    ["replay", "{p}/sess/capture.mcap", "--out", "{p}/sess", "--force"],
    ["reconstruct", "{p}/sess", "--calibration", "{p}/cams.json", "--out", "{p}/cams.json"],
    ["reconstruct", "{p}/sess", "--calibration", "{p}/cams.json", "--out", "{p}/sess/maneuver.csv"],
    ["synth", "--maneuver", "{p}/m.csv", "--out", "{p}", "--force"],
    ["synth", "--out", "{p}/new", "--truth-out", "{p}/new/truth"],
    ["calibrate", "{p}/sess", "--out", "{p}/sess/capture.mcap"],
    ["simulate", "--maneuver", "{p}/m.csv", "--out", "{p}/m.csv"],
    ["compare", "{p}/A.csv", "{p}/B.csv", "--json", "{p}/A.csv"],
    ["compare", "{p}/A.csv", "{p}/B.csv", "--json", "{p}/out.json", "--report", "{p}/out.json"],
    ["diagnose", "{p}/sess", "--json", "{p}/sess/capture.mcap"],
    ["diagnose", "{p}/A.csv", "--maneuver", "{p}/m.csv", "--json", "{p}/m.csv"],
]


@pytest.mark.parametrize("argv", CASES, ids=[" ".join(c[:1] + c[-2:]) for c in CASES])
def test_an_output_that_is_or_holds_an_input_is_refused(proj, argv, capsys):
    before = _snapshot(proj.parent)
    rc = main([a.format(p=proj) for a in argv])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert _snapshot(proj.parent) == before


def test_a_link_to_an_input_is_an_input(proj, capsys):
    os.symlink(proj / "m.csv", proj / "link.csv")
    os.link(proj / "m.csv", proj / "hard.csv")
    before = _snapshot(proj)
    for out in ("link.csv", "hard.csv"):
        assert main(["simulate", "--maneuver", str(proj / "m.csv"), "--out", str(proj / out)]) == 2
        assert "is an input" in capsys.readouterr().err
    assert _snapshot(proj) == before


def test_force_replaces_only_a_folder_dragline_wrote(tmp_path, capsys):
    synth = ["synth", "--duration", "0.2", "--wand-frames", "300", "--lframe-frames", "20", "--quiet"]
    user = tmp_path / "mine"
    user.mkdir()
    (user / "thesis.tex").write_text("months of work\n")
    assert main([*synth, "--out", str(user), "--force"]) == 2
    assert "not written by dragline" in capsys.readouterr().err
    assert (user / "thesis.tex").read_text() == "months of work\n"

    ours = tmp_path / "session"
    assert main([*synth, "--out", str(ours)]) == 0
    assert (ours / OUTPUT_MARKER).is_file()
    first = (ours / "capture.mcap").read_bytes()
    assert main([*synth, "--seed", "1", "--out", str(ours), "--force"]) == 0
    assert (ours / "capture.mcap").read_bytes() != first  # replaced, as asked
    assert sorted(os.listdir(tmp_path)) == ["mine", "session"]  # nothing left beside it
