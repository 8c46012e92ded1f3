"""Compiled right-hand side, fixed-step RK4 and the dissipative impulses of the dragline model.

Velocity Verlet, the default integrator, is in ``_verlet`` (it calls
``rhs_maxwell_update`` and ``dissipate`` from here).

Everything here works on the flat arrays that ``_model.assemble`` builds
(packed into one namedtuple, ``m``, a ``_model.KernelModel``, read by field name).

State vector layout (the offsets ``Model.o_part``, ``o_vel``, ``o_force``, ``o_ring`` in ``_model``):
  bodies    12 each: x y z, vx vy vz (inertial, m, m/s), roll pitch yaw (rad),
            p q r (body-frame rates, rad/s)
  particles 3 P positions, then 3 P velocities
  elements  E Maxwell-branch forces F_m (N) of Eq. 8's standard linear solid
  rings     2 each: unstretched rope on side A (m), slide rate (m/s)

Eq. 8 per element of rest length L_e, with Table 2's per-metre values read
as those of a 1 m length (k = K / L_e, c = C / L_e). A standard linear solid
is a spring Ks in parallel with a Maxwell branch (Kv in series with Cv), so
Eq. 8 is exactly
  F   = Ks/L_e (s - L_e) + F_m                 when taut (s > L_e), else 0
  F_m' = Kv/L_e * L_e (s/L_e)' - (Kv/Cv) F_m    (the Maxwell branch's force)
(differentiating F gives Eq. 8 term for term). Only F_m is a state: the
elastic part is then exact at every slack-taut transition, where an
integrated total force would lag and create or lose energy. The rate of
strain (s/L_e)' keeps the form right while reels pay out or rope slides
through a ring. Slack elements carry nothing and their F_m is reset to zero
(the paper's F = 0 when slack); tension is never negative. ``relax`` = Kv/Cv;
the dissipation-free model is Ks := Ks + Kv, Kv := 0.

A rope reeved through k rings (pulleys, sheaves) has k + 1 spans, each spread
evenly over its elements; ring j's state u_j is the unstretched rope from the
rope's start to it, so span j holds u_j - u_(j-1). Ring j's slide coordinate obeys
  m_s v_j' = mean(T_A) - mean(T_B) + (mechanism terms),
A the span before it and B the span after, where each span's mean is of
T + T^2 / (2 K), K = Ks + Kv: the generalised force -dE/du_j of the elastic
energy sum F^2 L_e / (2 K); m_s is the effective mass of the rope moving
through the ring, rho L / 3 (a linear velocity profile from the ring to the
rope's ends; one ring: exact for that profile), plus any sheave inertia
J / r^2. With several rings the rope's sliding kinetic energy couples them;
each keeps its own rho L / 3, a constant, so the energy balance stays exact.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

KIND_PARTICLE = 0
KIND_BODY = 1
KIND_FIXED = 2

STATUS_OK = 0
STATUS_NONFINITE = 1
STATUS_RUNAWAY = 2
STATUS_TOO_STIFF = 3  # the tracked step would exceed its budget (integrate_tracked)

# The step's functions allocate nothing, so they are compiled without numba's reference counting:
# with it, the atomic increments and decrements on the model's and the work's arrays took about
# 30 % of a baseline dig (measured with perf), and the right-hand side ran 1.7 times slower.
# ``_nrt`` is numba's own compile flag (its runtime, NRT, off); what the kernel computes does not
# change to the last bit (docs/model.md).
NO_REFCOUNT = {"_nrt": False}


@njit(cache=True, inline="always")
def _body_matrix(roll, pitch, yaw, T, b):
    """Eq. 11 into T[b] (indexing, not a view: views cost reference counting)."""
    sf, cf = np.sin(roll), np.cos(roll)
    st, ct = np.sin(pitch), np.cos(pitch)
    ss, cs = np.sin(yaw), np.cos(yaw)
    T[b, 0, 0] = cs * ct + ss * sf * st
    T[b, 0, 1] = -ss * ct + cs * sf * st
    T[b, 0, 2] = cf * st
    T[b, 1, 0] = ss * cf
    T[b, 1, 1] = cs * cf
    T[b, 1, 2] = -sf
    T[b, 2, 0] = -cs * st + ss * sf * ct
    T[b, 2, 1] = ss * st + cs * sf * ct
    T[b, 2, 2] = cf * ct
    return sf, cf, ss, cs


# A body's orientation is its chart's matrix times the Euler angles' (Eq. 11): T = ref @ R(roll, pitch,
# yaw). The angles' rates (Eq. 3) divide by cos(roll); when a body's roll in its chart passes
# REBASE_ROLL, between two steps, its chart moves to its pose and its angles return to zero, so no
# body ever comes near the singularity. A body whose chart never moves (every body of the paper's
# dragline) is computed exactly as before, to the last bit.
REBASE_ROLL = math.pi / 4.0


@njit(cache=True, inline="always")
def _body_pose(y, b, T, work):
    """T[b], body to inertial, from the state's angles in the body's chart; the sines and cosines of its roll
    and yaw there (as ``_body_matrix``)."""
    trig = _body_matrix(y[12 * b + 6], y[12 * b + 7], y[12 * b + 8], T, b)
    if work.rebased[b] != 0:
        ref = work.ref
        for j in range(3):
            c0, c1, c2 = T[b, 0, j], T[b, 1, j], T[b, 2, j]
            for i in range(3):
                T[b, i, j] = ref[b, i, 0] * c0 + ref[b, i, 1] * c1 + ref[b, i, 2] * c2
    return trig


@njit(cache=True, inline="always")
def rebase(y, work, nb):
    """Move the chart of every body whose roll there passed ``REBASE_ROLL`` to its pose (angles to zero).

    Between steps only. ``work.trig`` follows (Verlet's drift reads it).
    """
    T = work.pose
    for b in range(nb):
        o = 12 * b
        if abs(y[o + 6]) <= REBASE_ROLL:
            continue
        _body_pose(y, b, T, work)
        for i in range(3):
            for j in range(3):
                work.ref[b, i, j] = T[b, i, j]
        work.rebased[b] = 1
        y[o + 6] = 0.0
        y[o + 7] = 0.0
        y[o + 8] = 0.0
        work.trig[b, 0], work.trig[b, 1], work.trig[b, 2], work.trig[b, 3] = 0.0, 1.0, 0.0, 1.0


@njit(cache=True)
def chart_start(y, work, nb):
    """Every body's chart the inertial frame (the state's angles absolute, Eq. 11), then ``rebase``."""
    for b in range(nb):
        work.rebased[b] = 0
        for i in range(3):
            for j in range(3):
                work.ref[b, i, j] = 1.0 if i == j else 0.0
    rebase(y, work, nb)


@njit(cache=True)
def record_state(out, y, work, nb):
    """``out[:] = y`` with every body's angles absolute again (Eq. 11's sequence, as the state outside a run)."""
    for i in range(y.shape[0]):
        out[i] = y[i]
    T = work.pose
    for b in range(nb):
        if work.rebased[b] == 0:
            continue
        _body_pose(y, b, T, work)
        o = 12 * b
        # ``_kinematics.euler_from_matrix``
        out[o + 6] = math.atan2(-T[b, 1, 2], math.hypot(T[b, 1, 0], T[b, 1, 1]))
        out[o + 7] = math.atan2(T[b, 0, 2], T[b, 2, 2])
        out[o + 8] = math.atan2(T[b, 1, 0], T[b, 1, 1])


@njit(cache=True, inline="always")
def _reel_lengths(t, reel_t, reel_len, out_len, out_rate):
    """Linear interpolation of the reel table, held constant outside it."""
    n = reel_t.shape[0]
    if n == 1 or t <= reel_t[0]:
        for j in range(reel_len.shape[1]):
            out_len[j] = reel_len[0, j]
            out_rate[j] = 0.0
        return
    if t >= reel_t[n - 1]:
        for j in range(reel_len.shape[1]):
            out_len[j] = reel_len[n - 1, j]
            out_rate[j] = 0.0
        return
    k = np.searchsorted(reel_t, t, side="right") - 1
    dt = reel_t[k + 1] - reel_t[k]
    w = (t - reel_t[k]) / dt
    for j in range(reel_len.shape[1]):
        rate = (reel_len[k + 1, j] - reel_len[k, j]) / dt
        out_len[j] = reel_len[k, j] + w * (reel_len[k + 1, j] - reel_len[k, j])
        out_rate[j] = rate


@njit(cache=True, inline="always")
def _fixed_points(t, point_t, point_pos, fpos, fvel):
    """Fixed points' positions and velocities at t (linear in time, held outside)."""
    n = point_t.shape[0]
    if n == 1 or t <= point_t[0] or t >= point_t[n - 1]:
        k = 0 if (n == 1 or t <= point_t[0]) else n - 1
        for i in range(point_pos.shape[1]):
            for j in range(3):
                fpos[i, j] = point_pos[k, i, j]
                fvel[i, j] = 0.0
        return
    k = np.searchsorted(point_t, t, side="right") - 1
    dt = point_t[k + 1] - point_t[k]
    w = (t - point_t[k]) / dt
    for i in range(point_pos.shape[1]):
        for j in range(3):
            a = point_pos[k, i, j]
            b = point_pos[k + 1, i, j]
            fpos[i, j] = a + w * (b - a)
            fvel[i, j] = (b - a) / dt


