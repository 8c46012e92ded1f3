"""``dragline bench simulate``: speed and accuracy of the simulator, measured.

Each discretization level runs in its own process (so its peak memory is its
own) after a warm-up run that loads or compiles the kernel; the compile time
itself is measured in a process with an empty numba cache.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile


LEVELS = ("low", "baseline", "medium", "high")

_LEVEL_SCRIPT = r"""
import json, resource, sys, time
import numpy as np
from dragline.simulate import assemble, dig_maneuver, load_rig, simulate
from dragline.simulate import _kernel
from dragline.simulate._statics import solve_statics
from dragline.simulate._time_step import start_time_step
from dragline.simulate._tracked import RK4, VERLET, integrate_tracked

level, repeats, duration = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
rig, man = load_rig(), dig_maneuver()
model = assemble(rig, man, level)
t = time.perf_counter(); eq = solve_statics(model); statics = [time.perf_counter() - t]
m = model.kernel_tuple(); work = _kernel.make_work(m)
out_dt = 1 / 200
n_rec = int(round(duration * 200))
methods = {"verlet": VERLET, "rk4": RK4}
def run(name):
    # what simulate() does after the statics: the step at the start, then the tracked run
    t = time.perf_counter()
    dt0, lam0 = start_time_step(model, eq.state, 0.0, integrator=name)
    chosen = time.perf_counter() - t
    rec, sub, status, _, _ = integrate_tracked(eq.state, 0.0, out_dt, n_rec, dt0, lam0, m, work, 100.0,
                                               50_000_000, methods[name])
    assert status == 0
    return time.perf_counter() - t, chosen, rec, sub
for name in methods:  # warm-up: loads the compiled kernel
    integrate_tracked(eq.state, 0.0, out_dt, 1, 1e-4, 1.0, m, work, 100.0, 50_000_000, methods[name])
walls = {name: [] for name in methods}
chosen, last = [], {}
for _ in range(repeats):  # alternating, so load on the machine falls on both alike
    for name in methods:
        wall, pick, rec, sub = run(name)
        walls[name].append(wall); chosen.append(pick); last[name] = (rec, sub)
for _ in range(max(0, repeats - 1)):
    t = time.perf_counter(); solve_statics(model); statics.append(time.perf_counter() - t)
calls = []
for _ in range(max(1, repeats // 2)):
    t = time.perf_counter(); simulate(rig, man, level, duration=duration); calls.append(time.perf_counter() - t)
smallest = min(out_dt / last[name][1].max() for name in methods)
per = int(np.ceil(out_dt / (smallest / 8)))
ref, _, status, _, _ = integrate_tracked(eq.state, 0.0, out_dt, n_rec, out_dt / per, np.inf, m, work, 100.0,
                                         50_000_000, VERLET)
rk4_fine, _, _, _, _ = integrate_tracked(eq.state, 0.0, out_dt, n_rec, out_dt / per, np.inf, m, work, 100.0,
                                         50_000_000, RK4)
def errors(rec):
    return (1e3 * float(np.max(np.linalg.norm(rec[:, 0:3] - ref[:, 0:3], axis=1))),
            float(np.degrees(np.max(np.abs(rec[:, 7] - ref[:, 7])))))
out = {"statics_s": float(np.median(statics)), "simulate_call_s": float(np.median(calls)),
       "step_selection_s": float(np.median(chosen)), "states": model.n_state,
       "reference": "Verlet at a fixed step of the smallest tracked step / 8",
       "reference_vs_rk4_same_step_mm": errors(rk4_fine)[0],
       "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}
for name in methods:
    rec, sub = last[name]
    pos, pitch = errors(rec)
    out[name] = {"wall_s": float(np.median(walls[name])), "wall_runs_s": walls[name],
                 "real_time_factor": duration / float(np.median(walls[name])),
                 "dt_start_s": out_dt / int(sub[0]), "dt_smallest_s": out_dt / int(sub.max()),
                 "steps": int(sub.sum()), "error_bucket_position_mm": pos, "error_bucket_pitch_deg": pitch}
out["wall_s"] = out["verlet"]["wall_s"]
out["rk4_over_verlet"] = out["rk4"]["wall_s"] / out["verlet"]["wall_s"]
print(json.dumps(out))
"""

_COLD_SCRIPT = r"""
import time
t = time.perf_counter()
from dragline.simulate import simulate
simulate(duration=0.05)
print(time.perf_counter() - t)
"""


def _python(script, *args, env=None):
    out = subprocess.run([sys.executable, "-c", script, *map(str, args)], capture_output=True, text=True, env=env, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"benchmark subprocess failed: {out.stderr.strip().splitlines()[-1] if out.stderr else out.returncode}")
    return out.stdout.strip().splitlines()[-1]


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
        cold = float(_python(_COLD_SCRIPT, env=env))
        warm = float(_python(_COLD_SCRIPT, env=env))
    report["compile"] = {
        "cold_first_call_s": cold,
        "warm_cache_first_call_s": warm,
        "compile_s": cold - warm,
        "note": "first 0.05 s simulation in a fresh process, empty vs filled numba cache",
    }
    for level in levels:
        report[level] = json.loads(_python(_LEVEL_SCRIPT, level, repeats, duration))
    if moordyn:
        try:
            from ._bench_moordyn import bench_moordyn
        except ImportError as exc:  # moordyn is an optional (bench) dependency
            report["moordyn"] = {"skipped": str(exc)}
        else:
            report["moordyn"] = bench_moordyn()
    return report


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
    return lines


