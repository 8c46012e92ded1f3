"""One diagnosis of the sample session, timed as a user waits for it.

Each run is ``dragline diagnose SESSION --workers W --json FILE`` in a fresh
process: the interpreter's start and the imports, reading the session,
calibrating its cameras from its own takes, reconstructing, every
simulation of the diagnosis and writing the JSON. The session is the
committed sample's recipe (``samples/make_samples.sh``: seed 7, 10 s at
100 Hz, 600 wand frames, ring-pulley friction mu = 0.02 hidden), made
once before the timed runs unless one is given.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

__all__ = ["bench_diagnosis", "SAMPLE_RECIPE"]

# ``dragline synth`` arguments of the committed sample session.
SAMPLE_RECIPE = ("--seed", "7", "--duration", "10", "--rate", "100", "--wand-frames", "600",
                 "--lframe-frames", "50", "--physics", "pulley_friction:mu=0.02")
HIDDEN = {"mechanism": "pulley_friction", "mu": 0.02}


def _cli(*args):
    """Run the ``dragline`` command in a fresh interpreter; raise with its last line if it fails."""
    out = subprocess.run([sys.executable, "-m", "dragline.pipelines.cli", *args], capture_output=True, text=True,
                         check=False)
    if out.returncode != 0:
        last = out.stderr.strip().splitlines()[-1] if out.stderr.strip() else f"exit code {out.returncode}"
        raise RuntimeError(f"dragline {args[0]} failed: {last}")
    return out


def bench_diagnosis(session=None, repeats=3, workers=2, run_seed=None):
    """Time ``repeats`` diagnoses of one session, each in its own process.

    Parameters
    ----------
    session : path, optional
        A session folder; by default the sample session is synthesised into
        a temporary folder first (not timed).
    repeats : int
    workers : int
        Processes for the diagnosis's simulations.
    run_seed : int, optional
        Diagnose the session ``dragline run --seed RUN_SEED`` builds instead
        (12 s at 200 Hz of a rig drawn within its tolerances, simulated at
        ``medium`` with ring-pulley friction mu = 0.02), made first by
        ``dragline run --no-diagnose`` (not timed).

    Returns
    -------
    dict
        ``wall_s`` (every run, s), ``median_s``, ``min_s``, ``max_s``; per
        run the diagnosis's own ``timing`` (its simulations, seconds inside
        ``diagnose``, loading); ``verdict`` and ``value`` of the last run
        (they are the same every run); ``load_average`` before and after
        (1 min); ``cpus``.
    """
    if session is not None and run_seed is not None:
        raise ValueError("give a session folder or a run seed, not both")
    with tempfile.TemporaryDirectory(prefix="dragline-bench-diagnosis-") as tmp:
        made = session is None and run_seed is None
        if made:
            session = os.path.join(tmp, "session")
            _cli("synth", *SAMPLE_RECIPE, "--out", session, "--quiet")
        elif run_seed is not None:
            _cli("run", "--out", os.path.join(tmp, "run"), "--seed", str(int(run_seed)), "--no-diagnose", "--quiet")
            session = os.path.join(tmp, "run", "session")
        load_before = os.getloadavg()[0]
        walls, timings, doc = [], [], {}
        for i in range(repeats):
            out = os.path.join(tmp, f"diagnosis{i}.json")
            start = time.perf_counter()
            _cli("diagnose", os.fspath(session), "--workers", str(workers), "--json", out)
            walls.append(time.perf_counter() - start)
            with open(out) as f:
                doc = json.load(f)
            timings.append(doc.get("timing", {}))
        load_after = os.getloadavg()[0]
    named = doc.get("verdict")
    value = None
    for h in doc.get("hypotheses", []):
        if h.get("name") == named:
            value = {h["main_parameter"]: h["parameters"][h["main_parameter"]]}
    return {
        "session": ("the sample session's recipe, synthesised here" if made
                    else f"the session dragline run --seed {int(run_seed)} builds, made here" if run_seed is not None
                    else os.fspath(session)),
        "recipe": list(SAMPLE_RECIPE) if made else ["run", "--seed", str(int(run_seed))] if run_seed is not None else None,
        "hidden": HIDDEN if made or run_seed is not None else None,
        "what_is_timed": "dragline diagnose SESSION --workers W --json FILE in a fresh process: start-up, reading, "
                         "calibration from the session's takes, reconstruction, every simulation, the JSON",
        "workers": workers,
        "repeats": repeats,
        "wall_s": walls,
        "median_s": statistics.median(walls),
        "min_s": min(walls),
        "max_s": max(walls),
        "diagnosis_timing": timings,
        "verdict": named,
        "value": value,
        "load_average": {"before": load_before, "after": load_after},
        "cpus": os.cpu_count(),
    }


def summary_lines(report):
    """One line for the terminal."""
    return [f"diagnosis: median {report['median_s']:.1f} s of {report['repeats']} "
            f"({report['min_s']:.1f}-{report['max_s']:.1f} s) with {report['workers']} workers; "
            f"verdict {report['verdict']} {report['value']}"]