@njit(cache=True, inline="always")
def _segment_lengths(t, seg_len0, seg_reel, seg_reel_off, reel_t, reel_len, Lseg, dLseg, reel_buf, reel_rate_buf):
    _reel_lengths(t, reel_t, reel_len, reel_buf, reel_rate_buf)
    for s in range(seg_len0.shape[0]):
        r = seg_reel[s]
        if r < 0:
            Lseg[s] = seg_len0[s]
            dLseg[s] = 0.0
        else:
            Lseg[s] = reel_buf[r] - seg_reel_off[s]
            dLseg[s] = reel_rate_buf[r]


@njit(cache=True, inline="always")
def _node(kind, idx, arms, e, y, T, fpos, fvel, o_part, o_vel):
    """Position, velocity and inertial lever arm of an element end (9 scalars).

    ``arms[e]`` is the body-frame lever arm from the body's mass centre.
    Scalars, not scratch arrays: writes through arrays defeat the compiler's
    optimisation of this innermost function (13x slower when measured).
    """
    if kind == KIND_PARTICLE:
        j = o_part + 3 * idx
        v = o_vel + 3 * idx
        return y[j], y[j + 1], y[j + 2], y[v], y[v + 1], y[v + 2], 0.0, 0.0, 0.0
    if kind == KIND_BODY:
        b = 12 * idx
        p, q, rr = y[b + 9], y[b + 10], y[b + 11]
        r0, r1, r2 = arms[e, 0], arms[e, 1], arms[e, 2]
        # omega x r in body axes, then both to inertial
        wx = q * r2 - rr * r1
        wy = rr * r0 - p * r2
        wz = p * r1 - q * r0
        a0 = T[idx, 0, 0] * r0 + T[idx, 0, 1] * r1 + T[idx, 0, 2] * r2
        a1 = T[idx, 1, 0] * r0 + T[idx, 1, 1] * r1 + T[idx, 1, 2] * r2
        a2 = T[idx, 2, 0] * r0 + T[idx, 2, 1] * r1 + T[idx, 2, 2] * r2
        v0 = y[b + 3] + T[idx, 0, 0] * wx + T[idx, 0, 1] * wy + T[idx, 0, 2] * wz
        v1 = y[b + 4] + T[idx, 1, 0] * wx + T[idx, 1, 1] * wy + T[idx, 1, 2] * wz
        v2 = y[b + 5] + T[idx, 2, 0] * wx + T[idx, 2, 1] * wy + T[idx, 2, 2] * wz
        return y[b] + a0, y[b + 1] + a1, y[b + 2] + a2, v0, v1, v2, a0, a1, a2
    return fpos[idx, 0], fpos[idx, 1], fpos[idx, 2], fvel[idx, 0], fvel[idx, 1], fvel[idx, 2], 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def _gather_nodes(y, m, T, fpos, fvel, nx, nv, narm, o_part, o_vel, velocities):
    """Every element end's position (m) into ``nx`` and, with ``velocities``, velocity (m/s) into ``nv``.

    Rows follow ``_model._node_map``: particles, body ends (``narm`` gets
    their inertial lever arms), fixed points. One pass here and the element
    loops read both ends by index, with no branch on what an end is: the
    per-end branches cost the right-hand side about three quarters of its
    time (docs/model.md). A body end's arithmetic is ``_node``'s, operation
    for operation, so results do not change.
    """
    P = m.part_seg.shape[0]
    for i in range(P):
        j = o_part + 3 * i
        nx[i, 0], nx[i, 1], nx[i, 2] = y[j], y[j + 1], y[j + 2]
    if velocities:
        for i in range(P):
            v = o_vel + 3 * i
            nv[i, 0], nv[i, 1], nv[i, 2] = y[v], y[v + 1], y[v + 2]
    bnode_body, bnode_arm = m.bnode_body, m.bnode_arm
    NB = bnode_body.shape[0]
    for k in range(NB):
        idx = bnode_body[k]
        b = 12 * idx
        r0, r1, r2 = bnode_arm[k, 0], bnode_arm[k, 1], bnode_arm[k, 2]
        a0 = T[idx, 0, 0] * r0 + T[idx, 0, 1] * r1 + T[idx, 0, 2] * r2
        a1 = T[idx, 1, 0] * r0 + T[idx, 1, 1] * r1 + T[idx, 1, 2] * r2
        a2 = T[idx, 2, 0] * r0 + T[idx, 2, 1] * r1 + T[idx, 2, 2] * r2
        narm[k, 0], narm[k, 1], narm[k, 2] = a0, a1, a2
        nx[P + k, 0], nx[P + k, 1], nx[P + k, 2] = y[b] + a0, y[b + 1] + a1, y[b + 2] + a2
        if velocities:
            p, q, rr = y[b + 9], y[b + 10], y[b + 11]
            wx = q * r2 - rr * r1
            wy = rr * r0 - p * r2
            wz = p * r1 - q * r0
            nv[P + k, 0] = y[b + 3] + T[idx, 0, 0] * wx + T[idx, 0, 1] * wy + T[idx, 0, 2] * wz
            nv[P + k, 1] = y[b + 4] + T[idx, 1, 0] * wx + T[idx, 1, 1] * wy + T[idx, 1, 2] * wz
            nv[P + k, 2] = y[b + 5] + T[idx, 2, 0] * wx + T[idx, 2, 1] * wy + T[idx, 2, 2] * wz
    for f in range(m.point_pos.shape[1]):
        for k in range(3):
            nx[P + NB + f, k] = fpos[f, k]
            if velocities:
                nv[P + NB + f, k] = fvel[f, k]


