"""Velocity Verlet (simulate/_verlet.py): its order, its stability limit, and RK4's solution as its limit."""

import numpy as np
import pytest

from dragline.simulate import Maneuver, assemble, dig_maneuver, load_rig, parse_physics, simulate, solve_statics
from dragline.simulate import _kernel
from dragline.simulate._time_step import VERLET_SAFETY, start_time_step
from dragline.simulate._tracked import VERLET, integrate_tracked


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
                                 50_000_000, VERLET)

    assert run(dt0, lam0)[2] == _kernel.STATUS_OK  # the dig's first 2 s at the default safety
    assert run(dt0 / VERLET_SAFETY * 1.25, np.inf)[2] != _kernel.STATUS_OK


def test_an_element_turning_slack_makes_the_tracked_verlet_step_finer():
    # The dig's end pose (of the undamped model, whose ropes are stiffer)
    # pushed at 0.5 m/s, let go in the damped model: the chains go slack and
    # snap taut. Verlet at its full step gained energy there (a blow-up at
    # 0.75 of its limit); each interval with a slack change is done again
    # finer, and with Eq. 8's dissipation energy only falls.
    rig = load_rig()
    man = Maneuver([0.0], [10.1], [1.4])
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
    _kernel.dissipate(t, reused, 1e-4, m, work, True)
    _kernel.dissipate(t, fresh, 1e-4, m, _kernel.make_work(m), False)
    assert not np.array_equal(fresh, y)  # the impulses acted
    np.testing.assert_array_equal(reused, fresh)


def test_unknown_integrator_is_refused():
    with pytest.raises(ValueError, match="unknown integrator"):
        simulate(duration=0.01, integrator="euler")
