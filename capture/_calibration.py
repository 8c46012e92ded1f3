"""Camera calibration from an L-frame take and a wand take.

``calibrate`` needs nothing but the two takes and the nominal lens spec:

1. Starting intrinsics: the nominal focal length, the image centre, no
   distortion.
2. Pairwise relative poses from essential matrices (``cv2.findEssentialMat``,
   LMedS, so the still-unmodelled distortion is tolerated), each pair's
   translation scaled so the wand triangulates to its known length.
3. The pairs are chained into one rig along a maximum spanning tree of
   shared wand frames (root: the best-connected camera).
4. Sparse bundle adjustment (``_bundle``: Levenberg-Marquardt whose steps
   solve the sparse normal equations directly, a finite-difference Jacobian
   grouped by its sparsity pattern, soft-L1 loss) over every camera's pose (the root's
   fixes the gauge), focal length (square pixels), principal point and
   distortion ``k1, k2, p1, p2`` (``k3`` stays 0), every wand frame (centre
   and direction; the marker separation is held at ``wand_length``, which
   is what fixes the scale) and the four L-frame markers (free points,
   observed in every L-frame frame: their static views tie the cameras
   together). It runs twice: on 300 evenly spread frames with a wide loss
   (10 px; the start ignores distortion), then, every frame re-triangulated
   with those cameras, on all usable frames (evenly subsampled to
   ``max_frames`` if there are more) with the loss at 1 px.
5. The L-frame's reconstructed size is checked against ``lframe_points``
   (a wand length off by more than 1 % is refused, not absorbed), then the
   rig is moved rigidly (rotation and translation, no scale) so that its
   L-frame markers best fit ``lframe_points``: that fixes origin and axes,
   with K = I x J down into the floor.

Quality is measured afterwards, not assumed: reprojection RMS per camera and
the wand length triangulated marker by marker with the final cameras.
Degenerate takes raise ``ValueError`` naming the take and camera at fault.
"""

from __future__ import annotations


import cv2
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import minimum_spanning_tree
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from ._bundle import levenberg_marquardt
from ._cameras import Camera

__all__ = ["calibrate", "triangulate_views", "MIN_WAND_FRAMES", "MIN_CAMERA_FRAMES"]

MIN_WAND_FRAMES = 100
"""Fewest usable wand frames (both markers seen by two cameras or more)."""

MIN_CAMERA_FRAMES = 30
"""Fewest usable wand frames in which each camera must see both markers."""

_N_INTR = 7  # f, cx, cy, k1, k2, p1, p2
_PLANAR_RATIO = 0.05  # out-of-plane / in-plane spread below which the wand take is planar
_PLANAR_PX = 5.0  # homography misfit (px) below which a pair's wand views are planar
_EPIPOLAR_PX = 8.0  # epipolar misfit (px) above which a camera pair disagrees (good pairs: < 3)
_MAX_RMS_PX = 3.0  # a converged calibration of sane takes is far below this
_SCALE_TOL = 0.01  # wand and L-frame scale may differ by this fraction (L-frame: ~1e-4)
_FIRST_FRAMES = 300  # wand frames in the first adjustment
_MAX_ITER = 100
_FTOL = 1e-8


def _fail(msg):
    raise ValueError(msg)


# ---------------------------------------------------------------- geometry

def _rodrigues(rvecs):
    """Rotation matrices of rotation vectors, shape (n, 3) -> (n, 3, 3)."""
    return Rotation.from_rotvec(rvecs).as_matrix()


def _project(points, R, t, intr):
    """Project points (n, 3) through per-point cameras (R (n,3,3), t (n,3), intr (n,7))."""
    xc = np.einsum("nij,nj->ni", R, points) + t
    x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
    f, cx, cy, k1, k2, p1, p2 = intr.T
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + k2 * r2)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([f * xd + cx, f * yd + cy], axis=1)


