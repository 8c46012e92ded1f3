"""The executors: local processes and a Dask cluster give the same results (issue 13).

The cluster is a real ``distributed.LocalCluster`` on the loopback (two
worker processes); the jobs are the diagnosis's own candidate simulations
(``_grid_job`` with the context every task reads), so what is compared is
what a diagnosis would get back. A whole diagnosis through Dask runs in
tests/test_diagnose.py (``aero_diagnosis``).
"""

import os

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
dask = pytest.importorskip("dask")  # distributed's own dependency: its configuration

from dragline.compare import DaskExecutor, ExecutorError, LocalExecutor, executor_from  # noqa: E402
from dragline.compare.diagnose._hypotheses import _grid_job, _init  # noqa: E402
from dragline.simulate import dig_maneuver, load_rig, simulate  # noqa: E402

CHANNELS = ["bucket.x", "bucket.z", "bucket.pitch", "hoist_cluster.x"]


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        with distributed.Client(c) as client:
            yield c, client


@pytest.fixture(scope="module")
def context():
    start = simulate(discretization="low", duration=0.02, rate_hz=50.0)
    return {"rig": load_rig(), "maneuver": dig_maneuver(), "discretization": "low", "duration": 0.6,
            "rate_hz": 50.0, "initial_state": start.states[0], "channels": CHANNELS,
            "time": np.linspace(0.0, 0.6, 31)}


JOBS = [("aero_drag", "cd", 0.0), ("aero_drag", "cd", 4.0), ("pulley_inertia", "inertia", 1e-3),
        ("pulley_friction", "mu", 0.05)]


def _results(executor, context):
    session = executor.open(_init, (context,))
    try:
        return session.map(_grid_job, JOBS)
    finally:
        session.close()


def test_dask_returns_what_local_processes_return(cluster, context):
    _, client = cluster
    local = _results(LocalExecutor(2), context)
    dask = _results(DaskExecutor(client=client), context)
    serial = _results(LocalExecutor(1), context)
    assert [(n, v) for n, v, *_ in dask] == [(n, v) for n, v, *_ in local] == [(n, v) for n, _, v in JOBS]
    for (_, _, a), (_, _, b), (_, _, c) in zip(local, dask, serial):
        assert a.shape == (31, len(CHANNELS))
        np.testing.assert_array_equal(a, b)  # the same machine code on the same inputs: bit for bit
        np.testing.assert_array_equal(a, c)
    assert not np.array_equal(local[0][2], local[1][2])  # the jobs differ, so the comparison can fail


def test_a_session_says_how_many_tasks_run_at_once(cluster, context):
    # The model updating fills a trial point's idle slots with Jacobian columns: the count must be right.
    _, client = cluster
    for executor, slots in ((LocalExecutor(1), 1), (LocalExecutor(2), min(2, os.cpu_count())),
                            (DaskExecutor(client=client), 2)):
        session = executor.open(_init, (context,))
        try:
            assert session.slots == slots
        finally:
            session.close()


def test_the_slot_count_holds_while_the_client_refreshes_its_cache(cluster, context):
    # The client's periodic refresh of its scheduler cache lists no workers; read back from that
    # cache, a cluster of two once read as one slot (a CI run failed on it). A fast refresh makes
    # that race frequent (about 1 read in 15 with the cache), so every read must still say 2.
    c, _ = cluster
    with dask.config.set({"distributed.client.scheduler-info-interval": "5ms"}), distributed.Client(c) as client:
        executor = DaskExecutor(client=client)
        session = executor.open(_init, (context,))
        try:
            assert [session.slots for _ in range(300)] == [2] * 300
            assert [executor.describe()["workers"] for _ in range(100)] == [2] * 100
        finally:
            session.close()


def test_the_executor_is_described(cluster):
    c, client = cluster
    assert LocalExecutor(3).describe() == {"kind": "local", "address": None, "workers": 3}
    assert DaskExecutor(client=client).describe() == {"kind": "dask", "address": c.scheduler_address, "workers": 2}


def test_executor_from_options_and_environment(monkeypatch, cluster):
    c, _ = cluster
    monkeypatch.delenv("DRAGLINE_SCHEDULER", raising=False)
    assert executor_from(3).describe()["kind"] == "local"
    assert executor_from(3, c.scheduler_address).address == c.scheduler_address
    monkeypatch.setenv("DRAGLINE_SCHEDULER", c.scheduler_address)
    assert executor_from(2).describe() == {"kind": "dask", "address": c.scheduler_address, "workers": 2}


