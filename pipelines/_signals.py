"""SIGTERM, SIGHUP and SIGINT end a command the way Ctrl-C in a terminal does.

A job scheduler or ``timeout`` sends SIGTERM to the command's process alone,
not to its process group as a terminal's Ctrl-C does; the simulation workers
the diagnosis and the benchmarks fork would then run on, orphaned, and the
command's ``finally`` blocks (which remove partial outputs) would never run.
So each of these signals, in the command's own process:

1. stops its worker processes (SIGTERM, which a forked worker, having
   inherited this handler, passes on to its own workers before it exits;
   SIGKILL for any still alive after a grace period), then
2. raises :class:`Terminated`, a ``KeyboardInterrupt``, so that every
   ``finally`` and every ``except KeyboardInterrupt`` runs exactly as for
   Ctrl-C; ``cli.main`` turns it into one line and exit code 128 + signal.

A forked worker leaves with ``os._exit``: what it holds is in memory, and
the command's process owns and removes every file.

Stopping a process pool's workers races with the pool's own manager thread
(CPython 3.11): the main thread, unwinding, cancels the futures still
queued while the manager thread, seeing the workers gone, sets an error on
each, and one already cancelled raises ``InvalidStateError`` there. Its
traceback would print above the one line; after a signal that one error,
from that thread, is not reported.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from concurrent.futures import InvalidStateError

__all__ = ["Terminated", "handle_termination"]

SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP", "SIGINT") if hasattr(signal, name))
# Time a worker gets to stop its own workers and exit before SIGKILL (s).
GRACE_S = 3.0

_owner_pid = None


class Terminated(KeyboardInterrupt):
    """The command was asked to stop by a signal (``signum``)."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @property
    def exit_code(self):
        return 128 + self.signum


def _stop_workers():
    children = multiprocessing.active_children()
    for child in children:
        try:
            child.terminate()
        except (OSError, AttributeError):
            pass
    deadline = time.monotonic() + GRACE_S
    for child in children:
        child.join(max(0.0, deadline - time.monotonic()))
        if child.is_alive():
            child.kill()
            child.join(1.0)


def _quiet_pool_race(previous):
    def hook(args):
        if issubclass(args.exc_type, InvalidStateError) and type(args.thread).__name__ == "_ExecutorManagerThread":
            return
        previous(args)
    return hook


def _on_signal(signum, frame):
    # One stop is enough: a second signal during the clean-up must not cut it short.
    for s in SIGNALS:
        signal.signal(s, signal.SIG_IGN)
    if os.getpid() == _owner_pid:
        threading.excepthook = _quiet_pool_race(threading.excepthook)
    _stop_workers()
    if os.getpid() != _owner_pid:
        os._exit(128 + signum)
    raise Terminated(signum)


class handle_termination:
    """Context manager: the signals above stop the command cleanly while inside.

    The previous handlers come back on exit (``cli.main`` is also called
    in-process, by tests and by the fuzzer's fork server).
    """

    def __enter__(self):
        global _owner_pid
        self._saved = {}
        self._excepthook = threading.excepthook
        self._owner = _owner_pid
        _owner_pid = os.getpid()
        try:
            for s in SIGNALS:
                self._saved[s] = signal.signal(s, _on_signal)
        except ValueError:  # not the main thread: leave signals to whoever owns them
            self._restore()
        return self

    def _restore(self):
        for s, handler in self._saved.items():
            signal.signal(s, handler)
        self._saved = {}

    def __exit__(self, *exc):
        global _owner_pid
        self._restore()
        threading.excepthook = self._excepthook
        _owner_pid = self._owner
        return False