def _camera(name, image_size, intr, rvec, tvec):
    f, cx, cy, k1, k2, p1, p2 = intr
    return Camera(name, image_size, [[f, 0, cx], [0, f, cy], [0, 0, 1]],
                  [k1, k2, p1, p2, 0.0], rvec, tvec)


def triangulate_views(pixels, cameras):
    """Triangulate points from every camera that sees them (two at least).

    Linear least squares on undistorted normalised coordinates, solved twice:
    the second pass weights each view by 1/depth so the residual is the
    angular (reprojection) error rather than the algebraic one.

    Parameters
    ----------
    pixels : array_like, shape (cameras, ..., 2)
        Centroids (px), NaN where not seen.
    cameras : sequence of Camera

    Returns
    -------
    points : ndarray, shape (..., 3)
        Positions (m), NaN where fewer than two cameras see the point.
    """
    px = np.asarray(pixels, float)
    shape = px.shape[1:-1]
    px = px.reshape(len(cameras), -1, 2)
    n = px.shape[1]
    seen = np.isfinite(px).all(axis=-1)
    rows_a = np.zeros((len(cameras), n, 2, 3))
    rows_b = np.zeros((len(cameras), n, 2))
    Rs, ts = [], []
    for c, cam in enumerate(cameras):
        R, t = cam.R, cam.tvec
        Rs.append(R)
        ts.append(t)
        ok = seen[c]
        if not ok.any():
            continue
        xy = cv2.undistortPoints(px[c, ok].reshape(-1, 1, 2), cam.K, cam.dist).reshape(-1, 2)
        # (x r3 - r1) . X = t1 - x t3, and likewise for y
        rows_a[c, ok, 0] = xy[:, :1] * R[2] - R[0]
        rows_a[c, ok, 1] = xy[:, 1:] * R[2] - R[1]
        rows_b[c, ok, 0] = t[0] - xy[:, 0] * t[2]
        rows_b[c, ok, 1] = t[1] - xy[:, 1] * t[2]
    count = seen.sum(axis=0)
    weight = seen.astype(float)
    X = np.full((n, 3), np.nan)
    good = count >= 2
    for _ in range(2):
        w = weight[:, good, None, None]
        A = rows_a[:, good] * w
        b = rows_b[:, good] * w[..., 0]
        AtA = np.einsum("cnki,cnkj->nij", A, A)
        Atb = np.einsum("cnki,cnk->ni", A, b)
        X[good] = np.linalg.solve(AtA, Atb[..., None])[..., 0]
        depth = np.einsum("cj,nj->cn", np.array(Rs)[:, 2], X[good]) + np.array(ts)[:, 2:3]
        weight[:, good] = seen[:, good] / np.maximum(np.abs(depth), 1e-6)
    return X.reshape(shape + (3,))


def _rigid_fit(src, dst):
    """Rotation Q (det +1) and translation d minimising |Q src + d - dst| (Kabsch, through scipy).

    ``reconstruct.body_frames_svd`` is the same fit batched over frames with gaps; it stays separate
    because ``Rotation.align_vectors`` fits one point set at a time.
    """
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    rotation, _ = Rotation.align_vectors(dst - md, src - ms)
    Q = rotation.as_matrix()
    return Q, md - Q @ ms


# ------------------------------------------------------------ input checks

def _check_inputs(lframe, wand, names):
    wand = np.asarray(wand, float)
    if wand.ndim != 4 or wand.shape[2:] != (2, 2):
        _fail(f"wand take: detections must have shape (cameras, frames, 2, 2), got {wand.shape}")
    n_cam = wand.shape[0]
    if n_cam < 2:
        _fail(f"wand take: at least two cameras are needed, got {n_cam}")
    if lframe is None:
        _fail("L-frame take is missing")
    lframe = np.asarray(lframe, float)
    if lframe.ndim != 4 or lframe.shape[0] != n_cam or lframe.shape[2:] != (4, 2):
        _fail(f"L-frame take: detections must have shape ({n_cam}, frames, 4, 2), got {lframe.shape}")
    if names is None:
        names = [f"cam{i + 1}" for i in range(n_cam)]
    if len(names) != n_cam:
        _fail(f"{len(names)} camera names for {n_cam} cameras")
    return lframe, wand, list(names)


