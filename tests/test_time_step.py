"""The integration step: RK4's stability limit, found from the spectrum and tracked through a run."""

import numpy as np
import pytest
from dragline.simulate import (
    Maneuver,
    _kernel,
    assemble,
    dig_maneuver,
    load_rig,
    rig_from_dict,
    solve_statics,
)
from dragline.simulate._time_step import (
    largest_eigenvalues,
    rhs_jacobian,
    rk4_step_limit,
    stable_time_step,
    start_time_step,
)
from dragline.simulate._tracked import MAX_STEPS, NO_REFINEMENT, NO_SCHEDULE, RK4, integrate_tracked

RK4_REAL_LIMIT = 2.785293563  # |R(z)| = 1 on the negative real axis (z = -2.7853)


def test_rk4_limit_on_the_imaginary_and_real_axes():
    assert rk4_step_limit([1000j, -1000j]) == pytest.approx(2 * np.sqrt(2) / 1000, rel=1e-6)
    assert rk4_step_limit([-500.0]) == pytest.approx(RK4_REAL_LIMIT / 500, rel=1e-6)
    # the most restrictive eigenvalue decides; slow modes are left out
    assert rk4_step_limit([1000j, -1000j, -500.0, 1e-9 + 1j]) == pytest.approx(2 * np.sqrt(2) / 1000, rel=1e-6)


@pytest.mark.parametrize("integrator, limit", [("rk4", 2 * np.sqrt(2)), ("verlet", 2.0)])
def test_spectral_step_of_a_taut_string_is_its_highest_axial_mode(integrator, limit):
    # n particles on a string pulled taut between two fixed points: the
    # highest axial mode of the fixed-fixed chain is 2 sqrt(k/m) sin(n pi / 2(n+1));
    # RK4 is stable to h omega = 2 sqrt(2), kick-drift-kick Verlet to 2.
    n, length, span = 6, 0.99, 1.0
    rig = rig_from_dict({
        "fixed_points": {"a": [0.0, 0.0, -2.0], "b": [span, 0.0, -2.0]},
        "ropes": {"string": {"start": "fixed.a", "end": "fixed.b", "length": length, "particles": n,
                             "weight_per_length": 1e-3, "static_stiffness": 1e4, "viscous_stiffness": 1.0,
                             "viscous_damping": 1.0}},
    })
    model = assemble(rig, Maneuver([0.0]), dissipation=False)
    state = solve_statics(model).state
    a = model.arrays
    k = (a["seg_ks"][0] + a["seg_kv"][0]) / (length / (n + 1))
    m = a["seg_rho"][0] * length / n
    omega = 2 * np.sqrt(k / m) * np.sin(n * np.pi / (2 * (n + 1)))
    dt, _ = start_time_step(model, state, safety=1.0, integrator=integrator)
    assert dt == pytest.approx(limit / omega, rel=2e-3)


@pytest.fixture(scope="module")
def low_dig():
    model = assemble(load_rig(), dig_maneuver(), "low")
    state = solve_statics(model).state
    m = model.kernel_tuple()
    # reference: a fixed step a quarter of the Gershgorin bound's
    per = int(np.ceil(5e-3 / (0.25 * stable_time_step(model, state=state))))
    ref, status, _, _ = _kernel.integrate(state, 0.0, 5e-3 / per, 2000 * per, per, m, _kernel.make_work(m), 100.0)
    assert status == _kernel.STATUS_OK
    return model, state, ref


def _tracked(model, state, safety, track=True):
    dt0, lam0 = start_time_step(model, state, safety=safety)
    m = model.kernel_tuple()
    # lam0 = inf never cuts the step: a fixed step at the start's limit
    return integrate_tracked(state, 0.0, 5e-3, 2000, dt0, lam0 if track else np.inf, m, _kernel.make_work(m), 100.0,
                             MAX_STEPS, RK4, NO_SCHEDULE, NO_REFINEMENT)


def test_the_tracked_step_is_accurate_and_its_limit_is_real(low_dig):
    model, state, ref = low_dig
    rec, substeps, _, _, status, _, _ = _tracked(model, state, safety=None)
    assert status == _kernel.STATUS_OK
    assert 1e3 * np.max(np.linalg.norm(rec[:, :3] - ref[:, :3], axis=1)) < 0.05  # mm, bucket
    assert substeps.max() > substeps[0]  # the ring sides shorten during the dig: the step was cut
    # a quarter past the limit, the fastest mode grows and the run blows up
    assert _tracked(model, state, safety=1.25)[4] != _kernel.STATUS_OK


def test_without_tracking_the_start_step_blows_up_as_a_ring_side_shortens(low_dig):
    model, state, _ = low_dig
    _, _, _, _, status, bad_time, bad_index = _tracked(model, state, safety=None, track=False)
    assert status != _kernel.STATUS_OK and bad_time > 1.0
    assert "dump_rope" in model.describe_state_index(bad_index)


