"""Scheduling cost of the executors: the same simulations locally and on Dask.

Maps ``--tasks`` simulations of the dig maneuver (baseline discretization,
``--duration`` s from the nominal equilibrium, what one candidate simulation
of a diagnosis is) through ``LocalExecutor`` and a loopback Dask
``LocalCluster`` at 1 and 2 workers, ``--repeats`` times each, and prints
JSON: per executor the median wall time, tasks per hour, and the overhead
per task against the local executor with as many workers (wall difference
divided by tasks, and as a fraction of one task's time).

    python benchmarks/bench_executor.py --tasks 8 --repeats 3 --json executor.json

Only the package's public interface is used.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from dragline.capture import write_json
from dragline.compare import DaskExecutor, LocalExecutor
from dragline.simulate import simulate

_CTX = {}


def _set_context(ctx):
    _CTX.clear()
    _CTX.update(ctx)


def _task(k):
    r = simulate(duration=_CTX["duration"], rate_hz=100.0, initial_state=_CTX["initial_state"])
    return k, float(np.abs(r.states[-1]).sum())


def _timed(executor, ctx, tasks):
    session = executor.open(_set_context, (ctx,))
    try:
        started = time.perf_counter()
        results = session.map(_task, [(k,) for k in range(tasks)])
        return time.perf_counter() - started, results
    finally:
        session.close()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", type=int, default=8)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--duration", type=float, default=10.0)
    p.add_argument("--json", metavar="FILE")
    args = p.parse_args(argv)
    from distributed import Client, LocalCluster

    ctx = {"duration": args.duration, "initial_state": simulate(duration=0.01, rate_hz=100.0).states[0]}
    one = [_timed(LocalExecutor(1), ctx, 1)[0] for _ in range(args.repeats)]  # also compiles and warms caches
    report = {"tasks": args.tasks, "duration_s": args.duration, "task_s": statistics.median(one), "executors": {}}
    reference = None
    for workers in (1, 2):
        local = [_timed(LocalExecutor(workers), ctx, args.tasks) for _ in range(args.repeats)]
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0") as c, \
                Client(c) as client:
            _timed(DaskExecutor(client=client), ctx, workers)  # workers load the code once
            dask = [_timed(DaskExecutor(client=client), ctx, args.tasks) for _ in range(args.repeats)]
        reference = reference or local[0][1]
        assert all(r == reference for _, r in local + dask), "executors disagree"
        for name, runs in ((f"local_{workers}", local), (f"dask_{workers}", dask)):
            wall = statistics.median(t for t, _ in runs)
            report["executors"][name] = {"wall_s": wall, "runs_s": [t for t, _ in runs],
                                         "tasks_per_hour": 3600.0 * args.tasks / wall}
        extra = (report["executors"][f"dask_{workers}"]["wall_s"] - report["executors"][f"local_{workers}"]["wall_s"])
        report["executors"][f"dask_{workers}"]["overhead_per_task_s"] = extra / args.tasks
        report["executors"][f"dask_{workers}"]["overhead_fraction"] = extra / args.tasks / report["task_s"]
    print(json.dumps(report, indent=1))
    if args.json:
        write_json(args.json, report)


if __name__ == "__main__":
    main()
