"""The simulator against physics: analytic solutions, energy, equilibrium.

Small rigs are built here from dicts (the loader's own TOML layout), so each
physical law is checked in isolation before the whole dragline.
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from dragline.simulate import (
    Maneuver,
    assemble,
    rig_from_dict,
    simulate,
    solve_statics,
    stable_time_step,
)
from dragline.simulate._simulate import element_tensions, mechanical_energy

STILL = Maneuver([0.0])  # these rigs have no winch


def _rope(start, end, length, particles, weight=1e-3, K=1e5):
    return {"start": start, "end": end, "length": length, "particles": particles,
            "weight_per_length": weight, "static_stiffness": K, "viscous_stiffness": 1.0,
            "viscous_damping": 1.0}


def _pendulum(mass=1.0, length=1.0, K=1e5):
    return rig_from_dict({
        "g": 9.81,
        "fixed_points": {"pivot": [0.0, 0.0, -2.0]},
        "bodies": {"bob": {"mass": mass, "cg_body": [0, 0, 0], "inertia_diag": [1e-3] * 3,
                           "points": {"hook": [0, 0, 0]}, "position": [0.0, 0.0, -2.0 + length]}},
        "ropes": {"string": _rope("fixed.pivot", "bob.hook", length, 1, K=K)},
    })


def _periods(t, x):
    """Mean period from the upward zero crossings of x - mean(x)."""
    x = x - x.mean()
    i = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    return np.diff(crossings).mean()


def test_pendulum_swing_and_bounce_periods_match_analytic_values():
    g, mass, L, K = 9.81, 1.0, 1.0, 1e5
    rig = _pendulum(mass, L, K)
    model = assemble(rig, STILL, dissipation=False)
    eq = solve_statics(model)
    stretched = L * (1 + mass * g / K)  # static stretch of the two-element string
    assert eq.state[2] == pytest.approx(-2.0 + stretched, abs=1e-6)

    # swing: small angle, theta0 = 1 deg; T = 2 pi sqrt(l/g) (1 + theta0^2/16)
    theta0 = np.radians(1.0)
    y0 = eq.state.copy()
    y0[0] = stretched * np.sin(theta0)
    y0[2] = -2.0 + stretched * np.cos(theta0)
    y0[model.o_part : model.o_part + 3] = 0.5 * (y0[:3] + [0.0, 0.0, -2.0])
    res = simulate(rig, STILL, duration=8.0, rate_hz=400, dissipation=False, initial_state=y0)
    swing = 2 * np.pi * np.sqrt(stretched / g) * (1 + theta0**2 / 16)
    assert _periods(res.time, res.states[:, 0]) == pytest.approx(swing, rel=2e-4)

    # bounce: the string is two springs of 2K/L in series, k = K/L; half the
    # static stretch keeps it taut (at 1e-4 m it went slack every bounce)
    y0 = eq.state.copy()
    y0[2] += 5e-5
    res = simulate(rig, STILL, duration=0.3, rate_hz=20000, dissipation=False, initial_state=y0)
    bounce = 2 * np.pi * np.sqrt(mass / (K / L))
    assert _periods(res.time, res.states[:, 2]) == pytest.approx(bounce, rel=2e-3)


def test_slack_rope_carries_no_force_and_the_body_falls_freely():
    rig = _pendulum()
    model = assemble(rig, STILL)
    y0 = np.zeros(model.n_state)
    y0[:3] = [0.0, 0.0, -2.5]  # lifted: 0.5 m below the pivot on a 1 m string
    y0[model.o_part : model.o_part + 3] = [0.0, 0.0, -2.25]
    res = simulate(rig, STILL, duration=0.25, rate_hz=1000, initial_state=y0)
    t = res.time
    # free fall for 0.25 s drops 0.31 m: the string (0.5 m of slack) stays slack
    np.testing.assert_allclose(res.states[:, 2], -2.5 + 0.5 * 9.81 * t**2, atol=1e-9)
    assert np.all(element_tensions(model, t, res.states, "string") == 0.0)
    assert np.all(res.states[:, model.o_force : model.o_ring] == 0.0)


def _catenary_rig(particles, span=1.0, length=1.5, weight=1.0):
    return rig_from_dict({
        "fixed_points": {"a": [0.0, 0.0, -2.0], "b": [span, 0.0, -2.0]},
        "ropes": {"rope": _rope("fixed.a", "fixed.b", length, particles, weight=weight, K=1e5)},
    })


def test_hanging_rope_converges_to_the_catenary():
    span, length = 1.0, 1.5
    a = brentq(lambda a: 2 * a * np.sinh(span / (2 * a)) - length, 0.05, 10.0)
    errors = []
    for n in (4, 8, 16, 32):
        model = assemble(_catenary_rig(n, span, length), STILL)
        y = solve_statics(model).state
        p = y[model.o_part : model.o_vel].reshape(-1, 3)
        s = np.arange(1, n + 1) * length / (n + 1) - length / 2  # arc length from the vertex
        x = span / 2 + a * np.arcsinh(s / a)
        sag = a * np.cosh(span / (2 * a)) - a * np.sqrt(1 + (s / a) ** 2)  # below the supports (+z)
        errors.append(np.max(np.hypot(p[:, 0] - x, p[:, 2] - (-2.0 + sag))))
    errors = np.array(errors)
    ratios = errors[:-1] / errors[1:]
    assert np.all(ratios > 2.5), errors
    assert np.all(np.diff(ratios) > 0) and ratios[-1] > 3.5, ratios  # -> 4: second order in the spacing
    assert errors[-1] < 1e-3


def test_frictionless_ring_carries_equal_tension_on_both_sides(rig):
    model = assemble(rig, Maneuver([0.0], {"hoist": [8.6], "drag": [4.2]}))
    eq = solve_statics(model)
    for rope in ("dump_rope", "hoist_rope"):
        tension = element_tensions(model, [0.0], eq.state[None], rope)[0]
        side = model.arrays["el_side"][model.seg_elements[rope]]
        at_ring_a = tension[side == 1][-1]
        at_ring_b = tension[side == 2][0]
        assert at_ring_a == pytest.approx(at_ring_b, rel=0.02)


def _kicked(rig, hoist, drag, speed):
    """Equilibrium at the given reel lengths with everything moving at +x speed."""
    man = Maneuver([0.0], {"hoist": [hoist], "drag": [drag]})
    model = assemble(rig, man, dissipation=False)
    eq = solve_statics(model)
    y0 = eq.state.copy()
    for b in range(model.n_bodies):
        y0[12 * b + 3] = speed
    y0[model.o_vel : model.o_force].reshape(-1, 3)[:, 0] = speed
    e_rest = mechanical_energy(model, np.array([0.0]), eq.state[None])[0]
    return man, model, y0, e_rest


@pytest.mark.parametrize("integrator", ["verlet", "rk4"])
def test_energy_is_conserved_without_dissipation_and_converges_with_the_step(rig, integrator):
    # End pose of the dig (every rope and chain taut), reels still, a 0.2 m/s
    # push: the motion's energy must stay within 0.1 % over 5 s.
    man, model, y0, e_rest = _kicked(rig, 10.1, 1.4, 0.2)
    drift = []
    for factor in (1.0, 0.5):
        res = simulate(rig, man, duration=5.0, rate_hz=100, dissipation=False, initial_state=y0,
                       dt=stable_time_step(model, integrator=integrator) * factor, integrator=integrator)
        E = res.energy()
        motion = E[0] - e_rest
        assert motion > 0.1  # J: a real swing
        drift.append(np.max(np.abs(E - E[0])) / motion)
        assert np.ptp(res.table["bucket.x"]) > 0.01
    assert drift[0] < 1e-3, drift
    assert drift[1] < drift[0] / 2, drift  # and the residue is the integrator's


def test_dissipation_removes_energy(rig):
    man, model, y0, e_rest = _kicked(rig, 10.1, 1.4, 0.2)
    y0[model.o_force : model.o_ring] = 0.0
    res = simulate(rig, man, duration=3.0, rate_hz=100, initial_state=y0)
    E = res.energy()
    assert np.all(np.diff(E) < 1e-6)  # never gains energy (to rounding)
    assert E[-1] - e_rest < 0.7 * (E[0] - e_rest)


def test_a_simulation_started_at_equilibrium_stays_there(rig):
    man = Maneuver([0.0], {"hoist": [8.6], "drag": [4.2]})
    res = simulate(rig, man, duration=2.0, rate_hz=100)
    table = res.table
    speeds = np.abs(table[[c for c in table.columns if c.endswith((".vx", ".vy", ".vz"))]].to_numpy())
    assert speeds.max() < 1e-6
    assert np.abs(table["bucket.pitch"] - table["bucket.pitch"].iloc[0]).max() < 1e-6


def test_the_motion_table_is_the_full_tables_motion_columns(dig_baseline):
    # The diagnosis reads its hundreds of simulations through the lighter table: the same numbers.
    from dragline.simulate import trajectory_columns

    motion, full = dig_baseline.motion_table(), dig_baseline.table
    assert list(motion.columns) == [c for c in trajectory_columns() if c in full.columns]
    assert motion.equals(full[list(motion.columns)])
    assert "drag_rope.tension_start" in full and "drag_rope.tension_start" not in motion