@njit(cache=True, inline="always")
def _span_rest(s, side, y, m, Lseg, dLseg, o_ring):
    """Unstretched length (m), its rate (m/s) and element count of span ``side`` (1-based) of ring segment s.

    Span j runs from ring j - 1 (the rope's start for j = 1) to ring j (its
    end after the last ring); ring r's state holds the unstretched rope from
    the segment's start to it.
    """
    r0 = m.seg_ring[s]
    j = side - 1
    if j < m.seg_nring[s]:
        n = m.ring_nelA[r0 + j]
        hi, dhi = y[o_ring + 2 * (r0 + j)], y[o_ring + 2 * (r0 + j) + 1]
    else:
        n = m.ring_nelB[r0 + j - 1]
        hi, dhi = Lseg[s], dLseg[s]
    if j == 0:
        return hi, dhi, n
    return hi - y[o_ring + 2 * (r0 + j - 1)], dhi - y[o_ring + 2 * (r0 + j - 1) + 1], n


@njit(cache=True, inline="always")
def _element_rest(e, y, m, Lseg, dLseg, o_ring):
    """Rest length L_e (m) and its rate (m/s) of element e."""
    s = m.el_seg[e]
    side = m.el_side[e]
    if side == 0:
        n = m.seg_nel[s]
        return Lseg[s] / n, dLseg[s] / n
    length, rate, n = _span_rest(s, side, y, m, Lseg, dLseg, o_ring)
    return length / n, rate / n


@njit(cache=True, inline="always")
def side_rest_lengths(y, m, Lseg, dLseg, o_ring, rest, rest_rate, inv_rest):
    """Each segment side's element rest length (m), its rate (m/s) and its inverse, (S, spans + 1) each:
    ``_element_rest``'s divisions once per side, not once per element (the same arithmetic, the same bits)."""
    for s in range(m.seg_nel.shape[0]):
        n = m.seg_nel[s]
        rest[s, 0], rest_rate[s, 0] = Lseg[s] / n, dLseg[s] / n
        spans = m.seg_nring[s] + 1 if m.seg_ring[s] >= 0 else 0
        for side in range(1, spans + 1):
            length, rate, n_span = _span_rest(s, side, y, m, Lseg, dLseg, o_ring)
            rest[s, side], rest_rate[s, side] = length / n_span, rate / n_span
        for side in range(spans + 1):
            inv_rest[s, side] = 1.0 / rest[s, side]


@njit(cache=True, **NO_REFCOUNT)
def rhs(t, y, dy, m, work):
    """dy = f(t, y). ``work`` holds scratch arrays (see ``make_work``)."""
    _rhs(t, y, dy, m, work, False)


@njit(cache=True, **NO_REFCOUNT)
def rhs_maxwell_update(t, y, dy, m, work):
    """``rhs`` after advancing the Maxwell forces F_m in ``y`` exactly over the last step (``_verlet``).

    ``work.eps`` holds the elements' stretch ratios s / L_e at the step's
    start on entry, at (t, y) on return; ``work.seg_decay`` and
    ``work.seg_gain`` the step's exp(-lambda h) and Kv phi(lambda h) per segment.
    Only ``dy``'s accelerations are written: Verlet advances F_m exactly and
    drifts the positions with the velocities themselves, so it never reads
    the rest, nor the element ends' velocities, which only the F_m rates
    need (not gathered): bit for bit the accelerations of ``rhs``, in less
    time (docs/model.md).
    """
    _rhs(t, y, dy, m, work, True)


