"""Running the model: from equilibrium through a maneuver to a trajectory table."""

from __future__ import annotations

import time as _clock
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import _kernel
from ._kinematics import PAPER_SEQUENCE, angles_from_matrix, body_to_inertial, euler_from_matrix, matrix_from_angles
from ._maneuver import default_maneuver
from ._model import assemble
from ._release import POSE_COORDINATES, let_go
from ._rig import load_rig
from ._statics import _POSE, StaticsError, solve_statics
from ._time_step import start_time_step
from ._tracked import MAX_STEPS, NO_REFINEMENT, NO_SCHEDULE, RK4, VERLET, integrate_tracked
from ._table import trajectory_columns

# The integrators ``simulate`` offers, by name.
INTEGRATORS = {"rk4": RK4, "verlet": VERLET}

__all__ = ["SimulationError", "SimulationResult", "simulate"]


class SimulationError(RuntimeError):
    """The integration blew up (non-finite state or runaway speed)."""


# Work sized from the input is checked before it is spent (``MAX_STEPS``, the integrator's own bound): a
# mistyped --dt 1e-12 or --rate once ran for hours or until the kernel killed it.
MAX_RECORD_BYTES = 2 * 2**30
# No rope, cable or chain stretches a quarter of its length without breaking (nylon, the stretchiest fibre,
# parts near 20-25 %; steel wire near 2 %): a rig that must, to hang or to be held where its release says, is
# not a machine (a fuzzed mass centre 1 m off its rope's point stretched a string 98 % at a release, and the
# string's snap back ran past 100 m/s).
MAX_STRAIN = 0.25
# A reel table is refused when it runs a rope's elements below this length
# (the step would fall towards zero; the rope yanks its end away) or pays
# rope faster than this speed (a table that jumps 1 m in 1e-12 s).
MIN_ELEMENT_LENGTH = 1e-3  # m
MAX_REEL_SPEED = 20.0  # m/s, fifteen times the paper's rope speed limit


def _frozen_schedule(schedule, n_records, method):
    """``simulate``'s ``schedule`` as ``integrate_tracked`` takes it (empty arrays: none)."""
    if schedule is None or method != VERLET:
        return NO_SCHEDULE, NO_REFINEMENT
    substeps, refined = (np.asarray(a) for a in schedule)
    if substeps.ndim != 1 or refined.shape != substeps.shape or substeps.shape[0] < n_records:
        raise ValueError(f"a step schedule of {substeps.shape[0]} record intervals for a run of {n_records}")
    return (np.ascontiguousarray(substeps[:n_records], np.int64),
            np.ascontiguousarray(refined[:n_records], np.bool_))


