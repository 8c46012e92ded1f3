"""Velocity Verlet (simulate/_verlet.py): its order, its stability limit, and RK4's solution as its limit."""

import numpy as np
import pytest

from dragline.simulate import Maneuver, assemble, dig_maneuver, load_rig, parse_physics, simulate, solve_statics
from dragline.simulate import _kernel
from dragline.simulate._time_step import VERLET_SAFETY, start_time_step
from dragline.simulate._tracked import NO_REFINEMENT, NO_SCHEDULE, VERLET, integrate_tracked


def _bucket_error_um(a, b):
    return 1e6 * float(np.max(np.linalg.norm(a.states[:, 0:3] - b.states[:, 0:3], axis=1)))


def _rest(dissipation):
    """The dig's rest pose and RK4's step there, with or without Eq. 8's dissipation."""
    res = simulate(duration=0.05, rate_hz=200.0, dissipation=dissipation, integrator="rk4")
    return res.states[0], res.dt


@pytest.fixture(scope="module")
def dissipative_start():
    return _rest(True)


@pytest.fixture(scope="module")
def undamped_start():
    return _rest(False)


def _dig(y0, dt, integrator, dissipation):
    return simulate(duration=3.0, rate_hz=200.0, initial_state=y0, dt=dt, integrator=integrator,
                    dissipation=dissipation)


def test_without_dissipation_verlet_converges_at_second_order_to_the_rk4_solution(undamped_start):
    # The undamped model is smooth: RK4 at a quarter step is the reference
    # (4th order: its own error is far below Verlet's).
    y0, h = undamped_start
    ref = _dig(y0, h / 4, "rk4", False)
    err = [_bucket_error_um(_dig(y0, h * f, "verlet", False), ref) for f in (0.7, 0.35)]
    assert 3.0 < err[0] / err[1] < 5.0, err  # halving the step quarters the error
    assert err[0] < 5.0  # um, at about Verlet's default step


def test_with_dissipation_verlet_stays_second_order_and_rk4_converges_to_its_limit(dissipative_start):
    # Eq. 8's Maxwell branch and the slack reset: Verlet advances F_m exactly
    # over a step and resets it where the element is slack at the step's end,
    # so it stays second order (RK4, whose F_m is reset after its step, is
    # first order there: 2.0 and 0.66 um from Verlet's limit at a half and a
    # quarter of its step when measured). Both must converge to one solution.
    y0, h = dissipative_start
    v = [_dig(y0, h * f, "verlet", True) for f in (0.7, 0.35, 0.175)]
    d1, d2 = _bucket_error_um(v[0], v[1]), _bucket_error_um(v[1], v[2])
    assert 3.0 < d1 / d2 < 5.0, (d1, d2)
    r = [_dig(y0, h * f, "rk4", True) for f in (0.5, 0.25)]
    r1, r2 = _bucket_error_um(r[0], v[2]), _bucket_error_um(r[1], v[2])
    assert r2 < r1 < 5.0 and r2 < 2.0, (r1, r2)


def test_the_tracked_verlet_step_holds_the_dig_and_a_fixed_step_past_its_limit_blows_up():
    model = assemble(load_rig(), dig_maneuver(), "low")
    state = solve_statics(model).state
    m = model.kernel_tuple()
    dt0, lam0 = start_time_step(model, state, integrator="verlet")

    def run(step, lam):
        return integrate_tracked(state, 0.0, 5e-3, 400, step, lam, m, _kernel.make_work(m), 100.0,
                                 50_000_000, VERLET, NO_SCHEDULE, NO_REFINEMENT)

    assert run(dt0, lam0)[4] == _kernel.STATUS_OK  # the dig's first 2 s at the default safety
    assert run(dt0 / VERLET_SAFETY * 1.25, np.inf)[4] != _kernel.STATUS_OK


def test_an_element_turning_slack_makes_the_tracked_verlet_step_finer():
    # The dig's end pose (of the undamped model, whose ropes are stiffer)
    # pushed at 0.5 m/s, let go in the damped model: the chains go slack and
    # snap taut. Verlet at its full step gained energy there (a blow-up at
    # 0.75 of its limit); each interval with a slack change is done again
    # finer, and with Eq. 8's dissipation energy only falls.
    rig = load_rig()
    man = Maneuver([0.0], {"hoist": [10.1], "drag": [1.4]})
    model = assemble(rig, man, dissipation=False)
    y0 = solve_statics(model).state.copy()
    for b in range(model.n_bodies):
        y0[12 * b + 3] = 0.5
    y0[model.o_vel:model.o_force].reshape(-1, 3)[:, 0] = 0.5
    y0[model.o_force:model.o_ring] = 0.0
    res = simulate(rig, man, duration=2.0, rate_hz=100, initial_state=y0)
    dt0, _ = start_time_step(model, y0, integrator="verlet")
    assert res.dt < 0.5 * dt0  # intervals were redone finer
    assert np.diff(res.energy()).max() < 1e-6


def test_dissipation_reads_the_geometry_verlet_left_exactly_as_it_would_compute_it():
    # Verlet's step ends with the dissipative impulses at the positions its last
    # right-hand side saw, and they reuse that evaluation's geometry: the same
    # velocities to the bit as computing it afresh, for joints and rings alike.
    physics = [parse_physics("pulley_friction:mu=0.05"), parse_physics("chain_link_friction:mu=0.3"),
               parse_physics("rope_bending_damping")]
    res = simulate(duration=3.0, rate_hz=100.0, physics=physics)
    model = res.model
    m = model.kernel_tuple()
    t, y = float(res.time[-1]), res.states[-1]
    work = _kernel.make_work(m)
    _kernel.rhs(t, y, np.empty_like(y), m, work)
    reused, fresh = y.copy(), y.copy()
    _kernel.dissipate_fresh(t, reused, 1e-4, m, work)
    _kernel.dissipate(t, fresh, 1e-4, m, _kernel.make_work(m))
    assert not np.array_equal(fresh, y)  # the impulses acted
    np.testing.assert_array_equal(reused, fresh)


