"""Forward sensitivities: the derivative of the Verlet scheme itself, carried with the state.

The tangent of each step is the exact derivative of the discrete step
(``_verlet._step`` and ``_kernel.rhs_maxwell_update``) with respect to a set
of directions in the model's parameters, so a Jacobian built from it is the
Jacobian of the discrete model that ``simulate`` integrates, to rounding,
with the step schedule frozen (each record interval's step count as the
plain run chose it). The tangents of all directions are carried together,
``nd`` of them in the last axis of every tangent array, and each element's
geometry (unit vector, length, tension) is computed once for all of them.

A direction is a perturbation of the kernel model's parameter arrays
(``TANGENT_FIELDS``: masses, inertias, lever arms, rope stiffness and
damping, lengths, densities, drag areas, a sheave's added mass, bearing
damping and friction, the joints' bending damping and link friction, the
reel and fixed-point tables), with the initial state's own perturbation; ``_sensitivity`` maps a rig's parameters onto both.

The dissipative impulses after each step (``_kernel.dissipate``: the
joints' bending damping and chain-link friction, ring friction) are
differentiated in ``_tangent_impulses``.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ._kernel import (NO_REFCOUNT, REBASE_ROLL, _body_matrix, _body_pose, _offsets, rebase, record_state, rhs,
                      rhs_maxwell_update)
from ._tangent_impulses import impulses_tangent
from ._verlet import _euler_angle_rates_trig, _maxwell_factors, element_stretch

__all__ = ["TANGENT_FIELDS", "TangentModel", "make_tangent_work", "integrate_tangent", "rhs_tangent_at"]

# The kernel model's fields a direction perturbs; each tangent array has the field's shape plus (nd,).
TANGENT_FIELDS = (
    "body_mass", "body_I", "body_Iinv", "bnode_arm", "el_ra", "el_rb",
    "seg_ks", "seg_kv", "seg_relax", "seg_len0", "seg_reel_off", "seg_rho", "seg_cda",
    "ring_added_mass", "ring_visc", "ring_mu", "body_cda", "reel_len", "point_pos",
    "seg_bend_c", "seg_bend_k", "seg_link_mu", "seg_link_r", "body_lin_drag", "ring_bearing_mu",
)
TangentModel = namedtuple("TangentModel", TANGENT_FIELDS)

TangentWork = namedtuple("TangentWork", [
    "dT", "dref", "dtrig",  # (nb, 3, 3, nd), (nb, 3, 3, nd), (nb, 4, nd)
    "dLseg", "dreel", "dfpos", "dfvel",  # (S, nd), (reels, nd), (F, 3, nd) x 2
    "dnx", "dnarm", "dnf",  # (nodes, 3, nd), (body ends, 3, nd), (nodes, 3, nd)
    "dfb", "dmb", "dsumA", "dsumB",  # (nb, 3, nd) x 2, (R, nd) x 2
    "drest", "dinv_rest",  # (S, sides, nd)
    "deps",  # (E, nd) stretch ratios' tangents at the step's start, then its end
    "dinv_mass_seg", "dcda_seg",  # (S, nd)
    "F_then", "eps_then",  # (E,) the Maxwell forces and stretch ratios before the primal update
    "dR",  # (3, 3, nd) one body's rotation tangent in its chart
    "seg_phi", "seg_dphi", "step",  # (S,) phi(lambda h) and its derivative per segment, for step h (1,)
    # the joints' sweep: each element's unit vector, 1 / length, tension, lever arms, inverse masses (``work.el_*``)
    "del_u", "del_inv_len", "del_T", "del_arm", "del_inv_mass",  # (E, 3 | - | - | 6 | 4, nd)
])


def make_tangent_work(m, nd):
    """A ``TangentWork`` for the kernel model ``m`` and ``nd`` directions."""
    nb, P, S, R, E = m.nb, m.part_seg.shape[0], m.seg_ks.shape[0], m.ring_seg.shape[0], m.el_seg.shape[0]
    F = max(m.point_pos.shape[1], 1)
    NB = max(m.bnode_body.shape[0], 1)
    nodes = max(P + m.bnode_body.shape[0] + m.point_pos.shape[1], 1)
    sides = 2 + (int(m.seg_nring.max()) if S else 0)
    z = np.zeros
    return TangentWork(
        dT=z((max(nb, 1), 3, 3, nd)), dref=z((max(nb, 1), 3, 3, nd)), dtrig=z((max(nb, 1), 4, nd)),
        dLseg=z((S, nd)), dreel=z((m.reel_len.shape[1], nd)), dfpos=z((F, 3, nd)), dfvel=z((F, 3, nd)),
        dnx=z((nodes, 3, nd)), dnarm=z((NB, 3, nd)), dnf=z((nodes, 3, nd)),
        dfb=z((max(nb, 1), 3, nd)), dmb=z((max(nb, 1), 3, nd)), dsumA=z((max(R, 1), nd)), dsumB=z((max(R, 1), nd)),
        drest=z((S, sides, nd)), dinv_rest=z((S, sides, nd)), deps=z((E, nd)),
        dinv_mass_seg=z((S, nd)), dcda_seg=z((S, nd)), F_then=z(E), eps_then=z(E),
        dR=z((3, 3, nd)),
        seg_phi=z(S), seg_dphi=z(S), step=np.full(1, -1.0),
        del_u=z((E, 3, nd)), del_inv_len=z((E, nd)), del_T=z((E, nd)), del_arm=z((E, 6, nd)),
        del_inv_mass=z((E, 4, nd)),
    )


@njit(cache=True, inline="always")
def _interval(t, times):
    """(k, w): ``_kernel``'s linear interpolation in ``times`` at t is row k + w (row k + 1 - row k); held outside."""
    n = times.shape[0]
    if n == 1 or t <= times[0]:
        return 0, 0.0
    if t >= times[n - 1]:
        return n - 1, 0.0
    k = np.searchsorted(times, t, side="right") - 1
    return k, (t - times[k]) / (times[k + 1] - times[k])


