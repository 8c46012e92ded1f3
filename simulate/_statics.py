"""Static equilibrium: the pose the rig rests in at given rope lengths.

Two stages, as Costello and Kyle (2004) did it and then some:
1. dynamic relaxation: the full model with the reels frozen and heavy
   velocity damping added, from a rough hanging pose, until it is nearly
   at rest; velocity Verlet, with fictitious masses on the light parts
   (``_fictitious_masses``) so that its step is the bodies', not the
   chains';
2. a damped Newton polish of the static balance itself: net force on every
   particle and body, net moment on every body, and tension balance across
   every ring pulley, with every Maxwell branch relaxed (Eq. 8's steady
   state: F = Ks times strain).
The result is a state with zero velocities and steady element forces, from
which ``simulate`` starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..capture import column_groups
from . import _kernel
from ._blas import one_blas_thread
from ._kernel import KIND_PARTICLE
from ._model import kernel_model, rough_body_positions
from ._time_step import _shortest_rest_lengths
from ._tracked import MAX_STEPS, NO_REFINEMENT, NO_SCHEDULE, VERLET, gershgorin_rows, integrate_tracked
from ._verlet import VERLET_IMAGINARY_LIMIT

__all__ = ["Equilibrium", "StaticsError", "solve_statics"]

# The relaxation's budget in Verlet steps (one right-hand side each), of
# the true masses: 60 s of relaxing at the high level's step (24 us) needs
# 2.6e6 (with the fictitious masses, 0.14 ms: 4.3e5). About a minute of
# computing, as the 5e6 RK4 steps it replaced.
MAX_RELAX_STEPS = 2e7
# The relaxation hands over to Newton once every speed is below the first of these (m/s); if Newton
# fails from there, relaxing goes on to the next. Measured on the built-in rig (low to high): Newton
# converges to the same pose (1e-14 m) from 3e-2 m/s, and the relaxation, most of the statics' cost,
# ends twice as early as at 1e-4.
NEWTON_FROM_SPEEDS = (3e-2, 1e-4)
RELAX_CHECK_S = 0.1  # simulated seconds between looks at the speeds
RELAX_SLICES = 20  # record intervals in each look (``integrate_tracked``'s)
DIRECT_NEWTON_ITERATIONS = 10  # from a guess; beyond this it relaxes first
# The relaxation's step as a share of Verlet's limit on the Gershgorin bound. Verlet damps none of
# the fast modes and gains energy where an element turns slack or taut (``_tracked``), which a
# fixed-step relaxation does not redo finer. Measured on the built-in rig (low, baseline, high; the
# dig's start and three end poses; with and without Eq. 8's dissipation): at 0.6 the end pose
# 10.1 / 1.4 m without dissipation never came to rest (60 s of relaxing at the baseline); at 0.5
# three high-level poses took ten times longer than at 0.4, where all 24 settled in 0.05-0.33 s.
RELAX_SAFETY = 0.4


class StaticsError(ValueError):
    """No equilibrium at these rope lengths: bad input (exit code 2), not a crash."""


@dataclass(frozen=True)
class Equilibrium:
    """A static pose.

    Attributes
    ----------
    state : ndarray
        Full state vector (velocities zero, forces static).
    residual : float
        Largest force or moment imbalance left (N or N m).
    """

    state: np.ndarray
    residual: float


def _frozen(model, t):
    """The model's arrays with the reels held at their lengths at time t."""
    a = dict(model.arrays)
    a["reel_t"] = np.array([0.0])
    a["reel_len"] = model.arrays["reel_len"][:1].copy()
    at_t = model.maneuver.lengths_at(t)
    for k, winch in enumerate(model.rig.winches):
        a["reel_len"][0, k] = float(at_t[winch])
    a["point_pos"] = model.fixed_positions(t)
    return a


