"""Velocity Verlet for the dragline model: one right-hand side a step.

The step is set by the chains' axial modes (docs/model.md), which RK4 pays
for with four right-hand sides a step: stable to h omega = 2.83, 0.71 per
evaluation. Kick-drift-kick velocity Verlet is stable to h omega = 2 with
one evaluation (the last kick's accelerations are the next step's first):
2.8 times RK4's reach per evaluation on these modes, at second order. At
the stability-limited step its error is micrometres, below RK4's on the
dissipative model (where RK4's reset of slack elements after its step
makes it first order), and the 10 s dig runs about twice as fast
(docs/model.md has the measured figures).

The state splits into positions (body positions and Euler angles, particle
positions, the unstretched rope on each ring's side A) and velocities (body
velocities and rates, particle velocities, slide rates). One step of length
h:

1. kick: velocities += h/2 a_n;
2. drift: positions += h (their rates at the half-step velocities; the
   Euler angles by the midpoint rule, their rates depending on the angles);
3. accelerations a_{n+1} at the new positions from
   ``_kernel.rhs_maxwell_update``, which first advances the Maxwell branch
   forces exactly over the step (below) in the same pass over the elements,
   with the velocities extrapolated to the step's end (v_half + h/2 a_n):
   the forces that depend on velocity (air drag, the gyroscopic term, a
   sheave's bearing damping) then err by O(h^2) and the scheme stays
   second order;
4. kick: velocities += h/2 a_{n+1}; then the dissipative mechanisms'
   implicit impulses (``_kernel.dissipate_fresh``), as after an RK4 step.

Eq. 8's Maxwell branch, F_m' = Kv eps' - (Kv/Cv) F_m with eps = s / L_e the
element's stretch ratio, is linear in F_m: with eps' constant over the step,
F_m(t + h) = exp(-lambda h) F_m + Kv (eps(t + h) - eps(t)) phi(lambda h),
phi(x) = (1 - exp(-x)) / x. An element slack at the step's end carries no
F_m (the paper's F = 0 when slack, as ``_kernel.project`` does after an RK4
step); one that turns taut starts from eps = 1.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._kernel import (
    NO_REFCOUNT,
    _body_pose,
    _element_rest,
    _fixed_points,
    _gather_nodes,
    _offsets,
    _segment_lengths,
    dissipate_fresh,
    _rhs,
    rebase,
    rhs,
)

__all__ = ["VERLET_IMAGINARY_LIMIT", "verlet_scratch", "verlet_steps", "element_stretch"]

# Kick-drift-kick is stable for h omega < 2 on an undamped oscillator.
VERLET_IMAGINARY_LIMIT = 2.0


@njit(cache=True)
def element_stretch(t, y, m, work, eps):
    """eps[e] = s / L_e, every element's length over its rest length at (t, y)."""
    o_part, o_vel, o_F, o_ring = _offsets(m)
    T, fpos, fvel = work.T, work.fpos, work.fvel
    Lseg, dLseg = work.Lseg, work.dLseg
    _fixed_points(t, m.reel_t, m.point_pos, fpos, fvel)
    for b in range(m.nb):
        _body_pose(y, b, T, work)
    _segment_lengths(t, m.seg_len0, m.seg_reel, m.seg_reel_off, m.reel_t, m.reel_len, Lseg, dLseg,
                     work.reel_buf, work.reel_rate)
    nx = work.nx
    _gather_nodes(y, m, T, fpos, fvel, nx, work.nv, work.narm, o_part, o_vel, False)
    el_na, el_nb = m.el_na, m.el_nb
    for e in range(m.el_seg.shape[0]):
        Le, _ = _element_rest(e, y, m, Lseg, dLseg, o_ring)
        na, nb_ = el_na[e], el_nb[e]
        dx, dyy, dz = nx[nb_, 0] - nx[na, 0], nx[nb_, 1] - nx[na, 1], nx[nb_, 2] - nx[na, 2]
        eps[e] = math.sqrt(dx * dx + dyy * dyy + dz * dz) / Le


@njit(cache=True, inline="always")
def _maxwell_factors(h, m, work):
    """exp(-lambda h) and Kv phi(lambda h) per segment, recomputed only when h changes."""
    if work.step[0] == h:
        return
    work.step[0] = h
    for s in range(m.seg_kv.shape[0]):
        x = m.seg_relax[s] * h
        work.seg_decay[s] = math.exp(-x)
        work.seg_gain[s] = m.seg_kv[s] * (-math.expm1(-x) / x if x > 0.0 else 1.0)


@njit(cache=True, inline="always")
def _euler_angle_rates(roll, yaw, p, q, r):
    """Eq. 3: roll, pitch and yaw rates from the body rates (as ``_kernel.rhs``)."""
    return _euler_angle_rates_trig(math.sin(roll), math.cos(roll), math.sin(yaw), math.cos(yaw), p, q, r)


