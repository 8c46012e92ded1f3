"""One BLAS thread for the simulator's small dense work, at the cost of a function call.

The statics and the start step run LAPACK on matrices of a few hundred rows,
often in the diagnosis's parallel worker processes on a small machine, where
many-threaded BLAS took ten to twenty times longer. ``threadpoolctl``'s
``threadpool_limits`` finds the loaded BLAS libraries again at every use
(1-2.5 ms, twice in every simulation); one controller, made on first use, is
kept instead (0.03 ms a use).
"""

from __future__ import annotations

from threadpoolctl import ThreadpoolController

__all__ = ["one_blas_thread"]

_CONTROLLER = []


def one_blas_thread():
    """A context manager under which every BLAS library loaded so far uses one thread."""
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1)