@dataclass
class SimulationResult:
    """What a run produced.

    Attributes
    ----------
    time : ndarray (N,)
        Record times (s).
    states : ndarray (N, n_state)
        Full state at each record.
    model : Model
    dt : float
        Integration step (s): the smallest taken.
    equilibrium_residual : float
        Largest static imbalance of the starting pose (N or N m).
    steps : int
        Integration steps taken.
    dt_start : float
        The step the run started with (s).
    timings : dict
        Wall time (s) of the call's parts: ``statics_s`` (0 when started
        from ``initial_state``) and ``integrate_s`` (choosing the step and
        integrating); what ``dragline bench simulate`` reports.
    substeps : ndarray (N - 1,) of int, optional
        Verlet steps taken in each record interval (the schedule
        ``sensitivities`` differentiates on); None for RK4.
    refined : ndarray (N - 1,) of bool, optional
        Where that count is a slack refinement (``_tracked``).
    unrefined_slack : int
        On a given ``schedule``: record intervals where an element turned
        slack or taut at a step the schedule had not refined (the run is
        then less accurate there than its own schedule would make it).
    """

    time: np.ndarray
    states: np.ndarray
    model: object
    dt: float
    equilibrium_residual: float
    steps: int = 0
    dt_start: float = float("nan")
    timings: dict = field(default_factory=dict)
    substeps: np.ndarray | None = None
    refined: np.ndarray | None = None
    unrefined_slack: int = 0

    @property
    def schedule(self):
        """``(substeps, refined)``: what ``simulate(..., schedule=)`` takes to step as this run did; None for RK4."""
        return None if self.substeps is None else (self.substeps, self.refined)

    @property
    def table(self):
        """The trajectory table (docs/conventions.md), plus tension and reel columns."""
        return trajectory_table(self.model, self.time, self.states)

    def motion_table(self):
        """The trajectory table's motion columns only (docs/conventions.md), without tensions and reel lengths.

        A fifth of ``table``'s cost (2 against 10 ms for the 10 s dig): what
        the diagnosis reads of each of its hundreds of simulations.
        """
        return trajectory_table(self.model, self.time, self.states, extras=False)

    def rope_nodes(self, segment):
        """Node positions along a rope segment, (N, n_nodes, 3) in m."""
        return self.model.node_positions(self.states, segment, self.time)

    def rope_points(self, segment, distances):
        """Material points of a rope: positions at unstretched distances from its end.

        The rope between nodes is taken as straight and uniformly stretched
        within each element.

        Parameters
        ----------
        segment : str
        distances : array_like (M,)
            Unstretched distance from the rope's ``end`` (m).

        Returns
        -------
        ndarray (N, M, 3)
            NaN where the distance is beyond the rope's current length.
        """
        nodes = self.rope_nodes(segment)[:, ::-1]  # from the end backwards
        rest = element_rest_lengths(self.model, self.time, self.states, segment)[:, ::-1]
        cum = np.concatenate([np.zeros((rest.shape[0], 1)), np.cumsum(rest, axis=1)], axis=1)
        d = np.asarray(distances, float)
        out = np.full((nodes.shape[0], d.size, 3), np.nan)
        for i in range(nodes.shape[0]):
            j = np.searchsorted(cum[i], d, side="right") - 1
            ok = (j >= 0) & (j < rest.shape[1])
            jj = j[ok]
            w = (d[ok] - cum[i, jj]) / rest[i, jj]
            out[i, ok] = nodes[i, jj] * (1 - w)[:, None] + nodes[i, jj + 1] * w[:, None]
        return out

    def energy(self):
        """Mechanical energy (J) per record: kinetic, elastic and gravity.

        Elastic energy is that of the static springs, Ks/L_e stretch^2 / 2,
        plus that of the Maxwell branches' springs, F_m^2 L_e / (2 Kv);
        conserved exactly by the dissipation-free model (``dissipation=False``).
        """
        return mechanical_energy(self.model, self.time, self.states)


def element_rest_lengths(model, time, states, segment):
    """Rest length (m) of each element of a segment, (N, n_elements)."""
    a = model.arrays
    s = model.seg_names.index(segment)
    L = model.segment_lengths(time)[s]
    sl = model.seg_elements[segment]
    side = a["el_side"][sl]
    out = np.empty((len(time), sl.stop - sl.start))
    rings = model.seg_rings.get(segment, ())
    if not rings:
        out[:] = (L / a["seg_nel"][s])[:, None]
        return out
    # ring j holds the unstretched rope from the start to it; span j lies between rings j - 1 and j
    bounds = [np.zeros(len(time))] + [states[:, model.o_ring + 2 * r] for r in rings] + [L]
    for j in range(len(rings) + 1):
        on_span = side == j + 1
        out[:, on_span] = ((bounds[j + 1] - bounds[j]) / on_span.sum())[:, None]
    return out


def element_tensions(model, time, states, segment):
    """Tension (N) of each element of a segment, (N, n_elements).

    Eq. 8 in parallel form: Ks/L_e (s - L_e) + F_m when taut, else zero.
    """
    a = model.arrays
    s = model.seg_names.index(segment)
    nodes = model.node_positions(states, segment, time)
    length = np.linalg.norm(np.diff(nodes, axis=1), axis=2)
    rest = element_rest_lengths(model, time, states, segment)
    Fm = states[:, model.o_force : model.o_ring][:, model.seg_elements[segment]]
    tension = a["seg_ks"][s] / rest * (length - rest) + Fm
    return np.where(length > rest, np.maximum(tension, 0.0), 0.0)