@njit(cache=True, inline="always")
def _euler_angle_rates_trig(sf, cf, ss, cs, p, q, r):
    """``_euler_angle_rates`` from the sines and cosines of roll (sf, cf) and yaw (ss, cs)."""
    pitch_rate = (p * ss + q * cs) / cf
    return p * cs - q * ss, pitch_rate, r + pitch_rate * sf


@njit(cache=True, inline="always")
def _kick(y, acc, half, nb, o_vel, o_F, o_ring, R):
    for b in range(nb):
        o = 12 * b
        for k in range(3):
            y[o + 3 + k] += half * acc[o + 3 + k]
            y[o + 9 + k] += half * acc[o + 9 + k]
    for i in range(o_vel, o_F):
        y[i] += half * acc[i]
    for rg in range(R):
        y[o_ring + 2 * rg + 1] += half * acc[o_ring + 2 * rg + 1]


@njit(cache=True)
def verlet_scratch(t, y, m, work):
    """The accelerations at (t, y) and the evaluation state a run starts from.

    ``work.eps`` and ``work.trig`` are left as they are at (t, y).
    """
    n = y.shape[0]
    acc = np.empty(n)
    rhs(t, y, acc, m, work)
    element_stretch(t, y, m, work, work.eps)
    work.step[0] = -1.0
    return acc, np.empty(n)


@njit(cache=True, **NO_REFCOUNT)
def verlet_steps(t, h, n, y, acc, y_eval, m, work):
    """``n`` steps of length h from (t, y), in place (``_step`` each).

    One call for a record interval's steps, with the step and its
    right-hand side inlined: a compiled call that passes the model and its
    scratch arrays (``m``, ``work``: some 80 arrays, flattened into
    arguments) took 0.14 us even with an empty body, and a step made two
    (itself, then its right-hand side) of about 2 us.
    """
    for j in range(n):
        _step(t + j * h, h, y, acc, y_eval, m, work)
        rebase(y, work, m.nb)


@njit(cache=True, inline="always")
def _step(t, h, y, acc, y_eval, m, work):
    """One kick-drift-kick step of length h from (t, y), in place.

    ``acc`` holds the accelerations at (t, y) on entry and at (t + h, y) on
    return; ``work.eps`` the stretch ratios likewise, and ``work.trig`` the
    bodies' roll and yaw sines and cosines (the drift's first Euler-angle
    rates read them: the last right-hand side computed them at these
    angles, and recomputing them cost 5 % of the step); ``y_eval`` is scratch.
    """
    nb = m.nb
    R = m.ring_seg.shape[0]
    o_part, o_vel, o_F, o_ring = _offsets(m)
    half = 0.5 * h
    # Kick, drift and the evaluation state (velocities extrapolated to t + h) in one pass per
    # entry instead of four over the whole state: the same arithmetic, so the same bits.
    for b in range(nb):
        o = 12 * b
        for k in range(3):
            y[o + 3 + k] += half * acc[o + 3 + k]
            y[o + 9 + k] += half * acc[o + 9 + k]
        for k in range(3):
            y[o + k] += h * y[o + 3 + k]
        roll, pitch, yaw = y[o + 6], y[o + 7], y[o + 8]
        p, q, r = y[o + 9], y[o + 10], y[o + 11]
        d0, d1, d2 = _euler_angle_rates_trig(work.trig[b, 0], work.trig[b, 1], work.trig[b, 2], work.trig[b, 3],
                                             p, q, r)
        d0, d1, d2 = _euler_angle_rates(roll + half * d0, yaw + half * d2, p, q, r)
        y[o + 6] = roll + h * d0
        y[o + 7] = pitch + h * d1
        y[o + 8] = yaw + h * d2
        for k in range(12):
            y_eval[o + k] = y[o + k]
        for k in range(3):
            y_eval[o + 3 + k] += half * acc[o + 3 + k]
            y_eval[o + 9 + k] += half * acc[o + 9 + k]
    to_vel = o_vel - o_part
    for i in range(o_part, o_vel):
        v = y[i + to_vel] + half * acc[i + to_vel]
        x = y[i] + h * v
        y[i], y[i + to_vel] = x, v
        y_eval[i], y_eval[i + to_vel] = x, v + half * acc[i + to_vel]
    for e in range(o_F, o_ring):
        y_eval[e] = y[e]
    for rg in range(R):
        i = o_ring + 2 * rg
        v = y[i + 1] + half * acc[i + 1]
        x = y[i] + h * v
        y[i], y[i + 1] = x, v
        y_eval[i], y_eval[i + 1] = x, v + half * acc[i + 1]
    _maxwell_factors(h, m, work)
    _rhs(t + h, y_eval, acc, m, work, True)  # ``rhs_maxwell_update``, inlined
    for e in range(o_F, o_ring):
        y[e] = y_eval[e]  # the Maxwell forces, advanced in y_eval
    _kick(y, acc, half, nb, o_vel, o_F, o_ring, R)
    if m.has_joints != 0 or m.has_ring_friction != 0:
        dissipate_fresh(t + h, y, h, m, work)  # work holds the geometry at (t + h, y): rhs_maxwell_update

