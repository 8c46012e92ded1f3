"""``dragline bench diagnosis``: it times the committed sample session's recipe or `dragline run`'s session, and refuses bad options."""

import shlex
import subprocess
import sys
from pathlib import Path

from dragline.benchmarks._diagnosis import HIDDEN, SAMPLE_RECIPE

REPO = Path(__file__).resolve().parents[1]


def test_the_benchmark_synthesises_the_committed_samples_recipe():
    # The README's figure is "the sample session": the benchmark must make that very session.
    script = (REPO / "samples" / "make_samples.sh").read_text()
    command = " ".join(line.rstrip("\\").strip() for line in script.splitlines() if not line.startswith("#"))
    words = shlex.split(command[command.index("dragline synth"):])
    made = words[2:words.index("--out")]
    assert tuple(made) == SAMPLE_RECIPE
    name, value = SAMPLE_RECIPE[-1].split(":")
    assert HIDDEN == {"mechanism": name, value.split("=")[0]: float(value.split("=")[1])}


def test_a_missing_session_exits_2_with_one_line(tmp_path):
    out = subprocess.run([sys.executable, "-m", "dragline.pipelines.cli", "bench", "diagnosis", "--session",
                          str(tmp_path / "nowhere"), "--repeats", "1"], capture_output=True, text=True)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "nowhere" in lines[0] and "Traceback" not in out.stderr


def test_the_run_sessions_hidden_physics_is_what_the_benchmark_reports():
    # --run-session reports HIDDEN as the truth: it must be what `dragline run` hides.
    from dragline.pipelines._run import BUILTIN_HIDDEN_PHYSICS

    name, value = BUILTIN_HIDDEN_PHYSICS.split(":")
    assert HIDDEN == {"mechanism": name, value.split("=")[0]: float(value.split("=")[1])}


def test_a_session_folder_and_the_run_session_together_exit_2_with_one_line(tmp_path):
    out = subprocess.run([sys.executable, "-m", "dragline.pipelines.cli", "bench", "diagnosis", "--session",
                          str(tmp_path), "--run-session", "--repeats", "1"], capture_output=True, text=True)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "--run-session" in lines[0] and "Traceback" not in out.stderr