def trajectory_table(model, time, states, extras=True):
    """Trajectory table of a run (columns of docs/conventions.md first, then extras unless ``extras`` is False)."""
    cols = {"time": time}
    for b, name in enumerate(model.body_names):
        o = 12 * b
        for k, q in enumerate(("x", "y", "z")):
            cols[f"{name}.{q}"] = states[:, o + k]
        angles = states[:, o + 6 : o + 9].T
        sequence = model.rig.bodies[name].euler_sequence
        if sequence != PAPER_SEQUENCE:
            angles = angles_from_matrix(body_to_inertial(*angles), sequence)
        for q, values in zip(("roll", "pitch", "yaw"), angles):
            cols[f"{name}.{q}"] = values
        for k, q in enumerate(("vx", "vy", "vz")):
            cols[f"{name}.{q}"] = states[:, o + 3 + k]
        for k, q in enumerate(("p", "q", "r")):
            cols[f"{name}.{q}"] = states[:, o + 9 + k]
    for rope in model.rig.winches.values():
        nodes = model.node_positions(states, rope, time)
        cols[f"{rope}.length"] = np.linalg.norm(np.diff(nodes, axis=1), axis=2).sum(axis=1)
    frame = pd.DataFrame(cols, columns=trajectory_columns(model.rig))
    if not extras:
        return frame
    at_time = model.maneuver.lengths_at(time)
    extras = {f"{rope}.reel_length": at_time[winch] for winch, rope in model.rig.winches.items()}
    for seg in model.seg_names:
        tension = element_tensions(model, time, states, seg)
        extras[f"{seg}.tension_start"] = tension[:, 0]
        extras[f"{seg}.tension_end"] = tension[:, -1]
    return pd.concat([frame, pd.DataFrame(extras)], axis=1)


def mechanical_energy(model, time, states):
    a = model.arrays
    g = a["g"]
    E = np.zeros(len(time))
    for b in range(model.n_bodies):
        o = 12 * b
        m = a["body_mass"][b]
        v = states[:, o + 3 : o + 6]
        w = states[:, o + 9 : o + 12]
        E += 0.5 * m * (v**2).sum(1) + 0.5 * np.einsum("ni,ij,nj->n", w, a["body_I"][b], w)
        E -= m * g * states[:, o + 2]
    L = model.segment_lengths(time)
    P = model.n_particles
    for p in range(P):
        s = a["part_seg"][p]
        m = a["seg_rho"][s] * L[s] / a["seg_npart"][s]
        v = states[:, model.o_vel + 3 * p : model.o_vel + 3 * p + 3]
        E += 0.5 * m * (v**2).sum(1) - m * g * states[:, model.o_part + 3 * p + 2]
    for r in range(model.n_rings):
        s = a["ring_seg"][r]
        ms = a["seg_rho"][s] * L[s] / 3.0 + a["ring_added_mass"][r]
        E += 0.5 * ms * states[:, model.o_ring + 2 * r + 1] ** 2
    for s, seg in enumerate(model.seg_names):
        rest = element_rest_lengths(model, time, states, seg)
        nodes = model.node_positions(states, seg, time)
        stretch = np.maximum(np.linalg.norm(np.diff(nodes, axis=1), axis=2) - rest, 0.0)
        E += (0.5 * a["seg_ks"][s] / rest * stretch**2).sum(1)
        if a["seg_kv"][s] > 0:  # energy held in the Maxwell branches' springs
            Fm = states[:, model.o_force : model.o_ring][:, model.seg_elements[seg]]
            E += (Fm**2 * rest / (2 * a["seg_kv"][s])).sum(1)
    return E