@njit(cache=True, inline="always")
def _tables_tangent(t, m, dm, tw):
    """The tangents of the reels' lengths and the fixed points' positions at t (``tw.dreel``, ``tw.dfpos``)."""
    k, w = _interval(t, m.reel_t)
    k1 = min(k + 1, m.reel_t.shape[0] - 1)
    nd = tw.dreel.shape[1]
    for j in range(dm.reel_len.shape[1]):
        for d in range(nd):
            tw.dreel[j, d] = dm.reel_len[k, j, d] + w * (dm.reel_len[k1, j, d] - dm.reel_len[k, j, d])
    n = m.reel_t.shape[0]
    inside = n > 1 and m.reel_t[0] < t < m.reel_t[n - 1]
    for i in range(dm.point_pos.shape[1]):
        for c in range(3):
            for d in range(nd):
                a = dm.point_pos[k, i, c, d]
                tw.dfpos[i, c, d] = a + w * (dm.point_pos[k1, i, c, d] - a)
                tw.dfvel[i, c, d] = (dm.point_pos[k1, i, c, d] - a) / (m.reel_t[k1] - m.reel_t[k]) if inside else 0.0


@njit(cache=True, inline="always")
def _rotation_tangent(sf, cf, pitch, ss, cs, dY, o, dR):
    """dR (3, 3, nd): the tangent of Eq. 11's matrix R(roll, pitch, yaw) along the angles' tangents dY[o + 6:o + 9].

    ``sf``, ``cf``, ``ss``, ``cs``: the sines and cosines of roll and yaw.
    """
    st, ct = math.sin(pitch), math.cos(pitch)
    # partial derivatives of _kernel._body_matrix's entries, by roll (a), pitch (b) and yaw (c)
    a00, a01, a02 = ss * cf * st, cs * cf * st, -sf * st
    a10, a11, a12 = -ss * sf, -cs * sf, -cf
    a20, a21, a22 = ss * cf * ct, cs * cf * ct, -sf * ct
    b00, b01, b02 = -cs * st + ss * sf * ct, ss * st + cs * sf * ct, cf * ct
    b20, b21, b22 = -cs * ct - ss * sf * st, ss * ct - cs * sf * st, -cf * st
    c00, c01 = -ss * ct + cs * sf * st, -cs * ct - ss * sf * st
    c10, c11 = cs * cf, -ss * cf
    c20, c21 = ss * st + cs * sf * ct, cs * st - ss * sf * ct
    for k in range(dR.shape[2]):
        da, db, dc = dY[o + 6, k], dY[o + 7, k], dY[o + 8, k]
        dR[0, 0, k] = a00 * da + b00 * db + c00 * dc
        dR[0, 1, k] = a01 * da + b01 * db + c01 * dc
        dR[0, 2, k] = a02 * da + b02 * db
        dR[1, 0, k] = a10 * da + c10 * dc
        dR[1, 1, k] = a11 * da + c11 * dc
        dR[1, 2, k] = a12 * da
        dR[2, 0, k] = a20 * da + b20 * db + c20 * dc
        dR[2, 1, k] = a21 * da + b21 * db + c21 * dc
        dR[2, 2, k] = a22 * da + b22 * db


@njit(cache=True, inline="always")
def _pose_tangent(y, dY, b, work, tw, dT):
    """dT[b] (3, 3, nd): the tangent of body b's matrix ``ref @ R(angles)``, chart included."""
    o = 12 * b
    dR = tw.dR
    _rotation_tangent(math.sin(y[o + 6]), math.cos(y[o + 6]), y[o + 7], math.sin(y[o + 8]), math.cos(y[o + 8]),
                      dY, o, dR)
    _chart_tangent(y, b, work, tw, dT)


@njit(cache=True, inline="always")
def _pose_tangent_trig(y, dY, b, work, tw, dT):
    """``_pose_tangent`` with roll's and yaw's sines and cosines from ``work.trig`` (the primal's, at y)."""
    o = 12 * b
    _rotation_tangent(work.trig[b, 0], work.trig[b, 1], y[o + 7], work.trig[b, 2], work.trig[b, 3], dY, o, tw.dR)
    _chart_tangent(y, b, work, tw, dT)