def initial_state(model, t=0.0, held=None):
    """A rough pose: bodies hanging in line (or where ``held`` puts them), ropes straight or sagging.

    ``held``: body name -> (mass-centre position (3,) m, Euler angles (3,) rad).
    """
    pos = rough_body_positions(model.rig, {w: float(v) for w, v in model.maneuver.lengths_at(t).items()})
    y = np.zeros(model.n_state)
    for b, name in enumerate(model.body_names):
        y[12 * b : 12 * b + 3] = pos[name]
        if held and name in held:
            y[12 * b : 12 * b + 3], y[12 * b + 6 : 12 * b + 9] = held[name][:2]
    Lseg = model.segment_lengths(t)
    for s, name in enumerate(model.seg_names):
        nodes = model.seg_nodes[name]
        xyz = model.node_positions(y, name, [t])[0]
        # fill particles between their anchors (non-particle nodes)
        anchors = [j for j, n in enumerate(nodes) if n[0] != KIND_PARTICLE]
        spans = []
        for j0, j1 in zip(anchors[:-1], anchors[1:]):
            spans.append(np.linalg.norm(xyz[j1] - xyz[j0]))
        total = sum(spans)
        for (j0, j1), span in zip(zip(anchors[:-1], anchors[1:]), spans):
            n_el = j1 - j0
            rest = Lseg[s] * span / total
            sag = np.sqrt(max(0.0, 3.0 * span * (rest - span) / 8.0))
            for k in range(1, n_el):
                w = k / n_el
                p = (1 - w) * xyz[j0] + w * xyz[j1]
                p[2] += 4.0 * sag * w * (1 - w)
                idx = nodes[j0 + k][1]
                y[model.o_part + 3 * idx : model.o_part + 3 * idx + 3] = p
        for j, r in enumerate(model.seg_rings.get(name, ())):
            y[model.o_ring + 2 * r] = Lseg[s] * sum(spans[: j + 1]) / total
    return y


# A body's pose coordinates in the state (x, y, z, Eq. 11's three angles), and the rows of their accelerations.
_POSE = (0, 1, 2, 6, 7, 8)
_POSE_ACCEL = (3, 4, 5, 9, 10, 11)


def _free(model, held, settled):
    """Per body, which of its six pose coordinates (0-5, ``_POSE``'s order) the statics solve for."""
    settled = settled or {}
    return [range(6) if b not in held else tuple(settled.get(b, ())) for b in range(model.n_bodies)]


def _unknown_index(model, held=(), settled=None):
    idx = []
    for b, free in enumerate(_free(model, held, settled)):
        idx += [12 * b + _POSE[k] for k in free]
    idx += list(range(model.o_part, model.o_vel))
    idx += [model.o_ring + 2 * r for r in range(model.n_rings)]
    return np.array(idx)


