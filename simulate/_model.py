"""Assembly: a rig, a discretization and a maneuver become flat kernel arrays.

Topology of one rope segment with ``n`` particles (seed paper section 2.2):
``start - p1 - ... - pn - end``, n + 1 elements. A segment through a ring
pulley is ``start - (A particles) - ring - (B particles) - end``: the ring
splits one element, so it has n + 2 elements; the split of particles
between the sides is fixed for a run (proportional to the sides' initial
spans). A side between two fixed points (a rope from its winch to a fixed sheave)
is one massless straight element: the fixed winch-to-sheave path.

Winches (docs/model.md): the maneuver's ``<winch>_length`` column sets a
winch rope's *total* unstretched length from the winch; for a rope from its
winch through a fixed ring (the dragline's hoist rope over the boom
pulley) the ring state splits it between the fixed winch-to-ring path and
the modelled span, so the span's length is the winch length minus the
(stretching) fixed path.
Particle masses are the segment's current unstretched length times its mass
per length, shared evenly by its particles, so a reel paying out makes every
particle of the span heavier at the same rate.
"""

from __future__ import annotations

import functools
from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np

from ._kernel import KIND_BODY, KIND_FIXED, KIND_PARTICLE

__all__ = ["Model", "assemble", "winch_table", "rough_body_positions"]


@dataclass
class Model:
    """The assembled model: kernel arrays plus the names needed to read them."""

    rig: object
    maneuver: object
    counts: dict
    body_names: tuple
    seg_names: tuple
    arrays: dict
    seg_particles: dict  # segment -> slice into particles
    seg_elements: dict  # segment -> slice into elements
    seg_rings: dict  # segment -> its rings' indices in order from its start (segments through rings only)
    ring_sites: tuple  # each ring's site name
    seg_nodes: dict  # segment -> list of (kind, idx, r_body) along the rope
    physics: tuple = ()
    notes: list = field(default_factory=list)

    # ---- layout ---------------------------------------------------------
    @property
    def n_bodies(self):
        return len(self.body_names)

    @property
    def n_particles(self):
        return self.arrays["part_seg"].shape[0]

    @property
    def n_elements(self):
        return self.arrays["el_seg"].shape[0]

    @property
    def n_rings(self):
        return self.arrays["ring_seg"].shape[0]

    @property
    def o_part(self):
        return 12 * self.n_bodies

    @property
    def o_vel(self):
        return self.o_part + 3 * self.n_particles

    @property
    def o_force(self):
        return self.o_vel + 3 * self.n_particles

    @property
    def o_ring(self):
        return self.o_force + self.n_elements

    @property
    def n_state(self):
        return self.o_ring + 2 * self.n_rings

    def body_slice(self, name):
        b = self.body_names.index(name)
        return slice(12 * b, 12 * b + 12)

    def kernel_tuple(self):
        """The arrays the compiled kernel reads, as a ``KernelModel`` (a namedtuple)."""
        return kernel_model(self.arrays)

    def describe_state_index(self, i):
        """Name the body, rope particle, element or ring a state index belongs to."""
        if i < self.o_part:
            return f"body {self.body_names[i // 12]}"
        if i < self.o_force:
            p = ((i - self.o_part) % (3 * self.n_particles)) // 3
            return f"rope segment {self.seg_names[self.arrays['part_seg'][p]]}"
        if i < self.o_ring:
            return f"rope segment {self.seg_names[self.arrays['el_seg'][i - self.o_force]]}"
        r = (i - self.o_ring) // 2
        return f"ring pulley {self.ring_sites[r]} of {self.seg_names[self.arrays['ring_seg'][r]]}"

    # ---- reading records --------------------------------------------------
    def segment_lengths(self, t):
        """Total unstretched length of every segment at times ``t`` (S, ...)."""
        a = self.arrays
        t = np.asarray(t, float)
        out = np.empty((len(self.seg_names),) + t.shape)
        for s in range(len(self.seg_names)):
            r = a["seg_reel"][s]
            if r < 0:
                out[s] = a["seg_len0"][s]
            else:
                out[s] = np.interp(t, a["reel_t"], a["reel_len"][:, r]) - a["seg_reel_off"][s]
        return out

    def fixed_positions(self, time):
        """Fixed points' positions at times ``time`` (s), shape (N, F, 3) in m."""
        a = self.arrays
        t = np.atleast_1d(np.asarray(time, float))
        out = np.empty((t.size, a["point_pos"].shape[1], 3))
        for i in range(out.shape[1]):
            for k in range(3):
                out[:, i, k] = np.interp(t, a["reel_t"], a["point_pos"][:, i, k])
        return out

    def ring_nodes(self, segment):
        """Indices into ``node_positions``'s nodes of ``segment``'s rings, in order from its start."""
        nodes = self.seg_nodes[segment]
        return [j for j, (kind, _, _) in enumerate(nodes) if kind != KIND_PARTICLE][1:-1]

    def node_positions(self, states, segment, time=None):
        """Positions of a segment's nodes along the rope for each record.

        Parameters
        ----------
        states : ndarray, shape (N, n_state)
        segment : str
        time : ndarray, shape (N,), optional
            Record times (s); needed only when fixed points move (default 0).

        Returns
        -------
        ndarray, shape (N, n_nodes, 3)
            Start point, particles (with the ring point between the sides)
            and end point, in order along the rope (m).
        """
        from ._kinematics import body_to_inertial

        states = np.atleast_2d(states)
        nodes = self.seg_nodes[segment]
        out = np.empty((states.shape[0], len(nodes), 3))
        fixed = self.fixed_positions(np.zeros(states.shape[0]) if time is None else time)
        T_cache = {}
        for j, (kind, idx, r) in enumerate(nodes):
            if kind == KIND_PARTICLE:
                out[:, j] = states[:, self.o_part + 3 * idx : self.o_part + 3 * idx + 3]
            elif kind == KIND_FIXED:
                out[:, j] = fixed[:, idx]
            else:
                if idx not in T_cache:
                    o = 12 * idx
                    T_cache[idx] = body_to_inertial(states[:, o + 6], states[:, o + 7], states[:, o + 8])
                out[:, j] = states[:, 12 * idx : 12 * idx + 3] + T_cache[idx] @ r
        return out


