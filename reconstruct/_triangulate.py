"""Multi-camera triangulation of marker centroids, vectorised over all points.

All marker-frames are solved together with numpy, in blocks of a few
thousand; there is no Python loop over frames or markers (only over the
cameras, the blocks and the rejection rounds).

Method
------
1. Undistort every centroid once to normalised camera coordinates
   (``cv2.undistortPoints`` with the camera's ``K`` and ``dist``).
2. Linear least squares (inhomogeneous DLT). For a camera with world-to-camera
   ``R`` (rows ``r1, r2, r3``) and ``t``, a view ``(x, y)`` of the point ``X``
   gives the two rows ``(x r3 - r1) . X = t1 - x t3`` and
   ``(y r3 - r2) . X = t2 - y t3``. Their normal-equation contributions are
   linear in the four features ``(1, x, y, x^2 + y^2)``, because
   ``r1 r1^T + r2 r2^T + r3 r3^T = I``. So the 3x3 normal matrix and the
   right-hand side of every point are one matrix product of a
   ``(4 * cameras, points)`` feature array with per-camera constants, then a
   closed-form 3x3 solve. Missing views get weight 0.
3. The algebraic residual of a view equals depth times the normalised
   reprojection error, so the system is solved a second time with weights
   ``(f / depth)^2``: the residual is then the reprojection error in pixels.
4. Reprojection error of each view, in pixels of the undistorted image
   (normalised residual times ``fx``, ``fy``). Views behind the camera count
   as infinitely wrong. While a point's worst view is above
   ``max_reprojection_px``, that view is dropped and the point re-solved, as
   long as at least ``min_views`` views remain; a point whose remaining views
   still disagree, or that has fewer than ``min_views`` views, is NaN. A
   ghost (a wrong centroid in a marker's slot) is such an outlier view.
   In the first round, instead of that drop, a point of three or more
   views that fails the test restarts from the pair of its views that most
   other views agree with (``_consensus_views``): a ghost can pull the all-view solution
   towards itself so far that the worst view is a genuine one. A point left
   with two views is held to half the threshold (px): its residual is the
   epipolar part of the error alone, and no third view can outvote a ghost.
5. Optional Gauss-Newton refinement of the reprojection error (vectorised).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["triangulate", "undistort_detections"]

# Marker-frames per block. Small blocks stay in cache and keep OpenBLAS from
# threading the thin (9 x 24) @ (24 x N) product, which on a shared 2-core
# machine made it several times slower.
_CHUNK = 1 << 12


def undistort_detections(detections, cameras):
    """Undistorted normalised coordinates of every detection.

    Parameters
    ----------
    detections : array_like, shape (cameras, frames, markers, 2)
        Centroids (px), NaN where a marker was not seen.
    cameras : sequence of Camera

    Returns
    -------
    normalised : ndarray, shape (cameras, frames, markers, 2)
        ``(x, y)`` on the plane z = 1 of each camera (dimensionless), NaN where
        the detection is NaN.

    Notes
    -----
    OpenCV's default iteration count is used: with radial distortion
    ``k1 = -0.2`` its inversion error stayed within 1e-3 px for points up to
    600 px from the centre, and within 1e-4 px for ``|k1| <= 0.08`` (the
    simulated lab), far under centroid noise; more iterations would make
    undistortion dominate the cost of triangulation.
    """
    det = _check_detections(detections, cameras)
    xn, yn = _undistort_xy(det, cameras)
    return np.stack([xn, yn], axis=-1).reshape(det.shape)


def _undistort_xy(det, cameras):
    """Normalised x and y of every detection, each shape (C, frames * markers)."""
    C = det.shape[0]
    flat = det.reshape(C, -1, 2)
    xn = np.empty(flat.shape[:2])
    yn = np.empty(flat.shape[:2])
    for c, cam in enumerate(cameras):
        if flat.shape[1] == 0:
            continue
        if not np.any(cam.dist):
            # Without distortion the inversion is exact and needs no iteration.
            yn[c] = (flat[c, :, 1] - cam.K[1, 2]) / cam.K[1, 1]
            xn[c] = (flat[c, :, 0] - cam.K[0, 2] - cam.K[0, 1] * yn[c]) / cam.K[0, 0]
        else:
            pts = np.ascontiguousarray(flat[c]).reshape(-1, 1, 2)
            norm = cv2.undistortPoints(pts, cam.K, cam.dist).reshape(-1, 2)
            xn[c] = norm[:, 0]
            yn[c] = norm[:, 1]
    return xn, yn


def _check_detections(detections, cameras):
    det = np.asarray(detections, dtype=float)
    if det.ndim != 4 or det.shape[-1] != 2:
        raise ValueError(
            f"detections must have shape (cameras, frames, markers, 2), got {det.shape}"
        )
    if det.shape[0] != len(cameras):
        raise ValueError(f"detections cover {det.shape[0]} cameras but {len(cameras)} cameras given")
    return det


def _camera_constants(cameras):
    """Per-camera constants of the feature expansion, shape (4 * C, 9).

    Columns 0-5 are the unique entries (00, 01, 02, 11, 12, 22) of the normal
    matrix, 6-8 the right-hand side; rows are features (1, x, y, x^2 + y^2)
    of each camera in turn.
    """
    iu = ([0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2])
    rows = []
    for cam in cameras:
        R, t = cam.R, cam.tvec
        r1, r2, r3 = R
        s33 = np.outer(r3, r3)
        s31 = np.outer(r3, r1) + np.outer(r1, r3)
        s32 = np.outer(r3, r2) + np.outer(r2, r3)
        mats = (np.eye(3) - s33, -s31, -s32, s33)
        rhs = (
            -(t[0] * r1 + t[1] * r2),
            t[0] * r3 + t[2] * r1,
            t[1] * r3 + t[2] * r2,
            -t[2] * r3,
        )
        for m, v in zip(mats, rhs):
            rows.append(np.concatenate([m[iu], v]))
    return np.array(rows)


def _features(xn, yn):
    """Per-view features (1, x, y, x^2 + y^2), shape (C, 4, N)."""
    C, N = xn.shape
    feats = np.empty((C, 4, N))
    feats[:, 0] = 1.0
    feats[:, 1] = xn
    feats[:, 2] = yn
    np.multiply(xn, xn, out=feats[:, 3])
    feats[:, 3] += yn * yn
    return feats


def _solve(feats, w, consts):
    """Weighted linear least squares for every point.

    feats : (C, 4, N) from ``_features`` (finite everywhere); w : (C, N)
    view weights, 0 where a view is unused. Returns X (N, 3), NaN where the
    normal matrix is singular.
    """
    C, _, N = feats.shape
    wf = feats * w[:, None, :]
    a, b, c, d, e, f, g0, g1, g2 = consts.T @ wf.reshape(4 * C, N)
    # Closed-form inverse of the symmetric 3x3 [[a b c] [b d e] [c e f]].
    A = d * f - e * e
    B = c * e - b * f
    Cc = b * e - c * d
    D = a * f - c * c
    E = b * c - a * e
    F = a * d - b * b
    det = a * A + b * B + c * Cc
    X = np.empty((N, 3))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        X[:, 0] = (A * g0 + B * g1 + Cc * g2) * inv
        X[:, 1] = (B * g0 + D * g1 + E * g2) * inv
        X[:, 2] = (Cc * g0 + E * g1 + F * g2) * inv
    # A well-posed point has a normal matrix far from singular; a relative
    # determinant this small means (near-)parallel rays.
    scale = (a + d + f) ** 3
    X[~(np.abs(det) > 1e-12 * scale)] = np.nan
    return X


def _camera_coords(X, Rs, ts):
    """Camera-frame coordinates of points X (N, 3), shape (C, 3, N)."""
    C = Rs.shape[0]
    return (Rs.reshape(3 * C, 3) @ X.T).reshape(C, 3, -1) + ts[:, :, None]


def _reprojection_sq(X, xn, yn, used, Rs, ts, fxy):
    """Squared reprojection error (px^2), shape (C, N): NaN for unused views,
    inf where the point lies behind a camera that uses it."""
    Xc = _camera_coords(X, Rs, ts)
    z = Xc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        iz = 1.0 / z
        ex = (Xc[:, 0] * iz - xn) * fxy[:, 0, None]
        ey = (Xc[:, 1] * iz - yn) * fxy[:, 1, None]
    e2 = ex * ex + ey * ey
    e2[~(z > 0)] = np.inf
    e2[~used] = np.nan
    return e2


def _depths(X, Rs, ts):
    """Depth of points X (N, 3) in every camera, shape (C, N)."""
    return Rs[:, 2, :] @ X.T + ts[:, 2, None]


def _weights(z, used, fbar):
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (fbar[:, None] / z) ** 2
    return np.where(used & (z > 0) & np.isfinite(w), w, 0.0)


def _gauss_newton(X, xn, yn, used, Rs, ts, fxy, iterations=3):
    """Minimise the pixel reprojection error of every point (vectorised)."""
    iu = ([0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2])
    for _ in range(iterations):
        Xc = _camera_coords(X, Rs, ts)
        z = Xc[:, 2]
        ok = used & (z > 0)
        iz = np.where(ok, 1.0 / np.where(ok, z, 1.0), 0.0)
        u = Xc[:, 0] * iz
        v = Xc[:, 1] * iz
        fx, fy = fxy[:, 0, None], fxy[:, 1, None]
        rx = (u - xn) * fx * ok
        ry = (v - yn) * fy * ok
        # d(u)/dX = (r1 - u r3) / z and d(v)/dX = (r2 - v r3) / z, per camera.
        Jx = (Rs[:, 0, :, None] - u[:, None] * Rs[:, 2, :, None]) * (iz * fx)[:, None]
        Jy = (Rs[:, 1, :, None] - v[:, None] * Rs[:, 2, :, None]) * (iz * fy)[:, None]
        H = np.zeros((X.shape[0], 3, 3))
        for i, j in zip(*iu):
            H[:, i, j] = (Jx[:, i] * Jx[:, j] + Jy[:, i] * Jy[:, j]).sum(axis=0)
            H[:, j, i] = H[:, i, j]
        g = ((Jx * rx[:, None]) + (Jy * ry[:, None])).sum(axis=0).T
        good = np.isfinite(X).all(axis=1) & (np.abs(np.linalg.det(H)) > 0)
        step = np.zeros_like(X)
        if good.any():
            step[good] = np.linalg.solve(H[good], g[good][..., None])[..., 0]
        X = X - step
    return X


def _consensus_views(idx, used, feats, consts, Rs, ts, fxy, fbar, xs, ys, thr2):
    """The views of points ``idx`` that agree with their best pair of views.

    Every pair of a point's views is triangulated on its own (depth-weighted,
    as in the main solve); the pair must meet the two-view threshold and is
    scored by how many of the point's views reproject within ``thr2``, ties
    going to the smaller sum of squared errors over those views. Greedy
    dropping of the worst view fails when a ghost pulls the all-view
    solution towards itself: with three or four views it can leave the ghost
    and one genuine view, which always agree with each other. The pair that
    most views agree with is the genuine one whenever genuine views
    outnumber the ghosts. When no third view backs any pair and two pairs
    with different views both agree (a ghost on the epipolar line), nothing
    says which is genuine: the point gets no views (NaN), not a guess.
    Returns ``(C, len(idx))`` bool: the inliers of each point's best pair.
    """
    C = used.shape[0]
    u = used[:, idx]
    fi = feats[..., idx]
    xi, yi = xs[:, idx], ys[:, idx]
    w0 = (fbar ** 2)[:, None]
    best_count = np.zeros(idx.size, dtype=np.int64)
    best_sum = np.full(idx.size, np.inf)
    best_in = np.zeros((C, idx.size), dtype=bool)
    ambiguous = np.zeros(idx.size, dtype=bool)
    for a in range(C):
        for b in range(a + 1, C):
            pair = np.zeros_like(u)
            pair[[a, b]] = u[[a, b]]
            has = pair[a] & pair[b]
            if not has.any():
                continue
            Xp = _solve(fi, w0 * pair, consts)
            Xp2 = _solve(fi, _weights(_depths(np.nan_to_num(Xp), Rs, ts), pair, fbar), consts)
            Xp = np.where(np.isfinite(Xp2), Xp2, Xp)
            e2 = _reprojection_sq(Xp, xi, yi, u, Rs, ts, fxy)
            inl = u & (e2 <= thr2) & has[None, :]
            count = inl.sum(axis=0)
            total = np.where(inl, e2, 0.0).sum(axis=0)
            valid = has & (e2[a] <= thr2 / 4) & (e2[b] <= thr2 / 4)
            ambiguous |= valid & (count == 2) & (best_count == 2) & (inl != best_in).any(axis=0)
            # More agreeing views first; the sum of their errors breaks ties.
            better = valid & ((count > best_count) | ((count == best_count) & (total < best_sum)))
            ambiguous[better & (count > 2)] = False
            best_count[better] = count[better]
            best_sum[better] = total[better]
            best_in[:, better] = inl[:, better]
    best_in[:, ambiguous] = False
    return best_in


def _triangulate_block(xn, yn, seen, consts, Rs, ts, fxy, fbar, thr2, min_views, refine):
    C, N = xn.shape
    used = seen.copy()
    xs = np.where(used, xn, 0.0)
    ys = np.where(used, yn, 0.0)
    n = used.sum(axis=0)
    X = np.full((N, 3), np.nan)
    e2 = np.full((C, N), np.nan)
    w0 = (fbar**2)[:, None]
    feats = _features(xs, ys)

    def solve(idx):
        # Unit-free first pass, then reweight so the residual is in pixels.
        sel = slice(None) if idx.size == N else idx
        u = used[:, sel]
        fi = feats[..., sel]
        Xi = _solve(fi, w0 * u, consts)
        w = _weights(_depths(np.nan_to_num(Xi), Rs, ts), u, fbar)
        Xi2 = _solve(fi, w, consts)
        return np.where(np.isfinite(Xi2), Xi2, Xi)

    idx = np.flatnonzero(n >= min_views)
    if idx.size:
        X[idx] = solve(idx)
    rejected = np.zeros(N, dtype=np.int64)
    for round_ in range(C + 1):
        if idx.size == 0:
            break
        sel = slice(None) if idx.size == N else idx
        u = used[:, sel]
        Xs = X[sel]
        ei = _reprojection_sq(Xs, xs[:, sel], ys[:, sel], u, Rs, ts, fxy)
        singular = ~np.isfinite(Xs).all(axis=1)
        if singular.any():
            # A singular solve (parallel rays) makes every used view suspect.
            ei[:, singular] = np.inf
        ei[~u] = -1.0
        e2[:, sel] = ei
        # Two views have no third to outvote a wrong one, and their residual
        # is the epipolar part of the error only: hold them to a quarter of
        # the squared threshold (half in pixels).
        bad = ei.max(axis=0) > np.where(n[idx] > 2, thr2, thr2 / 4)
        if not bad.any():
            break
        bidx = idx[bad]
        greedy = np.ones(bidx.size, dtype=bool)
        if round_ == 0 and C > 2:
            # Points of three views or more whose views disagree restart from
            # the pair of views that the most other views agree with; the
            # greedy drop of later rounds then only cleans up.
            greedy = (n[bidx] <= 2) | singular[bad]
            multi = bidx[~greedy]
            if multi.size:
                keep = _consensus_views(multi, used, feats, consts, Rs, ts, fxy, fbar, xs, ys, thr2)
                rejected[multi] += (used[:, multi] & ~keep).sum(axis=0)
                used[:, multi] = keep
                n[multi] = keep.sum(axis=0)
        worst = np.argmax(ei[:, bad][:, greedy], axis=0)
        drop = bidx[greedy]
        used[worst, drop] = False
        rejected[drop] += 1
        n[drop] -= 1
        X[bidx[n[bidx] < min_views]] = np.nan
        idx = bidx[n[bidx] >= min_views]
        if idx.size:
            X[idx] = solve(idx)
    ok = np.isfinite(X).all(axis=1)
    used &= ok[None, :]
    if refine and ok.any():
        k = np.flatnonzero(ok)
        X[k] = _gauss_newton(X[k], xs[:, k], ys[:, k], used[:, k], Rs, ts, fxy)
        e2[:, k] = _reprojection_sq(X[k], xs[:, k], ys[:, k], used[:, k], Rs, ts, fxy)
    nv = used.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.where(used, e2, 0.0).sum(axis=0) / nv)
    rms[~ok] = np.nan
    return X, nv, rms, rejected, used


def triangulate(detections, cameras, max_reprojection_px=3.0, min_views=2, refine=False):
    """Triangulate every marker in every frame from all cameras that see it.

    Parameters
    ----------
    detections : array_like, shape (cameras, frames, markers, 2)
        Marker centroids (px), NaN where a camera did not see a marker.
    cameras : sequence of Camera
        Calibrated cameras, in the order of the first axis of ``detections``.
    max_reprojection_px : float, optional
        A view whose reprojection error (px, undistorted image) exceeds this
        is an outlier or ghost; the worst such view is dropped and the point
        re-solved, repeatedly, while ``min_views`` views remain. A point of
        two views is held to half of it.
    min_views : int, optional
        Fewest agreeing views a point needs (at least 2); otherwise NaN.
    refine : bool, optional
        Polish each point by Gauss-Newton on the reprojection error. The
        reweighted linear solution is already close to it, so this changes
        points by a small fraction of the noise.

    Returns
    -------
    points : ndarray, shape (frames, markers, 3)
        Inertial positions (m), NaN where fewer than ``min_views`` views agree.
    info : dict
        ``n_views`` (frames, markers) int: views used in the final point (0
        where NaN); ``rms_px`` (frames, markers): RMS reprojection error of
        those views (px), NaN where the point is NaN; ``n_rejected`` (frames,
        markers) int: views dropped as outliers; ``used`` (cameras, frames,
        markers) bool: which views made the point; ``rejected_views`` int:
        total views dropped.

    Raises
    ------
    ValueError
        On a wrong ``detections`` shape, a camera-count mismatch, ``min_views``
        below 2 or a non-positive threshold.
    """
    det = _check_detections(detections, cameras)
    if int(min_views) != min_views or min_views < 2:
        raise ValueError(f"min_views must be an integer >= 2, got {min_views}")
    if not max_reprojection_px > 0:
        raise ValueError(f"max_reprojection_px must be positive, got {max_reprojection_px}")
    C, F, M, _ = det.shape
    N = F * M
    xn, yn = _undistort_xy(det, cameras)
    seen = np.isfinite(xn) & np.isfinite(yn)

    consts = _camera_constants(cameras)
    Rs = np.array([cam.R for cam in cameras])
    ts = np.array([cam.tvec for cam in cameras])
    fxy = np.array([[cam.K[0, 0], cam.K[1, 1]] for cam in cameras])
    fbar = fxy.mean(axis=1)
    thr2 = float(max_reprojection_px) ** 2

    X = np.empty((N, 3))
    nv = np.empty(N, dtype=np.int64)
    rms = np.empty(N)
    rej = np.empty(N, dtype=np.int64)
    used = np.empty((C, N), dtype=bool)
    for s in range(0, N, _CHUNK):
        sl = slice(s, min(N, s + _CHUNK))
        X[sl], nv[sl], rms[sl], rej[sl], used[:, sl] = _triangulate_block(
            xn[:, sl], yn[:, sl], seen[:, sl], consts, Rs, ts, fxy, fbar, thr2, int(min_views), refine
        )
    info = {
        "n_views": nv.reshape(F, M),
        "rms_px": rms.reshape(F, M),
        "n_rejected": rej.reshape(F, M),
        "used": used.reshape(C, F, M),
        "rejected_views": int(rej.sum()),
    }
    return X.reshape(F, M, 3), info
