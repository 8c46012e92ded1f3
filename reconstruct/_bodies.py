"""Body frames, reference points and mass centres from marker positions.

Everything takes marker arrays and the markers' body-frame coordinates as
arguments; nothing here knows the rig. ``T`` is the matrix ``T_B->I`` of
Eq. 11: its columns are the body axes I_B, J_B, K_B in inertial components,
so ``r_inertial = origin + T @ r_body`` (Eq. 10). Euler angles follow from
``dragline.simulate.euler_from_matrix(T)``.

Bucket markers (paper section 3.2, Fig. 6), body axes I_B forward out of the
front, J_B lateral (to the right, looking forward), K_B down through the
bottom:

- ``alpha``: left of the lower hoist chain mount,
- ``beta``:  right of the lower hoist chain mount,
- ``gamma``: left of the nose,
- ``delta``: right of the nose.

Eqs. 14-16 use alpha, beta, gamma: ``beta - alpha`` points along +J_B and
``gamma - alpha`` must have a forward (+I_B) component, so that
``(gamma - alpha) x J_B`` points along +K_B. delta is redundant there; the
least-squares fit (``body_frames_svd``) uses all visible markers.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "body_frames_paper",
    "body_frames_svd",
    "body_origin",
    "mass_centre",
    "two_marker_position",
]


def _unit(v):
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _marker_frame(alpha, beta, gamma):
    """Eqs. 14-16: axes built from three markers, columns I, J, K."""
    J = _unit(beta - alpha)
    K = _unit(np.cross(gamma - alpha, J))
    Iax = _unit(np.cross(J, K))
    T = np.stack([Iax, J, K], axis=-1)
    T[~np.isfinite(T).all(axis=(-2, -1))] = np.nan
    return T


def body_frames_paper(alpha, beta, gamma, markers_body=None):
    """Body-to-inertial matrices from three markers (paper Eqs. 14-16).

    ``J = (beta - alpha) / |.|``, ``K = ((gamma - alpha) x J) / |.|``,
    ``I = (J x K) / |.|``.

    Parameters
    ----------
    alpha, beta, gamma : array_like, shape (frames, 3)
        Inertial marker positions (m); see the module docstring for which
        marker is which.
    markers_body : array_like, shape (3, 3), optional
        Body-frame coordinates (m) of alpha, beta, gamma (rows). Without it,
        the frame of Eqs. 14-16 (the marker frame) is taken as the body frame,
        which holds when ``beta - alpha`` lies along J_B and ``gamma - alpha``
        in the I_B-J_B plane with a forward component. With it, the constant
        rotation between the marker frame and the body frame is removed:
        ``T_B->I = T_M->I @ T_M->B^T``, so markers may sit anywhere (e.g. a
        nose lower than the chain mount).

    Returns
    -------
    T : ndarray, shape (frames, 3, 3)
        Columns I_B, J_B, K_B in inertial components; NaN in frames where an
        input is NaN or the three markers are collinear.
    """
    a, b, g = (np.asarray(v, dtype=float) for v in (alpha, beta, gamma))
    if not (a.shape == b.shape == g.shape) or a.shape[-1] != 3:
        raise ValueError(
            f"alpha, beta, gamma must share a shape (frames, 3); got {a.shape}, {b.shape}, {g.shape}"
        )
    T = _marker_frame(a, b, g)
    if markers_body is not None:
        mb = np.asarray(markers_body, dtype=float)
        if mb.shape != (3, 3):
            raise ValueError(f"markers_body must have shape (3, 3) (alpha, beta, gamma), got {mb.shape}")
        T_mb = _marker_frame(mb[0], mb[1], mb[2])
        if not np.isfinite(T_mb).all():
            raise ValueError("markers_body: alpha, beta, gamma are collinear")
        T = T @ T_mb.T
    return T


def _check_markers(markers, markers_body):
    m = np.asarray(markers, dtype=float)
    mb = np.asarray(markers_body, dtype=float)
    if m.ndim != 3 or m.shape[-1] != 3:
        raise ValueError(f"markers must have shape (frames, markers, 3), got {m.shape}")
    if mb.shape != m.shape[1:]:
        raise ValueError(f"markers_body must have shape {m.shape[1:]} to match markers, got {mb.shape}")
    return m, mb


def body_frames_svd(markers, markers_body, min_markers=3):
    """Least-squares rigid fit of a body to its visible markers (Kabsch).

    Finds, per frame, the proper rotation ``T`` (det +1) and ``origin`` that
    minimise ``sum_i |markers_i - (origin + T @ markers_body_i)|^2`` over the
    visible markers. Vectorised over frames (batched 3x3 SVD).

    Parameters
    ----------
    markers : array_like, shape (frames, M, 3)
        Inertial marker positions (m), NaN where not seen.
    markers_body : array_like, shape (M, 3)
        The same markers' body-frame coordinates (m), relative to the body
        reference point.
    min_markers : int, optional
        Fewest visible markers for a fit (at least 3).

    Returns
    -------
    T : ndarray, shape (frames, 3, 3)
        Body-to-inertial matrices (columns are the body axes).
    origin : ndarray, shape (frames, 3)
        Inertial position of the body reference point (m).
        Both are NaN in frames with fewer than ``min_markers`` visible markers
        or with the visible ones (nearly) collinear.
    """
    m, mb = _check_markers(markers, markers_body)
    if min_markers < 3:
        raise ValueError(f"min_markers must be at least 3 for a rigid fit, got {min_markers}")
    vis = np.isfinite(m).all(axis=-1)  # (F, M)
    w = vis.astype(float)
    n = w.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mc = np.einsum("fm,fmk->fk", w, np.where(vis[..., None], m, 0.0)) / n[:, None]
        bc = (w @ mb) / n[:, None]
    dm = np.where(vis[..., None], m - mc[:, None, :], 0.0)
    db = np.where(vis[..., None], mb[None] - bc[:, None, :], 0.0)
    H = np.einsum("fmi,fmj->fij", db, dm)  # body x inertial cross-covariance
    ok = n >= min_markers
    # Reject collinear marker sets: their body-frame scatter has rank < 2.
    S = np.einsum("fmi,fmj->fij", db, db)
    ev = np.linalg.eigvalsh(np.where(ok[:, None, None], S, np.eye(3)))
    ok &= ev[:, 1] > 1e-8 * ev[:, 2]
    H = np.where(ok[:, None, None], H, np.eye(3))
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.transpose(0, 2, 1) @ U.transpose(0, 2, 1)))
    D = np.zeros((len(d), 3, 3))
    D[:, 0, 0] = 1.0
    D[:, 1, 1] = 1.0
    D[:, 2, 2] = np.where(d == 0, 1.0, d)
    T = Vt.transpose(0, 2, 1) @ D @ U.transpose(0, 2, 1)
    origin = mc - np.einsum("fij,fj->fi", T, bc)
    T[~ok] = np.nan
    origin[~ok] = np.nan
    return T, origin


def body_origin(markers, markers_body, T):
    """Body reference point from markers and a known orientation.

    The paper's "linear combination of the bucket marker points": the mean
    over visible markers of ``marker_i - T @ markers_body_i``.

    Parameters
    ----------
    markers : array_like, shape (frames, M, 3)
        Inertial marker positions (m), NaN where not seen.
    markers_body : array_like, shape (M, 3)
        Body-frame marker coordinates (m).
    T : array_like, shape (frames, 3, 3)
        Body-to-inertial matrices.

    Returns
    -------
    origin : ndarray, shape (frames, 3)
        NaN where no marker is visible or ``T`` is NaN.
    """
    m, mb = _check_markers(markers, markers_body)
    T = np.asarray(T, dtype=float)
    est = m - np.einsum("fij,mj->fmi", T, mb)
    vis = np.isfinite(est).all(axis=-1)
    n = vis.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(vis[..., None], est, 0.0).sum(axis=1) / n[:, None] + np.where(
            n[:, None] > 0, 0.0, np.nan
        )


def mass_centre(T, origin, cg_body):
    """Mass-centre position: Eq. 10 read backwards, ``origin + T @ cg_body``.

    Parameters
    ----------
    T : array_like, shape (frames, 3, 3)
        Body-to-inertial matrices.
    origin : array_like, shape (frames, 3)
        Inertial position of the body reference point (m).
    cg_body : array_like, shape (3,)
        Mass centre in body-frame coordinates relative to the reference
        point (m).

    Returns
    -------
    ndarray, shape (frames, 3)
        Inertial mass-centre position (m).
    """
    T = np.asarray(T, dtype=float)
    return np.asarray(origin, dtype=float) + T @ np.asarray(cg_body, dtype=float)


def two_marker_position(marker_a, marker_b, offset=0.0):
    """Position of a two-marker body (e.g. the drag cluster): position only.

    Two markers fix an axis, not an orientation, so only a point on that axis
    is recoverable: the midpoint plus ``offset`` along the unit vector from
    ``marker_a`` to ``marker_b``.

    Parameters
    ----------
    marker_a, marker_b : array_like, shape (frames, 3)
        Inertial positions (m).
    offset : float, optional
        Signed distance (m) from the midpoint along ``b - a``.

    Returns
    -------
    ndarray, shape (frames, 3)
        NaN where either marker is NaN.
    """
    a = np.asarray(marker_a, dtype=float)
    b = np.asarray(marker_b, dtype=float)
    mid = 0.5 * (a + b)
    if offset == 0.0:
        return mid
    return mid + offset * _unit(b - a)