KERNEL_FIELDS = (
    "nb", "body_mass", "body_I", "body_Iinv", "g",
    "part_seg", "el_seg", "el_side",
    "el_ka", "el_ia", "el_ra", "el_kb", "el_ib", "el_rb",
    "seg_ks", "seg_kv", "seg_relax", "seg_len0", "seg_reel", "seg_reel_off",
    "seg_ring", "seg_nring", "seg_nel", "seg_npart", "seg_rho",
    "ring_seg", "ring_nelA", "ring_nelB", "ring_added_mass",
    "reel_t", "reel_len", "point_pos", "relax_damping",
    "body_cda", "seg_cda", "air_density",
    "has_joints", "joint_a", "joint_b", "joint_seg", "seg_bend_c", "seg_bend_k", "seg_link_mu",
    "ring_eA", "ring_eB", "ring_mu", "has_ring_friction", "seg_link_r",
    "ring_visc", "ring_bearing_mu",
    "el_na", "el_nb", "bnode_body", "bnode_arm",
    "part_accel_scale", "body_accel_scale", "body_lin_drag",
)  # fmt: skip

# The kernel reads the model by name; numba compiles a namedtuple of arrays like a plain tuple.
KernelModel = namedtuple("KernelModel", KERNEL_FIELDS)


def kernel_model(arrays):
    """The ``KernelModel`` of a model's ``arrays`` (a dict holding every field of KERNEL_FIELDS)."""
    return KernelModel(**{k: arrays[k] for k in KERNEL_FIELDS})


def _point_table(rig, maneuver, fixed_names):
    """Positions of the fixed points at the maneuver's times, (K, F, 3)."""
    table = np.empty((maneuver.time.size, len(fixed_names), 3))
    for i, name in enumerate(fixed_names):
        table[:, i] = maneuver.points.get(name, rig.fixed_points[name])
    unknown = set(maneuver.points) - set(fixed_names)
    if unknown:
        raise ValueError(f"{maneuver.described()} moves {sorted(unknown)[0]!r}, which is not a fixed point of the rig")
    return table