@njit(cache=True, inline="always")
def _chart_tangent(y, b, work, tw, dT):
    """dT[b] from dR (``tw.dR``): itself, or ``dref @ R + ref @ dR`` for a body whose chart moved."""
    o = 12 * b
    dR = tw.dR
    nd = dR.shape[2]
    if work.rebased[b] == 0:
        for i in range(3):
            for j in range(3):
                for k in range(nd):
                    dT[b, i, j, k] = dR[i, j, k]
        return
    R = work.pose  # scratch: R itself, row b
    _body_matrix(y[o + 6], y[o + 7], y[o + 8], R, b)
    ref, dref = work.ref, tw.dref
    for i in range(3):
        for j in range(3):
            for k in range(nd):
                acc = 0.0
                for l in range(3):
                    acc += dref[b, i, l, k] * R[b, l, j] + ref[b, i, l] * dR[l, j, k]
                dT[b, i, j, k] = acc


@njit(cache=True, inline="always")
def _phi_factors(m, tw, h):
    """phi(x) and phi'(x) per segment, x = lambda h, phi(x) = (1 - e^-x) / x; recomputed only when h changes."""
    if tw.step[0] == h:
        return
    tw.step[0] = h
    for s in range(m.seg_relax.shape[0]):
        x = m.seg_relax[s] * h
        if x > 1e-4:
            tw.seg_dphi[s] = (math.exp(-x) * (1.0 + x) - 1.0) / (x * x)
            tw.seg_phi[s] = -math.expm1(-x) / x
        else:  # series: the closed form loses digits to cancellation
            tw.seg_dphi[s] = -0.5 + x / 3.0 - x * x / 8.0
            tw.seg_phi[s] = 1.0 - x / 2.0 + x * x / 6.0 if x > 0.0 else 1.0


@njit(cache=True, **NO_REFCOUNT)
def rhs_tangent(t, y, dY, dacc, m, dm, work, tw, h):
    """The tangent of ``_kernel._rhs`` at (t, y), called right after it (it reads the primal's ``work``).

    ``dY`` (n, nd): the state's tangents; with a step ``h`` > 0 its Maxwell
    forces' rows are advanced as ``rhs_maxwell_update`` advanced the state's
    (from ``tw.F_then`` and ``tw.eps_then``, what they were before it, over
    step ``h``); ``h`` = 0 advances nothing. ``dacc`` (n, nd) receives the
    accelerations' tangents (only those rows). ``tw.deps`` holds the stretch
    ratios' tangents at the step's start on entry (``h`` > 0) and at (t, y)
    on return.
    """
    # Derived, not passed: a constant True or False in the call would be a literal type, and numba would compile
    # this whole tree once for each (about a third of the tangent's compile time).
    update = h > 0.0
    nb, nd = m.nb, dY.shape[1]
    P, E, R, S = m.part_seg.shape[0], m.el_seg.shape[0], m.ring_seg.shape[0], m.seg_ks.shape[0]
    o_part, o_vel, o_F, o_ring = _offsets(m)
    T, Lseg, nx, narm, nf = work.T, work.Lseg, work.nx, work.narm, work.nf
    rest, inv_rest = work.rest, work.inv_rest
    dT, dLseg, dnx, dnarm, dnf = tw.dT, tw.dLseg, tw.dnx, tw.dnarm, tw.dnf
    drest, dinv_rest, deps = tw.drest, tw.dinv_rest, tw.deps
    dfb, dmb, dsumA, dsumB = tw.dfb, tw.dmb, tw.dsumA, tw.dsumB

    _tables_tangent(t, m, dm, tw)
    for b in range(nb):
        _pose_tangent_trig(y, dY, b, work, tw, dT)
        o = 12 * b
        sf, cf, ss, cs = work.trig[b, 0], work.trig[b, 1], work.trig[b, 2], work.trig[b, 3]
        for k in range(nd):
            tw.dtrig[b, 0, k] = cf * dY[o + 6, k]
            tw.dtrig[b, 1, k] = -sf * dY[o + 6, k]
            tw.dtrig[b, 2, k] = cs * dY[o + 8, k]
            tw.dtrig[b, 3, k] = -ss * dY[o + 8, k]
    for s in range(S):
        r = m.seg_reel[s]
        for k in range(nd):
            dLseg[s, k] = dm.seg_len0[s, k] if r < 0 else tw.dreel[r, k] - dm.seg_reel_off[s, k]
    # the element ends' positions (``_gather_nodes``)
    for i in range(P):
        for c in range(3):
            for k in range(nd):
                dnx[i, c, k] = dY[o_part + 3 * i + c, k]
    NB = m.bnode_body.shape[0]
    for q in range(NB):
        b = m.bnode_body[q]
        r0, r1, r2 = m.bnode_arm[q, 0], m.bnode_arm[q, 1], m.bnode_arm[q, 2]
        for c in range(3):
            for k in range(nd):
                da = (dT[b, c, 0, k] * r0 + dT[b, c, 1, k] * r1 + dT[b, c, 2, k] * r2
                      + T[b, c, 0] * dm.bnode_arm[q, 0, k] + T[b, c, 1] * dm.bnode_arm[q, 1, k]
                      + T[b, c, 2] * dm.bnode_arm[q, 2, k])
                dnarm[q, c, k] = da
                dnx[P + q, c, k] = dY[12 * b + c, k] + da
    for f in range(m.point_pos.shape[1]):
        for c in range(3):
            for k in range(nd):
                dnx[P + NB + f, c, k] = tw.dfpos[f, c, k]
    # rest lengths per segment side (``_span_rest``)
    for s in range(S):
        n = m.seg_nel[s]
        for k in range(nd):
            drest[s, 0, k] = dLseg[s, k] / n
        spans = m.seg_nring[s] + 1 if m.seg_ring[s] >= 0 else 0
        r0 = m.seg_ring[s]
        for side in range(1, spans + 1):
            j = side - 1
            if j < m.seg_nring[s]:
                n_span = m.ring_nelA[r0 + j]
            else:
                n_span = m.ring_nelB[r0 + j - 1]
            for k in range(nd):
                hi = dY[o_ring + 2 * (r0 + j), k] if j < m.seg_nring[s] else dLseg[s, k]
                lo = dY[o_ring + 2 * (r0 + j - 1), k] if j > 0 else 0.0
                drest[s, side, k] = (hi - lo) / n_span
        for side in range(spans + 1):
            inv2 = inv_rest[s, side] * inv_rest[s, side]
            for k in range(nd):
                dinv_rest[s, side, k] = -drest[s, side, k] * inv2
    dnf[:, :, :] = 0.0
    dfb[:, :, :] = 0.0
    dmb[:, :, :] = 0.0
    dsumA[:, :] = 0.0
    dsumB[:, :] = 0.0
    _elements_tangent(y, dY, m, dm, work, tw, update, h, o_F)
    # each body end's force on its body, and its moment about the mass centre
    for q in range(NB):
        b = m.bnode_body[q]
        fx, fy, fz = nf[P + q, 0], nf[P + q, 1], nf[P + q, 2]
        a0, a1, a2 = narm[q, 0], narm[q, 1], narm[q, 2]
        for k in range(nd):
            gx, gy, gz = dnf[P + q, 0, k], dnf[P + q, 1, k], dnf[P + q, 2, k]
            b0, b1, b2 = dnarm[q, 0, k], dnarm[q, 1, k], dnarm[q, 2, k]
            dfb[b, 0, k] += gx
            dfb[b, 1, k] += gy
            dfb[b, 2, k] += gz
            dmb[b, 0, k] += b1 * fz - b2 * fy + a1 * gz - a2 * gy
            dmb[b, 1, k] += b2 * fx - b0 * fz + a2 * gx - a0 * gz
            dmb[b, 2, k] += b0 * fy - b1 * fx + a0 * gy - a1 * gx
    _particles_tangent(y, dY, dacc, m, dm, work, tw, o_part, o_vel)
    for b in range(nb):
        _body_tangent(b, y, dY, dacc, m, dm, work, tw)
    rd = m.relax_damping
    for rg in range(R):
        s = m.ring_seg[rg]
        vs = y[o_ring + 2 * rg + 1]
        mass = m.seg_rho[s] * Lseg[s] / 3.0 + m.ring_added_mass[rg]
        net = work.sumA[rg] / m.ring_nelA[rg] - work.sumB[rg] / m.ring_nelB[rg] - m.ring_visc[rg] * vs
        for k in range(nd):
            dmass = (dm.seg_rho[s, k] * Lseg[s] + m.seg_rho[s] * dLseg[s, k]) / 3.0 + dm.ring_added_mass[rg, k]
            dvs = dY[o_ring + 2 * rg + 1, k]
            dnet = (dsumA[rg, k] / m.ring_nelA[rg] - dsumB[rg, k] / m.ring_nelB[rg]
                    - dm.ring_visc[rg, k] * vs - m.ring_visc[rg] * dvs)
            dacc[o_ring + 2 * rg + 1, k] = dnet / mass - net * dmass / (mass * mass) - rd * dvs