@njit(cache=True, inline="always")
def _rhs(t, y, dy, m, work, update):
    nb = m.nb
    body_mass = m.body_mass
    body_I = m.body_I
    body_Iinv = m.body_Iinv
    g = m.g
    part_seg = m.part_seg
    el_seg = m.el_seg
    seg_ks = m.seg_ks
    seg_kv = m.seg_kv
    seg_relax = m.seg_relax
    seg_len0 = m.seg_len0
    seg_reel = m.seg_reel
    seg_reel_off = m.seg_reel_off
    seg_ring = m.seg_ring
    seg_nring = m.seg_nring
    ring_nelA = m.ring_nelA
    ring_nelB = m.ring_nelB
    seg_npart = m.seg_npart
    seg_rho = m.seg_rho
    ring_seg = m.ring_seg
    ring_added_mass = m.ring_added_mass
    reel_t = m.reel_t
    reel_len = m.reel_len
    point_pos = m.point_pos
    relax_damping = m.relax_damping
    body_cda = m.body_cda
    body_lin_drag = m.body_lin_drag
    seg_cda = m.seg_cda
    air_density = m.air_density
    ring_visc = m.ring_visc

    P = part_seg.shape[0]
    E = el_seg.shape[0]
    R = ring_seg.shape[0]
    o_part = 12 * nb
    o_vel = o_part + 3 * P
    o_F = o_vel + 3 * P
    o_ring = o_F + E

    T, Lseg, dLseg, reel_buf, reel_rate = work.T, work.Lseg, work.dLseg, work.reel_buf, work.reel_rate
    fb, mb, sumA, sumB, fpos, fvel = work.fb, work.mb, work.sumA, work.sumB, work.fpos, work.fvel
    trig, inv_mass_seg = work.trig, work.inv_mass_seg
    nx, nv, narm, nf = work.nx, work.nv, work.narm, work.nf
    el_na, el_nb, bnode_body = m.el_na, m.el_nb, m.bnode_body

    _fixed_points(t, reel_t, point_pos, fpos, fvel)
    for b in range(nb):
        trig[b, 0], trig[b, 1], trig[b, 2], trig[b, 3] = _body_pose(y, b, T, work)
    _segment_lengths(t, seg_len0, seg_reel, seg_reel_off, reel_t, reel_len, Lseg, dLseg, reel_buf, reel_rate)
    # Verlet (``update``) never reads dF_m/dt, the only use of the element ends' velocities.
    _gather_nodes(y, m, T, fpos, fvel, nx, nv, narm, o_part, o_vel, not update)
    fb[:, :] = 0.0
    mb[:, :] = 0.0
    nf[:, :] = 0.0
    sumA[:] = 0.0
    sumB[:] = 0.0

    el_side = m.el_side
    eps, seg_decay, seg_gain = work.eps, work.seg_decay, work.seg_gain
    rest, rest_rate, inv_rest = work.rest, work.rest_rate, work.inv_rest
    side_rest_lengths(y, m, Lseg, dLseg, o_ring, rest, rest_rate, inv_rest)
    slack_changes = 0.0
    for e in range(E):
        s = el_seg[e]
        side = el_side[e]
        Le, dLe = rest[s, side], rest_rate[s, side]
        na = el_na[e]
        nb_ = el_nb[e]
        dx = nx[nb_, 0] - nx[na, 0]
        dyy = nx[nb_, 1] - nx[na, 1]
        dz = nx[nb_, 2] - nx[na, 2]
        length = np.sqrt(dx * dx + dyy * dyy + dz * dz)
        if update:
            # F_m' = Kv eps' - lambda F_m, eps' constant over the step; from eps = 1 if it was slack
            eps_now = length / Le
            eps_then = eps[e]
            if (eps_now > 1.0) != (eps_then > 1.0):
                slack_changes += 1.0
            if length > Le:
                y[o_F + e] = seg_decay[s] * y[o_F + e] + seg_gain[s] * (eps_now - max(eps_then, 1.0))
            else:
                y[o_F + e] = 0.0
            eps[e] = eps_now
        Fm = y[o_F + e]
        tension = 0.0
        if length > Le:
            inv = 1.0 / length
            ux, uy, uz = dx * inv, dyy * inv, dz * inv
            invL = inv_rest[s, side]
            if not update:
                rate = ux * (nv[nb_, 0] - nv[na, 0]) + uy * (nv[nb_, 1] - nv[na, 1]) + uz * (nv[nb_, 2] - nv[na, 2])
                dy[o_F + e] = seg_kv[s] * invL * (rate - length * dLe * invL) - seg_relax[s] * Fm
            tension = seg_ks[s] * invL * (length - Le) + Fm
            if tension < 0.0:
                tension = 0.0
        elif not update:
            dy[o_F + e] = 0.0  # slack: F_m is held at zero by ``project``
        if side > 0:
            # -dE/du of the span's elastic energy: pulls the ring after the span forward, the one before back
            pull = tension + tension * tension / (2.0 * (seg_ks[s] + seg_kv[s]))
            if side <= seg_nring[s]:
                sumA[seg_ring[s] + side - 1] += pull
            if side >= 2:
                sumB[seg_ring[s] + side - 2] += pull
        if tension == 0.0:
            continue
        fx, fy, fz = tension * ux, tension * uy, tension * uz
        nf[na, 0] += fx
        nf[na, 1] += fy
        nf[na, 2] += fz
        nf[nb_, 0] -= fx
        nf[nb_, 1] -= fy
        nf[nb_, 2] -= fz
    if update:
        work.slack_changes[0] += slack_changes

    # each body end's force on its body, with its moment, in element order (as summed before the node map)
    for k in range(bnode_body.shape[0]):
        b = bnode_body[k]
        fx, fy, fz = nf[P + k, 0], nf[P + k, 1], nf[P + k, 2]
        a0, a1, a2 = narm[k, 0], narm[k, 1], narm[k, 2]
        fb[b, 0] += fx
        fb[b, 1] += fy
        fb[b, 2] += fz
        mb[b, 0] += a1 * fz - a2 * fy
        mb[b, 1] += a2 * fx - a0 * fz
        mb[b, 2] += a0 * fy - a1 * fx

    # particles: lumped mass from the segment's current unstretched length
    cda_seg = work.cda_seg
    for s in range(seg_rho.shape[0]):
        inv_mass_seg[s] = seg_npart[s] / (seg_rho[s] * Lseg[s])
        cda_seg[s] = seg_cda[s] * Lseg[s] / seg_npart[s]
    part_accel_scale = m.part_accel_scale
    for i in range(P):
        s = part_seg[i]
        inv_mass = inv_mass_seg[s] * part_accel_scale[i]
        cda = cda_seg[s]
        vx = y[o_vel + 3 * i]
        vy = y[o_vel + 3 * i + 1]
        vz = y[o_vel + 3 * i + 2]
        drag = 0.0
        if cda > 0.0:
            drag = 0.5 * air_density * cda * np.sqrt(vx * vx + vy * vy + vz * vz)
        for k in range(3):
            v = y[o_vel + 3 * i + k]
            if not update:  # Verlet's drift reads the velocities themselves
                dy[o_part + 3 * i + k] = v
            dy[o_vel + 3 * i + k] = (nf[i, k] - drag * v) * inv_mass - relax_damping * v
        dy[o_vel + 3 * i + 2] += g * part_accel_scale[i]

    for b in range(nb):
        o = 12 * b
        mass = body_mass[b]
        vx, vy, vz = y[o + 3], y[o + 4], y[o + 5]
        drag = 0.0
        if body_cda[b] > 0.0:
            drag = 0.5 * air_density * body_cda[b] * np.sqrt(vx * vx + vy * vy + vz * vz)
        if body_lin_drag[b] > 0.0:
            drag += body_lin_drag[b]
        scale = m.body_accel_scale[b]
        for k in range(3):
            v = y[o + 3 + k]
            if not update:
                dy[o + k] = v
            dy[o + 3 + k] = (fb[b, k] - drag * v) / mass * scale - relax_damping * v
        dy[o + 5] += g * scale
        p, q, r = y[o + 9], y[o + 10], y[o + 11]
        if not update:  # Verlet's drift takes the Euler-angle rates at its own midpoint
            sf, cf, ss, cs = trig[b, 0], trig[b, 1], trig[b, 2], trig[b, 3]
            pitch_rate = (p * ss + q * cs) / cf  # Eq. 3
            dy[o + 6] = p * cs - q * ss
            dy[o + 7] = pitch_rate
            dy[o + 8] = r + pitch_rate * sf
        # moment to body axes, then Euler's equations with the full inertia
        Mx = T[b, 0, 0] * mb[b, 0] + T[b, 1, 0] * mb[b, 1] + T[b, 2, 0] * mb[b, 2]
        My = T[b, 0, 1] * mb[b, 0] + T[b, 1, 1] * mb[b, 1] + T[b, 2, 1] * mb[b, 2]
        Mz = T[b, 0, 2] * mb[b, 0] + T[b, 1, 2] * mb[b, 1] + T[b, 2, 2] * mb[b, 2]
        hx = body_I[b, 0, 0] * p + body_I[b, 0, 1] * q + body_I[b, 0, 2] * r
        hy = body_I[b, 1, 0] * p + body_I[b, 1, 1] * q + body_I[b, 1, 2] * r
        hz = body_I[b, 2, 0] * p + body_I[b, 2, 1] * q + body_I[b, 2, 2] * r
        gx = Mx - (q * hz - r * hy)
        gy = My - (r * hx - p * hz)
        gz = Mz - (p * hy - q * hx)
        dy[o + 9] = (body_Iinv[b, 0, 0] * gx + body_Iinv[b, 0, 1] * gy + body_Iinv[b, 0, 2] * gz) * scale - relax_damping * p
        dy[o + 10] = (body_Iinv[b, 1, 0] * gx + body_Iinv[b, 1, 1] * gy + body_Iinv[b, 1, 2] * gz) * scale - relax_damping * q
        dy[o + 11] = (body_Iinv[b, 2, 0] * gx + body_Iinv[b, 2, 1] * gy + body_Iinv[b, 2, 2] * gz) * scale - relax_damping * r

    for rg in range(R):
        s = ring_seg[rg]
        vs = y[o_ring + 2 * rg + 1]
        mass = seg_rho[s] * Lseg[s] / 3.0 + ring_added_mass[rg]
        meanA = sumA[rg] / ring_nelA[rg]
        meanB = sumB[rg] / ring_nelB[rg]
        if not update:
            dy[o_ring + 2 * rg] = vs
        dy[o_ring + 2 * rg + 1] = (meanA - meanB - ring_visc[rg] * vs) / mass - relax_damping * vs