def _resolve(ref, rig, fixed_names):
    """``"body.point"`` -> (KIND_BODY, body index, lever arm from the mass centre)."""
    owner, _, point = ref.partition(".")
    if owner == "fixed":
        return KIND_FIXED, fixed_names.index(point), np.zeros(3)
    body = rig.bodies[owner]
    return KIND_BODY, list(rig.bodies).index(owner), body.points[point] - body.cg_body


def _ref_position(ref, rig, guess):
    owner, _, point = ref.partition(".")
    if owner == "fixed":
        return rig.fixed_points[point]
    return guess[owner] + rig.bodies[owner].points[point] - rig.bodies[owner].cg_body


def _span_particles(n, path, anchors, rig, guess):
    """Where a rope's ``n`` particles are cut between the spans of its path: ``cuts[j]`` particles lie before
    the path's point ``j`` (``cuts[0] = 0``, ``cuts[-1] = n``).

    A span between two fixed points (a winch to its fixed sheave) is one straight massless element. The
    others share the particles in proportion to their lengths in the rough hanging pose, each at least one
    while there are enough; fixed for a run.
    """
    fixed = [a[0] == KIND_FIXED for a in anchors]
    free = [not (fixed[j] and fixed[j + 1]) for j in range(len(path) - 1)]
    span = [np.linalg.norm(_ref_position(path[j + 1], rig, guess) - _ref_position(path[j], rig, guess)) if free[j]
            else 0.0 for j in range(len(path) - 1)]
    total = sum(span)
    least = 1 if n >= sum(free) else 0
    cuts, done = [0], 0.0
    for j in range(len(path) - 2):
        done += span[j]
        low = cuts[-1] + (least if free[j] else 0)
        high = n - least * sum(free[j + 1:])
        cuts.append(int(np.clip(round(n * done / total) if total > 0 else cuts[-1], low, max(low, high))))
    return cuts + [n]


