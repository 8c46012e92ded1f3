"""The bundle adjustment's solver (capture._bundle) against scipy's, on problems of the same shape.

The test problem has the adjustment's structure: a few shared unknowns
(a "camera": gain, offset and a quadratic term) and many local ones (each
"frame" has its own two unknowns), each residual touching the shared ones
and one frame's. scipy's dense trust-region solver is the independent
reference for where the soft-L1 minimum lies.
"""

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from dragline.capture._bundle import BlockArrowSolver, column_groups, levenberg_marquardt, sparse_jacobian

N_FRAMES, PER_FRAME = 40, 6


def _problem(outliers, seed=3):
    rng = np.random.default_rng(seed)
    shared = np.array([1.3, -0.4, 0.2])
    # Away from a = pi/2, where sin(a + b u) = cos(b u) would not tell b from -b.
    local = np.column_stack([rng.uniform(-0.5, 0.5, N_FRAMES), rng.uniform(0.5, 1.5, N_FRAMES)])
    u = rng.uniform(-1, 1, size=(N_FRAMES, PER_FRAME))

    def model(x):
        g, o, q = x[:3]
        a, b = x[3:].reshape(N_FRAMES, 2).T
        return g * np.sin(a[:, None] + b[:, None] * u) + o + q * u**2

    data = model(np.r_[shared, local.ravel()]) + 0.01 * rng.normal(size=u.shape)
    if outliers:
        # One wild reading in each of the first frames, as a mislabelled marker would give.
        frames = np.arange(outliers)
        data[frames, rng.integers(0, PER_FRAME, outliers)] += rng.choice([-1, 1], outliers) * 2.0

    def residuals(x):
        return (model(x) - data).ravel()

    sparsity = lil_matrix((N_FRAMES * PER_FRAME, 3 + 2 * N_FRAMES), dtype=np.int8)
    for f in range(N_FRAMES):
        rows = slice(f * PER_FRAME, (f + 1) * PER_FRAME)
        sparsity[rows, :3] = 1
        sparsity[rows, 3 + 2 * f: 5 + 2 * f] = 1
    x0 = np.r_[shared + [0.2, 0.1, -0.1], (local + 0.15 * rng.normal(size=local.shape)).ravel()]
    return residuals, sparsity.tocsr(), x0


def test_groups_share_no_residual_and_are_few():
    _, sparsity, _ = _problem(0)
    groups = column_groups(sparsity)
    S = sparsity.tocsc()
    for g in np.unique(groups):
        rows = np.concatenate([S.indices[S.indptr[j]:S.indptr[j + 1]] for j in np.flatnonzero(groups == g)])
        assert len(rows) == len(np.unique(rows))
    # Three shared columns touch every row; each frame's two columns can join the others' of the same slot.
    assert groups.max() + 1 == 5


def test_grouped_jacobian_equals_the_column_by_column_one():
    residuals, sparsity, x0 = _problem(0)
    f0 = residuals(x0)
    J = sparse_jacobian(residuals, x0, f0, sparsity, column_groups(sparsity)).toarray()
    dense = np.empty_like(J)
    for j in range(x0.size):
        h = 1e-7 * max(1.0, abs(x0[j]))
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        dense[:, j] = (residuals(xp) - residuals(xm)) / (2 * h)
    assert np.max(np.abs(J - dense)) < 1e-6
    assert np.all(J[sparsity.toarray() == 0] == 0)


@pytest.mark.parametrize("outliers", [0, 12])
def test_reaches_scipys_soft_l1_minimum(outliers):
    residuals, sparsity, x0 = _problem(outliers)
    ours = levenberg_marquardt(residuals, x0, sparsity, f_scale=0.05, ftol=1e-12, xtol=1e-12)
    ref = least_squares(residuals, x0, loss="soft_l1", f_scale=0.05, method="trf", ftol=1e-14, xtol=1e-14,
                        gtol=1e-14)
    assert ours.cost <= ref.cost * (1 + 1e-9)
    # The same minimum: far inside the unknowns' own uncertainty (about 0.01 with this noise).
    assert np.max(np.abs(ours.x - ref.x)) < 1e-5
    assert ours.njev < 100


def test_the_loss_discounts_outliers():
    residuals, sparsity, x0 = _problem(12)
    robust = levenberg_marquardt(residuals, x0, sparsity, f_scale=0.05, ftol=1e-12)
    plain = least_squares(residuals, x0, method="trf")
    truth_shared = np.array([1.3, -0.4, 0.2])
    assert np.max(np.abs(robust.x[:3] - truth_shared)) < 0.5 * np.max(np.abs(plain.x[:3] - truth_shared))


def test_the_block_solver_solves_the_damped_normal_equations():
    residuals, sparsity, x0 = _problem(12)
    J = sparse_jacobian(residuals, x0, residuals(x0), sparsity, column_groups(sparsity))
    A = (J.T @ J).tocsc()
    rng = np.random.default_rng(1)
    shift, b = rng.uniform(1e-3, 1.0, x0.size), rng.normal(size=x0.size)
    x = BlockArrowSolver(sparsity, 3, x0.size, 2).solve(A, shift, b)
    dense = np.linalg.solve(A.toarray() + np.diag(shift), b)
    np.testing.assert_allclose(x, dense, rtol=1e-9, atol=1e-12 * np.abs(dense).max())


def test_the_minimum_is_the_same_with_the_block_solver():
    residuals, sparsity, x0 = _problem(12)
    lu = levenberg_marquardt(residuals, x0, sparsity, f_scale=0.05, ftol=1e-12, xtol=1e-12)
    blocks = levenberg_marquardt(residuals, x0, sparsity, f_scale=0.05, ftol=1e-12, xtol=1e-12,
                                 blocks=(3, x0.size, 2))
    assert blocks.cost == pytest.approx(lu.cost, rel=1e-10)
    assert np.max(np.abs(blocks.x - lu.x)) < 1e-8


def test_blocks_that_share_a_residual_are_refused():
    _, sparsity, x0 = _problem(0)
    # Blocks of four join two frames' unknowns that no residual shares: fine. Blocks offset by one
    # split each frame's pair, whose residuals then touch two blocks.
    BlockArrowSolver(sparsity, 3, x0.size, 4)
    with pytest.raises(ValueError, match="two blocks"):
        BlockArrowSolver(sparsity, 4, x0.size - 1, 2)


def test_a_singular_system_gives_nan_as_a_failed_step():
    _, sparsity, x0 = _problem(0)
    A = (sparsity.T @ sparsity).astype(float).tolil()
    A[5, :] = 0.0  # a frame's unknown no residual constrains, and no damping
    A[:, 5] = 0.0
    x = BlockArrowSolver(sparsity, 3, x0.size, 2).solve(A, np.zeros(x0.size), np.ones(x0.size))
    assert np.isnan(x).all()
