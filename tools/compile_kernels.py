"""Compile the simulator's kernels into numba's on-disk cache before they are first needed.

A first simulation compiles the kernel (about 75 s on this project's
2-core machine) and a first sensitivity run the tangent (about 120 s
more); later processes load both from the cache. ``.ci/run`` runs this
beside ``dragline run``, whose own compile leaves the second core idle, so
that the test suite finds the tangent compiled instead of compiling it on
one of its two workers. Usage::

    python tools/compile_kernels.py
"""

from __future__ import annotations

import time

import numpy as np


def main():
    from dragline.simulate import apply_parameters, default_maneuver, load_rig, simulate_sensitivities

    start = time.perf_counter()
    rig = load_rig("pendulum")
    maneuver = default_maneuver(rig)
    params = [p for p in rig.tolerances if p.name == "bodies.ball.mass"]

    def build(x):
        return (*apply_parameters(rig, maneuver, params, x), ())

    # The plain run, its statics and the tangent's trajectory, statics and impulses: every entry point a
    # sensitivity run compiles.
    simulate_sensitivities(build, np.zeros(1), np.array([params[0].tolerance]), duration=0.05, rate_hz=100.0)
    print(f"kernels compiled or loaded in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
