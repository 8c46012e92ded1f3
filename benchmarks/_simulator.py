"""``dragline bench simulate``: speed and accuracy of the simulator, measured.

Each discretization level runs in its own process (so its peak memory is its
own) after a warm-up run that loads or compiles the kernel; the compile time
itself is measured in a process with an empty numba cache.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from dragline.simulate import assemble, dig_maneuver, load_rig, simulate, solve_statics

LEVELS = ("low", "baseline", "medium", "high")


def _measure_level(level, repeats, duration):
    """One level's figures (``bench_simulate``), measured in this process."""
    rig, man = load_rig(), dig_maneuver()
    model = assemble(rig, man, level)
    t = time.perf_counter()
    eq = solve_statics(model)
    statics = [time.perf_counter() - t]
    methods = ("verlet", "rk4")

    def run(name, **kw):
        # from the equilibrium: what simulate() times as integrate_s (the step at the start, then the run)
        return simulate(rig, man, level, duration=duration, initial_state=eq.state, integrator=name, **kw)

    for name in methods:  # warm-up: loads the compiled kernel
        simulate(rig, man, level, duration=0.005, initial_state=eq.state, integrator=name)
    walls = {name: [] for name in methods}
    last = {}
    for _ in range(repeats):  # alternating, so load on the machine falls on both alike
        for name in methods:
            last[name] = run(name)
            walls[name].append(last[name].timings["integrate_s"])
    for _ in range(max(0, repeats - 1)):
        t = time.perf_counter()
        solve_statics(model)
        statics.append(time.perf_counter() - t)
    calls = []
    for _ in range(max(1, repeats // 2)):
        t = time.perf_counter()
        simulate(rig, man, level, duration=duration)
        calls.append(time.perf_counter() - t)
    fine = min(last[name].dt for name in methods) / 8
    ref = run("verlet", dt=fine).table

    lead = next(iter(rig.bodies))  # the figures follow the rig's first body (the dragline's bucket)

    def errors(table):
        pos = np.stack([table[f"{lead}.{c}"] - ref[f"{lead}.{c}"] for c in "xyz"], axis=1)
        return (1e3 * float(np.max(np.linalg.norm(pos, axis=1))),
                float(np.degrees(np.max(np.abs(table[f"{lead}.pitch"] - ref[f"{lead}.pitch"])))))

    out = {"statics_s": float(np.median(statics)), "simulate_call_s": float(np.median(calls)),
           "states": model.n_state,
           "reference": "Verlet at a fixed step of the smallest tracked step / 8",
           "reference_vs_rk4_same_step_mm": errors(run("rk4", dt=fine).table)[0],
           "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}
    for name in methods:
        result = last[name]
        pos, pitch = errors(result.table)
        out[name] = {"wall_s": float(np.median(walls[name])), "wall_runs_s": walls[name],
                     "real_time_factor": duration / float(np.median(walls[name])),
                     "dt_start_s": result.dt_start, "dt_smallest_s": result.dt,
                     "steps": result.steps, "error_bucket_position_mm": pos, "error_bucket_pitch_deg": pitch}
    out["wall_s"] = out["verlet"]["wall_s"]
    out["rk4_over_verlet"] = out["rk4"]["wall_s"] / out["verlet"]["wall_s"]
    return out


# The first call is timed from before the import, so it runs as a command of its own: any
# module of this package would import the simulator before the clock starts.
_FIRST_CALL = """
import time
t = time.perf_counter()
from dragline.simulate import simulate
simulate(duration=0.05)
print(time.perf_counter() - t)
"""


def _first_call_s(env):
    out = subprocess.run([sys.executable, "-c", _FIRST_CALL], capture_output=True, text=True, env=env, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"benchmark subprocess failed: {out.stderr.strip().splitlines()[-1] if out.stderr else out.returncode}")
    return float(out.stdout.strip().splitlines()[-1])


def _level_in_process(level, repeats, duration):
    """``_measure_level`` in a fresh process (``python -m`` this module), so its peak memory is its own."""
    command = [sys.executable, "-m", __name__, level, str(repeats), str(duration)]
    out = subprocess.run(command, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"benchmark subprocess failed: {out.stderr.strip().splitlines()[-1] if out.stderr else out.returncode}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_simulate(levels=LEVELS, repeats=5, duration=10.0, moordyn=True):
    """Figures for the 10 s dig maneuver at each discretization level.

    Returns
    -------
    dict
        ``{level: {wall_s, statics_s, simulate_call_s, rk4_over_verlet,
        verlet: {wall_s, steps, error_bucket_position_mm,
        error_bucket_pitch_deg, ...}, rk4: {...}, ...}, "compile": {...},
        "moordyn": {...}}``. Per integrator, ``wall_s`` is what ``simulate``
        does after the statics (the starting step from the spectrum, then
        the tracked run; median of ``repeats``, the two integrators run
        alternately); errors are against Verlet at an eighth of the smallest
        step. ``wall_s`` of the level is Verlet's (``simulate``'s default),
        ``statics_s`` the equilibrium before it, ``simulate_call_s`` one
        whole ``simulate()`` call.
    """
    report = {"duration_s": duration, "repeats": repeats, "cpu_count": os.cpu_count()}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cold = _first_call_s(env)
        warm = _first_call_s(env)
    report["compile"] = {
        "cold_first_call_s": cold,
        "warm_cache_first_call_s": warm,
        "compile_s": cold - warm,
        "note": "first 0.05 s simulation in a fresh process, empty vs filled numba cache",
    }
    for level in levels:
        report[level] = _level_in_process(level, repeats, duration)
    if moordyn:
        report["moordyn"] = moordyn_report()
    return report


def moordyn_report():
    """The MoorDyn comparison's figures, or why it was skipped (the package is an optional extra)."""
    try:
        import moordyn  # noqa: F401 - imported where it runs; here only: is it there?
    except ImportError as exc:
        return {"skipped": f"{exc}; pip install -e '.[bench]' adds it"}
    from ._moordyn_peer import bench_moordyn

    return bench_moordyn()


def summary_lines(report):
    """Human-readable lines of a bench_simulate report."""
    lines = [f"compile: {report['compile']['compile_s']:.1f} s (cold first call {report['compile']['cold_first_call_s']:.1f} s)"]
    for level in LEVELS:
        if level in report:
            r = report[level]
            lines.append(f"{level:9s} {r['states']:4d} states  statics {r['statics_s']:.2f} s  whole call "
                         f"{r['simulate_call_s']:.2f} s  peak {r['peak_memory_mb']:.0f} MB  RK4 / Verlet {r['rk4_over_verlet']:.2f}")
            for name in ("verlet", "rk4"):
                x = r[name]
                lines.append(f"  {name:7s} wall {x['wall_s']:.2f} s (x{x['real_time_factor']:.1f} real time)  {x['steps']} steps  "
                             f"error {x['error_bucket_position_mm']:.4f} mm / {x['error_bucket_pitch_deg']:.5f} deg")
    if "skipped" in report.get("moordyn", {}):
        lines.append(f"MoorDyn comparison skipped: {report['moordyn']['skipped']}")
    return lines


if __name__ == "__main__":
    print(json.dumps(_measure_level(sys.argv[1], int(sys.argv[2]), float(sys.argv[3]))))