@njit(cache=True, inline="always")
def _elements_tangent(y, dY, m, dm, work, tw, update, h, o_F):
    """The elements' tangents: Maxwell forces (``update``), stretch ratios, node forces, ring pulls.

    Each element's geometry and tension are computed once, then all of its
    directions in one loop: the per-element cost of a direction loop is paid
    once, not once per quantity (one direction cost three plain runs when it
    was paid six times).
    """
    nd = dY.shape[1]
    nx, rest, inv_rest = work.nx, work.rest, work.inv_rest
    dnx, drest, dinv_rest, deps, dnf = tw.dnx, tw.drest, tw.dinv_rest, tw.deps, tw.dnf
    for e in range(m.el_seg.shape[0]):
        s, side = m.el_seg[e], m.el_side[e]
        na, nb_ = m.el_na[e], m.el_nb[e]
        Le = rest[s, side]
        dx, dyy, dz = nx[nb_, 0] - nx[na, 0], nx[nb_, 1] - nx[na, 1], nx[nb_, 2] - nx[na, 2]
        length = np.sqrt(dx * dx + dyy * dyy + dz * dz)
        inv = 1.0 / length
        ux, uy, uz = dx * inv, dyy * inv, dz * inv
        eps_now = length / Le
        taut = length > Le
        ks = m.seg_ks[s]
        invL = inv_rest[s, side]
        stretch = length - Le
        tension = ks * invL * stretch + y[o_F + e] if taut else 0.0
        if tension <= 0.0:
            tension = 0.0
        maxwell = update and taut
        reset = update and not taut
        decay, gain, phi, kv_dphi_h, F_then, jump, was_taut = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
        if maxwell:
            eps_then = tw.eps_then[e]
            decay, gain = work.seg_decay[s], work.seg_gain[s]
            phi, kv_dphi_h = tw.seg_phi[s], m.seg_kv[s] * tw.seg_dphi[s] * h
            F_then = tw.F_then[e]
            jump = eps_now - max(eps_then, 1.0)
            was_taut = eps_then > 1.0
        pulls = side > 0
        grow, shrink, r = 0.0, 0.0, 0
        if pulls:
            K = ks + m.seg_kv[s]
            grow = 1.0 + tension / K
            shrink = tension * tension / (2.0 * K * K)
            r = m.seg_ring[s] + side - 1
        into_a = pulls and side <= m.seg_nring[s]
        into_b = pulls and side >= 2
        for k in range(nd):
            d0 = dnx[nb_, 0, k] - dnx[na, 0, k]
            d1 = dnx[nb_, 1, k] - dnx[na, 1, k]
            d2 = dnx[nb_, 2, k] - dnx[na, 2, k]
            dlen = ux * d0 + uy * d1 + uz * d2
            dr = drest[s, side, k]
            deps_now = (dlen - eps_now * dr) / Le
            if maxwell:
                # exp(-lambda h) and Kv phi(lambda h), differentiated
                ddecay = -h * decay * dm.seg_relax[s, k]
                dgain = dm.seg_kv[s, k] * phi + kv_dphi_h * dm.seg_relax[s, k]
                djump = deps_now - (deps[e, k] if was_taut else 0.0)
                dY[o_F + e, k] = ddecay * F_then + decay * dY[o_F + e, k] + dgain * jump + gain * djump
            elif reset:
                dY[o_F + e, k] = 0.0
            deps[e, k] = deps_now
            if tension == 0.0:
                dtens = 0.0
            else:
                dtens = (dm.seg_ks[s, k] * invL * stretch + ks * dinv_rest[s, side, k] * stretch
                         + ks * invL * (dlen - dr) + dY[o_F + e, k])
            if pulls:
                dpull = dtens * grow - shrink * (dm.seg_ks[s, k] + dm.seg_kv[s, k])
                if into_a:
                    tw.dsumA[r, k] += dpull
                if into_b:
                    tw.dsumB[r - 1, k] += dpull
            if tension != 0.0:
                f0 = dtens * ux + tension * (d0 - ux * dlen) * inv
                f1 = dtens * uy + tension * (d1 - uy * dlen) * inv
                f2 = dtens * uz + tension * (d2 - uz * dlen) * inv
                dnf[na, 0, k] += f0
                dnf[na, 1, k] += f1
                dnf[na, 2, k] += f2
                dnf[nb_, 0, k] -= f0
                dnf[nb_, 1, k] -= f1
                dnf[nb_, 2, k] -= f2


