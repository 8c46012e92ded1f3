"""Forward sensitivities (``simulate._tangent``, ``simulate._sensitivity``) against central differences.

The truth is the simulation itself, differenced: the right-hand side's
tangent against its central differences, Richardson-extrapolated; the
whole run's (statics, Verlet on the frozen step schedule, the impulses,
the output map) against central differences of ``simulate`` (or of the
scheme over a few record intervals) where they have converged
(``_converged_difference``), on trials short and smooth enough (no rope
turns slack, no ring or joint switches between sticking and slipping)
that they do. The last test goes through an episode where chains turn
slack and taut element by element, to show where no derivative holds
(``Sensitivities.horizon``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dragline.simulate import (Maneuver, TangentUnavailable, apply_parameters, assemble, default_maneuver, load_rig,
                               make_mechanism, rig_from_dict, simulate, simulate_sensitivities, solve_statics)
from dragline.simulate import _kernel
from dragline.simulate._model import kernel_model
from dragline.simulate._tangent import TANGENT_FIELDS, TangentModel, integrate_tangent, make_tangent_work, rhs_tangent_at

RATE_HZ = 100.0
TOLERANCE = 1e-4  # column-norm relative error the issue asks of every column
LENGTHS = ("bnode_arm", "seg_len0", "seg_reel_off", "reel_len", "point_pos")


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def _acceleration_rows(model):
    bodies = [12 * b + k for b in range(model.n_bodies) for k in (3, 4, 5, 9, 10, 11)]
    rings = [model.o_ring + 2 * r + 1 for r in range(model.n_rings)]
    return np.r_[bodies, np.arange(model.o_vel, model.o_force), rings].astype(int)


@pytest.mark.parametrize("rig_name", ["gantry_crane", "dragline"])
def test_the_right_hand_sides_tangent_is_its_derivative_along_every_field(rig_name):
    rig = load_rig(rig_name)
    result = simulate(rig, duration=0.4, rate_hz=RATE_HZ)
    model, y = result.model, result.states[-1]
    arrays = dict(model.arrays)
    # drag (quadratic and linear) on every body, on every rope, and inertia and bearing damping at every
    # sheave, so that each is
    # differentiated where it acts
    arrays["body_cda"] = np.full(model.n_bodies, 0.01)
    arrays["seg_cda"] = np.full(len(model.seg_names), 0.002)
    arrays["ring_added_mass"] = np.full(model.n_rings, 0.08)
    arrays["ring_visc"] = np.full(model.n_rings, 0.4)
    arrays["body_lin_drag"] = np.full(model.n_bodies, 0.3)
    t = float(result.time[-1]) * 0.7  # inside the maneuver's table, between its rows
    rng = np.random.default_rng(5)
    rows = _acceleration_rows(model)

    def rhs(state, fields):
        m = kernel_model(fields)
        out = np.zeros_like(state)
        _kernel.rhs(t, state, out, m, _kernel.make_work(m))
        return out[rows]

    for which in ("state", *TANGENT_FIELDS):
        dY = rng.normal(size=model.n_state) * (np.abs(y) * 1e-5 + 1e-7) if which == "state" else np.zeros(model.n_state)
        dm = {f: np.zeros(np.shape(arrays[f])) for f in TANGENT_FIELDS}
        if which != "state":
            a = np.abs(np.asarray(arrays[which], float))
            # lengths and places by a micrometre a unit step (a rope element is millimetres from slack), the rest
            # by their own size
            scale = 1e-4 if which in LENGTHS else a + 1e-2 * max(a.max(initial=0.0), 1e-2)
            dm[which] = rng.normal(size=a.shape) * scale
        if not np.any(dm.get(which, dY)):
            continue
        m = kernel_model(arrays)
        # contiguous, as the simulator's own: another layout is another compiled specialization
        tangent = TangentModel(**{f: np.ascontiguousarray(dm[f][..., None]) for f in TANGENT_FIELDS})
        _, dacc = rhs_tangent_at(t, y, np.ascontiguousarray(dY[:, None]), m, tangent, _kernel.make_work(m),
                                 make_tangent_work(m, 1))
        quotients = []
        for h in (1e-2, 5e-3):  # Richardson: the steps' truncation errors, as h^2, cancel
            up = {**arrays, **{f: np.asarray(arrays[f], float) + h * dm[f] for f in TANGENT_FIELDS}}
            down = {**arrays, **{f: np.asarray(arrays[f], float) - h * dm[f] for f in TANGENT_FIELDS}}
            quotients.append((rhs(y + h * dY, up) - rhs(y - h * dY, down)) / (2 * h))
        fd = (4.0 * quotients[1] - quotients[0]) / 3.0
        if np.linalg.norm(fd) == 0.0:
            continue  # a field this rig does not use (no reels, no rings)
        assert _rel(dacc[rows, 0], fd) < 1e-6, which


def _converged_difference(run, coords, tolerance, j, largest=0.4, halvings=7):
    """Central differences of ``run`` along coordinate j, Richardson-extrapolated, where they have converged.

    Over steps of ``largest`` tolerances halved ``halvings`` times: each
    step's quotient and its half step's, Richardson-combined (their
    truncation errors, as the step squared, cancel); of those estimates the
    one closest to the next. Large steps leave the truncation of a strongly
    nonlinear column (a sheave's inertia), small ones the rounding a weak
    column's signal drowns in (air drag on a pendulum: a Maxwell force's
    rounding, coherent over 10^4 steps, is 1e-10 N), so no one step suits
    every column.
    """
    quotients = []
    for k in range(halvings + 1):
        h = largest * tolerance / 2**k
        up, down = coords.copy(), coords.copy()
        up[j] += h
        down[j] -= h
        quotients.append((run(up) - run(down)) / (2 * h))
    estimates = [(4.0 * b - a) / 3.0 for a, b in zip(quotients[:-1], quotients[1:])]
    gaps = [np.linalg.norm(a - b) for a, b in zip(estimates[:-1], estimates[1:])]
    return estimates[int(np.argmin(gaps))]


def _check_columns(build, coords, tolerances, duration, names):
    """Each column against ``_converged_difference``."""
    sens = simulate_sensitivities(build, coords, tolerances, duration=duration, rate_hz=RATE_HZ)
    dt = sens.result.dt
    assert np.all(sens.result.substeps == sens.result.substeps[0])  # a fixed step: simulate(dt=...) takes it too

    def states(x):
        rig, maneuver, physics = build(x)
        return simulate(rig, maneuver, physics=physics, duration=duration, rate_hz=RATE_HZ, dt=dt).states

    for j, name in enumerate(names):
        fd = _converged_difference(states, coords, tolerances[j], j)
        assert _rel(sens.tangents[..., j], fd) < TOLERANCE, name
    return sens


def _parameters(rig_name, wanted):
    rig = load_rig(rig_name)
    params = [p for p in rig.tolerances if p.name in wanted]
    assert [p.name for p in params] == list(wanted)
    return rig, params


def test_every_rig_parameter_kind_of_a_released_pendulum_matches_central_differences():
    """Mass, mass centre, rope stiffness and damping, a fixed point's coordinate: through the held release's statics."""
    names = ("bodies.ball.mass", "bodies.ball.cg_z", "ropes.wire_rope.static_stiffness",
             "ropes.wire_rope.viscous_damping", "fixed_points.pivot.z")
    rig, params = _parameters("pendulum", names)
    maneuver = default_maneuver(rig)

    def build(x):
        return (*apply_parameters(rig, maneuver, params, x), ())

    tol = np.array([p.tolerance for p in params])
    _check_columns(build, np.zeros(len(params)), tol, 0.5, names)


def test_a_reel_zero_and_sheave_mechanisms_of_the_crane_match_central_differences():
    """A winch's zero (the reel table), a sheave's inertia (its added mass) and bearing damping (viscous slide)."""
    rig, params = _parameters("gantry_crane", ("winches.hoist.zero",))
    maneuver = default_maneuver(rig)
    inertia0, damping0 = 2e-4, 0.02

    def build(x):
        r, m = apply_parameters(rig, maneuver, params, x[:1])
        physics = (make_mechanism("pulley_inertia", inertia=inertia0 * math.exp(x[1])),
                   make_mechanism("sheave_bearing_damping", c=damping0 * math.exp(x[2])))
        return r, m, physics

    _check_columns(build, np.zeros(3), np.array([params[0].tolerance, 0.5, 0.5]), 0.4,
                   ("winch zero", "sheave inertia", "bearing damping"))


def test_a_load_under_a_moving_point_matches_central_differences():
    """The load's mass, the anchor's track prescribed (the fixed-point table moving in time)."""
    names = ("bodies.load.mass",)
    rig, params = _parameters("slung_load", names)
    maneuver = default_maneuver(rig)

    def build(x):
        return (*apply_parameters(rig, maneuver, params, x), ())

    _check_columns(build, np.zeros(1), np.array([params[0].tolerance]), 0.5, names)


def test_air_drag_on_a_swinging_ball_matches_central_differences():
    """The drag coefficient (the body's and the rope's drag areas)."""
    rig = load_rig("pendulum")
    maneuver = default_maneuver(rig)

    def build(x):
        return rig, maneuver, (make_mechanism("aero_drag", cd=3.0 * math.exp(x[0])),)

    _check_columns(build, np.zeros(1), np.array([0.5]), 1.0, ("drag",))


def test_the_bending_stiffness_of_a_swinging_pendulums_wire_matches_central_differences():
    """A generic law at a site: the wire's bending stiffness (a spring at each joint between its elements)."""
    rig = load_rig("pendulum")
    maneuver = default_maneuver(rig)

    def build(x):
        return rig, maneuver, (make_mechanism("rope_bending_stiffness", share=math.exp(x[0])),)

    _check_columns(build, np.zeros(1), np.array([0.5]), 1.0, ("bending stiffness",))