def solve_statics(model, t=0.0, y0=None, damping=4.0, max_relax_time=60.0, tol=1e-6, held=None):
    """Equilibrium pose at the reel lengths of time ``t``, or the ropes' equilibrium under held bodies.

    Parameters
    ----------
    model : Model
    t : float
        Time whose reel lengths (and fixed-point positions) are used (s).
    y0 : ndarray, optional
        Starting state (a rough hanging pose by default).
    damping : float
        Velocity damping rate of the relaxation (1/s).
    max_relax_time : float
        Most simulated seconds of relaxation before the polish starts anyway.
    tol : float
        Largest force (N) or moment (N m) imbalance accepted.
    held : dict, optional
        Body name -> (mass-centre position (3,) m, Euler angles (3,) rad),
        optionally a third item, the pose coordinates the ropes settle
        (0-5: x, y, z and Eq. 11's angles): those bodies are held there
        and only the ropes (and the other bodies, and a held body's settled
        coordinates, from where the hold put them) settle, as a lab holds
        a load before it lets it go (a release). Their forces are not
        balanced but along their settled coordinates.

    Returns
    -------
    Equilibrium

    Raises
    ------
    StaticsError
        When no equilibrium is found (the rig cannot hang at these lengths).
    """
    arrays = _frozen(model, t)
    newton = kernel_model(arrays)
    work = _kernel.make_work(newton)
    held_index = tuple(model.body_names.index(name) for name in held) if held else ()
    settled = {model.body_names.index(name): tuple(pose[2]) for name, pose in (held or {}).items() if len(pose) > 2}
    y = initial_state(model, t, held) if y0 is None else np.array(y0, float)
    relaxing = _fictitious_masses(model, arrays, y, t)
    relaxing["body_accel_scale"] = relaxing["body_accel_scale"].copy()
    relaxing["body_accel_scale"][list(held_index)] = 0.0
    relaxing["relax_damping"] = float(damping)
    m = kernel_model(relaxing)
    # Refused on the true masses: the fictitious ones would relax a rig whose motion no step can follow.
    true_step = _relaxation_step(_largest_row(model, newton, y, t))
    steps = np.ceil(max_relax_time) / true_step if true_step > 0 else np.inf  # a float first: 1 / dt may overflow
    if not steps <= MAX_RELAX_STEPS:
        raise StaticsError(f"no static equilibrium sought at the rope lengths of t = {t:g} s: the stiffest rope or "
                           f"chain element there needs a {true_step:.2g} s step, so relaxing could take "
                           f"{steps:.2g} steps, more than the {MAX_RELAX_STEPS:.0e} "
                           "allowed (an element near zero length, a discretization far finer than 'high', or a "
                           "stiffness or mass far from what a rig has?)")
    stiffest = _largest_row(model, m, y, t)
    dt = _relaxation_step(stiffest)
    per = int(np.ceil(RELAX_CHECK_S / RELAX_SLICES / dt))  # steps per slice
    speed_index = np.r_[[12 * b + k for b in range(model.n_bodies) for k in (3, 4, 5)], np.arange(model.o_vel, model.o_force)].astype(int)
    chunks_left = int(np.ceil(max_relax_time / RELAX_CHECK_S))
    worst = np.inf
    if y0 is not None:
        # A guess (the equilibrium of a rig a few percent different) is near
        # its own: Newton from it directly, relaxing only if that fails.
        rest, worst = _polish(model, newton, work, y, tol, max_iter=DIRECT_NEWTON_ITERATIONS, held=held_index,
                              settled=settled)
        if np.isfinite(worst) and worst <= tol:
            return Equilibrium(state=rest.copy(), residual=worst)
    for stage, speed in enumerate(NEWTON_FROM_SPEEDS):  # Newton from an early pose first; relax on if it fails
        # A pose at rest has no speed to wait for: every start (the rough hanging pose, or a guess such
        # as another rig's equilibrium) is let go for a first look at least, and a fallback relaxes a
        # second at least.
        at_least = 1.0 if stage > 0 else RELAX_CHECK_S
        # The fallback tracks the step, in slices, each slice where an element turned slack or taut
        # done again finer (``_tracked``): Verlet gains energy there, which at the first stage's
        # speeds does not matter, but a hanging rope between fixed points (32 particles) kept
        # 0.02 m/s of it without end. Tracked from the start, the built-in rig's statics, whose
        # chains flap slack and taut while they settle, took 2.5 times longer.
        lam0 = np.inf if stage == 0 else stiffest
        relaxed = 0
        while chunks_left > 0 and (np.max(np.abs(y[speed_index]), initial=0.0) >= speed
                                   or relaxed * RELAX_CHECK_S < at_least - 1e-9):
            # Every argument given: an omitted one is a type of its own, and numba would compile the
            # whole integrator a second time for the statics.
            rec, _, _, _, status, _, _ = integrate_tracked(y, 0.0, per * dt, RELAX_SLICES, dt, lam0, m, work, 1e3,
                                                        MAX_STEPS, VERLET, NO_SCHEDULE, NO_REFINEMENT)
            if status != _kernel.STATUS_OK:
                raise StaticsError(f"no static equilibrium at the rope lengths of t = {t:g} s (relaxation diverged)")
            y = rec[-1].copy()
            chunks_left -= 1
            relaxed += 1
        rest, worst = _polish(model, newton, work, y, tol, held=held_index, settled=settled)
        if np.isfinite(worst) and worst <= tol:
            break
    if not np.isfinite(worst) or worst > tol:
        raise StaticsError(f"no static equilibrium at the rope lengths of t = {t:g} s "
                           f"(largest force imbalance left {worst:.3g} N)")
    return Equilibrium(state=rest.copy(), residual=worst)


def _gershgorin(model, m, y, t):
    """``gershgorin_rows`` of kernel model ``m`` at state y, the segments at their lengths of time t."""
    lengths = model.segment_lengths(np.array([float(t)])).min(axis=1)
    return gershgorin_rows(_shortest_rest_lengths(model, lengths, y), lengths, m)


def _relaxation_step(stiffest):
    """The relaxation's Verlet step (s) for the largest Gershgorin row ``stiffest`` (rad^2/s^2)."""
    return RELAX_SAFETY * VERLET_IMAGINARY_LIMIT / np.sqrt(stiffest) if stiffest > 0 else 1e-3


def _largest_row(model, m, y, t):
    return max(float(np.max(rows, initial=0.0)) for rows in _gershgorin(model, m, y, t))