def test_unknown_integrator_is_refused():
    with pytest.raises(ValueError, match="unknown integrator"):
        simulate(duration=0.01, integrator="euler")


def _textbook_step(t, h, y, acc, m, work):
    """Kick-drift-kick as four separate passes over the state: the reference for the fused step."""
    from dragline.simulate._verlet import _euler_angle_rates, _euler_angle_rates_trig, _maxwell_factors

    o_part, o_vel, o_F, o_ring = _kernel._offsets(m)
    vel = np.zeros(y.shape[0], bool)
    for b in range(m.nb):
        vel[12 * b + 3:12 * b + 6] = vel[12 * b + 9:12 * b + 12] = True
    vel[o_vel:o_F] = True
    vel[o_ring + 1::2] = True
    y = y.copy()
    y[vel] += 0.5 * h * acc[vel]
    for b in range(m.nb):
        o = 12 * b
        y[o:o + 3] += h * y[o + 3:o + 6]
        roll, pitch, yaw = y[o + 6:o + 9]
        d0, _, d2 = _euler_angle_rates_trig(*work.trig[b], *y[o + 9:o + 12])
        d = _euler_angle_rates(roll + 0.5 * h * d0, yaw + 0.5 * h * d2, *y[o + 9:o + 12])
        y[o + 6:o + 9] = roll + h * d[0], pitch + h * d[1], yaw + h * d[2]
    y[o_part:o_vel] += h * y[o_vel:o_F]
    y[o_ring::2] += h * y[o_ring + 1::2]
    y_eval = y.copy()
    y_eval[vel] += 0.5 * h * acc[vel]
    acc = acc.copy()
    _maxwell_factors(h, m, work)
    _kernel.rhs_maxwell_update(t + h, y_eval, acc, m, work)
    y[o_F:o_ring] = y_eval[o_F:o_ring]
    y[vel] += 0.5 * h * acc[vel]
    return y, acc


@pytest.mark.parametrize("physics", [[], ["pulley_friction:mu=0.05"]])
def test_the_fused_step_is_the_textbook_kick_drift_kick_to_the_bit(physics):
    # The step does its kick, drift and evaluation copy in one pass per entry
    # and a record interval's steps in one call: the same arithmetic as the
    # separate passes, so the same bits (on the dig at full speed, rings sliding).
    from dragline.simulate._verlet import element_stretch, verlet_scratch, verlet_steps

    res = simulate(duration=5.0, rate_hz=100.0, physics=[parse_physics(p) for p in physics])
    m = res.model.kernel_tuple()
    t, y0, h = float(res.time[-1]), res.states[-1], 1e-4
    work = _kernel.make_work(m)
    acc, y_eval = verlet_scratch(t, y0, m, work)
    fused = y0.copy()
    fused_acc = acc.copy()
    verlet_steps(t, h, 3, fused, fused_acc, y_eval, m, work)
    ref_work = _kernel.make_work(m)
    acc, _ = verlet_scratch(t, y0, m, ref_work)
    ref = y0.copy()
    for j in range(3):
        ref, acc = _textbook_step(t + j * h, h, ref, acc, m, ref_work)
        if m.has_ring_friction:
            _kernel.dissipate_fresh((t + j * h) + h, ref, h, m, ref_work)
    assert not np.array_equal(ref, y0)
    np.testing.assert_array_equal(fused, ref)
    np.testing.assert_array_equal(fused_acc, acc)
    eps = np.empty_like(work.eps)
    element_stretch(t + 3 * h, fused, m, work, eps)
    np.testing.assert_array_equal(work.eps, eps)


def test_the_right_hand_side_verlet_calls_gives_the_plain_accelerations():
    # In Verlet's right-hand side only the accelerations are written (no F_m
    # rates, no position rates, no element-end velocities gathered): they must
    # be the plain right-hand side's to the bit at the same state.
    from dragline.simulate._verlet import element_stretch

    res = simulate(duration=5.0, rate_hz=100.0)
    m = res.model.kernel_tuple()
    t, y = float(res.time[-1]), res.states[-1].copy()
    work = _kernel.make_work(m)
    element_stretch(float(res.time[-2]), res.states[-2], m, work, work.eps)  # the step's start: F_m moves
    work.seg_decay[:], work.seg_gain[:] = 0.9, m.seg_kv * 0.95
    updated, plain = np.zeros_like(y), np.zeros_like(y)
    y_update = y.copy()
    _kernel.rhs_maxwell_update(t, y_update, updated, m, work)
    assert not np.array_equal(y_update, y)  # the Maxwell forces advanced
    _kernel.rhs(t, y_update, plain, m, _kernel.make_work(m))
    o_part, o_vel, o_F, o_ring = _kernel._offsets(m)
    for b in range(m.nb):
        np.testing.assert_array_equal(updated[12 * b + 3:12 * b + 6], plain[12 * b + 3:12 * b + 6])
        np.testing.assert_array_equal(updated[12 * b + 9:12 * b + 12], plain[12 * b + 9:12 * b + 12])
    np.testing.assert_array_equal(updated[o_vel:o_F], plain[o_vel:o_F])
    np.testing.assert_array_equal(updated[o_ring + 1::2], plain[o_ring + 1::2])
    assert np.abs(plain[o_vel:o_F]).max() > 0.1  # the accelerations are not trivially zero