def _label(names, c):
    return f"camera {names[c]} (index {c})"


def _usable_wand(wand, names):
    """Per-marker visibility and the frames usable for calibration."""
    seen = np.isfinite(wand).all(axis=-1)  # (cams, frames, 2)
    both = seen.all(axis=-1)  # (cams, frames)
    usable = (seen.sum(axis=0) >= 2).all(axis=-1)  # both markers seen by >= 2 cameras
    per_camera = (both & usable).sum(axis=1)
    for c in np.flatnonzero(per_camera == 0):
        _fail(f"wand take: {_label(names, c)} never sees the wand")
    if usable.sum() < MIN_WAND_FRAMES:
        _fail(f"wand take: too few frames, {int(usable.sum())} with both markers seen by two cameras "
              f"(at least {MIN_WAND_FRAMES} needed)")
    for c in np.flatnonzero(per_camera < MIN_CAMERA_FRAMES):
        _fail(f"wand take: {_label(names, c)} sees the wand in only {per_camera[c]} usable frames "
              f"(at least {MIN_CAMERA_FRAMES} needed)")
    return usable


def _lframe_views(lframe, names):
    """Mean static view of each L-frame marker per camera, and its frame count."""
    seen = np.isfinite(lframe).all(axis=-1)  # (cams, frames, 4)
    if lframe.shape[1] == 0 or not seen.any():
        _fail("L-frame take: no L-frame marker is seen (is the L-frame missing?)")
    count = seen.sum(axis=1)  # (cams, 4)
    for m in range(4):
        if (count[:, m] > 0).sum() < 2:
            _fail(f"L-frame take: marker {m} is seen by fewer than two cameras")
    # Sums over seen frames, not nanmean: a camera that never sees a marker
    # (legal, as long as two others do) would make nanmean warn.
    total = np.where(seen[..., None], lframe, 0.0).sum(axis=1)  # (cams, 4, 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count[..., None] > 0, total / count[..., None], np.nan)
        dev2 = np.where(seen[..., None], (lframe - mean[:, None]) ** 2, 0.0).sum(axis=(1, 3))
        spread = np.where(count > 0, np.sqrt(dev2 / np.maximum(2 * count, 1)), 0.0)  # (cams, 4)
    c, m = np.unravel_index(np.argmax(spread), spread.shape)
    if spread[c, m] > 2.0:
        _fail(f"L-frame take: marker {m} moves by {spread[c, m]:.1f} px RMS in {_label(names, c)}; "
              "the L-frame must stay still")
    return mean, count


# ------------------------------------------------------ initial rig geometry

def _normalised(px, intr):
    f, cx, cy = intr[:3]
    return (px - [cx, cy]) / f


def _homography_px(a, b):
    """Median transfer error (px) of the best homography from views a to b."""
    H, _ = cv2.findHomography(a, b, cv2.LMEDS)
    if H is None:
        return np.inf
    return float(np.median(np.linalg.norm(cv2.perspectiveTransform(a[:, None], H)[:, 0] - b, axis=1)))