def test_an_unreachable_scheduler_is_one_line(monkeypatch):
    with pytest.raises(ValueError, match=r"cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        DaskExecutor("tcp://127.0.0.1:9", timeout_s=2.0).describe()


def test_a_worker_lost_mid_run_has_its_tasks_run_elsewhere(context):
    """Kill one of two workers while the jobs run: the map still returns every result, equal to local."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        with distributed.Client(c) as client:
            session = DaskExecutor(client=client).open(_init, (context,))
            import threading

            def kill_one():
                import time

                time.sleep(3.0)  # the workers are busy with the first simulations by then
                pid = list(client.run(os.getpid).values())[0]
                os.kill(pid, 9)

            killer = threading.Thread(target=kill_one)
            killer.start()
            try:
                got = session.map(_grid_job, JOBS * 3)
            finally:
                killer.join()
                session.close()
    local = _results(LocalExecutor(1), context)
    for (_, _, a), (_, _, b) in zip(local * 3, got):
        np.testing.assert_array_equal(a, b)


def test_a_cluster_without_workers_stops_with_one_line(context, monkeypatch):
    import dragline.compare._executor as executor_module

    monkeypatch.setattr(executor_module, "NO_WORKER_S", 3.0)
    with distributed.LocalCluster(n_workers=0, processes=True, dashboard_address=":0") as c:
        with distributed.Client(c) as client:
            session = DaskExecutor(client=client).open(_init, (context,))
            with pytest.raises(ExecutorError, match=r"has had no worker for 3 s; 4 of 4 tasks left undone"):
                session.map(_grid_job, JOBS)


def _blas_threads(*_):
    from threadpoolctl import threadpool_info

    return max(lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas")


@pytest.mark.parametrize("workers", [1, 2])
def test_local_workers_and_their_parent_run_one_blas_thread_while_open(workers):
    # A pool: every core has a worker, so BLAS threads could only oversubscribe them. One worker runs in
    # this process, held alike: a diagnosis's own linear algebra the same whatever ``workers``.
    from threadpoolctl import threadpool_limits

    if workers > (os.cpu_count() or 1):
        pytest.skip("one core: the local executor runs in this process, without a pool")

    with threadpool_limits(2, user_api="blas"):  # as a 2-core machine starts
        session = LocalExecutor(workers).open(_blas_threads, ())
        try:
            inside = _blas_threads()
            tasks = session.map(_blas_threads, [(i,) for i in range(4)])
        finally:
            session.close()
        assert inside == 1 and tasks == [1, 1, 1, 1]
        assert _blas_threads() == 2  # given back when the session closes


def test_refining_searches_side_by_side_evaluate_what_one_per_worker_does(cluster, context):
    # Three searches on two workers: run as threads that hand single simulations to the pool, they
    # must evaluate exactly the points each search evaluates alone in one process.
    from dragline.compare.diagnose._hypotheses import _refine_job, _refine_searches, simulate_channels
    from dragline.compare.diagnose._problem import Problem

    _init(context)
    truth = simulate_channels("aero_drag", "cd", 2.0, context)
    sigma = np.array([1e-3, 1e-3, 1e-2, 1e-3])
    measured = truth + np.random.default_rng(3).normal(size=truth.shape) * sigma
    problem = Problem(context["time"], measured, sigma, t_stop=0.3)
    refine = [("aero_drag", "cd", 0.5, 4.0), ("pulley_friction", "mu", 0.01, 0.1),
              ("pulley_inertia", "inertia", 1e-4, 1e-3)]
    _init(dict(context, problem=problem))
    alone = [_refine_job(*job) for job in refine]
    _, client = cluster
    for executor in (LocalExecutor(2), DaskExecutor(client=client)):
        session = executor.open(_init, (dict(context, problem=problem),))
        try:
            assert session.slots == 2
            together = _refine_searches(session, problem, refine)
        finally:
            session.close()
        assert [name for name, _ in together] == [name for name, _ in alone]
        for (_, points), (_, expected) in zip(together, alone):
            assert [v for v, _ in points] == [v for v, _ in expected] and len(points) >= 3
            for (_, a), (_, b) in zip(points, expected):
                np.testing.assert_array_equal(a, b)