@njit(cache=True, inline="always")
def _offsets(m):
    """Where the particles' positions and velocities, the forces and the rings start in the state."""
    o_part = 12 * m.nb
    o_vel = o_part + 3 * m.part_seg.shape[0]
    o_F = o_vel + 3 * m.part_seg.shape[0]
    return o_part, o_vel, o_F, o_F + m.el_seg.shape[0]


@njit(cache=True, **NO_REFCOUNT)
def project(t, y, m, work):
    """Enforce Eq. 8's slack branch: F_m = 0 where s <= L_e."""
    nb = m.nb
    E = m.el_seg.shape[0]
    o_part, o_vel, o_F, o_ring = _offsets(m)
    T, Lseg, dLseg, reel_buf, reel_rate, fpos, fvel = work.T, work.Lseg, work.dLseg, work.reel_buf, work.reel_rate, work.fpos, work.fvel
    _fixed_points(t, m.reel_t, m.point_pos, fpos, fvel)
    for b in range(nb):
        _body_pose(y, b, T, work)
    _segment_lengths(t, m.seg_len0, m.seg_reel, m.seg_reel_off, m.reel_t, m.reel_len, Lseg, dLseg, reel_buf, reel_rate)
    nx = work.nx
    _gather_nodes(y, m, T, fpos, fvel, nx, work.nv, work.narm, o_part, o_vel, False)
    el_na, el_nb = m.el_na, m.el_nb
    for e in range(E):
        if y[o_F + e] == 0.0:
            continue
        Le, _ = _element_rest(e, y, m, Lseg, dLseg, o_ring)
        na, nb_ = el_na[e], el_nb[e]
        dx = nx[nb_, 0] - nx[na, 0]
        dyy = nx[nb_, 1] - nx[na, 1]
        dz = nx[nb_, 2] - nx[na, 2]
        if dx * dx + dyy * dyy + dz * dz <= Le * Le:
            y[o_F + e] = 0.0


@njit(cache=True, **NO_REFCOUNT)
def dissipate(t, y, dt, m, work):
    """Implicit step of the dissipative mechanisms, after each step of either integrator (splitting).

    Joint moments (rope bending damping c, bending stiffness s = EI / l,
    chain-link friction mu r T) and ring friction (capstan, T_low (e^(mu beta) - 1), and a sheave bearing's
    Coulomb friction, mu_b |T_B u_B - T_A u_A|) are stiff on these light
    ropes: explicitly they would need steps far below the axial-wave limit.
    Here they act as velocity impulses solved implicitly, one Gauss-Seidel
    sweep over the joints: with w the joint's inverse inertia to a bending
    impulse (1/m over the joint's element ends, over L^2, plus the shared
    particle's cross term 2 (u1 . u2) / (m L1 L2)), damping
    takes H = -c dt omega / (1 + c dt w) (with stiffness, a spring impulse
    -s dt theta on the bend theta, explicit where 4 s w dt^2 <= 2 and
    otherwise as implicit as the step's stability asks, which damps only
    such unresolved bending), and Coulomb friction either stops
    the relative rotation (stick) or takes |H| = mu r T dt (slip); a ring's
    slide likewise. Unconditionally stable, and dissipative but for the
    bending stiffness's spring; first order in
    these terms (Lie splitting), exact in the nominal model, where it does
    nothing. Known limit of the splitting: a stuck joint or ring creeps, as
    the RK4 step moves it by about dt^2 a / 2 before friction stops it
    (time constant ~ 2 / (dt omega^2); tests/test_mechanism_signatures.py).

    ``work`` is brought to (t, y)'s positions first: body matrices, segment
    lengths and element-end positions (``dissipate_fresh`` when they are
    already there).
    """
    if m.has_joints == 0 and m.has_ring_friction == 0:
        return
    o_part, o_vel, o_F, o_ring = _offsets(m)
    _fixed_points(t, m.reel_t, m.point_pos, work.fpos, work.fvel)
    for b in range(m.nb):
        _body_pose(y, b, work.T, work)
    _segment_lengths(t, m.seg_len0, m.seg_reel, m.seg_reel_off, m.reel_t, m.reel_len, work.Lseg, work.dLseg,
                     work.reel_buf, work.reel_rate)
    _gather_nodes(y, m, work.T, work.fpos, work.fvel, work.nx, work.nv, work.narm, o_part, o_vel, False)
    dissipate_fresh(t, y, dt, m, work)