def _pair_pose(wand_px, wand_n, ok, i, j, wand_length, f):
    """Relative pose of camera j w.r.t. camera i from their shared wand views.

    Returns ``(R, t, frames, homography_px, epipolar_px)`` with ``t`` metric,
    or None when the pair shares too few views. The misfits are medians in
    px at the nominal focal length.
    """
    shared = ok[i] & ok[j]  # (frames, 2)
    if shared.sum() < 50:
        return None
    step = max(1, int(shared.sum()) // 800)
    a, b = wand_n[i][shared][::step], wand_n[j][shared][::step]
    # A plane's views are related by a homography: the parallax it leaves is
    # what the essential matrix, the focal lengths and the distortion feed on.
    h_px = _homography_px(wand_px[i][shared][::step], wand_px[j][shared][::step])
    E, mask = cv2.findEssentialMat(a, b, np.eye(3), method=cv2.LMEDS, prob=0.999)
    if E is None or E.shape != (3, 3):
        return None
    E = E[:3]
    line = np.hstack([a, np.ones((len(a), 1))]) @ E.T
    epi = np.abs((b * line[:, :2]).sum(axis=1) + line[:, 2]) / np.hypot(line[:, 0], line[:, 1])
    n_in, R, t, _ = cv2.recoverPose(E, a, b, np.eye(3), mask=mask)
    both = shared.all(axis=1)
    if n_in < 20 or both.sum() < 10:
        return None
    P1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    P2 = np.hstack([R, t])
    ends = []
    for m in range(2):
        Xh = cv2.triangulatePoints(P1, P2, wand_n[i][both, m].T.copy(), wand_n[j][both, m].T.copy())
        ends.append((Xh[:3] / Xh[3]).T)
    length = np.median(np.linalg.norm(ends[1] - ends[0], axis=1))
    if not np.isfinite(length) or length <= 0:
        return None
    return R, t.ravel() * (wand_length / length), int(both.sum()), h_px, float(np.median(epi)) * f


def _initial_rig(wand, usable, intr0, wand_length, names):
    """Chain pairwise essential-matrix poses into one metric rig."""
    n_cam = wand.shape[0]
    w = wand[:, usable]
    ok = np.isfinite(w).all(axis=-1)
    wn = [_normalised(w[c], intr0[c]) for c in range(n_cam)]
    poses, weight, flat = {}, np.zeros((n_cam, n_cam)), []
    paired, bad = np.zeros((n_cam, n_cam), bool), np.zeros((n_cam, n_cam), bool)
    for i in range(n_cam):
        for j in range(i + 1, n_cam):
            p = _pair_pose(w, wn, ok, i, j, wand_length, intr0[0, 0])
            if p is None:
                continue
            flat.append(p[3])
            paired[i, j] = paired[j, i] = True
            if p[4] > _EPIPOLAR_PX:
                bad[i, j] = bad[j, i] = True
                continue
            poses[i, j] = p[:2]
            weight[i, j] = weight[j, i] = p[2]
    if flat and np.median(flat) < _PLANAR_PX:
        _fail(f"wand take: the wand moved in a plane (a homography maps one camera's views onto "
              f"another's within {np.median(flat):.1f} px, median over camera pairs); "
              "wave it through the whole volume")
    n_bad, n_paired = bad.sum(axis=1), paired.sum(axis=1)
    for c in np.flatnonzero((n_paired >= 2) & (2 * n_bad > n_paired)):
        _fail(f"wand take: {_label(names, c)} disagrees with {n_bad[c]} of {n_paired[c]} other cameras "
              "about the wand (epipolar misfit); are its wand markers mislabelled, or did it move?")
    # Maximum spanning tree = minimum spanning tree of negated weights.
    tree = minimum_spanning_tree(csr_matrix(-weight)).toarray()
    adj = (tree != 0) | (tree.T != 0)
    root = int(np.argmax(weight.sum(axis=1)))
    R = {root: np.eye(3)}
    t = {root: np.zeros(3)}
    stack = [root]
    while stack:
        i = stack.pop()
        for j in np.flatnonzero(adj[i]):
            if j in R:
                continue
            Rij, tij = poses[i, j] if (i, j) in poses else _invert(*poses[j, i])
            R[j], t[j] = Rij @ R[i], Rij @ t[i] + tij
            stack.append(j)
    lost = [names[c] for c in range(n_cam) if c not in R]
    if lost:
        _fail(f"wand take: camera(s) {', '.join(lost)} share too few wand frames with the others "
              "to be placed in the rig")
    return root, np.array([R[c] for c in range(n_cam)]), np.array([t[c] for c in range(n_cam)])


def _invert(R, t):
    return R.T, -R.T @ t


def _check_lframe(points, lframe_points, wand_length, shape_tol, scale_tol):
    """Raise if the reconstructed L-frame's shape or size differs from the known one.

    ``points`` are in the wand's scale: a size mismatch means the wand length
    or ``lframe_points`` is wrong, and the scale would silently be off.
    """
    seen = np.linalg.norm(points[:, None] - points[None], axis=-1)
    known = np.linalg.norm(lframe_points[:, None] - lframe_points[None], axis=-1)
    ratio = (seen * known).sum() / (known * known).sum()
    misfit = np.abs(seen - ratio * known).max()
    if misfit > shape_tol * known.max():
        _fail(f"L-frame take: the markers' layout differs from lframe_points' by up to {1000 * misfit:.0f} mm "
              "(wrong marker order or layout?)")
    if abs(ratio - 1) > scale_tol:
        _fail(f"the wand length ({wand_length:g} m) and the L-frame disagree on scale by "
              f"{100 * (ratio - 1):+.1f} %: check the wand length and lframe_points")


def _check_not_planar(points, what):
    """Raise if the wand markers' positions (n, 3) all lie near one plane."""
    p = points[np.isfinite(points).all(axis=1)]
    s = np.sqrt(np.linalg.eigvalsh(np.cov(p.T)))  # ascending
    if s[0] < _PLANAR_RATIO * s[1]:
        _fail(f"wand take: the wand moved in a plane (out-of-plane spread {1000 * s[0]:.0f} mm "
              f"vs {1000 * s[1]:.0f} mm in plane{what}); wave it through the whole volume")


# ------------------------------------------------------- bundle adjustment

class _Problem:
    """Parameter layout, residuals and Jacobian sparsity of the adjustment.

    x = [intrinsics (cams x 7) | poses of the non-root cameras (x 6) |
         wand frames (centre 3, direction tangent 2) | L-frame points (4 x 3)]
    """

    def __init__(self, n_cam, root, wand_obs, lframe_obs, dirs, wand_length):
        self.n_cam, self.root, self.half = n_cam, root, wand_length / 2
        cam_w, frame_w, marker_w, uv_w = wand_obs
        cam_l, marker_l, uv_l, weight_l = lframe_obs
        self.n_frames = len(dirs)
        self.d0 = dirs
        # Tangent basis of each frame's initial direction: direction = d0 + a e1 + b e2.
        helper = np.where(np.abs(dirs[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        e1 = np.cross(dirs, helper)
        self.e1 = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
        self.e2 = np.cross(dirs, self.e1)
        self.cam = np.concatenate([cam_w, cam_l])
        self.point = np.concatenate([2 * frame_w + marker_w, 2 * self.n_frames + marker_l])
        self.n_wand = len(cam_w)
        self.uv = np.concatenate([uv_w, uv_l])
        self.weight = np.concatenate([np.ones(len(cam_w)), weight_l])
        self.extr_index = np.cumsum(np.arange(n_cam) != root) - 1  # camera -> pose slot
        self.o_extr = n_cam * _N_INTR
        self.o_frame = self.o_extr + (n_cam - 1) * 6
        self.o_lframe = self.o_frame + 5 * self.n_frames
        self.n_params = self.o_lframe + 12

    def unpack(self, x):
        intr = x[: self.o_extr].reshape(self.n_cam, _N_INTR)
        pose = x[self.o_extr: self.o_frame].reshape(-1, 6)
        rvec = np.zeros((self.n_cam, 3))
        tvec = np.zeros((self.n_cam, 3))
        others = np.arange(self.n_cam) != self.root
        rvec[others], tvec[others] = pose[:, :3], pose[:, 3:]
        fr = x[self.o_frame: self.o_lframe].reshape(-1, 5)
        d = self.d0 + fr[:, 3:4] * self.e1 + fr[:, 4:5] * self.e2
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        wand = np.stack([fr[:, :3] - self.half * d, fr[:, :3] + self.half * d], axis=1)
        points = np.concatenate([wand.reshape(-1, 3), x[self.o_lframe:].reshape(4, 3)])
        return intr, rvec, tvec, points

    def pack(self, intr, rvec, tvec, centres, lpoints):
        others = np.arange(self.n_cam) != self.root
        frames = np.hstack([centres, np.zeros((len(centres), 2))])
        return np.concatenate([intr.ravel(), np.hstack([rvec[others], tvec[others]]).ravel(),
                               frames.ravel(), lpoints.ravel()])

    def raw_residuals(self, x):
        """Reprojection error (px), shape (observations, 2), unweighted."""
        intr, rvec, tvec, points = self.unpack(x)
        R = _rodrigues(rvec)
        c = self.cam
        return _project(points[self.point], R[c], tvec[c], intr[c]) - self.uv

    def residuals(self, x):
        return (self.raw_residuals(x) * self.weight[:, None]).ravel()

    def sparsity(self):
        n_obs = len(self.cam)
        rows, cols = [], []
        obs = np.arange(n_obs)
        for k in range(_N_INTR):
            rows.append(obs)
            cols.append(self.cam * _N_INTR + k)
        moving = self.cam != self.root
        for k in range(6):
            rows.append(obs[moving])
            cols.append(self.o_extr + 6 * self.extr_index[self.cam[moving]] + k)
        wand = obs < self.n_wand
        frame = self.point[wand] // 2
        for k in range(5):
            rows.append(obs[wand])
            cols.append(self.o_frame + 5 * frame + k)
        lpt = self.point[~wand] - 2 * self.n_frames
        for k in range(3):
            rows.append(obs[~wand])
            cols.append(self.o_lframe + 3 * lpt + k)
        r = np.concatenate(rows)
        c = np.concatenate(cols)
        r = np.concatenate([2 * r, 2 * r + 1])
        c = np.concatenate([c, c])
        return csr_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(2 * n_obs, self.n_params))


def _observations(wand, frames, lmean, lcount):
    """Flatten the wand views of ``frames`` and the mean L-frame views."""
    w = wand[:, frames]
    cam, frame, marker = np.nonzero(np.isfinite(w).all(axis=-1))
    wand_obs = (cam, frame, marker, w[cam, frame, marker])
    cl, ml = np.nonzero(lcount > 0)
    # A mean of n static views counts as n views: weight sqrt(n).
    lframe_obs = (cl, ml, lmean[cl, ml], np.sqrt(lcount[cl, ml]))
    return wand_obs, lframe_obs


def _problem(n_cam, root, wand, frames, ends, lmean, lcount, wand_length):
    dirs = ends[:, 1] - ends[:, 0]
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    wand_obs, lframe_obs = _observations(wand, frames, lmean, lcount)
    return _Problem(n_cam, root, wand_obs, lframe_obs, dirs, wand_length)


def _even(n, most):
    """Indices of at most ``most`` of ``n`` items, evenly spread."""
    return np.unique(np.round(np.linspace(0, n - 1, min(n, most))).astype(int))


def _adjust(problem, x0, f_scale):
    # On a loaded machine BLAS threads wait for a core at every hand-off (an LSMR solver here once ran
    # 15x slower so): one thread.
    with threadpool_limits(1, user_api="blas"):
        return levenberg_marquardt(problem.residuals, x0, problem.sparsity(), f_scale, ftol=_FTOL, xtol=1e-10,
                                   max_iter=_MAX_ITER, blocks=(problem.o_frame, problem.o_lframe, 5))


# ------------------------------------------------------------------ the API

def calibrate(lframe, wand, wand_length, lframe_points, image_size, nominal_focal_px, *,
              names=None, max_frames=2000):
    """Calibrate a camera rig from an L-frame take and a wand take.

    Parameters
    ----------
    lframe : array_like, shape (cameras, frames, 4, 2)
        Centroids (px) of the static L-frame markers, NaN where not seen, in
        the order of ``lframe_points``.
    wand : array_like, shape (cameras, frames, 2, 2)
        Centroids (px) of the two wand markers (consistently labelled), NaN
        where not seen.
    wand_length : float
        Distance between the wand markers (m); sets the scale.
    lframe_points : array_like, shape (4, 3)
        Inertial positions (m) of the L-frame markers; set origin and axes.
    image_size : tuple of int
        (width, height) in px, the same for every camera.
    nominal_focal_px : float
        Nominal focal length of the lenses (px), the starting value.
    names : sequence of str, optional
        Camera names; ``cam1``, ``cam2``, ... by default.
    max_frames : int
        Most wand frames used in the bundle adjustment (evenly subsampled).

    Returns
    -------
    cameras : list of Camera
        World-to-camera poses in the inertial frame, intrinsics, distortion.
    quality : dict
        ``reprojection_rms_px`` (per camera, RMS of the x and y residuals of
        every view used: comparable with a per-axis centroid noise sigma),
        ``reprojection_rms_px_all`` (all cameras), ``reprojection_rms_2d_px_all``
        (RMS length of the 2D residual vectors), ``wand_length_mean_mm``
        and ``wand_length_std_mm`` (each marker triangulated on its own in
        every usable wand frame), ``lframe_misfit_mm`` (RMS distance of the
        calibrated L-frame markers from ``lframe_points``),
        ``frames_usable``, ``frames_used``, ``iterations``, ``root_camera``.

    Raises
    ------
    ValueError
        For degenerate takes: a camera that never (or too rarely) sees the
        wand, too few wand frames, a wand moved in a plane, a camera whose
        wand views disagree with the others', a missing, moving or
        misnumbered L-frame, a wand length that disagrees with the L-frame's
        size by more than 1 %, or a calibration that does not fit its takes.
    """
    lframe, wand, names = _check_inputs(lframe, wand, names)
    lframe_points = np.asarray(lframe_points, float)
    if lframe_points.shape != (4, 3):
        _fail(f"lframe_points must have shape (4, 3), got {lframe_points.shape}")
    if not wand_length > 0:
        _fail(f"wand length must be positive, got {wand_length}")
    width, height = (int(v) for v in image_size)
    n_cam = wand.shape[0]

    usable = _usable_wand(wand, names)
    lmean, lcount = _lframe_views(lframe, names)

    intr0 = np.tile([nominal_focal_px, (width - 1) / 2, (height - 1) / 2, 0, 0, 0, 0], (n_cam, 1))
    root, R0, t0 = _initial_rig(wand, usable, intr0, wand_length, names)
    rvec0 = np.array([cv2.Rodrigues(r)[0].ravel() for r in R0])
    cams0 = [_camera(names[c], (width, height), intr0[c], rvec0[c], t0[c]) for c in range(n_cam)]

    frames = np.flatnonzero(usable)
    ends = triangulate_views(wand[:, frames], cams0)  # (frames, 2, 3)
    _check_not_planar(ends.reshape(-1, 3), "")
    fine = np.isfinite(ends).all(axis=(1, 2))
    frames, ends = frames[fine], ends[fine]
    lpts0 = triangulate_views(lmean, cams0)
    if not np.isfinite(lpts0).all():
        _fail("L-frame take: the L-frame markers could not be triangulated")
    # Loose: the first rig ignores distortion and guesses the focal lengths.
    _check_lframe(lpts0, lframe_points, wand_length, shape_tol=0.1, scale_tol=0.2)

    # A first adjustment on a few frames, with a wide loss (the start ignores
    # distortion), gets the cameras close; every frame is then re-triangulated
    # and the full adjustment, at the noise level, needs only a few steps.
    sub = _even(len(frames), _FIRST_FRAMES)
    problem = _problem(n_cam, root, wand, frames[sub], ends[sub], lmean, lcount, wand_length)
    sol = _adjust(problem, problem.pack(intr0, rvec0, t0, ends[sub].mean(axis=1), lpts0), f_scale=10.0)
    intr, rvec, tvec, points = problem.unpack(sol.x)
    cams1 = [_camera(names[c], (width, height), intr[c], rvec[c], tvec[c]) for c in range(n_cam)]
    ends = triangulate_views(wand[:, frames], cams1)
    fine = np.isfinite(ends).all(axis=(1, 2))
    frames, ends = frames[fine], ends[fine]
    pick = _even(len(frames), max_frames)
    frames, ends = frames[pick], ends[pick]
    problem = _problem(n_cam, root, wand, frames, ends, lmean, lcount, wand_length)
    sol2 = _adjust(problem, problem.pack(intr, rvec, tvec, ends.mean(axis=1), points[-4:]), f_scale=1.0)
    intr, rvec, tvec, points = problem.unpack(sol2.x)

    _check_lframe(points[-4:], lframe_points, wand_length, shape_tol=0.01, scale_tol=_SCALE_TOL)
    # Origin and axes from the L-frame: a rigid move, the wand keeps the scale.
    Q, d = _rigid_fit(points[-4:], lframe_points)
    cameras = []
    for c in range(n_cam):
        Rw = _rodrigues(rvec[c:c + 1])[0] @ Q.T
        cameras.append(_camera(names[c], (width, height), intr[c],
                               cv2.Rodrigues(Rw)[0].ravel(), tvec[c] - Rw @ d))
    quality = _quality(problem, sol2.x, wand, usable, cameras, names, lframe, points[-4:] @ Q.T + d,
                       lframe_points)
    quality.update(frames_usable=int(usable.sum()), frames_used=len(frames),
                   iterations=int(sol.njev + sol2.njev), root_camera=names[root])
    return cameras, quality


def _quality(problem, x, wand, usable, cameras, names, lframe, lpoints, lframe_points):
    intr, rvec, tvec, points = problem.unpack(x)
    res = problem.raw_residuals(x)
    wand_res = res[: problem.n_wand]
    # The L-frame enters the fit as mean views; its quality counts every frame.
    seen = np.isfinite(lframe).all(axis=-1)
    cam_l, fr_l, m_l = np.nonzero(seen)
    R = _rodrigues(rvec)
    Q_lp = points[-4:]
    l_res = _project(Q_lp[m_l], R[cam_l], tvec[cam_l], intr[cam_l]) - lframe[cam_l, fr_l, m_l]
    cam = np.concatenate([problem.cam[: problem.n_wand], cam_l])
    sq = np.concatenate([wand_res, l_res]) ** 2
    rms = {names[c]: float(np.sqrt(sq[cam == c].mean())) for c in range(len(cameras))}
    worst = max(rms, key=rms.get)
    if rms[worst] > _MAX_RMS_PX:
        _fail(f"calibration does not fit its takes: camera {worst} reprojection RMS {rms[worst]:.1f} px "
              "(mislabelled wand markers or a camera that moved?)")
    ends = triangulate_views(wand[:, usable], cameras)
    _check_not_planar(ends.reshape(-1, 3), " after adjustment")
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    length = length[np.isfinite(length)]
    misfit = float(np.sqrt(((lpoints - lframe_points) ** 2).sum(axis=1).mean()))
    return {
        "reprojection_rms_px": rms,
        "reprojection_rms_px_all": float(np.sqrt(sq.mean())),
        "reprojection_rms_2d_px_all": float(np.sqrt(2 * sq.mean())),
        "wand_length_mean_mm": float(1000 * length.mean()),
        "wand_length_std_mm": float(1000 * length.std()),
        "lframe_misfit_mm": 1000 * misfit,
    }