def test_a_bending_stiffness_past_the_explicit_limit_is_stable_and_differentiated():
    """A rope as thick as its elements are long, stiff enough that the joint's z = 4 s w dt^2 passes 2, where the
    spring's impulse turns as implicit as stability asks (``_kernel._joint_impulses``: beta = 1/2 - 1/z): plucked,
    it swings without growing, and its tangent (beta's own derivative included) holds. z = 2.2 (beta 0.045), so
    that the swing, damped at about beta z / 8 dt (150 1/s), lasts the window."""
    props = {"kind": "rope", "weight_per_length": 0.0675, "static_stiffness": 1.0e5, "viscous_stiffness": 5.0e4,
             "viscous_damping": 500.0, "diameter": 0.6}
    rig = rig_from_dict({"g": 9.81, "fixed_points": {"top": [0.0, 0.0, -2.0], "bottom": [0.0, 0.0, -1.394]},
                         "ropes": {"thick": {"start": "fixed.top", "end": "fixed.bottom", "length": 0.6,
                                             "particles": 1, **props}}})
    still = Maneuver([0.0])
    mass, element = 0.0675 / 9.81 * 0.6, 0.303
    # the joint's w is 4 / (m L_e^2) on a one-particle string between fixed points; s = EI / L_e
    z_per_share = 4.0 * 1.0e5 * 0.6**2 / 16.0 / element * 4.0 / (mass * element**2)
    h = 1.0 / RATE_HZ / simulate(rig, still, duration=0.01, rate_hz=RATE_HZ).substeps.max()
    physics = (make_mechanism("rope_bending_stiffness", share=2.2 / (z_per_share * h**2)),)
    model = assemble(rig, still, physics=physics)
    rest = solve_statics(model).state
    y0 = rest.copy()
    y0[model.o_part] += 0.003
    result = simulate(rig, still, physics=physics, initial_state=y0, duration=0.05, rate_hz=RATE_HZ)
    assert 1.0 / RATE_HZ / result.substeps.max() == h
    swing = np.abs(result.states[:, model.o_part] - rest[model.o_part])
    assert swing.max() <= 0.003 * (1 + 1e-6) and swing[2] > 1e-4
    _check_window(result, 0, 2, {"seg_bend_k": 0.1 * np.asarray(model.arrays["seg_bend_k"], float),
                                 "state": _state_direction(result, 0, 11)})


