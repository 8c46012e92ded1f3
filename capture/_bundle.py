"""Sparse Levenberg-Marquardt for the bundle adjustment, with a soft-L1 loss.

The adjustment's normal matrix has a known shape: a dense block for the
cameras and the L-frame (under a hundred unknowns), one 5 x 5 block per wand
frame, and the coupling between them. scipy's trust-region solver with
LSMR steps cannot use that shape: the problem is ill-conditioned (focal
length against distance), so each step took about 900 LSMR iterations and
the calibration of a 600-frame session 4.9 s. Here each step solves the
damped normal equations directly (a sparse LU factorisation, whose fill
stays in the camera block), a few milliseconds.

- Jacobian: forward differences, the columns that share no residual moved
  together (greedy colouring of the sparsity pattern: about twenty
  residual evaluations for two thousand unknowns).
- Loss: soft-L1, ``rho(z) = 2 (sqrt(1 + z) - 1)`` of ``z = (r / f_scale)^2``,
  as scipy's ``least_squares(loss="soft_l1")``; minimised by iteratively
  reweighted Gauss-Newton (weights ``rho'(z)``), whose fixed point is the
  robust cost's stationary point.
- Damping: Marquardt's (the normal matrix's diagonal), the multiplier
  divided by 3 after a step that lowers the cost and multiplied by 4 after
  one that does not (Nielsen's rule without its gain ratio).
- Stops when a step lowers the cost by less than ``ftol`` of it, moves x by
  less than ``xtol`` (relative), or after ``max_iter`` Jacobians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csc_matrix, diags
from scipy.sparse.linalg import spsolve

__all__ = ["BundleResult", "column_groups", "sparse_jacobian", "levenberg_marquardt", "BlockArrowSolver"]

_EPS = np.finfo(float).eps
# The damping multiplier's range: below, Gauss-Newton; above, the step is nil.
_LAMBDA_MIN, _LAMBDA_MAX = 1e-12, 1e12


@dataclass
class BundleResult:
    """``x``: the solution; ``cost``: its robust cost; ``njev``, ``nfev``: Jacobians and residual evaluations."""

    x: np.ndarray
    cost: float
    njev: int
    nfev: int


def column_groups(sparsity):
    """Colour the columns so that no two of one colour share a row.

    Parameters
    ----------
    sparsity : scipy.sparse matrix (m, n)
        Nonzero where a residual depends on an unknown.

    Returns
    -------
    ndarray (n,) of int
        Each column's group; a residual evaluation per group gives a Jacobian.
    """
    S = csc_matrix(sparsity)
    m, n = S.shape
    # Per row, a bit per group some column touching it already belongs to (first fit: the lowest free
    # group), 64 groups to a word.
    taken = np.zeros((m, 1), dtype=np.uint64)
    group = np.empty(n, dtype=int)
    for j in range(n):
        rows = S.indices[S.indptr[j]:S.indptr[j + 1]]
        used = np.bitwise_or.reduce(taken[rows], axis=0) if rows.size else np.zeros(taken.shape[1], np.uint64)
        free = ~used
        word = int(np.argmax(free != 0)) if free.any() else taken.shape[1]
        if word == taken.shape[1]:
            taken = np.hstack([taken, np.zeros((m, 1), dtype=np.uint64)])
            bit = 0
        else:
            low = int(free[word])
            bit = (low & -low).bit_length() - 1
        taken[rows, word] |= np.uint64(1 << bit)
        group[j] = 64 * word + bit
    return group


def sparse_jacobian(fun, x, f0, sparsity, groups):
    """Forward-difference Jacobian on the sparsity pattern, one residual evaluation per column group.

    Parameters
    ----------
    fun : callable
        Residuals, (m,) from x (n,).
    x, f0 : ndarray
        Where, and ``fun(x)``.
    sparsity : scipy.sparse matrix (m, n)
    groups : ndarray (n,)
        From :func:`column_groups`.

    Returns
    -------
    scipy.sparse.csc_matrix (m, n)
    """
    S = csc_matrix(sparsity)
    if not S.has_sorted_indices:
        S = S.sorted_indices()  # a copy: the caller's matrix stays as given
    h = np.sqrt(_EPS) * np.maximum(1.0, np.abs(x))
    cols = np.repeat(np.arange(S.shape[1]), np.diff(S.indptr))
    data = np.empty(S.indices.size)
    for g in range(int(groups.max()) + 1 if groups.size else 0):
        moved = groups == g
        xp = x.copy()
        xp[moved] += h[moved]
        step = xp - x  # the step actually taken, after rounding
        diff = fun(xp) - f0
        here = moved[cols]
        data[here] = diff[S.indices[here]] / step[cols[here]]
    return csc_matrix((data, S.indices, S.indptr), shape=S.shape)


def _soft_l1_cost(f, f_scale):
    z = (f / f_scale) ** 2
    return float(f_scale**2 * np.sum(np.sqrt(1.0 + z) - 1.0))  # 0.5 f_scale^2 sum rho(z)


class BlockArrowSolver:
    """Solves ``(A + diag(shift)) x = b`` for normal matrices whose local unknowns form diagonal blocks.

    The unknowns ``start`` to ``stop`` are consecutive blocks of ``size``
    that share no residual with one another (a wand frame's); every other
    unknown is global (cameras, L-frame). Eliminating the blocks leaves the
    global unknowns' Schur complement, dense and small.

    Parameters
    ----------
    sparsity : scipy.sparse matrix (m, n)
        The Jacobian's pattern: no residual may touch two blocks.
    start, stop, size : int

    Raises
    ------
    ValueError
        Some residual touches two blocks.
    """

    def __init__(self, sparsity, start, stop, size):
        n = sparsity.shape[1]
        if not (0 <= start <= stop <= n and (stop - start) % size == 0):
            raise ValueError(f"blocks of {size} from {start} to {stop} do not tile {n} unknowns")
        pattern = csc_matrix(sparsity, dtype=float)
        local = pattern[:, start:stop]
        touched = (local.T @ local).tocoo()
        if np.any(touched.row // size != touched.col // size):
            raise ValueError("a residual touches two blocks: the normal matrix is not block-diagonal there")
        self.size = size
        self.local = np.arange(start, stop)
        self.shared = np.r_[np.arange(start), np.arange(stop, n)]

    def split(self, A):
        """The parts of ``A`` (sparse (n, n), symmetric) a solve reads: ``(A_cc, A_pc, blocks)``, dense.

        Taken once per matrix: a damped step that fails is solved again with
        more damping on the same matrix.
        """
        A = csc_matrix(A)
        p, c, k = self.local, self.shared, self.size
        nb = p.size // k
        App = A[p][:, p].tocoo()
        blocks = np.zeros((nb, k, k))
        blocks[App.row // k, App.row % k, App.col % k] = App.data
        return A[c][:, c].toarray(), A[p][:, c].toarray().reshape(nb, k, c.size), blocks

    def solve(self, A, shift, b, parts=None):
        """``x`` (n,) with ``(A + diag(shift)) x = b``; ``parts``: ``split(A)`` when already taken.

        A singular system gives NaN, as a failed step (the damping then grows).
        """
        Acc, Apc, blocks = self.split(A) if parts is None else parts
        p, c, k = self.local, self.shared, self.size
        nb = p.size // k
        blocks = blocks.copy()
        blocks[:, np.arange(k), np.arange(k)] += shift[p].reshape(nb, k)
        x = np.full(b.size, np.nan)
        try:
            # Each block's solve against its coupling columns and its right-hand side at once.
            both = np.linalg.solve(blocks, np.concatenate([Apc, b[p].reshape(nb, k, 1)], axis=2))
            Y, z = both[:, :, :-1].reshape(p.size, c.size), both[:, :, -1].ravel()
            Apc = Apc.reshape(p.size, c.size)
            xc = np.linalg.solve(Acc + np.diag(shift[c]) - Apc.T @ Y, b[c] - Apc.T @ z)
        except np.linalg.LinAlgError:
            return x
        x[c] = xc
        x[p] = z - Y @ xc
        return x


def levenberg_marquardt(fun, x0, sparsity, f_scale, ftol=1e-8, xtol=1e-10, max_iter=100, blocks=None):
    """Minimise the soft-L1 cost of ``fun``'s residuals by damped, reweighted Gauss-Newton.

    Parameters
    ----------
    fun : callable
        Residuals (m,) of the unknowns (n,).
    x0 : ndarray (n,)
    sparsity : scipy.sparse matrix (m, n)
        Which residuals each unknown moves.
    f_scale : float
        The loss's soft margin, in the residuals' unit (px).
    ftol, xtol : float
        Relative decrease of the cost, and relative step, below which it stops.
    max_iter : int
        Most Jacobians.
    blocks : (start, stop, size), optional
        Unknowns that form independent blocks (``BlockArrowSolver``): the
        steps are solved by their Schur complement.

    Returns
    -------
    BundleResult
    """
    sparsity = csc_matrix(sparsity).sorted_indices()  # once: each Jacobian reads it by columns
    arrow = BlockArrowSolver(sparsity, *blocks) if blocks is not None else None
    groups = column_groups(sparsity)
    n_groups = int(groups.max()) + 1 if groups.size else 0
    x = np.asarray(x0, float).copy()
    f = fun(x)
    cost = _soft_l1_cost(f, f_scale)
    nfev, njev, lam = 1, 0, 1e-3
    while njev < max_iter:
        J = sparse_jacobian(fun, x, f, sparsity, groups)
        nfev += n_groups
        njev += 1
        w = 1.0 / np.sqrt(1.0 + (f / f_scale) ** 2)
        Jw = diags(w) @ J
        A = (J.T @ Jw).tocsc()
        g = Jw.T @ f
        d = np.maximum(A.diagonal(), 1e-12 * max(A.diagonal().max(), 1.0))
        parts = arrow.split(A) if arrow is not None else None
        while True:
            dx = (arrow.solve(A, lam * d, -g, parts) if arrow is not None
                  else spsolve(A + diags(lam * d, format="csc"), -g))
            x_new = x + dx
            f_new = fun(x_new)
            nfev += 1
            cost_new = _soft_l1_cost(f_new, f_scale) if np.all(np.isfinite(f_new)) else np.inf
            if cost_new < cost:
                lam = max(lam / 3.0, _LAMBDA_MIN)
                break
            lam *= 4.0
            if lam > _LAMBDA_MAX:
                return BundleResult(x, cost, njev, nfev)
        gain = cost - cost_new
        small_step = np.linalg.norm(dx) < xtol * (xtol + np.linalg.norm(x))
        x, f, cost = x_new, f_new, cost_new
        if gain < ftol * (cost + gain) or small_step:
            break
    return BundleResult(x, cost, njev, nfev)
