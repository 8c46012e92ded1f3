"""Where the fan-outs of simulations and cases run: local processes or a Dask cluster.

One small interface (``Executor.open(initializer, initargs)`` gives a session
whose ``map(fn, jobs, each=None)`` returns ``fn(*job)`` for every job, in
order, handing each result to ``each`` as it comes, and whose ``slots`` says
how many tasks run at once) serves
every place that fans out work: the diagnosis's candidate, sensitivity and
model-error simulations, and the discovery benchmark's cases. What a task
needs besides its job (the rig, the maneuver, the recording's channels: the
*context*) is sent once per session, not once per task: locally through the
pool's initializer, on Dask scattered to every worker.

- ``LocalExecutor(workers)``: forked processes on this machine, as before;
  one worker runs in this process.
- ``DaskExecutor(address)``: the ``dask.distributed`` scheduler at
  ``address`` (``tcp://host:8786``); workers need dragline installed and
  read nothing from this machine's disk. A worker lost mid-run has its
  tasks run again elsewhere (Dask's own retry); a cluster left without
  workers for ``NO_WORKER_S`` stops the run with one line, never a hang.

``executor_from(workers, scheduler)`` picks one: ``scheduler`` (the
``--scheduler`` option, else ``DRAGLINE_SCHEDULER``) means Dask.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor

from threadpoolctl import threadpool_limits

__all__ = ["Executor", "LocalExecutor", "DaskExecutor", "ExecutorError", "executor_from", "as_executor"]

# A Dask cluster without a single worker for this long stops the run (s).
NO_WORKER_S = 60.0
# How often the wait for Dask results looks at the cluster (s).
_POLL_S = 2.0


class ExecutorError(RuntimeError):
    """The cluster cannot run the work (no workers, unreachable scheduler): one line, exit code 1."""


class Executor:
    """Runs ``map(fn, jobs)`` somewhere; subclasses say where."""

    kind = "abstract"

    def open(self, initializer, initargs=()):
        """A session (``map``, ``close``, ``slots``) whose tasks find ``initializer(*initargs)`` done."""
        raise NotImplementedError

    def describe(self):
        """JSON-ready: ``{"kind", "address", "workers"}``."""
        raise NotImplementedError

    def limited(self, workers):
        """The same executor with at most ``workers`` parallel tasks where that means anything."""
        return self


def _collect(results, each):
    """The results in order, each handed to ``each`` as it comes (progress lines)."""
    out = []
    for result in results:
        out.append(result)
        if each is not None:
            each(result)
    return out


class _Serial:
    """The tasks run in this process, with one BLAS thread while the session is open, as a pool's parent
    and workers run: a diagnosis's own linear algebra then runs as it does under a pool. (Case 94551 of
    the trusted-verdict set, run alone with the BLAS threaded throughout, ended its updating at chi2
    7.35e6 instead of 7.22e6 and read "unexplained" instead of "none"; held to one thread it followed the
    set's path.)"""

    slots = 1

    def __init__(self, initializer, initargs):
        self._blas = threadpool_limits(1)
        try:
            initializer(*initargs)
        except BaseException:
            self._blas.restore_original_limits()  # no close() will come
            raise

    def map(self, fn, jobs, each=None):
        return _collect((fn(*job) for job in jobs), each)

    def close(self):
        self._blas.restore_original_limits()


def _one_blas_thread_then(initializer, *initargs):
    threadpool_limits(1)  # for the worker's life
    initializer(*initargs)


class _LocalPool:
    """Worker processes, one per core asked for, each with one BLAS thread.

    Every core has a worker, so BLAS threads (the parent's fits, a worker's
    statics) could only oversubscribe them: the parent runs with one thread
    too while the pool is open. (With one BLAS thread everywhere,
    ``OPENBLAS_NUM_THREADS=1``, the session ``dragline run`` makes was
    diagnosed in 72.7 and 74.0 s against 75.9 and 76.9 s, alternated, the
    same verdict and fit; 2026-11-26, two cores.)
    """

    def __init__(self, workers, initializer, initargs):
        self._blas = threadpool_limits(1)
        try:
            initializer(*initargs)  # the parent evaluates too (the serial parts of a fit)
            self.slots = workers
            method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
            self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(method),
                                             initializer=_one_blas_thread_then, initargs=(initializer, *initargs))
        except BaseException:
            self._blas.restore_original_limits()  # no close() will come
            raise

    def map(self, fn, jobs, each=None):
        return _collect(self._pool.map(fn, *zip(*jobs)), each) if jobs else []

    def close(self):
        try:
            self._pool.shutdown()
        finally:
            self._blas.restore_original_limits()


class LocalExecutor(Executor):
    """Forked processes on this machine (``workers`` at once; 1 = in this process)."""

    kind = "local"

    def __init__(self, workers=2):
        self.workers = max(1, int(workers))

    def open(self, initializer, initargs=()):
        workers = min(self.workers, os.cpu_count() or 1)
        return _Serial(initializer, initargs) if workers <= 1 else _LocalPool(workers, initializer, initargs)

    def limited(self, workers):
        return LocalExecutor(min(self.workers, max(1, int(workers))))

    def describe(self):
        return {"kind": "local", "address": None, "workers": self.workers}