def test_linear_drag_on_a_swinging_ball_matches_central_differences():
    """A generic law at a site: linear drag on the ball alone (its coefficient)."""
    rig = load_rig("pendulum")
    maneuver = default_maneuver(rig)

    def build(x):
        return rig, maneuver, (make_mechanism("linear_drag@ball", c=0.3 * math.exp(x[0])),)

    _check_columns(build, np.zeros(1), np.array([0.5]), 1.0, ("linear drag",))


def test_an_output_of_the_states_and_the_rig_is_differentiated_with_them():
    """``Sensitivities.of``: a marker-like output (the ball's lowest point, moved by its mass centre) by chain rule."""
    names = ("bodies.ball.cg_z",)
    rig, params = _parameters("pendulum", names)
    maneuver = default_maneuver(rig)

    def build(x):
        return (*apply_parameters(rig, maneuver, params, x), ())

    def bottom_z(result):  # the ball's surface point 4 cm below its geometric centre, in the inertial frame
        table = result.motion_table()
        cg = result.model.rig.bodies["ball"].cg_body
        pitch = np.asarray(table["ball.pitch"], float)
        return np.asarray(table["ball.z"], float) + (0.04 - cg[2]) * np.cos(pitch)

    tol = np.array([params[0].tolerance])
    sens = simulate_sensitivities(build, np.zeros(1), tol, duration=0.3, rate_hz=RATE_HZ)
    dt = sens.result.dt

    def output(x):
        r, m, _ = build(x)
        return bottom_z(simulate(r, m, duration=0.3, rate_hz=RATE_HZ, dt=dt))

    fd = _converged_difference(output, np.zeros(1), tol[0], 0)
    assert _rel(sens.of(bottom_z)[0], fd) < TOLERANCE