def assemble(rig, maneuver, discretization="baseline", physics=(), dissipation=True):
    """Build the kernel arrays for a rig.

    Parameters
    ----------
    rig : Rig
    maneuver : Maneuver
        A length column for each of the rig's winches, moving points.
    discretization : str or dict
        Level name or per-rope particle counts (``Rig.particle_counts``).
    physics : sequence of Mechanism
        Optional mechanisms; each adjusts the arrays (``_physics``).
    dissipation : bool
        False switches the visco-elastic relaxation off (pure springs of
        stiffness Ks + Kv): the conservative model of the energy test.

    Returns
    -------
    Model
    """
    counts = rig.particle_counts(discretization)
    fixed_names = list(rig.fixed_points)
    seg_names = tuple(rig.ropes)
    missing = [w for w in rig.winches if w not in maneuver.lengths]
    if missing:
        raise ValueError(f"{maneuver.described()} has no {missing[0]}_length column for winch {missing[0]!r} of "
                         "the rig")
    unknown = [w for w in maneuver.lengths if w not in rig.winches]
    if unknown:
        raise ValueError(f"{maneuver.described()}: its {unknown[0]}_length column names no winch of the rig "
                         f"(its winches: {', '.join(rig.winches) or 'none'})")
    guess = rough_body_positions(rig, maneuver.lengths_at(maneuver.time[0]))

    part_seg, el = [], []
    seg = {k: [] for k in ("ks", "kv", "relax", "len0", "reel", "reel_off", "ring", "nring", "nel", "npart", "rho")}
    ring_seg, ring_nelA, ring_nelB, ring_eA, ring_sites = [], [], [], [], []
    seg_particles, seg_elements, seg_rings, seg_nodes = {}, {}, {}, {}
    for s, name in enumerate(seg_names):
        spec = rig.ropes[name]
        n = counts[name]
        path = [spec.start, *spec.rings, spec.end]
        anchors = [_resolve(ref, rig, fixed_names) for ref in path]
        p0, e0 = len(part_seg), len(el)
        cuts = _span_particles(n, path, anchors, rig, guess)
        chain, sides = [anchors[0]], []
        for j in range(len(path) - 1):
            chain += [(KIND_PARTICLE, p0 + i, np.zeros(3)) for i in range(cuts[j], cuts[j + 1])] + [anchors[j + 1]]
            sides += [j + 1 if spec.rings else 0] * (cuts[j + 1] - cuts[j] + 1)
        if spec.rings:
            seg_rings[name] = tuple(range(len(ring_seg), len(ring_seg) + len(spec.rings)))
            for j, site in enumerate(spec.ring_sites):
                ring_seg.append(s)
                ring_sites.append(site)
                ring_nelA.append(sides.count(j + 1))
                ring_nelB.append(sides.count(j + 2))
                ring_eA.append(e0 + sum(sides.count(i) for i in range(1, j + 2)) - 1)
        part_seg += [s] * n
        for (ka, ia, ra), (kb, ib, rb), side in zip(chain[:-1], chain[1:], sides):
            el.append((s, side, ka, ia, ra, kb, ib, rb))
        seg_particles[name] = slice(p0, p0 + n)
        seg_elements[name] = slice(e0, len(el))
        seg_nodes[name] = chain
        rho = spec.weight_per_length / rig.g
        if dissipation:
            seg["ks"].append(spec.static_stiffness)
            seg["kv"].append(spec.viscous_stiffness)
            seg["relax"].append(spec.viscous_stiffness / spec.viscous_damping)
        else:  # Cv -> infinity: the Maxwell branch is a second spring in parallel
            seg["ks"].append(spec.static_stiffness + spec.viscous_stiffness)
            seg["kv"].append(0.0)
            seg["relax"].append(0.0)
        seg["len0"].append(spec.length if spec.winch is None else 0.0)
        seg["reel"].append(-1 if spec.winch is None else list(rig.winches).index(spec.winch))
        seg["reel_off"].append(0.0)
        seg["ring"].append(seg_rings[name][0] if spec.rings else -1)
        seg["nring"].append(len(spec.rings))
        seg["nel"].append(len(sides))
        seg["npart"].append(max(n, 1))
        seg["rho"].append(rho)

    joints = _joints(seg_nodes, seg_elements, seg_names)
    bodies = list(rig.bodies.values())
    I = np.array([b.inertia for b in bodies]).reshape(-1, 3, 3)
    E = len(el)
    arrays = {
        "nb": len(bodies),
        "body_mass": np.array([b.mass for b in bodies], float),
        "body_I": I,
        "body_Iinv": np.linalg.inv(I),
        "g": float(rig.g),
        "part_seg": np.array(part_seg, np.int64),
        "el_seg": np.array([e[0] for e in el], np.int64),
        "el_side": np.array([e[1] for e in el], np.int64),
        "el_ka": np.array([e[2] for e in el], np.int64),
        "el_ia": np.array([e[3] for e in el], np.int64),
        "el_ra": np.array([e[4] for e in el], float).reshape(E, 3),
        "el_kb": np.array([e[5] for e in el], np.int64),
        "el_ib": np.array([e[6] for e in el], np.int64),
        "el_rb": np.array([e[7] for e in el], float).reshape(E, 3),
        "seg_ks": np.array(seg["ks"]),
        "seg_kv": np.array(seg["kv"]),
        "seg_relax": np.array(seg["relax"]),
        "seg_len0": np.array(seg["len0"]),
        "seg_reel": np.array(seg["reel"], np.int64),
        "seg_reel_off": np.array(seg["reel_off"]),
        "seg_ring": np.array(seg["ring"], np.int64),
        "seg_nring": np.array(seg["nring"], np.int64),
        "seg_nel": np.array(seg["nel"], np.int64),
        "seg_npart": np.array(seg["npart"], np.int64),
        "seg_rho": np.array(seg["rho"]),
        "ring_seg": np.array(ring_seg, np.int64),
        "ring_nelA": np.array(ring_nelA, np.int64),
        "ring_nelB": np.array(ring_nelB, np.int64),
        "ring_added_mass": np.zeros(len(ring_seg)),
        "reel_t": np.array(maneuver.time, float),
        "reel_len": winch_table(rig, maneuver),
        "point_pos": _point_table(rig, maneuver, fixed_names),
        "relax_damping": 0.0,
        # The statics' relaxation scales accelerations down (fictitious masses, _statics); 1 in a simulation.
        "part_accel_scale": np.ones(len(part_seg)),
        "body_accel_scale": np.ones(len(bodies)),
        "body_cda": np.array([b.drag_area for b in bodies], float),
        "body_lin_drag": np.zeros(len(bodies)),  # N s/m: a force -c v on the body's mass centre
        "seg_cda": np.zeros(len(seg_names)),
        "air_density": 1.2,
        "has_joints": 0,
        "joint_a": np.array([j[0] for j in joints], np.int64),
        "joint_b": np.array([j[1] for j in joints], np.int64),
        "joint_seg": np.array([j[2] for j in joints], np.int64),
        "seg_bend_c": np.zeros(len(seg_names)),
        # N m^2: a rope's bending stiffness EI, a moment EI / l times the bend at each joint between its elements
        # (l the mean of the two elements' lengths), none where a rope meets a body (a pin)
        "seg_bend_k": np.zeros(len(seg_names)),
        "seg_link_mu": np.zeros(len(seg_names)),
        "ring_eA": np.array(ring_eA, np.int64),
        "ring_eB": np.array(ring_eA, np.int64) + 1,
        "ring_mu": np.zeros(len(ring_seg)),
        "has_ring_friction": 0,
        "seg_link_r": np.zeros(len(seg_names)),
        "ring_visc": np.zeros(len(ring_seg)),
        # -: a Coulomb force ring_bearing_mu |bearing load| against the slide (the bearing's mu times its
        # pin's radius over the sheave's)
        "ring_bearing_mu": np.zeros(len(ring_seg)),
    }
    arrays.update(_node_map(arrays))
    model = Model(
        rig=rig,
        maneuver=maneuver,
        counts=counts,
        body_names=tuple(rig.bodies),
        seg_names=seg_names,
        arrays=arrays,
        seg_particles=seg_particles,
        seg_elements=seg_elements,
        seg_rings=seg_rings,
        ring_sites=tuple(ring_sites),
        seg_nodes=seg_nodes,
        physics=tuple(physics),
    )
    for mechanism in physics:
        mechanism.apply(model)
    arrays["has_joints"] = int(any(np.any(arrays[f] > 0) for f in ("seg_bend_c", "seg_bend_k", "seg_link_mu")))
    arrays["has_ring_friction"] = int(np.any(arrays["ring_mu"] > 0) or np.any(arrays["ring_bearing_mu"] > 0))
    return model


