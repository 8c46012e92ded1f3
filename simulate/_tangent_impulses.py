"""The tangent of the dissipative impulses after each Verlet step (``_kernel.dissipate``).

Joints first (rope bending damping, chain-link friction: one Gauss-Seidel
sweep of implicit angular impulses, each joint reading the velocities the
joints before it left), then ring friction (the capstan, a bearing's Coulomb
friction in proportion to its load), as the kernel
applies them. Each is applied here with its tangent, the primal arithmetic
copied from the kernel operation for operation (the same bits), since each
impulse's derivative needs the velocities it changes.

Coulomb laws are differentiated where they are smooth: a joint or ring
that slips loses an impulse whose size is the friction limit, and that is
differentiated; one that sticks has its relative motion stopped, which is
differentiated too (the stopping impulse depends on the parameters through
the inverse masses); the step at which either switches moves with the
parameters, and that the tangent does not see (``docs/sensitivities.md``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._kernel import (KIND_BODY, KIND_PARTICLE, _bearing_load, _dissipate_geometry, _joint_geometry, _kick, _node,
                      _offsets, _turn)

__all__ = ["impulses_tangent"]


@njit(cache=True)
def impulses_tangent(y, dY, h, m, dm, work, tw):
    """``_kernel.dissipate_fresh(t + h, y, h, m, work)`` with its tangent on ``dY`` (n, nd).

    ``work`` and ``tw`` hold the geometry and its tangent at y's positions
    (the last right-hand side's and its tangent's).
    """
    o_part, o_vel, o_F, o_ring = _offsets(m)
    if m.has_joints != 0:
        for e in range(m.el_seg.shape[0]):
            se = m.el_seg[e]
            if m.seg_bend_c[se] == 0.0 and m.seg_bend_k[se] == 0.0 and m.seg_link_mu[se] == 0.0:
                continue
            _dissipate_geometry(e, y, m, work, o_F, o_ring)
            _joint_geometry_tangent(e, y, dY, m, dm, work, tw, o_F)
        _joint_geometry(m, work.Lseg, work.el_len, work.el_arm, work.el_inv_len, work.el_inv_mass)
        _inverse_mass_tangents(m, dm, work, tw)
        _joints(y, dY, h, m, dm, work, tw, o_part, o_vel)
    if m.has_ring_friction != 0:
        _ring_friction(y, dY, h, m, dm, work, tw, o_F, o_ring)


@njit(cache=True)
def _element_geometry_tangent(e, y, dY, m, dm, work, tw, o_F, k):
    """Element e's unit vector, tension and their tangents along direction k, and its length's tangent.

    Returns (ux, uy, uz, tension, dux, duy, duz, dtension, length, dlength), at the positions of the last
    right-hand side.
    """
    s, side = m.el_seg[e], m.el_side[e]
    na, nb_ = m.el_na[e], m.el_nb[e]
    nx, dnx = work.nx, tw.dnx
    Le, invL = work.rest[s, side], work.inv_rest[s, side]
    dx, dyy, dz = nx[nb_, 0] - nx[na, 0], nx[nb_, 1] - nx[na, 1], nx[nb_, 2] - nx[na, 2]
    length = math.sqrt(dx * dx + dyy * dyy + dz * dz)
    ux, uy, uz = dx / length, dyy / length, dz / length
    d0, d1, d2 = dnx[nb_, 0, k] - dnx[na, 0, k], dnx[nb_, 1, k] - dnx[na, 1, k], dnx[nb_, 2, k] - dnx[na, 2, k]
    dlen = ux * d0 + uy * d1 + uz * d2
    tension, dtension = 0.0, 0.0
    if length > Le:
        tension = m.seg_ks[s] * invL * (length - Le) + y[o_F + e]
        if tension > 0.0:
            drest = tw.drest[s, side, k]
            dtension = (dm.seg_ks[s, k] * invL * (length - Le) + m.seg_ks[s] * tw.dinv_rest[s, side, k] * (length - Le)
                        + m.seg_ks[s] * invL * (dlen - drest) + dY[o_F + e, k])
        else:
            tension = 0.0
    return (ux, uy, uz, tension, (d0 - ux * dlen) / length, (d1 - uy * dlen) / length, (d2 - uz * dlen) / length,
            dtension, length, dlen)


@njit(cache=True)
def _joint_geometry_tangent(e, y, dY, m, dm, work, tw, o_F):
    """Tangents of what ``_kernel._dissipate_geometry`` stored for element e (unit vector, 1 / length, tension,
    the ends' inertial lever arms)."""
    P = m.part_seg.shape[0]
    body_end = P + m.bnode_body.shape[0]
    for k in range(dY.shape[1]):
        _, _, _, _, dux, duy, duz, dtension, length, dlen = _element_geometry_tangent(e, y, dY, m, dm, work, tw, o_F,
                                                                                       k)
        tw.del_u[e, 0, k], tw.del_u[e, 1, k], tw.del_u[e, 2, k] = dux, duy, duz
        tw.del_inv_len[e, k] = -dlen / (length * length)
        tw.del_T[e, k] = dtension
        for end in range(2):
            node = m.el_na[e] if end == 0 else m.el_nb[e]
            for c in range(3):
                tw.del_arm[e, 3 * end + c, k] = tw.dnarm[node - P, c, k] if P <= node < body_end else 0.0


@njit(cache=True)
def _inverse_mass_tangents(m, dm, work, tw):
    """Tangents of ``_kernel._end_inverse_masses`` for every element the joints sweep (``work.el_inv_mass``)."""
    for e in range(m.el_seg.shape[0]):
        if work.el_len[e] <= 0.0:
            continue
        for end in range(2):
            kind = m.el_ka[e] if end == 0 else m.el_kb[e]
            idx = m.el_ia[e] if end == 0 else m.el_ib[e]
            for k in range(tw.del_inv_mass.shape[2]):
                lin, bend = 0.0, 0.0
                if kind == KIND_PARTICLE:
                    s = m.part_seg[idx]
                    value = m.seg_npart[s] / (m.seg_rho[s] * work.Lseg[s])
                    lin = -value * (dm.seg_rho[s, k] / m.seg_rho[s] + tw.dLseg[s, k] / work.Lseg[s])
                    bend = lin
                elif kind == KIND_BODY:
                    i = _smallest_inertia(m.body_I, idx)
                    imin = m.body_I[idx, i, i]
                    lin = -dm.body_mass[idx, k] / (m.body_mass[idx] * m.body_mass[idx])
                    a0, a1, a2 = work.el_arm[e, 3 * end], work.el_arm[e, 3 * end + 1], work.el_arm[e, 3 * end + 2]
                    da = (a0 * tw.del_arm[e, 3 * end, k] + a1 * tw.del_arm[e, 3 * end + 1, k]
                          + a2 * tw.del_arm[e, 3 * end + 2, k])
                    r2 = a0 * a0 + a1 * a1 + a2 * a2
                    bend = lin + 2.0 * da / imin - r2 * dm.body_I[idx, i, i, k] / (imin * imin)
                tw.del_inv_mass[e, 2 * end, k] = lin
                tw.del_inv_mass[e, 2 * end + 1, k] = bend


@njit(cache=True, inline="always")
def _smallest_inertia(body_I, b):
    """The index of body b's smallest principal inertia as ``min(I00, min(I11, I22))`` picks it."""
    if body_I[b, 1, 1] <= body_I[b, 2, 2]:
        return 0 if body_I[b, 0, 0] <= body_I[b, 1, 1] else 1
    return 0 if body_I[b, 0, 0] <= body_I[b, 2, 2] else 2


@njit(cache=True)
def _end_velocity_tangent(kind, idx, arms, darms, e, y, dY, m, work, tw, o_vel, k):
    """The tangent (3,) of ``_kernel._node``'s velocity of an element end, along direction k."""
    if kind == KIND_PARTICLE:
        v = o_vel + 3 * idx
        return dY[v, k], dY[v + 1, k], dY[v + 2, k]
    if kind == KIND_BODY:
        b = 12 * idx
        T, dT = work.T, tw.dT
        p, q, rr = y[b + 9], y[b + 10], y[b + 11]
        dp, dq, dr = dY[b + 9, k], dY[b + 10, k], dY[b + 11, k]
        r0, r1, r2 = arms[e, 0], arms[e, 1], arms[e, 2]
        e0, e1, e2 = darms[e, 0, k], darms[e, 1, k], darms[e, 2, k]
        wx, wy, wz = q * r2 - rr * r1, rr * r0 - p * r2, p * r1 - q * r0
        dwx = dq * r2 + q * e2 - dr * r1 - rr * e1
        dwy = dr * r0 + rr * e0 - dp * r2 - p * e2
        dwz = dp * r1 + p * e1 - dq * r0 - q * e0
        out0 = dY[b + 3, k] + dT[idx, 0, 0, k] * wx + dT[idx, 0, 1, k] * wy + dT[idx, 0, 2, k] * wz + (
            T[idx, 0, 0] * dwx + T[idx, 0, 1] * dwy + T[idx, 0, 2] * dwz)
        out1 = dY[b + 4, k] + dT[idx, 1, 0, k] * wx + dT[idx, 1, 1, k] * wy + dT[idx, 1, 2, k] * wz + (
            T[idx, 1, 0] * dwx + T[idx, 1, 1] * dwy + T[idx, 1, 2] * dwz)
        out2 = dY[b + 5, k] + dT[idx, 2, 0, k] * wx + dT[idx, 2, 1, k] * wy + dT[idx, 2, 2, k] * wz + (
            T[idx, 2, 0] * dwx + T[idx, 2, 1] * dwy + T[idx, 2, 2] * dwz)
        return out0, out1, out2
    return tw.dfvel[idx, 0, k], tw.dfvel[idx, 1, k], tw.dfvel[idx, 2, k]


@njit(cache=True)
def _spin_tangent(e, y, dY, m, dm, work, tw, o_part, o_vel, k):
    """The tangent of element e's angular velocity (u x (v_b - v_a)) / L, along direction k."""
    _, _, _, vxa, vya, vza, _, _, _ = _node(m.el_ka[e], m.el_ia[e], m.el_ra, e, y, work.T, work.fpos, work.fvel,
                                            o_part, o_vel)
    _, _, _, vxb, vyb, vzb, _, _, _ = _node(m.el_kb[e], m.el_ib[e], m.el_rb, e, y, work.T, work.fpos, work.fvel,
                                            o_part, o_vel)
    ax, ay, az = _end_velocity_tangent(m.el_ka[e], m.el_ia[e], m.el_ra, dm.el_ra, e, y, dY, m, work, tw, o_vel, k)
    bx, by, bz = _end_velocity_tangent(m.el_kb[e], m.el_ib[e], m.el_rb, dm.el_rb, e, y, dY, m, work, tw, o_vel, k)
    ux, uy, uz = work.el_u[e, 0], work.el_u[e, 1], work.el_u[e, 2]
    dux, duy, duz = tw.del_u[e, 0, k], tw.del_u[e, 1, k], tw.del_u[e, 2, k]
    i, di = work.el_inv_len[e], tw.del_inv_len[e, k]
    gx, gy, gz = vxb - vxa, vyb - vya, vzb - vza
    dgx, dgy, dgz = bx - ax, by - ay, bz - az
    cx, cy, cz = uy * gz - uz * gy, uz * gx - ux * gz, ux * gy - uy * gx
    dcx = duy * gz + uy * dgz - duz * gy - uz * dgy
    dcy = duz * gx + uz * dgx - dux * gz - ux * dgz
    dcz = dux * gy + ux * dgy - duy * gx - uy * dgx
    return dcx * i + cx * di, dcy * i + cy * di, dcz * i + cz * di


@njit(cache=True)
def _turn_tangent(b, hx, hy, hz, dhx, dhy, dhz, m, dm, work, tw, dY, k):
    """The tangent of ``_kernel._turn``: body b's rates += Iinv T' H for an angular impulse H (inertial axes)."""
    T, dT, Iinv, dIinv = work.T, tw.dT, m.body_Iinv, dm.body_Iinv
    bx = T[b, 0, 0] * hx + T[b, 1, 0] * hy + T[b, 2, 0] * hz
    by = T[b, 0, 1] * hx + T[b, 1, 1] * hy + T[b, 2, 1] * hz
    bz = T[b, 0, 2] * hx + T[b, 1, 2] * hy + T[b, 2, 2] * hz
    dbx = dT[b, 0, 0, k] * hx + dT[b, 1, 0, k] * hy + dT[b, 2, 0, k] * hz + T[b, 0, 0] * dhx + T[b, 1, 0] * dhy + T[b, 2, 0] * dhz
    dby = dT[b, 0, 1, k] * hx + dT[b, 1, 1, k] * hy + dT[b, 2, 1, k] * hz + T[b, 0, 1] * dhx + T[b, 1, 1] * dhy + T[b, 2, 1] * dhz
    dbz = dT[b, 0, 2, k] * hx + dT[b, 1, 2, k] * hy + dT[b, 2, 2, k] * hz + T[b, 0, 2] * dhx + T[b, 1, 2] * dhy + T[b, 2, 2] * dhz
    o = 12 * b
    for c in range(3):
        dY[o + 9 + c, k] += (dIinv[b, c, 0, k] * bx + dIinv[b, c, 1, k] * by + dIinv[b, c, 2, k] * bz
                             + Iinv[b, c, 0] * dbx + Iinv[b, c, 1] * dby + Iinv[b, c, 2] * dbz)


@njit(cache=True)
def _kick_tangent(kind, idx, e, end, jx, jy, jz, djx, djy, djz, m, dm, work, tw, dY, o_vel, k):
    """The tangent of ``_kernel._kick`` of impulse J at element e's end (0: a, 1: b), along direction k."""
    inv, dinv = work.el_inv_mass[e, 2 * end], tw.del_inv_mass[e, 2 * end, k]
    if kind == KIND_PARTICLE:
        o = o_vel + 3 * idx
    elif kind == KIND_BODY:
        o = 12 * idx + 3
    else:
        return
    dY[o, k] += djx * inv + jx * dinv
    dY[o + 1, k] += djy * inv + jy * dinv
    dY[o + 2, k] += djz * inv + jz * dinv
    if kind == KIND_BODY:
        a0, a1, a2 = work.el_arm[e, 3 * end], work.el_arm[e, 3 * end + 1], work.el_arm[e, 3 * end + 2]
        d0, d1, d2 = tw.del_arm[e, 3 * end, k], tw.del_arm[e, 3 * end + 1, k], tw.del_arm[e, 3 * end + 2, k]
        _turn_tangent(idx, a1 * jz - a2 * jy, a2 * jx - a0 * jz, a0 * jy - a1 * jx,
                      d1 * jz + a1 * djz - d2 * jy - a2 * djy, d2 * jx + a2 * djx - d0 * jz - a0 * djz,
                      d0 * jy + a0 * djy - d1 * jx - a1 * djx, m, dm, work, tw, dY, k)


@njit(cache=True)
def _kick_pair_tangent(e, hx, hy, hz, dhx, dhy, dhz, sign, m, dm, work, tw, dY, o_vel, k):
    """The tangents of the couple ``sign (H x u) / L`` at element e's end b and its opposite at end a."""
    ux, uy, uz = work.el_u[e, 0], work.el_u[e, 1], work.el_u[e, 2]
    dux, duy, duz = tw.del_u[e, 0, k], tw.del_u[e, 1, k], tw.del_u[e, 2, k]
    i, di = work.el_inv_len[e], tw.del_inv_len[e, k]
    cx, cy, cz = hy * uz - hz * uy, hz * ux - hx * uz, hx * uy - hy * ux
    dcx = dhy * uz + hy * duz - dhz * uy - hz * duy
    dcy = dhz * ux + hz * dux - dhx * uz - hx * duz
    dcz = dhx * uy + hx * duy - dhy * ux - hy * dux
    # The end from a loop, not a constant: a literal 0 or 1 would compile ``_kick_tangent`` once for each.
    for end in range(2):
        kind, idx, sg = (m.el_kb[e], m.el_ib[e], sign) if end == 1 else (m.el_ka[e], m.el_ia[e], -sign)
        _kick_tangent(kind, idx, e, end, sg * cx * i, sg * cy * i, sg * cz * i, sg * (dcx * i + cx * di),
                      sg * (dcy * i + cy * di), sg * (dcz * i + cz * di), m, dm, work, tw, dY, o_vel, k)


@njit(cache=True)
def _joints(y, dY, h, m, dm, work, tw, o_part, o_vel):
    """``_kernel._joint_impulses`` (its arithmetic) with each joint's impulse differentiated before it is applied."""
    T, dT, fpos, fvel = work.T, tw.dT, work.fpos, work.fvel
    el_u, el_inv_len, el_inv_mass, el_T, el_arm = work.el_u, work.el_inv_len, work.el_inv_mass, work.el_T, work.el_arm
    el_ka, el_ia, el_ra, el_kb, el_ib, el_rb = m.el_ka, m.el_ia, m.el_ra, m.el_kb, m.el_ib, m.el_rb
    body_I, body_Iinv = m.body_I, m.body_Iinv
    for j in range(m.joint_b.shape[0]):
        s = m.joint_seg[j]
        c = m.seg_bend_c[s]
        mu = m.seg_link_mu[s]
        if c == 0.0 and mu == 0.0 and m.seg_bend_k[s] == 0.0:
            continue
        e2 = m.joint_b[j]
        e1 = m.joint_a[j]
        _, _, _, vxa, vya, vza, _, _, _ = _node(el_ka[e2], el_ia[e2], el_ra, e2, y, T, fpos, fvel, o_part, o_vel)
        _, _, _, vxb, vyb, vzb, _, _, _ = _node(el_kb[e2], el_ib[e2], el_rb, e2, y, T, fpos, fvel, o_part, o_vel)
        u2x, u2y, u2z = el_u[e2, 0], el_u[e2, 1], el_u[e2, 2]
        i2 = el_inv_len[e2]
        w2x = (u2y * (vzb - vza) - u2z * (vyb - vya)) * i2
        w2y = (u2z * (vxb - vxa) - u2x * (vzb - vza)) * i2
        w2z = (u2x * (vyb - vya) - u2y * (vxb - vxa)) * i2
        w = (el_inv_mass[e2, 1] + el_inv_mass[e2, 3]) * i2 * i2
        b = 0
        i1 = 1.0
        u1x, u1y, u1z = 0.0, 0.0, 0.0
        p, q, r = 0.0, 0.0, 0.0
        stiffness = 0.0
        if e1 >= 0:
            _, _, _, vxa, vya, vza, _, _, _ = _node(el_ka[e1], el_ia[e1], el_ra, e1, y, T, fpos, fvel, o_part, o_vel)
            _, _, _, vxb, vyb, vzb, _, _, _ = _node(el_kb[e1], el_ib[e1], el_rb, e1, y, T, fpos, fvel, o_part, o_vel)
            u1x, u1y, u1z = el_u[e1, 0], el_u[e1, 1], el_u[e1, 2]
            i1 = el_inv_len[e1]
            w1x = (u1y * (vzb - vza) - u1z * (vyb - vya)) * i1
            w1y = (u1z * (vxb - vxa) - u1x * (vzb - vza)) * i1
            w1z = (u1x * (vyb - vya) - u1y * (vxb - vxa)) * i1
            w += ((el_inv_mass[e1, 1] + el_inv_mass[e1, 3]) * i1 * i1
                  + 2.0 * (u1x * u2x + u1y * u2y + u1z * u2z) * el_inv_mass[e2, 0] * i1 * i2)
            tension = 0.5 * (el_T[e1] + el_T[e2])
            stiffness = 2.0 * m.seg_bend_k[s] * i1 * i2 / (i1 + i2)
        else:
            b = -e1 - 1
            p, q, r = y[12 * b + 9], y[12 * b + 10], y[12 * b + 11]
            w1x = T[b, 0, 0] * p + T[b, 0, 1] * q + T[b, 0, 2] * r
            w1y = T[b, 1, 0] * p + T[b, 1, 1] * q + T[b, 1, 2] * r
            w1z = T[b, 2, 0] * p + T[b, 2, 1] * q + T[b, 2, 2] * r
            w += 1.0 / min(body_I[b, 0, 0], min(body_I[b, 1, 1], body_I[b, 2, 2]))
            tension = el_T[e2]
        r0x, r0y, r0z = w2x - w1x, w2y - w1y, w2z - w1z
        along = r0x * u2x + r0y * u2y + r0z * u2z
        rx, ry, rz = r0x - along * u2x, r0y - along * u2y, r0z - along * u2z
        z = 4.0 * stiffness * w * h * h  # the stiffness's share of implicitness, beta, as the kernel's
        beta = 0.5 - 1.0 / z if z > 2.0 else 0.0
        cs = c + beta * stiffness * h
        den = 1.0 + cs * h * w
        kk = cs * h / den
        g = stiffness * h / den
        tx, ty, tz = u1y * u2z - u1z * u2y, u1z * u2x - u1x * u2z, u1x * u2y - u1y * u2x  # the bend, u1 x u2
        hx, hy, hz = -kk * rx - g * tx, -kk * ry - g * ty, -kk * rz - g * tz
        qx, qy, qz = rx + w * hx, ry + w * hy, rz + w * hz
        slip = False
        stop = False
        speed, limit, f = 0.0, 0.0, 0.0
        if mu > 0.0 and tension > 0.0:
            speed = np.sqrt(qx * qx + qy * qy + qz * qz)
            if speed > 0.0:
                limit = mu * m.seg_link_r[s] * tension * h
                f = min(speed / w, limit) / speed
                stop = speed / w <= limit
                slip = not stop
        for k in range(dY.shape[1]):
            dw2x, dw2y, dw2z = _spin_tangent(e2, y, dY, m, dm, work, tw, o_part, o_vel, k)
            du2x, du2y, du2z = tw.del_u[e2, 0, k], tw.del_u[e2, 1, k], tw.del_u[e2, 2, k]
            di2 = tw.del_inv_len[e2, k]
            dw = ((tw.del_inv_mass[e2, 1, k] + tw.del_inv_mass[e2, 3, k]) * i2 * i2
                  + 2.0 * (el_inv_mass[e2, 1] + el_inv_mass[e2, 3]) * i2 * di2)
            dstiffness = 0.0
            du1x, du1y, du1z = 0.0, 0.0, 0.0
            if e1 >= 0:
                dw1x, dw1y, dw1z = _spin_tangent(e1, y, dY, m, dm, work, tw, o_part, o_vel, k)
                du1x, du1y, du1z = tw.del_u[e1, 0, k], tw.del_u[e1, 1, k], tw.del_u[e1, 2, k]
                di1 = tw.del_inv_len[e1, k]
                dstiffness = 2.0 * (dm.seg_bend_k[s, k] * i1 * i2 / (i1 + i2)
                                    + m.seg_bend_k[s] * (di1 * i2 * i2 + di2 * i1 * i1) / ((i1 + i2) * (i1 + i2)))
                dot = u1x * u2x + u1y * u2y + u1z * u2z
                ddot = du1x * u2x + du1y * u2y + du1z * u2z + u1x * du2x + u1y * du2y + u1z * du2z
                m20 = el_inv_mass[e2, 0]
                dw += ((tw.del_inv_mass[e1, 1, k] + tw.del_inv_mass[e1, 3, k]) * i1 * i1
                       + 2.0 * (el_inv_mass[e1, 1] + el_inv_mass[e1, 3]) * i1 * di1
                       + 2.0 * (ddot * m20 * i1 * i2 + dot * (tw.del_inv_mass[e2, 0, k] * i1 * i2 + m20 * di1 * i2
                                                             + m20 * i1 * di2)))
                dtension = 0.5 * (tw.del_T[e1, k] + tw.del_T[e2, k])
            else:
                dp, dq, dr = dY[12 * b + 9, k], dY[12 * b + 10, k], dY[12 * b + 11, k]
                dw1x = dT[b, 0, 0, k] * p + dT[b, 0, 1, k] * q + dT[b, 0, 2, k] * r + T[b, 0, 0] * dp + T[b, 0, 1] * dq + T[b, 0, 2] * dr
                dw1y = dT[b, 1, 0, k] * p + dT[b, 1, 1, k] * q + dT[b, 1, 2, k] * r + T[b, 1, 0] * dp + T[b, 1, 1] * dq + T[b, 1, 2] * dr
                dw1z = dT[b, 2, 0, k] * p + dT[b, 2, 1, k] * q + dT[b, 2, 2, k] * r + T[b, 2, 0] * dp + T[b, 2, 1] * dq + T[b, 2, 2] * dr
                i_min = _smallest_inertia(body_I, b)
                dw -= dm.body_I[b, i_min, i_min, k] / (body_I[b, i_min, i_min] * body_I[b, i_min, i_min])
                dtension = tw.del_T[e2, k]
            dr0x, dr0y, dr0z = dw2x - dw1x, dw2y - dw1y, dw2z - dw1z
            dalong = dr0x * u2x + dr0y * u2y + dr0z * u2z + r0x * du2x + r0y * du2y + r0z * du2z
            drx = dr0x - dalong * u2x - along * du2x
            dry = dr0y - dalong * u2y - along * du2y
            drz = dr0z - dalong * u2z - along * du2z
            dbeta = 4.0 * h * h * (dstiffness * w + stiffness * dw) / (z * z) if z > 2.0 else 0.0
            dcs = dm.seg_bend_c[s, k] + (dbeta * stiffness + beta * dstiffness) * h
            dden = h * (dcs * w + cs * dw)
            dkk = (dcs * h - cs * cs * h * h * dw) / (den * den)
            dg = (dstiffness * h * den - stiffness * h * dden) / (den * den)
            dtx = du1y * u2z - du1z * u2y + u1y * du2z - u1z * du2y
            dty = du1z * u2x - du1x * u2z + u1z * du2x - u1x * du2z
            dtz = du1x * u2y - du1y * u2x + u1x * du2y - u1y * du2x
            dhx = -dkk * rx - kk * drx - dg * tx - g * dtx
            dhy = -dkk * ry - kk * dry - dg * ty - g * dty
            dhz = -dkk * rz - kk * drz - dg * tz - g * dtz
            dqx, dqy, dqz = drx + dw * hx + w * dhx, dry + dw * hy + w * dhy, drz + dw * hz + w * dhz
            if stop:  # the joint's rotation stopped: H - q / w
                dhx -= dqx / w - qx * dw / (w * w)
                dhy -= dqy / w - qy * dw / (w * w)
                dhz -= dqz / w - qz * dw / (w * w)
            elif slip:  # slipping at the limit mu r T h: H - (limit / speed) q
                dlimit = h * (dm.seg_link_mu[s, k] * m.seg_link_r[s] * tension + mu * dm.seg_link_r[s, k] * tension
                              + mu * m.seg_link_r[s] * dtension)
                dspeed = (qx * dqx + qy * dqy + qz * dqz) / speed
                df = dlimit / speed - limit * dspeed / (speed * speed)
                dhx -= df * qx + f * dqx
                dhy -= df * qy + f * dqy
                dhz -= df * qz + f * dqz
            fx, fy, fz = (hx - f * qx, hy - f * qy, hz - f * qz) if (stop or slip) else (hx, hy, hz)
            _kick_pair_tangent(e2, fx, fy, fz, dhx, dhy, dhz, 1.0, m, dm, work, tw, dY, o_vel, k)
            if e1 >= 0:
                _kick_pair_tangent(e1, fx, fy, fz, dhx, dhy, dhz, -1.0, m, dm, work, tw, dY, o_vel, k)
            else:
                _turn_tangent(b, -fx, -fy, -fz, -dhx, -dhy, -dhz, m, dm, work, tw, dY, k)
        if stop or slip:
            hx, hy, hz = hx - f * qx, hy - f * qy, hz - f * qz
        _apply_joint(y, m, work, e1, e2, b, hx, hy, hz, u1x, u1y, u1z, u2x, u2y, u2z, i1, i2, o_vel)


@njit(cache=True)
def _apply_joint(y, m, work, e1, e2, b, hx, hy, hz, u1x, u1y, u1z, u2x, u2y, u2z, i1, i2, o_vel):
    """The joint's impulses on its elements' ends (``_kernel._joint_impulses``'s last lines)."""
    T, el_inv_mass, el_arm, body_Iinv = work.T, work.el_inv_mass, work.el_arm, m.body_Iinv
    el_ka, el_ia, el_kb, el_ib = m.el_ka, m.el_ia, m.el_kb, m.el_ib
    jx = (hy * u2z - hz * u2y) * i2
    jy = (hz * u2x - hx * u2z) * i2
    jz = (hx * u2y - hy * u2x) * i2
    _kick(el_kb[e2], el_ib[e2], el_arm[e2, 3], el_arm[e2, 4], el_arm[e2, 5], jx, jy, jz, el_inv_mass[e2, 2], y, body_Iinv, T, o_vel)
    _kick(el_ka[e2], el_ia[e2], el_arm[e2, 0], el_arm[e2, 1], el_arm[e2, 2], -jx, -jy, -jz, el_inv_mass[e2, 0], y, body_Iinv, T, o_vel)
    if e1 >= 0:
        jx = -(hy * u1z - hz * u1y) * i1
        jy = -(hz * u1x - hx * u1z) * i1
        jz = -(hx * u1y - hy * u1x) * i1
        _kick(el_kb[e1], el_ib[e1], el_arm[e1, 3], el_arm[e1, 4], el_arm[e1, 5], jx, jy, jz, el_inv_mass[e1, 2], y, body_Iinv, T, o_vel)
        _kick(el_ka[e1], el_ia[e1], el_arm[e1, 0], el_arm[e1, 1], el_arm[e1, 2], -jx, -jy, -jz, el_inv_mass[e1, 0], y, body_Iinv, T, o_vel)
    else:
        _turn(b, -hx, -hy, -hz, y, body_Iinv, T)


@njit(cache=True)
def _ring_friction(y, dY, h, m, dm, work, tw, o_F, o_ring):
    """``_kernel.dissipate``'s ring friction (its arithmetic), differentiated before it acts.

    A slipping ring's rate loses sign(v) limit h / mass, limit = min(T_A, T_B)
    (e^(mu beta) - 1) + mu_b |T_B u_B - T_A u_A| with beta the angle the rope
    turns through; a stuck ring's rate is zero whatever the parameters, so is
    its tangent.
    """
    Lseg, el_u, el_T = work.Lseg, work.el_u, work.el_T
    for rg in range(m.ring_seg.shape[0]):
        mu, mu_b = m.ring_mu[rg], m.ring_bearing_mu[rg]
        if mu == 0.0 and mu_b == 0.0:
            continue
        s = m.ring_seg[rg]
        eA, eB = m.ring_eA[rg], m.ring_eB[rg]
        _dissipate_geometry(eA, y, m, work, o_F, o_ring)
        _dissipate_geometry(eB, y, m, work, o_F, o_ring)
        cosb = el_u[eA, 0] * el_u[eB, 0] + el_u[eA, 1] * el_u[eB, 1] + el_u[eA, 2] * el_u[eB, 2]
        beta = np.arccos(min(1.0, max(-1.0, cosb)))
        grow = np.exp(mu * beta)
        limit = min(el_T[eA], el_T[eB]) * (grow - 1.0)
        load = _bearing_load(el_T[eA], el_T[eB], cosb)
        if mu_b != 0.0:
            limit += mu_b * load
        mass = m.seg_rho[s] * Lseg[s] / 3.0 + m.ring_added_mass[rg]
        i = o_ring + 2 * rg + 1
        vs = y[i]
        if abs(vs) * mass <= limit * h:
            y[i] = 0.0  # stick
            for k in range(dY.shape[1]):
                dY[i, k] = 0.0
            continue
        sign = 1.0 if vs > 0.0 else (-1.0 if vs < 0.0 else 0.0)
        for k in range(dY.shape[1]):
            _, _, _, TA, dax, day, daz, dTA, _, _ = _element_geometry_tangent(eA, y, dY, m, dm, work, tw, o_F, k)
            _, _, _, TB, dbx, dby, dbz, dTB, _, _ = _element_geometry_tangent(eB, y, dY, m, dm, work, tw, o_F, k)
            dlow = dTA if el_T[eA] <= el_T[eB] else dTB
            low = min(el_T[eA], el_T[eB])
            dcos = (dax * el_u[eB, 0] + day * el_u[eB, 1] + daz * el_u[eB, 2]
                    + el_u[eA, 0] * dbx + el_u[eA, 1] * dby + el_u[eA, 2] * dbz)
            dbeta = -dcos / math.sqrt(1.0 - cosb * cosb) if abs(cosb) < 1.0 else 0.0
            dlimit = dlow * (grow - 1.0) + low * grow * (dm.ring_mu[rg, k] * beta + mu * dbeta)
            dlimit += dm.ring_bearing_mu[rg, k] * load
            if mu_b != 0.0 and load > 0.0:
                TA, TB = el_T[eA], el_T[eB]
                dlimit += mu_b * (TA * dTA + TB * dTB - cosb * (dTA * TB + TA * dTB) - TA * TB * dcos) / load
            dmass = (dm.seg_rho[s, k] * Lseg[s] + m.seg_rho[s] * tw.dLseg[s, k]) / 3.0 + dm.ring_added_mass[rg, k]
            dY[i, k] -= sign * h * (dlimit / mass - limit * dmass / (mass * mass))
        y[i] = vs - np.sign(vs) * limit * h / mass