def _check_window(result, start, records, directions):
    """The tangent of ``records`` record intervals of ``result`` from record ``start`` against converged central
    differences, along each of ``directions`` (a kernel field's perturbation, or "state")."""
    model = result.model
    y0, t0 = result.states[start], float(result.time[start])
    schedule = result.substeps[start:start + records].copy()
    for name, d in directions.items():
        fields = {f: np.zeros(np.shape(model.arrays[f]) + (1,)) for f in TANGENT_FIELDS}
        if name != "state":
            fields[name] = np.ascontiguousarray(d[..., None])
        dY0 = np.ascontiguousarray((d if name == "state" else np.zeros(model.n_state))[:, None])

        def run(x):
            arrays = dict(model.arrays)
            if name != "state":
                arrays[name] = np.asarray(model.arrays[name], float) + x[0] * d
            m = kernel_model(arrays)
            return integrate_tangent(y0 + x[0] * dY0[:, 0], dY0, t0, 1.0 / RATE_HZ, schedule, m, TangentModel(**fields),
                                     _kernel.make_work(m), make_tangent_work(m, 1))[0]

        m = model.kernel_tuple()
        _, tangents = integrate_tangent(y0, dY0, t0, 1.0 / RATE_HZ, schedule, m, TangentModel(**fields),
                                        _kernel.make_work(m), make_tangent_work(m, 1))
        assert _rel(tangents[..., 0], _converged_difference(run, np.zeros(1), 0.05, 0)) < TOLERANCE, name