def check_reel_table(model):
    """ValueError (one line) when the maneuver's reel table is not one the rig's ropes can follow.

    Every rope on a reel keeps each element at least ``MIN_ELEMENT_LENGTH``
    long, and no reel pays out or winds in faster than ``MAX_REEL_SPEED``.
    """
    a = model.arrays
    t = np.asarray(a["reel_t"], float)
    lengths = model.segment_lengths(t)
    for s, name in enumerate(model.seg_names):
        if a["seg_reel"][s] < 0:
            continue
        n_el = int(a["seg_nel"][s])
        k = int(np.argmin(lengths[s]))
        if lengths[s, k] < MIN_ELEMENT_LENGTH * n_el:
            raise ValueError(f"the maneuver runs {name} down to {lengths[s, k]:.3g} m of rope at t = {t[k]:g} s; "
                             f"its {n_el} elements need at least {MIN_ELEMENT_LENGTH * n_el:g} m")
        if t.size > 1:
            speed = np.abs(np.diff(lengths[s])) / np.diff(t)
            k = int(np.argmax(speed))
            if speed[k] > MAX_REEL_SPEED:
                raise ValueError(f"the maneuver moves {name} at {speed[k]:.3g} m/s between t = {t[k]:.12g} and "
                                 f"{t[k + 1]:.12g} s; reels move at most {MAX_REEL_SPEED:g} m/s")


def _check_strain(model, state, t, how):
    """ValueError naming the rig file and the rope when a rope must stretch beyond ``MAX_STRAIN`` at ``state``."""
    time = np.array([float(t)])
    for seg in model.seg_names:
        rest = element_rest_lengths(model, time, state[None], seg)[0]
        length = np.linalg.norm(np.diff(model.node_positions(state[None], seg, time)[0], axis=0), axis=1)
        strain = float(np.max(length / rest - 1.0))
        if strain > MAX_STRAIN:
            raise ValueError(f"{model.rig.source}: {how}, rope {seg} is stretched {100 * strain:.0f} %; no rope, "
                             f"cable or chain bears more than {100 * MAX_STRAIN:.0f} % (a point, mass or length "
                             "far from the machine's?)")


# The first fraction of a start's displacement from rest its held statics are solved at (``_settled_from_rest``),
# and the least it halves to where a step fails.
HOLD_STEP, HOLD_STEP_MIN = 0.25, 1.0 / 64.0


def _settled_from_rest(model, rig, t0, rest, release):
    """The statics of a start given ``about_rest``, reached from the rest pose ``rest`` in steps.

    The held bodies are moved from rest by a fraction of their
    displacement at a time (``HOLD_STEP``, halved where a step's statics
    fail, down to ``HOLD_STEP_MIN``), each statics starting from the one
    before: the second way to a start's statics, where the first (from
    the rig's rough hanging pose, relaxed, then Newton) did not converge.
    That one failed or not on the held statics of a box turned 0.2 rad on
    three taut cables (the three-drone flights, ``docs/real-recordings.md``)
    with a lid point moved by 0.2 mm, and the diagnosis's finite
    differences failed with it; this one starts each Newton next to its
    answer. Either ends at the balance to the statics' tolerance.
    """
    y, done, step = np.array(rest, float), 0.0, HOLD_STEP
    while done < 1.0:
        fraction = min(1.0, done + step)
        part = {name: dict(pose, position=fraction * np.asarray(pose["position"], float),
                           angles=fraction * np.asarray(pose.get("angles", np.zeros(3)), float))
                if pose.get("about_rest") else pose for name, pose in release.items()}
        held = _held_pose(rig, _about_rest(model, rest, part))
        try:
            eq = solve_statics(model, t0, y0=_placed(model, y, held), held=held)
        except StaticsError:
            if step / 2.0 < HOLD_STEP_MIN:
                raise
            step /= 2.0
            continue
        y, done = eq.state, fraction
    return eq