@njit(cache=True, inline="always")
def _particles_tangent(y, dY, dacc, m, dm, work, tw, o_part, o_vel):
    """The particles' accelerations' tangents (lumped masses from the segments' lengths, air drag)."""
    nd = dY.shape[1]
    Lseg, nf, dnf, dLseg = work.Lseg, work.nf, tw.dnf, tw.dLseg
    rd, rho_air = m.relax_damping, m.air_density
    for s in range(m.seg_rho.shape[0]):
        ims = work.inv_mass_seg[s]
        for k in range(nd):
            tw.dinv_mass_seg[s, k] = -ims * (dm.seg_rho[s, k] / m.seg_rho[s] + dLseg[s, k] / Lseg[s])
            tw.dcda_seg[s, k] = (dm.seg_cda[s, k] * Lseg[s] + m.seg_cda[s] * dLseg[s, k]) / m.seg_npart[s]
    for i in range(m.part_seg.shape[0]):
        s = m.part_seg[i]
        scale = m.part_accel_scale[i]
        inv_mass = work.inv_mass_seg[s] * scale
        cda = work.cda_seg[s]
        o = o_vel + 3 * i
        vx, vy, vz = y[o], y[o + 1], y[o + 2]
        speed = np.sqrt(vx * vx + vy * vy + vz * vz)
        drag = 0.5 * rho_air * cda * speed
        for k in range(nd):
            dspeed = (vx * dY[o, k] + vy * dY[o + 1, k] + vz * dY[o + 2, k]) / speed if speed > 0.0 else 0.0
            ddrag = 0.5 * rho_air * (tw.dcda_seg[s, k] * speed + cda * dspeed)
            dinv = tw.dinv_mass_seg[s, k] * scale
            for c in range(3):
                v = y[o + c]
                dacc[o + c, k] = ((dnf[i, c, k] - ddrag * v - drag * dY[o + c, k]) * inv_mass
                                  + (nf[i, c] - drag * v) * dinv - rd * dY[o + c, k])