@njit(cache=True, **NO_REFCOUNT)
def dissipate_fresh(t, y, dt, m, work):
    """``dissipate`` with ``work`` already at (t, y)'s positions: Verlet's last right-hand side was evaluated
    there and its kick moved only velocities, so the geometry is not computed again (a Verlet step with ring
    friction 3.08 -> 2.62 us). One function, not a flag: a constant flag is a type of its own to numba, and
    each value compiled the whole body again.
    """
    has_joints = m.has_joints != 0
    has_rings = m.has_ring_friction != 0
    if not (has_joints or has_rings):
        return
    E = m.el_seg.shape[0]
    o_part, o_vel, o_F, o_ring = _offsets(m)
    T, Lseg, fpos, fvel = work.T, work.Lseg, work.fpos, work.fvel
    el_u, el_len, el_T, el_arm = work.el_u, work.el_len, work.el_T, work.el_arm
    el_seg, seg_rho = m.el_seg, m.seg_rho
    if has_joints:
        for e in range(E):
            se = el_seg[e]
            if m.seg_bend_c[se] == 0.0 and m.seg_bend_k[se] == 0.0 and m.seg_link_mu[se] == 0.0:
                continue  # no joint mechanism acts on this segment
            _dissipate_geometry(e, y, m, work, o_F, o_ring)
        _joint_geometry(m, Lseg, el_len, el_arm, work.el_inv_len, work.el_inv_mass)
        _joint_impulses(y, dt, m, T, fpos, fvel, el_u, work.el_inv_len, work.el_inv_mass, el_T, el_arm, o_part, o_vel)
    if has_rings:
        ring_seg, ring_mu, ring_eA, ring_eB = m.ring_seg, m.ring_mu, m.ring_eA, m.ring_eB
        for rg in range(ring_seg.shape[0]):
            if ring_mu[rg] == 0.0 and m.ring_bearing_mu[rg] == 0.0:
                continue
            s = ring_seg[rg]
            eA, eB = ring_eA[rg], ring_eB[rg]
            # the capstan and the bearing need only the two elements that meet at the ring
            _dissipate_geometry(eA, y, m, work, o_F, o_ring)
            _dissipate_geometry(eB, y, m, work, o_F, o_ring)
            cosb = el_u[eA, 0] * el_u[eB, 0] + el_u[eA, 1] * el_u[eB, 1] + el_u[eA, 2] * el_u[eB, 2]
            beta = np.arccos(min(1.0, max(-1.0, cosb)))
            limit = min(el_T[eA], el_T[eB]) * (np.exp(ring_mu[rg] * beta) - 1.0)
            if m.ring_bearing_mu[rg] != 0.0:
                limit += m.ring_bearing_mu[rg] * _bearing_load(el_T[eA], el_T[eB], cosb)
            mass = seg_rho[s] * Lseg[s] / 3.0 + m.ring_added_mass[rg]
            i = o_ring + 2 * rg + 1
            vs = y[i]
            if abs(vs) * mass <= limit * dt:
                y[i] = 0.0  # stick
            else:
                y[i] = vs - np.sign(vs) * limit * dt / mass


@njit(cache=True, inline="always")
def _bearing_load(TA, TB, cosb):
    """The load (N) on a ring's bearing: |T_B u_B - T_A u_A|, the two sides' pulls (cosb = u_A . u_B)."""
    return np.sqrt(max(TA * TA + TB * TB - 2.0 * TA * TB * cosb, 0.0))


@njit(cache=True, **NO_REFCOUNT)
def _dissipate_geometry(e, y, m, work, o_F, o_ring):
    """Element e's length, unit vector, tension and end lever arms into ``work`` (``dissipate``).

    Called, not inlined: three inlined copies cost the first run 4-9 s more
    compiling and the step nothing measurable.
    """
    Le, _ = _element_rest(e, y, m, work.Lseg, work.dLseg, o_ring)
    nx, narm = work.nx, work.narm
    na, nb_ = m.el_na[e], m.el_nb[e]
    dx, dyy, dz = nx[nb_, 0] - nx[na, 0], nx[nb_, 1] - nx[na, 1], nx[nb_, 2] - nx[na, 2]
    length = np.sqrt(dx * dx + dyy * dyy + dz * dz)
    work.el_len[e] = length
    work.el_u[e, 0], work.el_u[e, 1], work.el_u[e, 2] = dx / length, dyy / length, dz / length
    tension = m.seg_ks[m.el_seg[e]] / Le * (length - Le) + y[o_F + e] if length > Le else 0.0
    work.el_T[e] = max(tension, 0.0)
    P = m.part_seg.shape[0]
    body_end = P + m.bnode_body.shape[0]  # nodes P .. body_end - 1 are body ends
    for end in range(2):
        node = na if end == 0 else nb_
        for k in range(3):
            work.el_arm[e, 3 * end + k] = narm[node - P, k] if P <= node < body_end else 0.0


@njit(cache=True, inline="always")
def _end_inverse_masses(kind, idx, arm0, arm1, arm2, part_seg, seg_npart, seg_rho, body_mass, body_I, Lseg):
    """An element end's inverse mass (1/kg): to a linear impulse, and to a bending one (a body adds its rotation).

    Arrays, not the kernel model: passed the model's tuple, this loop ran 30 times slower.
    """
    if kind == KIND_PARTICLE:
        s = part_seg[idx]
        lin = seg_npart[s] / (seg_rho[s] * Lseg[s])
        return lin, lin
    if kind == KIND_BODY:
        imin = min(body_I[idx, 0, 0], min(body_I[idx, 1, 1], body_I[idx, 2, 2]))
        lin = 1.0 / body_mass[idx]
        return lin, lin + (arm0 * arm0 + arm1 * arm1 + arm2 * arm2) / imin
    return 0.0, 0.0


@njit(cache=True, inline="always")
def _turn(b, hx, hy, hz, y, body_Iinv, T):
    """Apply an angular impulse (N m s, inertial axes) to body b's rates."""
    bx = T[b, 0, 0] * hx + T[b, 1, 0] * hy + T[b, 2, 0] * hz
    by = T[b, 0, 1] * hx + T[b, 1, 1] * hy + T[b, 2, 1] * hz
    bz = T[b, 0, 2] * hx + T[b, 1, 2] * hy + T[b, 2, 2] * hz
    o = 12 * b
    y[o + 9] += body_Iinv[b, 0, 0] * bx + body_Iinv[b, 0, 1] * by + body_Iinv[b, 0, 2] * bz
    y[o + 10] += body_Iinv[b, 1, 0] * bx + body_Iinv[b, 1, 1] * by + body_Iinv[b, 1, 2] * bz
    y[o + 11] += body_Iinv[b, 2, 0] * bx + body_Iinv[b, 2, 1] * by + body_Iinv[b, 2, 2] * bz


@njit(cache=True, inline="always")
def _kick(kind, idx, arm0, arm1, arm2, jx, jy, jz, inv, y, body_Iinv, T, o_vel):
    """Apply a linear impulse (N s) at an element end (``inv``: its linear inverse mass): particle or body point."""
    if kind == KIND_PARTICLE:
        y[o_vel + 3 * idx] += jx * inv
        y[o_vel + 3 * idx + 1] += jy * inv
        y[o_vel + 3 * idx + 2] += jz * inv
    elif kind == KIND_BODY:
        o = 12 * idx
        y[o + 3] += jx * inv
        y[o + 4] += jy * inv
        y[o + 5] += jz * inv
        _turn(idx, arm1 * jz - arm2 * jy, arm2 * jx - arm0 * jz, arm0 * jy - arm1 * jx, y, body_Iinv, T)


