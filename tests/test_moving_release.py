"""A release may be moving: a trial that starts mid-motion, the ropes carried with the bodies they hold."""

from pathlib import Path

import numpy as np
import pytest

from dragline.simulate import assemble, default_maneuver, load_rig, simulate, solve_statics
from dragline.simulate._release import let_go

PENDULUM = Path(load_rig.__code__.co_filename).parent / "data" / "pendulum.toml"


@pytest.fixture(scope="module")
def pendulum():
    return load_rig("pendulum")


def test_a_body_let_go_turning_carries_its_rope_with_it(pendulum):
    # the ball and its wire turning rigidly about the pivot at 1 rad/s: each wire particle moves as omega x r
    model = assemble(pendulum, default_maneuver(pendulum), "baseline")
    held = solve_statics(model, 0.0).state
    pivot = np.asarray(pendulum.fixed_points["pivot"], float)
    omega = np.array([0.0, 1.0, 0.0])
    release = {"ball": {"velocity": np.cross(omega, held[0:3] - pivot), "rates": omega}}
    moving = let_go(model, held, 0.0, release)
    assert np.array_equal(held, solve_statics(model, 0.0).state)  # not modified
    for p in range(model.n_particles):
        x = moving[model.o_part + 3 * p: model.o_part + 3 * p + 3]
        v = moving[model.o_vel + 3 * p: model.o_vel + 3 * p + 3]
        assert np.allclose(v, np.cross(omega, x - pivot), atol=1e-9 * np.linalg.norm(x - pivot))
    assert let_go(model, held, 0.0, {"ball": {"velocity": np.zeros(3), "rates": np.zeros(3)}}) is held


def _moving_pendulum(tmp_path, speed):
    # the ball at the bottom (where it hangs), pushed along x, turning with the swing: omega = v / (pivot to centre)
    text = PENDULUM.read_text().replace('maneuver = "pendulum.csv"', "")
    reach = 1.000203 + 0.04
    text = text.replace("position = [0.180629, 0.0, -0.975600]", f"position = [0.0, 0.0, {-2.0 + reach:.6f}]")
    text = text.replace("angles_deg = [0.0, 10.0, 0.0]", f"angles_deg = [0.0, 0.0, 0.0]\nvelocity = [{speed}, 0.0, 0.0]\n"
                        f"rates_deg = [0.0, {np.degrees(speed / reach):.9f}, 0.0]")
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return load_rig(path), reach


def test_a_pendulum_pushed_at_the_bottom_rises_as_its_energy_says(tmp_path):
    speed = 0.5
    rig, reach = _moving_pendulum(tmp_path, speed)
    result = simulate(rig, duration=1.2, rate_hz=500.0, dissipation=False, discretization="medium")
    first = result.states[0]
    assert np.allclose(first[3:6], [speed, 0.0, 0.0]) and first[10] == pytest.approx(speed / reach)
    ball, wire = rig.bodies["ball"], rig.ropes["wire"]
    # kinetic energy: the ball's translation and turn, and the wire's (mass rho L, speed growing linearly along it)
    eye = reach - 0.04
    m_wire = wire.weight_per_length / rig.g * eye
    kinetic = (0.5 * ball.mass * speed**2 + 0.5 * ball.inertia[1, 1] * (speed / reach) ** 2
               + 0.5 * m_wire * (speed * eye / reach) ** 2 / 3.0)
    energy = result.energy()
    assert np.abs(energy - energy[0]).max() < 1e-3 * kinetic  # nothing dissipates: it is kept
    # at the top of the swing all of it is height: the ball's centre, and the wire's (half the eye's rise)
    rise = result.states[:, 2].min() - first[2]
    lifted = -(ball.mass * rig.g * rise + m_wire * rig.g * 0.5 * rise * eye / reach)
    assert lifted == pytest.approx(kinetic, rel=0.01)