@njit(cache=True, inline="always")
def _body_tangent(b, y, dY, dacc, m, dm, work, tw):
    """Body b's accelerations' tangents: translation (mass, drag) and Euler's equations."""
    nd = dY.shape[1]
    o = 12 * b
    T, fb, mb, dT, dfb, dmb = work.T, work.fb, work.mb, tw.dT, tw.dfb, tw.dmb
    I, Iinv, dI, dIinv = m.body_I, m.body_Iinv, dm.body_I, dm.body_Iinv
    rd, scale, mass = m.relax_damping, m.body_accel_scale[b], m.body_mass[b]
    vx, vy, vz = y[o + 3], y[o + 4], y[o + 5]
    speed = np.sqrt(vx * vx + vy * vy + vz * vz)
    cda = m.body_cda[b]
    drag = 0.5 * m.air_density * cda * speed + m.body_lin_drag[b]
    p, q, r = y[o + 9], y[o + 10], y[o + 11]
    M0 = T[b, 0, 0] * mb[b, 0] + T[b, 1, 0] * mb[b, 1] + T[b, 2, 0] * mb[b, 2]
    M1 = T[b, 0, 1] * mb[b, 0] + T[b, 1, 1] * mb[b, 1] + T[b, 2, 1] * mb[b, 2]
    M2 = T[b, 0, 2] * mb[b, 0] + T[b, 1, 2] * mb[b, 1] + T[b, 2, 2] * mb[b, 2]
    hx = I[b, 0, 0] * p + I[b, 0, 1] * q + I[b, 0, 2] * r
    hy = I[b, 1, 0] * p + I[b, 1, 1] * q + I[b, 1, 2] * r
    hz = I[b, 2, 0] * p + I[b, 2, 1] * q + I[b, 2, 2] * r
    g0, g1, g2 = M0 - (q * hz - r * hy), M1 - (r * hx - p * hz), M2 - (p * hy - q * hx)
    for k in range(nd):
        dspeed = (vx * dY[o + 3, k] + vy * dY[o + 4, k] + vz * dY[o + 5, k]) / speed if speed > 0.0 else 0.0
        ddrag = 0.5 * m.air_density * (dm.body_cda[b, k] * speed + cda * dspeed) + dm.body_lin_drag[b, k]
        dmass = dm.body_mass[b, k]
        for c in range(3):
            v, dv = y[o + 3 + c], dY[o + 3 + c, k]
            dacc[o + 3 + c, k] = ((dfb[b, c, k] - ddrag * v - drag * dv) / mass
                                  - (fb[b, c] - drag * v) * dmass / (mass * mass)) * scale - rd * dv
        dp, dq, dr = dY[o + 9, k], dY[o + 10, k], dY[o + 11, k]
        dM0 = 0.0
        dM1 = 0.0
        dM2 = 0.0
        for j in range(3):
            dM0 += dT[b, j, 0, k] * mb[b, j] + T[b, j, 0] * dmb[b, j, k]
            dM1 += dT[b, j, 1, k] * mb[b, j] + T[b, j, 1] * dmb[b, j, k]
            dM2 += dT[b, j, 2, k] * mb[b, j] + T[b, j, 2] * dmb[b, j, k]
        dh0 = dI[b, 0, 0, k] * p + dI[b, 0, 1, k] * q + dI[b, 0, 2, k] * r + I[b, 0, 0] * dp + I[b, 0, 1] * dq + I[b, 0, 2] * dr
        dh1 = dI[b, 1, 0, k] * p + dI[b, 1, 1, k] * q + dI[b, 1, 2, k] * r + I[b, 1, 0] * dp + I[b, 1, 1] * dq + I[b, 1, 2] * dr
        dh2 = dI[b, 2, 0, k] * p + dI[b, 2, 1, k] * q + dI[b, 2, 2, k] * r + I[b, 2, 0] * dp + I[b, 2, 1] * dq + I[b, 2, 2] * dr
        dg0 = dM0 - (dq * hz + q * dh2 - dr * hy - r * dh1)
        dg1 = dM1 - (dr * hx + r * dh0 - dp * hz - p * dh2)
        dg2 = dM2 - (dp * hy + p * dh1 - dq * hx - q * dh0)
        for c in range(3):
            dacc[o + 9 + c, k] = ((dIinv[b, c, 0, k] * g0 + dIinv[b, c, 1, k] * g1 + dIinv[b, c, 2, k] * g2
                                   + Iinv[b, c, 0] * dg0 + Iinv[b, c, 1] * dg1 + Iinv[b, c, 2] * dg2) * scale
                                  - rd * dY[o + 9 + c, k])


@njit(cache=True, inline="always")
def _rates_tangent(sf, cf, ss, cs, dsf, dcf, dss, dcs, p, q, r, dp, dq, dr):
    """The tangent of ``_verlet._euler_angle_rates_trig`` (Eq. 3)."""
    pitch_rate = (p * ss + q * cs) / cf
    dpitch = (dp * ss + p * dss + dq * cs + q * dcs - pitch_rate * dcf) / cf
    return dp * cs + p * dcs - dq * ss - q * dss, dpitch, dr + dpitch * sf + pitch_rate * dsf