def test_a_rig_stiffening_without_bound_stops_instead_of_stepping_towards_zero(low_dig):
    model, state, _ = low_dig
    dt0, lam0 = start_time_step(model, state)
    m = model.kernel_tuple()
    work = _kernel.make_work(m)
    # As if the stiffness had grown ten-million-fold since dt0 was found: the step would fall below
    # MIN_STEP_RATIO of it.
    _, _, _, _, status, bad_time, need = integrate_tracked(state, 0.0, 5e-3, 10, dt0, lam0 * 1e-7, m, work, 100.0,
                                                        MAX_STEPS, RK4, NO_SCHEDULE, NO_REFINEMENT)
    assert status == _kernel.STATUS_TOO_STIFF and bad_time == 0.0
    assert need >= 5e-3 / (dt0 * 1e-3)
    # A run whose steps would exceed the budget stops at the record that would pass it.
    per_record = int(np.ceil(5e-3 / dt0 - 1e-9))
    rec, substeps, _, _, status, bad_time, _ = integrate_tracked(state, 0.0, 5e-3, 10, dt0, np.inf, m, work, 100.0,
                                                              3 * per_record, RK4, NO_SCHEDULE, NO_REFINEMENT)
    assert status == _kernel.STATUS_TOO_STIFF and len(rec) == 4 and bad_time == pytest.approx(3 * 5e-3)
    assert substeps.sum() == 3 * per_record


@pytest.mark.parametrize("level", ["low", "baseline", "high"])
def test_arnoldis_largest_eigenvalue_is_the_full_spectrums(level):
    # Verlet's step comes from ARPACK's largest |lambda|; LAPACK's whole spectrum is the reference.
    rig, maneuver = load_rig(), dig_maneuver()
    model = assemble(rig, maneuver, level)
    t0 = float(maneuver.time[0])
    state = solve_statics(model, t0).state
    jacobian = rhs_jacobian(model, state, t0)
    full = np.abs(np.linalg.eigvals(jacobian)).max()
    assert np.abs(largest_eigenvalues(jacobian)).max() == pytest.approx(full, rel=1e-12)
    # and a run repeats to the bit (a fixed start vector)
    assert np.array_equal(largest_eigenvalues(jacobian), largest_eigenvalues(jacobian))


def test_the_largest_of_many_oscillators_and_a_fast_decay():
    # A real matrix, rotated out of its block-diagonal form: a decay at -5000 /s and oscillators at
    # +-1000 k i (k = 1..59): the largest magnitude is the fastest oscillator's, 59000.
    blocks = [np.array([[-5000.0]]), np.array([[-1.0]])]
    blocks += [np.array([[0.0, w], [-w, 0.0]]) for w in 1000.0 * np.arange(1, 60)]
    d = np.zeros((120, 120))
    i = 0
    for b in blocks:
        d[i:i + len(b), i:i + len(b)] = b
        i += len(b)
    q, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(120, 120)))
    assert np.abs(largest_eigenvalues(q @ d @ q.T)).max() == pytest.approx(59000.0, rel=1e-10)


def test_a_run_on_a_frozen_schedule_steps_as_the_schedule_says_and_a_run_on_its_own_repeats_itself():
    """The hook-block crane's slings hang at the slack point: its run refines a record interval where an element
    turned slack or taut. On its own schedule the run repeats itself bit for bit; a rig a small change of the
    hoist rope's stiffness away takes the same steps on it (and refines nothing of its own), so the two runs'
    difference is the parameter's, not two step sequences'."""
    from dragline.simulate import apply_parameters, default_maneuver, load_rig, simulate

    rig = load_rig("hook_block_crane")
    maneuver = default_maneuver(rig)
    base = simulate(rig, maneuver, duration=3.0, rate_hz=100.0)
    assert base.refined.any()  # the case the schedule is for
    again = simulate(rig, maneuver, duration=3.0, rate_hz=100.0, schedule=base.schedule)
    np.testing.assert_array_equal(again.states, base.states)
    assert again.steps == base.steps
    params = rig.tolerances
    stiffness = [p.name for p in params].index("ropes.hoist_rope.static_stiffness")
    for sign in (1.0, -1.0):
        x = np.zeros(len(params))
        x[stiffness] = sign * 0.01 * params[stiffness].tolerance
        moved_rig, moved = apply_parameters(rig, maneuver, params, x)
        run = simulate(moved_rig, moved, duration=3.0, rate_hz=100.0, schedule=base.schedule)
        np.testing.assert_array_equal(run.substeps, base.substeps)
        np.testing.assert_array_equal(run.refined, base.refined)
        moved_by = np.abs(run.states[:, :3] - base.states[:, :3]).max()  # the hook block's position (m)
        assert 0.0 < moved_by < 1e-5
    with pytest.raises(ValueError, match="step schedule"):
        simulate(rig, maneuver, duration=4.0, rate_hz=100.0, schedule=base.schedule)