def _node_map(arrays):
    """Where each element end's position is gathered in the kernel (``_kernel._gather_nodes``).

    Nodes are the particles (0..P-1), then one node per element end on a
    body, in element order, end a before end b (the order the body forces
    were always summed in, so the sums are the same to the last bit), then
    the fixed points. ``el_na`` / ``el_nb``: the node of each element's end
    a / b; ``bnode_body`` and ``bnode_arm``: each body node's body and lever
    arm (m, body frame, from the mass centre).
    """
    P = arrays["part_seg"].shape[0]
    E = arrays["el_seg"].shape[0]
    body_ends = [(e, end) for e in range(E) for end in "ab" if arrays[f"el_k{end}"][e] == KIND_BODY]
    first_fixed = P + len(body_ends)
    node = {(e, end): P + k for k, (e, end) in enumerate(body_ends)}
    ends = {}
    for end in "ab":
        kind, idx = arrays[f"el_k{end}"], arrays[f"el_i{end}"]
        ends[end] = np.array([idx[e] if kind[e] == KIND_PARTICLE else node[(e, end)] if kind[e] == KIND_BODY
                              else first_fixed + idx[e] for e in range(E)], np.int64)
    return {
        "el_na": ends["a"],
        "el_nb": ends["b"],
        "bnode_body": np.array([arrays[f"el_i{end}"][e] for e, end in body_ends], np.int64),
        "bnode_arm": np.array([arrays[f"el_r{end}"][e] for e, end in body_ends], float).reshape(-1, 3),
    }


