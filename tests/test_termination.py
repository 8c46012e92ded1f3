"""SIGTERM, SIGHUP and SIGINT sent to the command alone (as a job scheduler or
``timeout`` does) stop it like Ctrl-C: workers stopped, partial outputs
removed, one line, exit code 128 + signal."""

import os
import signal
import subprocess
import sys
import time

import pytest

EXE = os.path.join(os.path.dirname(sys.executable), "dragline")


def _children(pid):
    """Every live process whose parent is ``pid`` (read from /proc)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            found.append(int(entry))
    return found


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _start(argv, tmp_path):
    env = dict(os.environ, TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    return subprocess.Popen([EXE, *argv], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)


def _wait_for(condition, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.2)
    return False


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads process parents from /proc")
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_to_the_command_alone_stops_its_workers(tmp_path, signum):
    proc = _start(["bench", "discovery", "--quick", "--workers", "2", "--json", "bench.json"], tmp_path)
    try:
        assert _wait_for(lambda: len(_children(proc.pid)) >= 2, 60), "the benchmark started no workers"
        workers = _children(proc.pid)
        grandchildren = [g for w in workers for g in _children(w)]
        proc.send_signal(signum)
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    stderr = proc.stderr.read()
    assert code == 128 + signum
    assert stderr.count("\n") == 1 and signal.Signals(signum).name in stderr, stderr
    assert "Traceback" not in stderr
    assert _wait_for(lambda: not any(_alive(p) for p in workers + grandchildren), 10), "a worker outlived the command"
    assert not (tmp_path / "bench.json").exists()
    assert os.listdir(tmp_path / "tmp") == []  # the cases' work folder is gone too


def test_sigterm_during_run_leaves_no_partial_folder(tmp_path):
    proc = _start(["run", "--out", "result", "--quiet"], tmp_path)
    try:
        assert _wait_for(lambda: any(p.startswith(".result.partial-") for p in os.listdir(tmp_path)), 60)
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    stderr = proc.stderr.read()
    assert code == 143, stderr
    assert "SIGTERM" in stderr and stderr.count("\n") == 1
    assert sorted(os.listdir(tmp_path)) == ["tmp"]


def test_only_the_pool_managers_cancelled_future_race_is_kept_quiet():
    # The one error a process pool's manager thread raises when the workers it watched were stopped
    # while the main thread cancelled their futures (CPython 3.11) is not printed; anything else is.
    import concurrent.futures.process as pool
    import threading
    from concurrent.futures import InvalidStateError

    from dragline.pipelines._signals import _quiet_pool_race

    seen = []
    hook = _quiet_pool_race(seen.append)

    class Args:
        def __init__(self, exc_type, thread):
            self.exc_type, self.thread = exc_type, thread

    manager = pool._ExecutorManagerThread.__new__(pool._ExecutorManagerThread)
    other = threading.Thread()
    hook(Args(InvalidStateError, manager))
    assert seen == []
    for args in (Args(InvalidStateError, other), Args(RuntimeError, manager)):
        hook(args)
    assert len(seen) == 2