def _state_direction(result, start, seed):
    y = result.states[start]
    return np.random.default_rng(seed).normal(size=y.shape) * (np.abs(y) * 1e-5 + 1e-7)


@pytest.mark.parametrize("mechanism, value, field", [
    ("pulley_friction", {"mu": 0.02}, "ring_mu"),
    ("sheave_bearing_friction", {"mu": 0.08}, "ring_bearing_mu"),
])
def test_ring_friction_while_the_rope_slips_matches_central_differences(mechanism, value, field):
    """The impulse of a slipping ring (the capstan; a bearing's friction in proportion to its load), along its
    friction coefficient, its sheave's inertia, the rope's stiffness and the state: over five record intervals of
    the dig in which both of the dragline's rings slip."""
    result = simulate(load_rig("dragline"), duration=3.0, rate_hz=RATE_HZ,
                      physics=(make_mechanism(mechanism, **value),))
    model = result.model
    rates = np.abs(result.states[:, model.o_ring + 1 + 2 * np.arange(model.n_rings)]).min(axis=1)
    start = next(i for i in range(len(rates) - 6) if np.all(rates[i:i + 6] > 2e-3))
    _check_window(result, start, 5, {field: np.full(model.n_rings, 0.01),
                                     "ring_added_mass": np.full(model.n_rings, 1e-3),
                                     "seg_ks": 0.1 * np.asarray(model.arrays["seg_ks"], float),
                                     "state": _state_direction(result, start, 8)})


@pytest.mark.parametrize("mechanism, value, fields", [
    ("rope_bending_damping", {"c": 0.05}, ("seg_bend_c",)),
    ("chain_link_friction", {"mu": 0.2}, ("seg_link_mu", "seg_link_r")),
    ("rope_bending_stiffness", {"share": 10.0}, ("seg_bend_k",)),  # its limit: a column above the rounding
])
def test_the_joints_impulses_match_central_differences(mechanism, value, fields):
    """The joints' sweep (bending damping, chain-link friction), along its coefficients, the bodies' masses and the
    state, over five record intervals half a second into the dig."""
    result = simulate(load_rig("dragline"), duration=1.0, rate_hz=RATE_HZ, physics=(make_mechanism(mechanism, **value),))
    arrays = result.model.arrays
    # the particles' masses move each joint's inverse inertia w, and with it the implicit factor c h / (1 + c h w)
    directions = {f: 0.1 * np.asarray(arrays[f], float) for f in (*fields, "body_mass", "seg_rho")}
    _check_window(result, 50, 5, {**directions, "state": _state_direction(result, 50, 9)})


def test_a_moving_release_is_refused_not_differentiated_wrongly():
    rig = load_rig("pendulum")
    release = {name: {**pose, "velocity": np.array([0.1, 0.0, 0.0])} for name, pose in rig.release.items()}
    moving = dataclasses.replace(rig, release=release)
    maneuver = default_maneuver(rig)

    def build(x):
        return moving, maneuver, (make_mechanism("aero_drag", cd=math.exp(x[0])),)

    with pytest.raises(TangentUnavailable):
        simulate_sensitivities(build, np.zeros(1), np.ones(1), duration=0.1, rate_hz=RATE_HZ)