def _joints(seg_nodes, seg_elements, seg_names):
    """Rope joints: (first element or -(body+1), second element, segment).

    Consecutive elements meeting at a particle, and a segment's end element
    with the body it hangs from. Not across a ring: the rope slides there.
    """
    joints = []
    for s, name in enumerate(seg_names):
        nodes = seg_nodes[name]
        e0 = seg_elements[name].start
        for k in range(1, len(nodes) - 1):
            if nodes[k][0] == KIND_PARTICLE:
                joints.append((e0 + k - 1, e0 + k, s))
        if nodes[0][0] == KIND_BODY:
            joints.append((-(nodes[0][1] + 1), e0, s))
        if nodes[-1][0] == KIND_BODY:
            joints.append((-(nodes[-1][1] + 1), e0 + len(nodes) - 2, s))
    return joints


def winch_table(rig, maneuver):
    """The maneuver's winch lengths in the rig's winch order, (K, W) m; (K, 1) of ones for a rig without winches."""
    if not rig.winches:
        return np.ones((maneuver.time.size, 1))
    return np.column_stack([maneuver.lengths[w] for w in rig.winches]).astype(float)


def rough_body_positions(rig, lengths):
    """A rough pose (mass-centre positions, m) to start the statics from.

    With the rig's ``rough_pose``, its bodies are one rigid block hanging
    from the ``hang`` rope's span below its ring and, when it is taut, held
    back by the ``hold`` rope; the block's place is found on the x-z plane
    by a two-rope balance. Without one, each body starts at its
    ``position`` (the origin when it gives none).

    Parameters
    ----------
    rig : Rig
    lengths : dict
        Winch name -> its length (m) at the start.
    """
    pose = rig.rough_pose
    if pose is None:
        return {name: (np.zeros(3) if b.position is None else b.position) for name, b in rig.bodies.items()}
    hang, hold = rig.ropes[pose.hang], rig.ropes[pose.hold]
    fp = rig.fixed_points
    ring = fp[hang.rings[0].partition(".")[2]]
    hang_from, hold_from = fp[hang.start.partition(".")[2]], fp[hold.start.partition(".")[2]]
    hang_body, hold_body = hang.end.partition(".")[0], hold.end.partition(".")[0]
    p = np.array(_hanging_block(tuple(map(float, ring)), tuple(map(float, hang_from)), tuple(map(float, hold_from)),
                                float(lengths[hang.winch]), float(lengths[hold.winch]),
                                tuple(map(float, pose.offsets[hang_body])), tuple(map(float, pose.offsets[hold_body]))))
    return {name: p + off for name, off in pose.offsets.items()}


@functools.lru_cache(maxsize=64)
def _hanging_block(ring, hang_from, hold_from, hang_length, hold_length, hang_offset, hold_offset):
    """The first body's rough place (x, 0, z) for ``rough_body_positions``.

    Kept per fixed points and lengths: every model is assembled through
    here, and a diagnosis assembles hundreds of rigs that differ only in
    masses and ropes (4 ms each).
    """
    from scipy.optimize import minimize

    ring, hang_from, hold_from = np.array(ring), np.array(hang_from), np.array(hold_from)
    hang_offset, hold_offset = np.array(hang_offset), np.array(hold_offset)
    span = hang_length - np.linalg.norm(ring - hang_from)

    def cost(xz):
        p = np.array([xz[0], 0.0, xz[1]])
        dh = np.linalg.norm(p + hang_offset - ring) - 0.99 * span
        dd = max(0.0, np.linalg.norm(p + hold_offset - hold_from) - 0.99 * hold_length)
        return dh**2 + dd**2 + 1e-4 * (-p[2])

    x0 = np.array([ring[0] + 0.3, ring[2] + span + 0.55])
    res = minimize(cost, x0, method="Nelder-Mead", options={"xatol": 1e-6, "fatol": 1e-12, "maxiter": 4000})
    return float(res.x[0]), 0.0, float(res.x[1])