def _placed(model, state, held):
    """``state`` with each held body moved to its held pose but for the coordinates the ropes settle."""
    state = np.array(state, float)
    for name, (position, angles, settled) in held.items():
        b = model.body_names.index(name)
        pose = np.r_[position, angles]
        for k, at in enumerate(_POSE):
            if k not in settled:
                state[12 * b + at] = pose[k]
    return state


def _about_rest(model, rest, release):
    """``release`` with each pose given ``about_rest`` (a displacement from the rest pose ``rest``) made absolute.

    Its settled coordinates are held at rest's values until the ropes
    settle them: the coordinates a start displaces are soft, restored by
    gravity (a sway, a turn), so moving along them from rest lifts the body
    and the ropes, held at rest's height and tilt, are taut - where the
    settling's Newton steps are smooth (from a slack rope they are not).
    """
    out = {}
    for name, pose in release.items():
        if pose.get("about_rest"):
            b = model.body_names.index(name)
            sequence = model.rig.bodies[name].euler_sequence
            at_rest = rest[12 * b: 12 * b + 9].copy()
            angles = np.array(angles_from_matrix(body_to_inertial(*at_rest[6:]), sequence))
            turned = matrix_from_angles(*(angles + np.asarray(pose.get("angles", np.zeros(3)), float)), sequence)
            held = np.r_[at_rest[:3] + np.asarray(pose["position"], float), euler_from_matrix(turned)]
            for k, c in enumerate(POSE_COORDINATES):
                if c in pose.get("settled", ()):
                    held[k] = at_rest[k if k < 3 else k + 3]
            pose = dict(pose, about_rest=False, position=held[:3],
                        angles=np.array(angles_from_matrix(body_to_inertial(*held[3:]), sequence)))
        out[name] = pose
    return out


def _held_pose(rig, release):
    """``release`` (body -> position, angles) as ``solve_statics``'s ``held``; ValueError naming an unknown body."""
    held = {}
    for name, pose in release.items():
        if name not in rig.bodies:
            raise ValueError(f"the release names {name!r}, which is not a body of the rig")
        position = np.asarray(pose["position"], float)
        angles = np.asarray(pose.get("angles", (0.0, 0.0, 0.0)), float)
        if position.shape != (3,) or angles.shape != (3,) or not (np.isfinite(position).all()
                                                                   and np.isfinite(angles).all()):
            raise ValueError(f"the release of {name!r} needs a finite position (3) and angles (3)")
        # given in the body's output sequence; the state's are Eq. 11's
        turn = matrix_from_angles(*angles, rig.bodies[name].euler_sequence)
        settled = pose.get("settled", ())
        if any(c not in POSE_COORDINATES for c in settled):
            raise ValueError(f"the release of {name!r} settles {list(settled)}; a body's pose coordinates are "
                             f"{', '.join(POSE_COORDINATES)}")
        held[name] = (position, np.array(euler_from_matrix(turn)),
                      tuple(POSE_COORDINATES.index(c) for c in settled))
    return held