@njit(cache=True, inline="always")
def _step_tangent(t, h, y, acc, y_eval, dY, dacc, dY_eval, m, dm, work, tw):
    """``_verlet._step`` with its tangent: the same arithmetic on the state, its derivative on ``dY``."""
    nb, nd = m.nb, dY.shape[1]
    R = m.ring_seg.shape[0]
    o_part, o_vel, o_F, o_ring = _offsets(m)
    half = 0.5 * h
    for b in range(nb):
        o = 12 * b
        for c in range(3):
            y[o + 3 + c] += half * acc[o + 3 + c]
            y[o + 9 + c] += half * acc[o + 9 + c]
            for k in range(nd):
                dY[o + 3 + c, k] += half * dacc[o + 3 + c, k]
                dY[o + 9 + c, k] += half * dacc[o + 9 + c, k]
        for c in range(3):
            y[o + c] += h * y[o + 3 + c]
            for k in range(nd):
                dY[o + c, k] += h * dY[o + 3 + c, k]
        roll, pitch, yaw = y[o + 6], y[o + 7], y[o + 8]
        p, q, r = y[o + 9], y[o + 10], y[o + 11]
        sf, cf, ss, cs = work.trig[b, 0], work.trig[b, 1], work.trig[b, 2], work.trig[b, 3]
        d0, d1, d2 = _euler_angle_rates_trig(sf, cf, ss, cs, p, q, r)
        roll_m, yaw_m = roll + half * d0, yaw + half * d2
        sfm, cfm, ssm, csm = math.sin(roll_m), math.cos(roll_m), math.sin(yaw_m), math.cos(yaw_m)
        for k in range(nd):
            dp, dq, dr = dY[o + 9, k], dY[o + 10, k], dY[o + 11, k]
            e0, _, e2 = _rates_tangent(sf, cf, ss, cs, tw.dtrig[b, 0, k], tw.dtrig[b, 1, k], tw.dtrig[b, 2, k],
                                       tw.dtrig[b, 3, k], p, q, r, dp, dq, dr)
            droll = dY[o + 6, k] + half * e0
            dyaw = dY[o + 8, k] + half * e2
            e0, e1, e2 = _rates_tangent(sfm, cfm, ssm, csm, cfm * droll, -sfm * droll, csm * dyaw, -ssm * dyaw,
                                        p, q, r, dp, dq, dr)
            dY[o + 6, k] += h * e0
            dY[o + 7, k] += h * e1
            dY[o + 8, k] += h * e2
        d0, d1, d2 = _euler_angle_rates_trig(sfm, cfm, ssm, csm, p, q, r)  # the same bits as _euler_angle_rates
        y[o + 6] = roll + h * d0
        y[o + 7] = pitch + h * d1
        y[o + 8] = yaw + h * d2
        for c in range(12):
            y_eval[o + c] = y[o + c]
            for k in range(nd):
                dY_eval[o + c, k] = dY[o + c, k]
        for c in range(3):
            y_eval[o + 3 + c] += half * acc[o + 3 + c]
            y_eval[o + 9 + c] += half * acc[o + 9 + c]
            for k in range(nd):
                dY_eval[o + 3 + c, k] += half * dacc[o + 3 + c, k]
                dY_eval[o + 9 + c, k] += half * dacc[o + 9 + c, k]
    to_vel = o_vel - o_part
    for i in range(o_part, o_vel):
        _drift_pair(i, i + to_vel, h, half, y, acc, y_eval, dY, dacc, dY_eval)
    for e in range(o_F, o_ring):
        y_eval[e] = y[e]
        tw.F_then[e - o_F] = y[e]
        for k in range(nd):
            dY_eval[e, k] = dY[e, k]
    for rg in range(R):
        i = o_ring + 2 * rg
        _drift_pair(i, i + 1, h, half, y, acc, y_eval, dY, dacc, dY_eval)
    for e in range(tw.eps_then.shape[0]):
        tw.eps_then[e] = work.eps[e]
    _maxwell_factors(h, m, work)
    _phi_factors(m, tw, h)
    rhs_maxwell_update(t + h, y_eval, acc, m, work)  # a call, not inlined: compiled once, in the kernel's cache
    rhs_tangent(t + h, y_eval, dY_eval, dacc, m, dm, work, tw, h)
    for e in range(o_F, o_ring):
        y[e] = y_eval[e]
        for k in range(nd):
            dY[e, k] = dY_eval[e, k]
    for b in range(nb):
        o = 12 * b
        for c in range(3):
            _kick_row(o + 3 + c, half, y, acc, dY, dacc)
            _kick_row(o + 9 + c, half, y, acc, dY, dacc)
    for i in range(o_vel, o_F):
        _kick_row(i, half, y, acc, dY, dacc)
    for rg in range(R):
        _kick_row(o_ring + 2 * rg + 1, half, y, acc, dY, dacc)
    if m.has_joints != 0 or m.has_ring_friction != 0:
        impulses_tangent(y, dY, h, m, dm, work, tw)


@njit(cache=True, inline="always")
def _drift_pair(ix, iv, h, half, y, acc, y_eval, dY, dacc, dY_eval):
    """Kick and drift of one position ``ix`` and its velocity ``iv``, and their evaluation state, with tangents."""
    v = y[iv] + half * acc[iv]
    x = y[ix] + h * v
    y[ix], y[iv] = x, v
    y_eval[ix], y_eval[iv] = x, v + half * acc[iv]
    for k in range(dY.shape[1]):
        dv = dY[iv, k] + half * dacc[iv, k]
        dx = dY[ix, k] + h * dv
        dY[ix, k], dY[iv, k] = dx, dv
        dY_eval[ix, k], dY_eval[iv, k] = dx, dv + half * dacc[iv, k]


@njit(cache=True, inline="always")
def _kick_row(i, half, y, acc, dY, dacc):
    y[i] += half * acc[i]
    for k in range(dY.shape[1]):
        dY[i, k] += half * dacc[i, k]