@pytest.mark.parametrize("rig_name, physics", [
    ("dragline", (("chain_link_friction", {"mu": 0.2}), ("pulley_friction", {"mu": 0.02}),
                  ("sheave_bearing_friction", {"mu": 0.04}))),
    ("gantry_crane", ()),
])
def test_the_runs_that_carry_tangents_are_simulates_runs_to_the_bit(rig_name, physics):
    """The primal beside the tangent repeats the kernel's arithmetic (impulses included) on the schedule the plain
    run took: the Jacobian is that of the very trajectory ``simulate`` returns."""
    result = simulate(load_rig(rig_name), duration=2.0, rate_hz=RATE_HZ,
                      physics=tuple(make_mechanism(name, **value) for name, value in physics))
    m = result.model.kernel_tuple()
    fields = TangentModel(*(np.zeros(np.shape(result.model.arrays[f]) + (1,)) for f in TANGENT_FIELDS))
    records, _ = integrate_tangent(result.states[0], np.zeros((result.model.n_state, 1)), float(result.time[0]),
                                   1.0 / RATE_HZ, result.substeps, m, fields, _kernel.make_work(m),
                                   make_tangent_work(m, 1))
    assert np.array_equal(records, result.states)


# A point the updating's first trust-region step reached on samples/dig_sample, in tolerances of the dragline's
# sixteen parameters (the rig file's order): there the drag chains turn slack and taut element by element as the
# reels stop, about 6.5 s into the dig.
SLACK_EPISODE = np.array([-0.53, -0.023, -0.038, 0.012, -0.115, -0.543, -0.065, -0.016, 0.013, 1.031, 0.061, 0.0,
                          0.606, 0.495, 0.647, 0.554])


def test_the_horizon_marks_where_the_scheme_stops_being_differentiable_on_a_fits_scale():
    """Before ``Sensitivities.horizon`` the tangent is the secant of small steps; after it, secants over 1e-4 and
    1e-6 of a tolerance differ many times over while both runs end within a millimetre of the same motion."""
    rig = load_rig("dragline")
    maneuver = default_maneuver(rig)
    params = list(rig.tolerances)
    tol = np.array([p.tolerance for p in params])

    def build(x):
        return (*apply_parameters(rig, maneuver, params, x), ())

    duration = 7.0
    nominal = simulate_sensitivities(build, np.zeros(len(tol)), tol, duration=duration, rate_hz=RATE_HZ)
    assert nominal.horizon() == math.inf
    sens = simulate_sensitivities(build, SLACK_EPISODE * tol, tol, duration=duration, rate_hz=RATE_HZ)
    horizon = sens.horizon()
    assert 6.0 < horizon < duration
    base = sens.result
    model = base.model
    positions = np.r_[[12 * b + c for b in range(model.n_bodies) for c in range(3)],
                      np.arange(model.o_part, model.o_vel)].astype(int)

    def frozen(x):  # the run on the base run's step schedule, so that only the parameter differs
        start = simulate(*build(x)[:2], duration=2.0 / RATE_HZ, rate_hz=RATE_HZ, statics_guess=base.states[0])
        m = start.model.kernel_tuple()
        dm = TangentModel(*(np.zeros(np.shape(start.model.arrays[f]) + (1,)) for f in TANGENT_FIELDS))
        records, _ = integrate_tangent(start.states[0], np.zeros((model.n_state, 1)), float(start.time[0]),
                                       1.0 / RATE_HZ, base.substeps, m, dm, _kernel.make_work(m), make_tangent_work(m, 1))
        return records

    j = 0  # the bucket's mass
    before = base.time < horizon - 0.2
    after = base.time > horizon + 0.1
    secants, spreads = [], []
    for step in (1e-4, 1e-6):
        up, down = SLACK_EPISODE * tol, SLACK_EPISODE * tol
        up[j] += step * tol[j]
        down[j] -= step * tol[j]
        a, b = frozen(up), frozen(down)
        secants.append((a - b) / (2 * step * tol[j]))
        spreads.append(float(np.abs(a - b)[after][:, positions].max()))
        if step == 1e-4:  # the smaller step's rounding, as 1 / step, is 1e-4 of the column before the episode
            assert _rel(secants[-1][before], sens.tangents[before, :, j]) < 1e-5
    late = [float(np.linalg.norm(s[after])) for s in secants]
    assert late[1] > 10.0 * late[0]  # a hundredth of the step, tens of times the quotient: no derivative there
    assert max(spreads) < 1e-3
