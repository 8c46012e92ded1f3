"""``dragline bench sensitivities``: a Jacobian from the scheme's tangent against finite differences, timed.

The Jacobian is the one the updating needs: every state of a run with
respect to each of the rig's toleranced parameters (the dragline's sixteen
on its dig). Its two ways, alternated in one process so that the machine's
drift falls on both alike:

- finite differences as the updating takes them today, one simulation per
  parameter, a hundredth of its tolerance away, started from the base run's
  equilibrium (``_differences``' ``FD_FRACTION`` and statics guess);
- ``simulate_sensitivities``: the base run, the assembly differenced, the
  statics and the trajectory differentiated, all parameters in one pass.

Both in one process on one core: the updating runs its differences in two
worker processes, so its wall time is half the first figure.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from dragline.simulate import apply_parameters, default_maneuver, load_rig, simulate, simulate_sensitivities

FD_FRACTION = 0.01  # of a tolerance, as the updating's differences


def bench_sensitivities(rig_name="dragline", duration=10.0, repeats=5, rate_hz=100.0):
    """Timings (s, medians of ``repeats``) and the two Jacobians' agreement, as a dict."""
    rig = load_rig(rig_name)
    maneuver = default_maneuver(rig)
    params = list(rig.tolerances)
    tol = np.array([p.tolerance for p in params])
    x0 = np.zeros(len(params))

    def build(x):
        return (*apply_parameters(rig, maneuver, params, x), ())

    def base():
        return simulate(*build(x0)[:2], duration=duration, rate_hz=rate_hz)

    def differences(result):
        columns = []
        for j in range(len(params)):
            x = x0.copy()
            x[j] += FD_FRACTION * tol[j]
            moved = simulate(*build(x)[:2], duration=duration, rate_hz=rate_hz, statics_guess=result.states[0])
            columns.append((moved.states - result.states) / (FD_FRACTION * tol[j]))
        return columns

    def tangents():
        return simulate_sensitivities(build, x0, tol, duration=duration, rate_hz=rate_hz)

    result = base()  # warm-up: compiles or loads both
    sens = tangents()
    walls = {"simulate": [], "finite_differences": [], "tangent": []}
    for _ in range(repeats):
        t = time.perf_counter()
        result = base()
        walls["simulate"].append(time.perf_counter() - t)
        t = time.perf_counter()
        fd = differences(result)
        walls["finite_differences"].append(time.perf_counter() - t)
        t = time.perf_counter()
        sens = tangents()
        walls["tangent"].append(time.perf_counter() - t)
    median = {k: statistics.median(v) for k, v in walls.items()}
    agreement = [float(np.linalg.norm(sens.tangents[..., j] - fd[j]) / np.linalg.norm(sens.tangents[..., j]))
                 for j in range(len(params))]
    return {
        "rig": rig_name,
        "duration_s": duration,
        "parameters": [p.name for p in params],
        "records": int(result.states.shape[0]),
        "verlet_steps": int(result.steps),
        "repeats": repeats,
        "simulate_s": median["simulate"],
        "finite_differences_s": median["finite_differences"],
        "tangent_s": median["tangent"],
        "tangent_in_simulations": median["tangent"] / median["simulate"],
        "finite_differences_over_tangent": median["finite_differences"] / median["tangent"],
        "timings_s": walls,
        "column_difference": dict(zip([p.name for p in params], agreement)),
        "note": "column_difference: |tangent - one-sided difference over 1 % of a tolerance| / |tangent| per "
                "parameter; the difference's own truncation and noise, not the tangent's error (that is "
                "tests/test_sensitivity.py's)",
    }


def summary_lines(report):
    """One line for the terminal."""
    return [f"sensitivities ({report['rig']}, {report['duration_s']:g} s, {len(report['parameters'])} parameters): "
            f"tangent {report['tangent_s']:.2f} s ({report['tangent_in_simulations']:.1f} simulations), "
            f"finite differences {report['finite_differences_s']:.2f} s, ratio "
            f"{report['finite_differences_over_tangent']:.2f} (median of {report['repeats']})"]
