"""Numeric and word options: a bad value is refused at the door, naming the option (pipelines._options).

Each case is what a fuzz run of the command line found refused without the
option named ("duration must be positive, got -1.0"), or not refused at all.
"""

from __future__ import annotations

import pytest

from dragline.pipelines.cli import main

OUT = "never-written.csv"
CASES = [
    (["simulate", "--out", OUT, "--duration"], ["-1", "0", "nan", "inf", "abc"]),
    (["simulate", "--out", OUT, "--rate"], ["-5", "0", "nan"]),
    (["simulate", "--out", OUT, "--dt"], ["0", "-1e-4", "inf"]),
    (["synth", "--out", "never-written", "--dropout"], ["1.5", "-0.1", "nan"]),
    (["synth", "--out", "never-written", "--noise-px"], ["-1", "inf"]),
    (["synth", "--out", "never-written", "--wand-frames"], ["2.5", "-3"]),  # 0: a session without a wand take
    (["reconstruct", "session", "--out", OUT, "--max-gap"], ["-1", "1.5", "nan"]),
    (["reconstruct", "session", "--out", OUT, "--outlier-mm"], ["-20", "inf"]),  # 0 keeps every sample
    (["reconstruct", "session", "--out", OUT, "--max-reprojection-px"], ["0", "1e300"]),  # squared: overflow
    (["calibrate", "session", "--out", "c.json", "--max-frames"], ["0", "nan"]),
    (["compare", "a.csv", "b.csv", "--max-offset"], ["-1", "nan", "1e9"]),  # 1e9: a 1.5 TiB search grid
    (["diagnose", "a.csv", "--workers"], ["0", "1.5"]),
    (["run", "--seed"], ["-1", "x"]),
]


def _one_error(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dragline: error:"), err
    return err[0]


@pytest.mark.parametrize("argv, values", CASES, ids=[" ".join((c[0][0], c[0][-1])) for c in CASES])
def test_a_bad_number_names_its_option(argv, values, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for value in values:
        assert main([*argv[:-1], f"{argv[-1]}={value}"]) == 2, value  # "=": argparse takes -1e-4 for an option
        line = _one_error(capsys)
        assert argv[-1] in line and repr(value) in line, line
    assert list(tmp_path.iterdir()) == []


def test_a_good_number_is_taken(tmp_path, capsys):
    out = tmp_path / "t.csv"
    assert main(["simulate", "--out", str(out), "--duration", "0.05", "--rate", "100", "--quiet"]) == 0
    assert len(out.read_text().splitlines()) == 1 + 6  # header and 0, 0.01, ..., 0.05 s


@pytest.mark.parametrize("option, value, words", [
    ("--discretization", "hoist_rope=0", "from 1 to"),
    ("--discretization", "foo=3", "unknown rope 'foo'"),
    ("--discretization", "hoist_rope=abc", "must be an integer"),
    ("--discretization", "ultra", "unknown discretization"),
    ("--physics", "magic", "unknown mechanism"),
    ("--physics", "aero_drag:cd=-1", "cd"),
    ("--physics", "aero_drag:cd=1,cd=2", "cd given twice"),
])
def test_a_bad_model_option_names_the_option(option, value, words, tmp_path, capsys):
    out = tmp_path / "t.csv"
    assert main(["simulate", option, value, "--out", str(out), "--duration", "0.05", "--quiet"]) == 2
    line = _one_error(capsys)
    assert line.startswith(f"dragline: error: {option}:") and words in line, line
    assert not out.exists()


@pytest.mark.parametrize("old, new", [
    ("static_stiffness = 3513.0", "static_stiffness = 1e9"),  # the dump rope: 1.5e8 steps, ran past 30 s
    ("weight_per_length = 0.55781", "weight_per_length = 1e-300"),  # a chain: a zero step, 1 / dt overflowed
])
def test_a_rig_too_stiff_to_relax_is_refused_at_once(tmp_path, capsys, old, new):
    """Fuzzed rigs whose statics would need more steps than allowed: refused before any is taken."""
    from importlib import resources

    text = resources.files("dragline.simulate").joinpath("data/rig.toml").read_text()
    assert old in text
    rig = tmp_path / "stiff.toml"
    rig.write_text(text.replace(old, new, 1))
    out = tmp_path / "t.csv"
    assert main(["simulate", "--rig", str(rig), "--out", str(out), "--duration", "0.05", "--quiet"]) == 2
    line = _one_error(capsys)
    assert str(rig) in line and "steps, more than" in line, line
    assert not out.exists()