# Per Dask worker process: the key of the context it last initialised from.
_WORKER_CONTEXT = {"key": None}


def _identity(value):
    return value


def _dask_task(initializer, key, initargs, fn, job):
    if _WORKER_CONTEXT["key"] != key:
        initializer(*initargs)
        _WORKER_CONTEXT["key"] = key
    return fn(*job)


def _cluster_size(client):
    """(workers, threads) the scheduler has now.

    Asked of the scheduler itself: ``client.scheduler_info()`` returns a cache that the client's
    periodic update may overwrite, between the fetch and the return, with a reply that lists no
    workers, which read as a cluster of one slot.
    """
    info = client.sync(client.scheduler.identity)
    workers = info.get("workers", {})
    return (int(info.get("n_workers", len(workers))),
            int(info.get("total_threads", sum(int(w.get("nthreads", 1)) for w in workers.values()))))


class _DaskSession:
    def __init__(self, client, address, initializer, initargs):
        self._client = client
        self._address = address
        initializer(*initargs)
        self._initializer = initializer
        # The context travels once, as a task of its own: every task depends on it, and if the
        # workers holding it are lost, the scheduler runs it again (scattered data would be gone).
        self._initargs = client.submit(_identity, tuple(initargs), pure=False)
        self._key = f"ctx-{id(self)}-{time.monotonic_ns()}"

    @property
    def slots(self):
        """Tasks the cluster runs at once now (its workers' threads, at least 1)."""
        return max(1, _cluster_size(self._client)[1])

    def map(self, fn, jobs, each=None):
        futures = [self._client.submit(_dask_task, self._initializer, self._key, self._initargs, fn, tuple(job),
                                       pure=False) for job in jobs]
        from distributed import KilledWorker  # noqa: PLC0415

        try:
            for future in futures:
                self._wait(future, futures)
            return _collect((future.result() for future in futures), each)
        except KilledWorker as exc:
            self._client.cancel(futures)
            raise ExecutorError(f"Dask task {exc.task} was running on {exc.allowed_failures + 1} workers that "
                                "died under it; the run stops rather than lose more (out of memory on the "
                                "workers?)") from None
        except BaseException:
            self._client.cancel(futures)
            raise

    def _wait(self, future, futures):
        """Until ``future`` is done; a cluster without workers for NO_WORKER_S ends the wait."""
        from distributed import wait  # noqa: PLC0415 - Dask is an optional extra

        alone_since = None
        while True:
            try:
                wait([future], timeout=_POLL_S)
                return
            except TimeoutError:  # not done yet: is anyone still working on it?
                pass
            if _cluster_size(self._client)[0]:
                alone_since = None
            elif alone_since is None:
                alone_since = time.monotonic()
            elif time.monotonic() - alone_since > NO_WORKER_S:
                left = sum(not f.done() for f in futures)
                raise ExecutorError(f"the Dask cluster at {self._address} has had no worker for "
                                    f"{NO_WORKER_S:.0f} s; {left} of {len(futures)} tasks left undone")

    def close(self):
        self._client.cancel([self._initargs])


class DaskExecutor(Executor):
    """The ``dask.distributed`` scheduler at ``address`` (or an existing ``client``)."""

    kind = "dask"

    def __init__(self, address=None, client=None, timeout_s=30.0):
        if address is None and client is None:
            raise ValueError("a Dask executor needs a scheduler address")
        self.address = address if client is None else client.scheduler.address
        self._client = client
        self._timeout_s = timeout_s

    @property
    def client(self):
        if self._client is None:
            try:
                from distributed import Client  # noqa: PLC0415
            except ImportError:
                raise ValueError("--scheduler needs Dask: pip install 'dragline[dask]'") from None
            try:
                self._client = Client(self.address, timeout=self._timeout_s)
            except (OSError, TimeoutError) as exc:
                raise ValueError(f"cannot reach the Dask scheduler at {self.address}: "
                                 f"{' '.join(str(exc).split())[:120]}") from None
        return self._client

    def open(self, initializer, initargs=()):
        return _DaskSession(self.client, self.address, initializer, initargs)

    def describe(self):
        return {"kind": "dask", "address": self.address,
                "workers": _cluster_size(self.client)[0]}


def executor_from(workers=2, scheduler=None):
    """``DaskExecutor(scheduler)`` when a scheduler is given (or ``DRAGLINE_SCHEDULER`` is set), else local."""
    scheduler = scheduler or os.environ.get("DRAGLINE_SCHEDULER") or None
    return DaskExecutor(scheduler) if scheduler else LocalExecutor(workers)


def as_executor(workers):
    """An ``Executor`` as given, or a ``LocalExecutor`` of ``workers`` processes."""
    return workers if isinstance(workers, Executor) else LocalExecutor(workers)