@njit(cache=True, inline="always")
def _rebase_tangent(y, dY, work, tw, nb):
    """Before ``_kernel.rebase``: a body whose chart moves takes its pose's tangent as its chart's, its angles' none."""
    for b in range(nb):
        o = 12 * b
        if abs(y[o + 6]) <= REBASE_ROLL:
            continue
        _pose_tangent(y, dY, b, work, tw, tw.dT)
        for i in range(3):
            for j in range(3):
                for k in range(dY.shape[1]):
                    tw.dref[b, i, j, k] = tw.dT[b, i, j, k]
        for c in range(6, 9):
            for k in range(dY.shape[1]):
                dY[o + c, k] = 0.0
        for c in range(4):
            for k in range(dY.shape[1]):
                tw.dtrig[b, c, k] = 0.0


@njit(cache=True, inline="always")
def _record_tangent(out, y, dY, work, tw, nb):
    """``out`` (n, nd) = dY with every body's angle tangents those of its absolute angles (``record_state``)."""
    for i in range(dY.shape[0]):
        for k in range(dY.shape[1]):
            out[i, k] = dY[i, k]
    T, dT = work.pose, tw.dT
    for b in range(nb):
        if work.rebased[b] == 0:
            continue
        _body_pose(y, b, T, work)
        _pose_tangent(y, dY, b, work, tw, dT)
        _body_pose(y, b, T, work)  # _pose_tangent used the scratch for R
        o = 12 * b
        a, c = -T[b, 1, 2], math.hypot(T[b, 1, 0], T[b, 1, 1])
        for k in range(dY.shape[1]):
            da = -dT[b, 1, 2, k]
            dc = (T[b, 1, 0] * dT[b, 1, 0, k] + T[b, 1, 1] * dT[b, 1, 1, k]) / c
            out[o + 6, k] = (c * da - a * dc) / (a * a + c * c)
            out[o + 7, k] = ((T[b, 2, 2] * dT[b, 0, 2, k] - T[b, 0, 2] * dT[b, 2, 2, k])
                             / (T[b, 0, 2] ** 2 + T[b, 2, 2] ** 2))
            out[o + 8, k] = ((T[b, 1, 1] * dT[b, 1, 0, k] - T[b, 1, 0] * dT[b, 1, 1, k])
                             / (T[b, 1, 0] ** 2 + T[b, 1, 1] ** 2))


@njit(cache=True, **NO_REFCOUNT)
def tangent_steps(t, h, n, y, acc, y_eval, dY, dacc, dY_eval, m, dm, work, tw):
    """``n`` steps of length h from (t, y) with their tangents, in place: ``_verlet.verlet_steps``'s loop."""
    for j in range(n):
        _step_tangent(t + j * h, h, y, acc, y_eval, dY, dacc, dY_eval, m, dm, work, tw)
        _rebase_tangent(y, dY, work, tw, m.nb)
        rebase(y, work, m.nb)


@njit(cache=True)
def integrate_tangent(y0, dY0, t0, out_dt, substeps, m, dm, work, tw):
    """Verlet from (t0, y0) on the step schedule ``substeps`` (steps per record interval), with tangents.

    Returns
    -------
    records : ndarray (len(substeps) + 1, n_state)
        As ``_tracked.integrate_tracked`` records them on that schedule.
    tangents : ndarray (len(substeps) + 1, n_state, nd)
        Their derivatives along the directions of ``dm`` and ``dY0``.
    """
    n, nd, nb = y0.shape[0], dY0.shape[1], m.nb
    n_rec = substeps.shape[0]
    records = np.empty((n_rec + 1, n))
    tangents = np.empty((n_rec + 1, n, nd))
    y, dY = y0.copy(), dY0.copy()
    for b in range(nb):
        work.rebased[b] = 0
        for i in range(3):
            for j in range(3):
                work.ref[b, i, j] = 1.0 if i == j else 0.0
                for k in range(nd):
                    tw.dref[b, i, j, k] = 0.0
    _rebase_tangent(y, dY, work, tw, nb)
    rebase(y, work, nb)
    acc = np.empty(n)
    dacc = np.zeros((n, nd))
    rhs(t0, y, acc, m, work)
    rhs_tangent(t0, y, dY, dacc, m, dm, work, tw, 0.0)
    element_stretch(t0, y, m, work, work.eps)
    work.step[0] = -1.0
    y_eval, dY_eval = np.empty(n), np.empty((n, nd))
    record_state(records[0], y, work, nb)
    _record_tangent(tangents[0], y, dY, work, tw, nb)
    for rec in range(n_rec):
        sub = substeps[rec]
        h = out_dt / sub
        t_rec = t0 + rec * out_dt
        tangent_steps(t_rec, h, sub, y, acc, y_eval, dY, dacc, dY_eval, m, dm, work, tw)
        record_state(records[rec + 1], y, work, nb)
        _record_tangent(tangents[rec + 1], y, dY, work, tw, nb)
    return records, tangents


@njit(cache=True)
def rhs_tangent_at(t, y, dY, m, dm, work, tw):
    """The accelerations at (t, y) and their tangents (n, nd) along ``dY`` and ``dm`` (no Maxwell update)."""
    n, nd = y.shape[0], dY.shape[1]
    for b in range(m.nb):
        work.rebased[b] = 0
        for i in range(3):
            for j in range(3):
                work.ref[b, i, j] = 1.0 if i == j else 0.0
    acc = np.empty(n)
    dacc = np.zeros((n, nd))
    rhs(t, y, acc, m, work)
    rhs_tangent(t, y, dY, dacc, m, dm, work, tw, 0.0)
    return acc, dacc