@njit(cache=True, **NO_REFCOUNT)
def _joint_geometry(m, Lseg, el_len, el_arm, el_inv_len, el_inv_mass):
    """What the joints' sweep needs of the geometry: 1 / length, each end's linear and bending inverse mass.

    Its own loop, ahead of the sweep: there every division waited on the
    joint before (Gauss-Seidel), which made the sweep twice as slow; stored
    from ``dissipate``'s geometry pass instead, the stores slowed that pass
    more than they saved.
    """
    el_ka, el_ia, el_kb, el_ib = m.el_ka, m.el_ia, m.el_kb, m.el_ib
    part_seg, seg_npart, seg_rho, body_mass, body_I = m.part_seg, m.seg_npart, m.seg_rho, m.body_mass, m.body_I
    for e in range(el_len.shape[0]):
        if el_len[e] <= 0.0:
            continue  # no mechanism on its segment: never swept
        el_inv_len[e] = 1.0 / el_len[e]
        lin, bend = _end_inverse_masses(el_ka[e], el_ia[e], el_arm[e, 0], el_arm[e, 1], el_arm[e, 2], part_seg,
                                        seg_npart, seg_rho, body_mass, body_I, Lseg)
        el_inv_mass[e, 0] = lin
        el_inv_mass[e, 1] = bend
        lin, bend = _end_inverse_masses(el_kb[e], el_ib[e], el_arm[e, 3], el_arm[e, 4], el_arm[e, 5], part_seg,
                                        seg_npart, seg_rho, body_mass, body_I, Lseg)
        el_inv_mass[e, 2] = lin
        el_inv_mass[e, 3] = bend


@njit(cache=True, **NO_REFCOUNT)
def _joint_impulses(y, dt, m, T, fpos, fvel, el_u, el_inv_len, el_inv_mass, el_T, el_arm, o_part, o_vel):
    """One Gauss-Seidel sweep of the joints' implicit bending impulses (``dissipate``).

    ``el_inv_len`` and ``el_inv_mass`` (linear and bending inverse mass of
    end a, then of end b) come from ``dissipate``'s geometry pass.
    """
    joint_a, joint_b, joint_seg = m.joint_a, m.joint_b, m.joint_seg
    seg_bend_c, seg_bend_k, seg_link_mu, seg_link_r = m.seg_bend_c, m.seg_bend_k, m.seg_link_mu, m.seg_link_r
    el_ka, el_ia, el_ra, el_kb, el_ib, el_rb = m.el_ka, m.el_ia, m.el_ra, m.el_kb, m.el_ib, m.el_rb
    body_I, body_Iinv = m.body_I, m.body_Iinv
    for j in range(joint_b.shape[0]):
        s = joint_seg[j]
        c = seg_bend_c[s]
        mu = seg_link_mu[s]
        if c == 0.0 and mu == 0.0 and seg_bend_k[s] == 0.0:
            continue
        e2 = joint_b[j]
        e1 = joint_a[j]
        # angular velocity of e2 from the current velocities (earlier joints moved them);
        # written out here and for e1 below: an inline helper measured 13 % slower
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
        stiffness = 0.0  # N m/rad: EI over the joint's length, where two elements meet
        if e1 >= 0:
            _, _, _, vxa, vya, vza, _, _, _ = _node(el_ka[e1], el_ia[e1], el_ra, e1, y, T, fpos, fvel, o_part, o_vel)
            _, _, _, vxb, vyb, vzb, _, _, _ = _node(el_kb[e1], el_ib[e1], el_rb, e1, y, T, fpos, fvel, o_part, o_vel)
            u1x, u1y, u1z = el_u[e1, 0], el_u[e1, 1], el_u[e1, 2]
            i1 = el_inv_len[e1]
            w1x = (u1y * (vzb - vza) - u1z * (vyb - vya)) * i1
            w1y = (u1z * (vxb - vxa) - u1x * (vzb - vza)) * i1
            w1z = (u1x * (vyb - vya) - u1y * (vxb - vxa)) * i1
            # the shared node (end a of e2) takes both couples: cross term 2 (u1 . u2) / (m_p L1 L2)
            w += ((el_inv_mass[e1, 1] + el_inv_mass[e1, 3]) * i1 * i1
                  + 2.0 * (u1x * u2x + u1y * u2y + u1z * u2z) * el_inv_mass[e2, 0] * i1 * i2)
            tension = 0.5 * (el_T[e1] + el_T[e2])
            stiffness = 2.0 * seg_bend_k[s] * i1 * i2 / (i1 + i2)
        else:
            b = -e1 - 1
            p, q, r = y[12 * b + 9], y[12 * b + 10], y[12 * b + 11]
            w1x = T[b, 0, 0] * p + T[b, 0, 1] * q + T[b, 0, 2] * r
            w1y = T[b, 1, 0] * p + T[b, 1, 1] * q + T[b, 1, 2] * r
            w1z = T[b, 2, 0] * p + T[b, 2, 1] * q + T[b, 2, 2] * r
            w += 1.0 / min(body_I[b, 0, 0], min(body_I[b, 1, 1], body_I[b, 2, 2]))
            tension = el_T[e2]
        rx, ry, rz = w2x - w1x, w2y - w1y, w2z - w1z
        along = rx * u2x + ry * u2y + rz * u2z  # a rope carries no torsion
        rx, ry, rz = rx - along * u2x, ry - along * u2y, rz - along * u2z
        # implicit damping, the stiffness as implicit as stability asks, then Coulomb friction on what is left:
        # H = -dt (c r' + s (theta + beta dt r')) with r' = r + w H and the bend theta = u1 x u2 (the moment of
        # s (1 - u1 . u2)). z = 4 s w dt^2 bounds the rope's coupled bending modes' (omega dt)^2 (a uniform
        # rope's highest, 16 s / m L^2, against a joint's w s = 6 s / m L^2); beta = 0 (symplectic Euler: no
        # loss) while z <= 2, else 1/2 - 1/z, which keeps the step's margin 4 + (2 beta - 1) z >= 2
        z = 4.0 * stiffness * w * dt * dt
        cs = c + (0.5 - 1.0 / z if z > 2.0 else 0.0) * stiffness * dt
        den = 1.0 + cs * dt * w
        k = cs * dt / den
        g = stiffness * dt / den
        hx = -k * rx - g * (u1y * u2z - u1z * u2y)
        hy = -k * ry - g * (u1z * u2x - u1x * u2z)
        hz = -k * rz - g * (u1x * u2y - u1y * u2x)
        rx, ry, rz = rx + w * hx, ry + w * hy, rz + w * hz
        if mu > 0.0 and tension > 0.0:
            speed = np.sqrt(rx * rx + ry * ry + rz * rz)
            if speed > 0.0:
                f = min(speed / w, mu * seg_link_r[s] * tension * dt) / speed
                hx, hy, hz = hx - f * rx, hy - f * ry, hz - f * rz
        # the angular impulse on e2 as the linear couple (H x u2) / L2 at its ends
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


