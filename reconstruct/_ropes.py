"""Rope length from rope markers: cubic fit in the rope's plane (Eq. 22).

Per frame, the rope's vertical plane is the vertical plane through the span's
two end points. Markers and ends are projected into it: the horizontal
coordinate ``s`` runs along the horizontal direction from ``start`` to
``end`` (``s = 0`` at start, ``s = L`` at end), the vertical one is the
inertial ``z`` (down positive). The paper's cubic
``z = a0 + a1 s + a2 s^2 + a3 s^3`` (Eq. 22) is fitted by least squares and
its arc length from ``s = 0`` to ``s = L`` is the rope length.

The two end points are included in the fit as data points, with the same
weight as a marker: the markers cover only part of the rope, and without the
ends the cubic would be extrapolated over the rest of the span. The curve is
not forced through the ends exactly, so a noisy end point costs no more than a
noisy marker.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rope_length_cubic"]


def rope_length_cubic(rope_markers, start, end, include_ends=True, nodes=24):
    """Arc length of the least-squares cubic through a rope's markers.

    Parameters
    ----------
    rope_markers : array_like, shape (frames, M, 3)
        Inertial positions of the markers on the rope (m), NaN where not seen.
    start, end : array_like, shape (frames, 3)
        Inertial positions of the span's two ends (m), e.g. the boom pulley
        and the hoist chain connection.
    include_ends : bool, optional
        Fit the ends together with the markers (default; see module notes).
    nodes : int, optional
        Gauss-Legendre nodes for the arc-length integral.

    Returns
    -------
    length : ndarray, shape (frames,)
        Rope length (m). NaN where fewer than four points (markers plus ends)
        are available, where the ends are NaN, or where the span is vertical
        (no horizontal extent to fit ``z(s)`` over).

    Notes
    -----
    The abscissa is scaled to ``xi = s / L`` in [0, 1] so the cubic's normal
    equations stay well conditioned; the length is then
    ``integral_0^1 sqrt(L^2 + (dz/dxi)^2) dxi``.
    """
    m = np.asarray(rope_markers, dtype=float)
    a = np.asarray(start, dtype=float)
    b = np.asarray(end, dtype=float)
    if m.ndim != 3 or m.shape[-1] != 3:
        raise ValueError(f"rope_markers must have shape (frames, markers, 3), got {m.shape}")
    if a.shape != (m.shape[0], 3) or b.shape != a.shape:
        raise ValueError(f"start and end must have shape ({m.shape[0]}, 3), got {a.shape} and {b.shape}")
    if int(nodes) < 2:
        raise ValueError(f"nodes must be at least 2, got {nodes}")

    pts = np.concatenate([a[:, None], b[:, None], m], axis=1) if include_ends else m
    horiz = (b - a)[:, :2]
    L = np.hypot(horiz[:, 0], horiz[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = horiz / L[:, None]
        xi = np.einsum("fpk,fk->fp", pts[..., :2] - a[:, None, :2], u) / L[:, None]
    z = pts[..., 2]
    ok = np.isfinite(xi) & np.isfinite(z)
    n_ok = ok.sum(axis=1)
    good = (n_ok >= 4) & (L > 0) & np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)

    xs = np.where(ok, xi, 0.0)
    zs = np.where(ok, z, 0.0)
    V = xs[..., None] ** np.arange(4) * ok[..., None]  # masked Vandermonde (F, P, 4)
    A = np.einsum("fpi,fpj->fij", V, V)
    r = np.einsum("fpi,fp->fi", V, zs)
    # Four points at fewer than four distinct abscissae leave A singular.
    cond_ok = good.copy()
    if good.any():
        cond_ok[good] = np.linalg.cond(A[good]) < 1e12
    coef = np.full((m.shape[0], 4), np.nan)
    if cond_ok.any():
        coef[cond_ok] = np.linalg.solve(A[cond_ok], r[cond_ok][..., None])[..., 0]

    x, wq = np.polynomial.legendre.leggauss(int(nodes))
    t = 0.5 * (x + 1.0)  # nodes on [0, 1]
    dz = coef[:, 1, None] + 2.0 * coef[:, 2, None] * t + 3.0 * coef[:, 3, None] * t**2
    length = 0.5 * np.sum(wq * np.sqrt(L[:, None] ** 2 + dz**2), axis=1)
    length[~cond_ok] = np.nan
    return length