def simulate(
    rig=None,
    maneuver=None,
    discretization="baseline",
    physics=(),
    duration=10.0,
    rate_hz=200.0,
    dt=None,
    dissipation=True,
    initial_state=None,
    max_speed=100.0,
    statics_guess=None,
    integrator="verlet",
    release=None,
    schedule=None,
):
    """Simulate a maneuver from static equilibrium, or from a release.

    Parameters
    ----------
    rig : Rig, optional
        The built-in 1/16-scale rig by default.
    maneuver : Maneuver, optional
        The rig's own (``default_maneuver``; the dig for the built-in rig).
    discretization : str or dict
        low, baseline, medium, high, or per-rope particle counts.
    physics : sequence of Mechanism
        Optional mechanisms (``parse_physics``).
    duration : float
        Simulated time from the maneuver's start (s).
    rate_hz : float
        Output rate (Hz); the step divides the output interval.
    dt : float, optional
        A fixed integration step (s), rounded down to divide the output
        interval. By default the step is the integrator's stability limit at
        the start (``start_time_step``), cut as the rig stiffens
        (``integrate_tracked``).
    dissipation : bool
        False: visco-elastic relaxation off (energy-conserving model).
    initial_state : ndarray, optional
        Start here instead of at the static equilibrium.
    max_speed : float
        Any speed above this (m/s) is a blow-up.
    statics_guess : ndarray, optional
        Where the statics start (for example the equilibrium of a rig a few
        percent different, same discretization): the relaxation then ends
        almost at once and Newton polishes.
    release : dict, optional
        Body name -> ``{"position": (3,) m, "angles": (3,) rad}`` (angles
        default level; ``velocity`` m/s and ``rates`` rad/s body axes to
        let go of it moving; ``settled``: pose coordinates of
        ``POSE_COORDINATES`` the ropes settle from there instead of the
        hold; ``about_rest``: position and angles are a displacement from
        the rig's rest pose at the start): the trial starts from a
        release, those bodies held there at rest, the ropes (and any body
        not named) settled under them, then let go. By default the
        maneuver's ``start``, else the rig's own ``release``, else the
        static equilibrium.
    integrator : {"verlet", "rk4"}
        Kick-drift-kick velocity Verlet (``_verlet``: one right-hand side a
        step, about twice as fast at the baseline) or classical RK4, the
        reference.
    schedule : tuple, optional
        An earlier run's ``SimulationResult.schedule`` (Verlet, no ``dt``;
        the same rate and start, as long or longer): step as it did,
        record by record (``_tracked.integrate_tracked``'s ``frozen``), so
        that the difference of two runs a small parameter change apart is
        the change, not two step sequences' scatter (the diagnosis's
        finite differences). Where the rig stiffens beyond the
        schedule's margin the run steps on its own; elsewhere it refines no
        interval the schedule did not, wherever an element turns slack or
        taut (``_tracked.integrate_tracked``).

    Returns
    -------
    SimulationResult

    Raises
    ------
    SimulationError
        On a blow-up, naming the time and the segment or body.
    """
    rig = load_rig() if rig is None else rig
    maneuver = default_maneuver(rig) if maneuver is None else maneuver
    if integrator not in INTEGRATORS:
        raise ValueError(f"unknown integrator {integrator!r}; choose one of {', '.join(INTEGRATORS)}")
    if not duration > 0:
        raise ValueError(f"duration must be positive, got {duration}")
    if not rate_hz > 0:
        raise ValueError(f"output rate must be positive, got {rate_hz}")
    if not (np.isfinite(duration) and np.isfinite(rate_hz)):
        raise ValueError(f"duration and output rate must be finite, got {duration} s at {rate_hz} Hz")
    if dt is not None:
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"time step must be positive and finite, got {dt}")
        steps = duration * max(rate_hz, 1.0 / dt)
        if steps > MAX_STEPS:
            raise ValueError(f"a {duration:g} s simulation at a {dt:g} s step needs {steps:.3g} steps, "
                             f"more than the {MAX_STEPS:.0e} allowed (hours of computing)")
    model = assemble(rig, maneuver, discretization, physics=physics, dissipation=dissipation)
    check_reel_table(model)
    t0 = float(maneuver.time[0])
    clock = _clock.perf_counter()
    if initial_state is None:
        # Every mechanism acts only on motion (or is modelled so), so the
        # rest pose is the nominal model's; its statics are also cheaper.
        nominal = assemble(rig, maneuver, discretization, dissipation=dissipation) if physics else model
        guess = None
        if statics_guess is not None and np.shape(statics_guess) == (nominal.n_state,):
            guess = statics_guess
        release = (maneuver.start or rig.release) if release is None else release
        if release and any(pose.get("about_rest") for pose in release.values()):
            rest = solve_statics(nominal, t0, y0=guess).state
            absolute = _about_rest(nominal, rest, release)
            try:
                eq = solve_statics(nominal, t0, held=_held_pose(rig, absolute))
            except StaticsError:
                eq = _settled_from_rest(nominal, rig, t0, rest, release)
            release = absolute
        else:
            held = None if not release else _held_pose(rig, release)
            eq = solve_statics(nominal, t0, y0=guess if held is None else None, held=held)
        y0, residual = eq.state, eq.residual
        _check_strain(nominal, y0, t0, "held where its release says" if release else "at rest")
        if release:
            y0 = let_go(nominal, y0, t0, release)
    else:
        y0, residual = np.array(initial_state, float), float("nan")
    statics_s = _clock.perf_counter() - clock
    out_dt = 1.0 / rate_hz
    n_records = int(round(duration * rate_hz))
    needed = (n_records + 1) * model.n_state * 8
    if needed > MAX_RECORD_BYTES:
        raise ValueError(f"{n_records} records of {model.n_state} states ({duration:g} s at {rate_hz:g} Hz) "
                         f"need {needed / 2**30:.3g} GiB, more than the {MAX_RECORD_BYTES / 2**30:g} GiB allowed")
    m = model.kernel_tuple()
    work = _kernel.make_work(m)
    method = INTEGRATORS[integrator]
    clock = _clock.perf_counter()
    if dt is None:
        dt0, lam0 = start_time_step(model, y0, t0, integrator=integrator)
        frozen, frozen_refined = _frozen_schedule(schedule, n_records, method)
        records, substeps, refined, unrefined, status, bad_time, bad_index = integrate_tracked(
            y0, t0, out_dt, n_records, dt0, lam0, m, work, max_speed, MAX_STEPS, method, frozen, frozen_refined
        )
        if status == _kernel.STATUS_TOO_STIFF:
            raise ValueError(
                f"the rig stiffens beyond what can be integrated: at t = {bad_time:.3f} s a step of "
                f"{out_dt / max(bad_index, 1):.2g} s would be needed (a rope or chain element near zero length? "
                f"check the maneuver's reel lengths), more than the {MAX_STEPS:.0e} steps allowed")
        taken = substeps if method == VERLET else None
        refined = refined if method == VERLET else None
        unrefined = int(unrefined)
        step = out_dt / max(int(substeps.max(initial=1)), 1)  # the smallest step taken
        steps, dt_start = int(substeps.sum()), out_dt / max(int(substeps[0]), 1) if len(substeps) else dt0
    else:
        per_record = max(1, int(np.ceil(out_dt / float(dt) - 1e-9)))
        step = dt_start = out_dt / per_record
        steps = n_records * per_record
        taken = np.full(n_records, per_record, np.int64) if method == VERLET else None
        refined = np.zeros(n_records, bool) if method == VERLET else None
        unrefined = 0
        if method == VERLET:
            # lam0 = inf: the step is never cut, nor refined at a slack change (a fixed step was asked)
            records, _, _, _, status, bad_time, bad_index = integrate_tracked(
                y0, t0, out_dt, n_records, step, np.inf, m, work, max_speed, MAX_STEPS, method, NO_SCHEDULE,
                NO_REFINEMENT)
        else:
            records, status, bad_step, bad_index = _kernel.integrate(
                y0, t0, step, n_records * per_record, per_record, m, work, max_speed
            )
            bad_time = t0 + bad_step * step
    if status != _kernel.STATUS_OK:
        what = "a non-finite value" if status == _kernel.STATUS_NONFINITE else f"a speed above {max_speed:g} m/s"
        raise SimulationError(
            f"simulation blew up at t = {bad_time:.4f} s: {what} in {model.describe_state_index(bad_index)}"
        )
    integrate_s = _clock.perf_counter() - clock
    time = t0 + np.arange(records.shape[0]) * out_dt
    return SimulationResult(time=time, states=records, model=model, dt=step, equilibrium_residual=residual,
                            steps=steps, dt_start=dt_start,
                            timings={"statics_s": statics_s, "integrate_s": integrate_s},
                            substeps=None if taken is None else taken[: records.shape[0] - 1],
                            refined=None if refined is None else refined[: records.shape[0] - 1],
                            unrefined_slack=unrefined)