# Scratch arrays for ``rhs``, ``project`` and ``dissipate``, allocated once per run.
Work = namedtuple("Work", [
    "T",  # (nb, 3, 3) body-to-inertial matrices
    "Lseg", "dLseg",  # (S,) unstretched segment lengths (m) and their rates (m/s)
    "reel_buf", "reel_rate",  # (reels,) reel lengths and rates
    "fb", "mb",  # (nb, 3) force (N) and moment (N m) on each body, inertial axes
    "sumA", "sumB",  # (R,) tension sums over each ring's sides
    "fpos", "fvel",  # (F, 3) fixed points' positions and velocities
    "trig",  # (nb, 4) per body: sin, cos of roll and yaw
    "inv_mass_seg",  # (S,) 1 / particle mass per segment
    "el_u", "el_len", "el_T", "el_arm",  # dissipate: element unit vectors, lengths, tensions, lever arms
    "el_inv_len", "el_inv_mass",  # dissipate: 1 / length; per end (a, b) the linear and bending inverse mass
    "nx", "nv", "nf",  # (nodes, 3) element ends' positions (m), velocities (m/s), forces (N): _model._node_map
    "narm",  # (body ends, 3) body ends' lever arms (m, inertial axes)
    "eps", "seg_decay", "seg_gain", "step",  # Verlet (rhs_maxwell_update): stretch ratios, per-segment factors, their h
    "slack_changes",  # (1,) elements that turned slack or taut since it was zeroed (rhs_maxwell_update)
    "rest", "rest_rate", "inv_rest",  # (S, spans + 1) element rest length (m), its rate (m/s) and inverse, per
    # segment and side (0: a segment through no ring; j: the span before its ring j, or after its last)
    "cda_seg",  # (S,) each particle's drag area (m^2) per segment
    "ref", "rebased",  # (nb, 3, 3) each body's chart (T = ref @ R(angles)); (nb,) 1 where it is not the identity
    "pose",  # (nb, 3, 3) scratch of ``rebase`` and ``record_state``
])


def make_work(m):
    """A ``Work`` for the kernel model ``m``."""
    nb = m.nb
    P = m.part_seg.shape[0]
    S = m.seg_ks.shape[0]
    R = m.ring_seg.shape[0]
    E = m.el_seg.shape[0]
    F = max(m.point_pos.shape[1], 1)
    nreel = m.reel_len.shape[1]
    nodes = max(P + m.bnode_body.shape[0] + m.point_pos.shape[1], 1)
    sides = 2 + (int(m.seg_nring.max()) if S else 0)
    return Work(T=np.zeros((nb, 3, 3)), Lseg=np.zeros(S), dLseg=np.zeros(S), reel_buf=np.zeros(nreel),
                reel_rate=np.zeros(nreel), fb=np.zeros((nb, 3)), mb=np.zeros((nb, 3)),
                sumA=np.zeros(max(R, 1)), sumB=np.zeros(max(R, 1)), fpos=np.zeros((F, 3)), fvel=np.zeros((F, 3)),
                trig=np.zeros((max(nb, 1), 4)), inv_mass_seg=np.zeros(S), el_u=np.zeros((E, 3)), el_len=np.zeros(E),
                el_T=np.zeros(E), el_arm=np.zeros((E, 6)), el_inv_len=np.zeros(E), el_inv_mass=np.zeros((E, 4)), eps=np.zeros(E), seg_decay=np.zeros(S),
                seg_gain=np.zeros(S), step=np.zeros(1), slack_changes=np.zeros(1),
                nx=np.zeros((nodes, 3)), nv=np.zeros((nodes, 3)), nf=np.zeros((nodes, 3)),
                narm=np.zeros((max(m.bnode_body.shape[0], 1), 3)), rest=np.zeros((S, sides)),
                rest_rate=np.zeros((S, sides)), inv_rest=np.zeros((S, sides)), cda_seg=np.zeros(S),
                ref=np.zeros((max(nb, 1), 3, 3)), rebased=np.zeros(max(nb, 1), dtype=np.int64),
                pose=np.zeros((max(nb, 1), 3, 3)))


@njit(cache=True, **NO_REFCOUNT)
def rk4_step(t, h, y, k1, k2, k3, k4, tmp, m, work):
    """One classical RK4 step of length h from (t, y), in place; then slack and dissipation."""
    n = y.shape[0]
    half = 0.5 * h
    rhs(t, y, k1, m, work)
    for i in range(n):
        tmp[i] = y[i] + half * k1[i]
    rhs(t + half, tmp, k2, m, work)
    for i in range(n):
        tmp[i] = y[i] + half * k2[i]
    rhs(t + half, tmp, k3, m, work)
    for i in range(n):
        tmp[i] = y[i] + h * k3[i]
    rhs(t + h, tmp, k4, m, work)
    sixth = h / 6.0
    for i in range(n):
        y[i] += sixth * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
    project(t + h, y, m, work)
    if m.has_joints != 0 or m.has_ring_friction != 0:  # skip even the call in the nominal model
        dissipate(t + h, y, h, m, work)


@njit(cache=True)
def rk4_scratch(n):
    """The four stage derivatives and the stage state ``rk4_step`` works in."""
    return np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)


@njit(cache=True, inline="always")
def first_bad(y, nb, P, max_speed):
    """(status, state index) of the first non-finite value or runaway speed; (STATUS_OK, -1) if none."""
    for i in range(y.shape[0]):
        if not np.isfinite(y[i]):
            return STATUS_NONFINITE, i
    for i in range(nb):
        for k in range(3):
            if abs(y[12 * i + 3 + k]) > max_speed:
                return STATUS_RUNAWAY, 12 * i + 3 + k
    o_vel = 12 * nb + 3 * P
    for i in range(3 * P):
        if abs(y[o_vel + i]) > max_speed:
            return STATUS_RUNAWAY, o_vel + i
    return STATUS_OK, -1


@njit(cache=True)
def integrate(y0, t0, dt, n_steps, record_every, m, work, max_speed):
    """Fixed-step classical RK4 from ``t0``; records every ``record_every`` steps.

    Returns
    -------
    records : ndarray (n_steps // record_every + 1, n_state)
        State at t0 and after every ``record_every`` steps.
    status : int
        STATUS_OK, STATUS_NONFINITE or STATUS_RUNAWAY.
    bad_step : int
        Step at which the run stopped (status != OK), else -1.
    bad_index : int
        State index found bad first, else -1.
    """
    n = y0.shape[0]
    n_rec = n_steps // record_every + 1
    records = np.empty((n_rec, n))
    y = y0.copy()
    k1, k2, k3, k4, tmp = rk4_scratch(n)
    nb = m.nb
    chart_start(y, work, nb)
    record_state(records[0], y, work, nb)
    P = m.part_seg.shape[0]
    for step in range(n_steps):
        rk4_step(t0 + step * dt, dt, y, k1, k2, k3, k4, tmp, m, work)
        rebase(y, work, nb)
        if (step + 1) % record_every == 0:
            status, index = first_bad(y, nb, P, max_speed)
            if status != STATUS_OK:
                return records[: (step + 1) // record_every], status, step + 1, index
            record_state(records[(step + 1) // record_every], y, work, nb)
    return records, STATUS_OK, -1, -1