def _fictitious_masses(model, arrays, y, t):
    """A copy of ``arrays`` whose light parts are made heavy, so the relaxation can take a longer step.

    The relaxation only has to arrive at rest: its masses are free. Every
    particle, body and ring slide whose Gershgorin row (its own stiffest
    frequency squared) is above the bodies' highest translational row has
    its accelerations scaled down to that row (``part_accel_scale``,
    ``body_accel_scale``: gravity is scaled with them, so the rest pose is
    the same) or its slide mass raised (``ring_added_mass``, which no
    static balance holds). On the built-in rig at baseline this lengthens
    the step 5.3 times (the chains' particles, the drag cluster's spin and
    the dump rope's slide through the hoist cluster were faster than the
    bodies), and the swing that has to die out, set by the heavy bucket,
    is hardly slower: 14,080 steps against 81,900 unscaled (high: 22,320
    against 144,840), the whole statics 0.10 s against 0.37 s.
    """
    particles, bodies, spins, rings = _gershgorin(model, kernel_model(arrays), y, t)
    out = dict(arrays)
    if bodies.size == 0:
        return out  # a line between fixed points: nothing slow to scale towards
    target = float(bodies.max())
    with np.errstate(divide="ignore"):
        out["part_accel_scale"] = np.minimum(1.0, target / particles)
        out["body_accel_scale"] = np.minimum(1.0, target / np.maximum(bodies, spins.max(axis=1)))
    lengths = model.segment_lengths(float(t))
    slide_mass = arrays["seg_rho"][arrays["ring_seg"]] * lengths[arrays["ring_seg"]] / 3.0 + arrays["ring_added_mass"]
    out["ring_added_mass"] = arrays["ring_added_mass"] + slide_mass * np.maximum(0.0, rings / target - 1.0)
    return out


def _polish(model, m, work, y, tol, max_iter=60, held=(), settled=None):
    """Newton on the static balance from relaxed state ``y``: (rest state, largest imbalance left).

    ``held``: indices of bodies held where they are (no unknowns, no balance)
    but for ``settled`` (body index -> pose coordinates 0-5 it balances).
    """
    y = np.array(y, float)
    for b in range(model.n_bodies):  # a body may have turned a full circle while settling
        if b not in held:
            y[12 * b + 6 : 12 * b + 9] = np.angle(np.exp(1j * y[12 * b + 6 : 12 * b + 9]))
    unknown = _unknown_index(model, held, settled)
    rows = _accel_index(model, held, settled)
    scale = _residual_scale(model, held, settled)
    rest = _at_rest(model, y)
    dy = np.zeros(model.n_state)

    def residual(q):
        rest[unknown] = q
        _kernel.rhs(0.0, rest, dy, m, work)
        return dy[rows] * scale

    # One BLAS thread: the diagnosis runs statics in parallel processes on two
    # cores, where many-threaded LAPACK took ten times longer.
    with one_blas_thread():
        q = _newton(residual, rest[unknown].copy(), _jacobian_pattern(model, unknown), tol, max_iter)
    rest[unknown] = q
    return rest, float(np.max(np.abs(residual(q)), initial=0.0))


def _at_rest(model, y):
    """The state with every velocity zero and every Maxwell branch relaxed."""
    rest = np.array(y, float)
    for b in range(model.n_bodies):
        rest[12 * b + 3 : 12 * b + 6] = 0.0
        rest[12 * b + 9 : 12 * b + 12] = 0.0
    rest[model.o_vel : model.o_ring] = 0.0
    rest[model.o_ring + 1 :: 2] = 0.0
    return rest


def _newton(residual, q, pattern, tol, max_iter=60):
    """Damped Newton on the static balance with a grouped finite-difference Jacobian.

    Central differences: a stiff element stretches by h^2 / (2 L) under a
    transverse step h, and with forward differences that error swamps the
    soft transverse stiffness T / L the equilibrium hinges on (it is even in
    h, so central differences cancel it). The step must also stay well below
    the smallest stretch (T L / K, micrometres for stiff chains), or the
    difference straddles the slack kink. The least-squares step copes with
    directions of zero stiffness (a body free to spin about a rope through
    its mass centre); backtracking keeps each step downhill.
    """
    groups = _column_groups(pattern)
    r = residual(q)
    for _ in range(max_iter):
        if np.max(np.abs(r), initial=0.0) < 0.01 * tol:
            break
        J = np.zeros(pattern.shape)
        h = 1e-8 * np.maximum(1.0, np.abs(q))  # well inside every element's stretch
        for g in groups:
            qq = q.copy()
            qq[g] += h[g]
            up = residual(qq)
            qq[g] -= 2 * h[g]
            dr = up - residual(qq)
            for j in g:
                rows = pattern[:, j]
                J[rows, j] = dr[rows] / (2 * h[j])
        step = np.linalg.lstsq(J, -r, rcond=1e-12)[0]
        norm0 = np.linalg.norm(r)
        for _ in range(30):
            r_new = residual(q + step)
            if np.isfinite(r_new).all() and np.linalg.norm(r_new) < norm0:
                break
            step *= 0.5
        else:
            break  # no downhill step: the caller judges what is left
        q = q + step
        r = r_new
    return q


