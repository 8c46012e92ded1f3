"""Integration (Verlet or RK4) whose step follows the rig's stiffness, record by record.

Rope sliding through a ring pulley shortens the elements on one side (in
the dig, the dump rope's short side falls to a fifth of an even share, the
hoist rope's to a quarter), and an element's axial frequency grows as
1 / sqrt(length). A fixed step must either assume the worst before the run
or risk it. Here the step starts from the spectral limit at the start
(``_time_step``) and, at every record, is cut by the growth of a Gershgorin
bound on the stiffness since the start: cheap (one pass over the elements
every 5 ms of motion) and exact in how stiffness scales with length.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._kernel import (
    KIND_BODY,
    KIND_PARTICLE,
    STATUS_OK,
    STATUS_TOO_STIFF,
    _segment_lengths,
    chart_start,
    first_bad,
    rebase,
    record_state,
    rk4_scratch,
    rk4_step,
    side_rest_lengths,
)
from ._verlet import verlet_scratch, verlet_steps

__all__ = ["gershgorin_lambda", "gershgorin_rows", "state_gershgorin_lambda", "integrate_tracked", "RK4", "VERLET",
           "MAX_STEPS"]

# The steps a run may take (``max_steps``): a rig that stiffens without bound stops here. About 45 min at the
# 57 us a step measured on the baseline rig (2 cores, 2026-11-24); a fine-step study (10 s at 1 us) needs 1e7.
MAX_STEPS = 50_000_000

# Integrators ``integrate_tracked`` runs (``_verlet`` says why there are two).
RK4 = 0
VERLET = 1
# Verlet's step in a record interval where an element turns slack or taut,
# as a share of its step elsewhere (``_verlet``: the kink's energy error).
SLACK_STEP_FACTOR = 0.35

# A frozen schedule (``integrate_tracked``'s ``frozen``) is kept where its step is at most this much longer
# than the run's own tracked step: within the stability limit's margin (``_time_step.VERLET_SAFETY`` 0.85 of
# h |lambda| = 2), and wider than a finite difference's change of the stiffness (a tenth of a tolerance of the
# rope's stiffness, ln 3: 11 %, the step 5 %). Beyond it the run steps on its own.
FROZEN_MARGIN = 1.1
NO_SCHEDULE = np.zeros(0, dtype=np.int64)
NO_REFINEMENT = np.zeros(0, dtype=np.bool_)

# The dig's shortest ring side cuts the step about fivefold; a step a
# thousand times below the start's means an element near zero length (a
# reel table run to nothing), where the step would fall without end.
MIN_STEP_RATIO = 1e-3


@njit(cache=True)
def gershgorin_rows(rest, L, m):
    """Gershgorin bounds (rad^2/s^2) on the eigenvalues of M^-1 K, row by row.

    Particles and body translation (2 sum k / m), body rotation about each
    body axis i (2 sum k (|r|^2 - r_i^2) / I_ii) and each ring's slide
    (2 (K / side_A + K / side_B) / m_slide), with the instantaneous
    stiffness (Ks + Kv) / rest of every element. Accelerations scaled by
    the model (``part_accel_scale``, ``body_accel_scale``: the statics'
    fictitious masses) scale their rows.

    Parameters
    ----------
    rest : ndarray (E,)
        Element rest lengths (m).
    L : ndarray (S,)
        Segment lengths (m): they set the particle masses.
    m : tuple
        The model's kernel tuple.

    Returns
    -------
    particles : ndarray (P,)
    bodies : ndarray (nb,)
        Translation.
    spins : ndarray (nb, 3)
        Rotation about each body axis.
    rings : ndarray (R,)
    """
    nb, body_mass, body_I = m.nb, m.body_mass, m.body_I
    part_seg, el_seg, el_side = m.part_seg, m.el_seg, m.el_side
    el_ka, el_ia, el_ra, el_kb, el_ib, el_rb = m.el_ka, m.el_ia, m.el_ra, m.el_kb, m.el_ib, m.el_rb
    seg_ks, seg_kv, seg_ring, seg_npart, seg_rho = m.seg_ks, m.seg_kv, m.seg_ring, m.seg_npart, m.seg_rho
    ring_seg, ring_added_mass = m.ring_seg, m.ring_added_mass
    P = part_seg.shape[0]
    R = ring_seg.shape[0]
    k_part = np.zeros(P)
    k_body = np.zeros(nb)
    k_rot = np.zeros((nb, 3))
    side_len = np.zeros((R, 2))  # each ring's span before (0) and after (1)
    for e in range(el_seg.shape[0]):
        s = el_seg[e]
        k = (seg_ks[s] + seg_kv[s]) / rest[e]
        side = el_side[e]
        if side > 0:
            if side <= m.seg_nring[s]:
                side_len[seg_ring[s] + side - 1, 0] += rest[e]
            if side >= 2:
                side_len[seg_ring[s] + side - 2, 1] += rest[e]
        for end in range(2):
            kind = el_ka[e] if end == 0 else el_kb[e]
            idx = el_ia[e] if end == 0 else el_ib[e]
            if kind == KIND_PARTICLE:
                k_part[idx] += k
            elif kind == KIND_BODY:
                k_body[idx] += k
                r0 = el_ra[e, 0] if end == 0 else el_rb[e, 0]
                r1 = el_ra[e, 1] if end == 0 else el_rb[e, 1]
                r2 = el_ra[e, 2] if end == 0 else el_rb[e, 2]
                k_rot[idx, 0] += k * (r1 * r1 + r2 * r2)
                k_rot[idx, 1] += k * (r0 * r0 + r2 * r2)
                k_rot[idx, 2] += k * (r0 * r0 + r1 * r1)
    particles = np.empty(P)
    for p in range(P):
        s = part_seg[p]
        particles[p] = 2.0 * k_part[p] / (seg_rho[s] * L[s] / seg_npart[s]) * m.part_accel_scale[p]
    bodies = np.empty(nb)
    spins = np.empty((nb, 3))
    for b in range(nb):
        bodies[b] = 2.0 * k_body[b] / body_mass[b] * m.body_accel_scale[b]
        for i in range(3):
            spins[b, i] = 2.0 * k_rot[b, i] / body_I[b, i, i] * m.body_accel_scale[b]
    rings = np.empty(R)
    for r in range(R):
        s = ring_seg[r]
        K = seg_ks[s] + seg_kv[s]
        m_slide = seg_rho[s] * L[s] / 3.0 + ring_added_mass[r]
        rings[r] = 2.0 * (K / side_len[r, 0] + K / side_len[r, 1]) / m_slide
    return particles, bodies, spins, rings


@njit(cache=True)
def gershgorin_lambda(rest, L, m):
    """Gershgorin bound on the largest eigenvalue of M^-1 K (rad^2/s^2): the largest of ``gershgorin_rows``."""
    particles, bodies, spins, rings = gershgorin_rows(rest, L, m)
    lam = 0.0
    for x in particles:
        lam = max(lam, x)
    for x in bodies:
        lam = max(lam, x)
    for x in spins.ravel():
        lam = max(lam, x)
    for x in rings:
        lam = max(lam, x)
    return lam


@njit(cache=True)
def state_gershgorin_lambda(t, y, m, work):
    """``gershgorin_lambda`` of the rig as it is at (t, y)."""
    el_seg = m.el_seg
    seg_len0, seg_reel, seg_reel_off = m.seg_len0, m.seg_reel, m.seg_reel_off
    reel_t, reel_len = m.reel_t, m.reel_len
    Lseg, dLseg, reel_buf, reel_rate = work.Lseg, work.dLseg, work.reel_buf, work.reel_rate
    _segment_lengths(t, seg_len0, seg_reel, seg_reel_off, reel_t, reel_len, Lseg, dLseg, reel_buf, reel_rate)
    nb = m.nb
    P = m.part_seg.shape[0]
    E = el_seg.shape[0]
    o_ring = 12 * nb + 6 * P + E
    # Per segment side, then per element: ``_element_rest`` called element by element, handed the model's
    # tuple in a function compiled with reference counting (it allocates; the likely cause), made this
    # bound, taken every record, 2.3 times as costly and a baseline dig 17 % slower (docs/model.md).
    by_side, rate, inverse = np.empty_like(work.rest), np.empty_like(work.rest), np.empty_like(work.rest)
    side_rest_lengths(y, m, Lseg, dLseg, o_ring, by_side, rate, inverse)
    rest = np.empty(E)
    el_side = m.el_side
    for e in range(E):
        rest[e] = by_side[el_seg[e], el_side[e]]
    return gershgorin_lambda(rest, Lseg.copy(), m)


@njit(cache=True)
def integrate_tracked(y0, t0, out_dt, n_records, dt0, lam0, m, work, max_speed, max_steps=MAX_STEPS, method=RK4,
                      frozen=NO_SCHEDULE, frozen_refined=NO_REFINEMENT):
    """RK4 or Verlet from ``t0``, one record every ``out_dt``, the step cut as the rig stiffens.

    In each record interval the step is ``dt0 * sqrt(lam0 / lam)`` when the
    Gershgorin bound ``lam`` at the interval's start exceeds ``lam0`` (the
    bound where ``dt0`` was found), else ``dt0``; rounded down to divide
    ``out_dt``. The steps of the whole run stay within ``max_steps``, and
    the step above ``MIN_STEP_RATIO * dt0``: a rig that stiffens without
    bound (a rope reeled in to nothing) would otherwise cut the step
    towards zero and never finish. With ``lam0`` infinite the step is
    ``dt0`` throughout (a fixed step).

    ``frozen`` (Verlet; steps per record interval) and ``frozen_refined``
    (which of those counts were a slack refinement), an earlier run's
    ``substeps`` and ``refined``: the run takes that schedule instead of its
    own, so that runs a small parameter change apart step alike and their
    difference is a derivative, not the jumps of two schedules
    (``FROZEN_MARGIN``). Such a run refines no interval where an element
    turns slack or taut: the schedule says where it steps finer. An element
    that hangs at the slack point (a sling at rest) turns slack and taut at
    the least change: on the hook-block crane, runs 1 % of a tolerance of
    the hoist rope's stiffness either way took 52,862 and 53,755 steps on
    their own schedules against the base run's 53,155.

    ``method``: ``RK4`` (classical, four right-hand sides a step) or
    ``VERLET`` (``_verlet``, one). A tracked Verlet run does a record
    interval again at ``SLACK_STEP_FACTOR`` of its step when an element
    turned slack or taut in it: Verlet damps none of the fast modes (RK4 at
    its step halves the fastest every step) and gains energy at that kink
    at its full step (the dig's end pose pushed at 0.5 m/s: +0.9 J at 0.7
    of its limit, a blow-up at 0.75; RK4 loses energy there), none at 0.3.

    Returns
    -------
    records : ndarray (n_records + 1, n_state)
    substeps : ndarray (n_records,) of int
        Steps taken in each record interval.
    refined : ndarray (n_records,) of bool
        Where that count is a slack refinement.
    unrefined : int
        Record intervals of a ``frozen`` schedule where an element turned
        slack or taut at a step the schedule had not refined.
    status : int
        STATUS_OK, STATUS_NONFINITE, STATUS_RUNAWAY or STATUS_TOO_STIFF.
    bad_time : float
        Time (s) of the record at which the run stopped, else NaN.
    bad_index : int
        State index found bad first (STATUS_TOO_STIFF: the steps the
        interval needed), else -1.
    """
    n = y0.shape[0]
    records = np.empty((n_records + 1, n))
    substeps = np.zeros(n_records, dtype=np.int64)
    refined = np.zeros(n_records, dtype=np.bool_)
    y = y0.copy()
    k1, k2, k3, k4, tmp = rk4_scratch(n)
    nb = m.nb
    chart_start(y, work, nb)
    if method == VERLET:
        acc, y_eval = verlet_scratch(t0, y, m, work)
        y_start, acc_start, eps_start = np.empty(n), np.empty(n), np.empty(work.eps.shape[0])
        trig_start = np.empty_like(work.trig)
    else:
        acc, y_eval = k1, tmp
        y_start, acc_start, eps_start, trig_start = tmp, tmp, tmp, work.trig
    ref_start, rebased_start = work.ref.copy(), work.rebased.copy()
    record_state(records[0], y, work, nb)
    P = m.part_seg.shape[0]
    total = 0
    tracked = lam0 < np.inf
    frozen_run = method == VERLET and frozen.shape[0] >= n_records > 0
    unrefined = 0
    for rec in range(n_records):
        t_rec = t0 + rec * out_dt
        lam = state_gershgorin_lambda(t_rec, y, m, work)
        dt = dt0 * math.sqrt(lam0 / lam) if lam > lam0 > 0.0 else dt0
        need = math.ceil(out_dt / dt - 1e-9) * 1.0 if dt > 0.0 else math.inf
        if total + need > max_steps or dt < MIN_STEP_RATIO * dt0:
            return records[: rec + 1], substeps[: rec + 1], refined[: rec + 1], unrefined, STATUS_TOO_STIFF, \
                t_rec, int(min(need, 2**62))
        sub = max(1, int(need))
        kept = frozen_run and frozen[rec] * FROZEN_MARGIN >= sub
        if kept:
            sub = frozen[rec]
            refined[rec] = frozen_refined[rec]
        total += sub
        substeps[rec] = sub
        h = out_dt / sub
        if method == VERLET:
            y_start[:] = y
            acc_start[:] = acc
            eps_start[:] = work.eps
            trig_start[:] = work.trig
            ref_start[:] = work.ref
            rebased_start[:] = work.rebased
            work.slack_changes[0] = 0.0
            verlet_steps(t_rec, h, sub, y, acc, y_eval, m, work)
            if work.slack_changes[0] > 0.0 and kept and not refined[rec]:
                unrefined += 1
            if work.slack_changes[0] > 0.0 and tracked and not kept:
                # An element turned slack or taut: Verlet, which damps nothing, would
                # take energy from that kink at its full step; the interval again, finer.
                y[:] = y_start
                acc[:] = acc_start
                work.eps[:] = eps_start
                work.trig[:] = trig_start  # the drift reads them (``verlet_steps``)
                work.ref[:] = ref_start  # the charts the state's angles are in
                work.rebased[:] = rebased_start
                fine = int(math.ceil(sub / SLACK_STEP_FACTOR - 1e-9))
                if total + fine > max_steps:
                    return (records[: rec + 1], substeps[: rec + 1], refined[: rec + 1], unrefined, STATUS_TOO_STIFF,
                            t_rec, fine)
                total += fine
                substeps[rec] = fine
                refined[rec] = True
                h = out_dt / fine
                verlet_steps(t_rec, h, fine, y, acc, y_eval, m, work)
        else:
            for j in range(sub):
                rk4_step(t_rec + j * h, h, y, k1, k2, k3, k4, tmp, m, work)
                rebase(y, work, nb)
        status, index = first_bad(y, nb, P, max_speed)
        if status != STATUS_OK:
            return records[: rec + 1], substeps[: rec + 1], refined[: rec + 1], unrefined, status, t_rec + out_dt, \
                index
        record_state(records[rec + 1], y, work, nb)
    return records, substeps, refined, unrefined, STATUS_OK, np.nan, -1
