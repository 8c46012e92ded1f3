"""Numba's cache keyed on the sources (simulate/_numba_cache.py): an edit to a called file is never run stale.

Each case runs in a fresh interpreter: numba picks a function's cache
folder once, when the function is decorated.
"""

import os
import subprocess
import sys
import textwrap
import time

from dragline.simulate import _numba_cache
from dragline.simulate._numba_cache import source_key

# The module is loaded from its file: importing it through ``dragline.simulate``
# would key numba's (process-wide) cache on the simulator's sources first.
INIT = """
import importlib.util
from pathlib import Path
spec = importlib.util.spec_from_file_location("numba_cache", {module!r})
numba_cache = importlib.util.module_from_spec(spec)
spec.loader.exec_module(numba_cache)
FOLDER = numba_cache.use_source_keyed_cache(Path(__file__).parent)
"""
CALLER = """
from numba import njit
from .callee import step

@njit(cache=True)
def run(x):
    return step(x)
"""
CALLEE = """
from numba import njit

@njit(cache=True)
def step(x):
    return x + {increment}
"""


def _package(root, increment):
    pkg = root / "kernelpkg"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text(INIT.format(module=_numba_cache.__file__))
    (pkg / "caller.py").write_text(CALLER)
    (pkg / "callee.py").write_text(CALLEE.format(increment=increment))
    return pkg


def _python(root, code, **env):
    environ = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    environ.update(PYTHONPATH=str(root), **env)
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                         env=environ, check=True)
    return out.stdout.strip()


def test_a_change_to_a_called_file_is_compiled_again_not_loaded_stale(tmp_path):
    # numba alone would load caller.run's cached code, with the old step
    # inlined, since caller.py did not change (numba issue #1833).
    _package(tmp_path, 1)
    code = "import kernelpkg.caller as c; print(c.run(1))"
    assert _python(tmp_path, code) == "2"
    assert _python(tmp_path, code) == "2"  # from the cache
    _package(tmp_path, 2)
    assert _python(tmp_path, code) == "3"
    folders = sorted(p.name for p in (tmp_path / "kernelpkg" / "__pycache__").glob("numba-*"))
    assert len(folders) == 2 and f"numba-{source_key(tmp_path / 'kernelpkg')}" in folders


def test_the_users_cache_folder_is_left_as_chosen(tmp_path):
    _package(tmp_path, 1)
    chosen = tmp_path / "mine"
    out = _python(tmp_path, "import kernelpkg, numba; print(kernelpkg.FOLDER, numba.config.CACHE_DIR)",
                  NUMBA_CACHE_DIR=str(chosen))
    assert out == f"None {chosen}"


def test_caches_of_other_sources_are_removed_after_a_day(tmp_path):
    pkg = _package(tmp_path, 1)
    old, recent = pkg / "__pycache__" / "numba-0000000000000000", pkg / "__pycache__" / "numba-1111111111111111"
    old.mkdir(parents=True)
    recent.mkdir()
    two_days_ago = time.time() - 2 * 86400
    os.utime(old, (two_days_ago, two_days_ago))
    _python(tmp_path, "import kernelpkg")
    assert not old.exists() and recent.exists()


def test_the_key_follows_names_and_contents(tmp_path):
    pkg = _package(tmp_path, 1)
    key = source_key(pkg)
    assert source_key(pkg) == key
    (pkg / "callee.py").write_text(CALLEE.format(increment=1) + "\n")
    assert source_key(pkg) != key
    (pkg / "callee.py").write_text(CALLEE.format(increment=1))
    assert source_key(pkg) == key
    (pkg / "callee.py").rename(pkg / "other.py")
    assert source_key(pkg) != key