def _jacobian_pattern(model, unknown):
    """Which residual rows each unknown can move: element connectivity.

    A ring's slide changes every rest length of its segment, so it couples
    the whole segment.
    """
    a = model.arrays
    col = {int(i): k for k, i in enumerate(unknown)}

    def node_dofs(kind, idx):
        if kind == KIND_PARTICLE:
            return [col[model.o_part + 3 * idx + k] for k in range(3)]
        if kind == _kernel.KIND_BODY:  # a held body has no unknowns, a partly held one some
            return [col[12 * idx + k] for k in _POSE if 12 * idx + k in col]
        return []

    seg_dofs = {}
    element_dofs = []
    for e in range(model.n_elements):
        dofs = node_dofs(a["el_ka"][e], a["el_ia"][e]) + node_dofs(a["el_kb"][e], a["el_ib"][e])
        s = a["el_seg"][e]
        element_dofs.append((s, dofs))
        seg_dofs.setdefault(s, set()).update(dofs)
    pattern = np.eye(len(unknown), dtype=bool)
    ring_dofs = {s: {col[model.o_ring + 2 * r] for r in model.seg_rings.get(name, ())}
                 for s, name in enumerate(model.seg_names)}
    for s, dofs in element_dofs:
        coupled = set(dofs)
        if ring_dofs[s]:
            coupled |= seg_dofs[s] | ring_dofs[s]
        idx = np.array(sorted(coupled))
        pattern[np.ix_(idx, idx)] = True
    for s, dofs in seg_dofs.items():
        if ring_dofs[s]:
            idx = np.array(sorted(dofs | ring_dofs[s]))
            pattern[np.ix_(idx, idx)] = True
    return pattern


def _column_groups(pattern):
    """Greedy colouring: columns that share no row are perturbed together.

    The pattern depends only on the rig's topology, and a diagnosis solves
    the statics of hundreds of rigs of one topology: the colouring (9 ms at
    the baseline) is kept per pattern.
    """
    key = (pattern.shape, np.packbits(pattern).tobytes())
    if key not in _GROUPS:
        if len(_GROUPS) >= 16:
            _GROUPS.clear()
        _GROUPS[key] = _colour_columns(pattern)
    return [g.copy() for g in _GROUPS[key]]


_GROUPS = {}


def _colour_columns(pattern):
    labels = column_groups(pattern)  # the bundle adjustment's first-fit colouring, in column order
    return [np.flatnonzero(labels == g) for g in range(int(labels.max()) + 1 if labels.size else 0)]


def _accel_index(model, held=(), settled=None):
    idx = []
    for b, free in enumerate(_free(model, held, settled)):
        idx += [12 * b + _POSE_ACCEL[k] for k in free]
    idx += list(range(model.o_vel, model.o_force))
    idx += [model.o_ring + 2 * r + 1 for r in range(model.n_rings)]
    return np.array(idx)


def _residual_scale(model, held=(), settled=None):
    """Accelerations -> forces (N) and moments (N m): multiply by the mass or inertia."""
    a = model.arrays
    scale = []
    for b, free in enumerate(_free(model, held, settled)):
        per = [a["body_mass"][b]] * 3 + list(np.diag(a["body_I"][b]))
        scale += [per[k] for k in free]
    L = model.segment_lengths(0.0)
    for p in range(model.n_particles):
        s = a["part_seg"][p]
        scale += [a["seg_rho"][s] * L[s] / a["seg_npart"][s]] * 3
    for r in range(model.n_rings):
        s = a["ring_seg"][r]
        scale.append(a["seg_rho"][s] * L[s] / 3.0 + a["ring_added_mass"][r])
    return np.array(scale)
