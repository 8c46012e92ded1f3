"""Bodies turn through every orientation: the simulator's charts never meet the Euler angles' singularity.

A block hung by a wire from its mass centre feels no moment: set spinning,
it turns as a free rigid body. A spin about a principal axis keeps its rate
and turns the block steadily (T(t) = T0 R_x(p t)); a spin about the
intermediate axis tumbles (Dzhanibekov), through every orientation, while
its kinetic energy and its angular momentum in the inertial frame stay
what they were. Both pass the paper's sequence's singularity (roll 90 deg)
many times; before the charts, Eq. 3's division by cos(roll) broke them.
The block's output channels follow its rig's own sequence (ZYX), read by
the reconstruction from its markers as the simulator wrote them.
"""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dragline.reconstruct import trajectory_from_markers
from dragline.simulate import (
    body_to_inertial,
    euler_from_matrix,
    load_rig,
    marker_positions,
    matrix_from_angles,
    simulate,
)

RIG = Path(__file__).parent / "data" / "spinning_block.toml"


@pytest.fixture(scope="module")
def block():
    return load_rig(RIG)


def _spun(rig, angles, rates, duration, integrator="verlet"):
    rest = simulate(rig, duration=0.01, rate_hz=100.0).states[0].copy()
    rest[6:9] = angles
    rest[9:12] = rates
    return simulate(rig, duration=duration, rate_hz=200.0, initial_state=rest, dissipation=False,
                    integrator=integrator)


def _matrices(result):
    return body_to_inertial(*result.states[:, 6:9].T)


@pytest.mark.parametrize("integrator", ["verlet", "rk4"])
def test_a_steady_spin_turns_the_block_as_the_exact_rotation(block, integrator):
    # yawed by 0.06 deg, so that the spin about the body's I axis takes the paper's roll within 0.06 deg of
    # its singularity, where Eq. 3 divides by cos(roll) = 0.001, twice a turn (without the charts the
    # rotation was off by 2e-4 with Verlet, 2e-6 with RK4; with them 6e-11 and 3e-13)
    angles, p = np.array([0.0, 0.0, 0.001]), 6.0
    result = _spun(block, angles, [p, 0.0, 0.0], 3.0, integrator)
    T = _matrices(result)
    exact = body_to_inertial(*angles) @ Rotation.from_rotvec(np.outer(p * result.time, [1.0, 0.0, 0.0])).as_matrix()
    assert np.abs(T - exact).max() < 1e-9
    assert np.abs(np.degrees(result.states[:, 6])).max() > 89.0
    assert np.allclose(result.states[:, 9:12], [p, 0.0, 0.0], atol=1e-9)


# The integrators' global error is of order (h omega)^2 for Verlet and (h omega)^4 for RK4: with h omega
# 3.7e-4 and 5.2e-4 here, 1.4e-7 and 7e-14; the bounds sit a decade above (measured with the charts: 1.2e-7
# and 2.4e-14; without them the momentum drifted 2.7e-6 and 2.2e-10).
MOMENTUM_DRIFT = {"verlet": 1e-6, "rk4": 1e-11}


@pytest.mark.parametrize("integrator", ["verlet", "rk4"])
def test_a_tumbling_block_keeps_its_energy_and_its_angular_momentum(block, integrator):
    # its intermediate axis J (about which it spins) across the inertial y: the body's K axis sweeps through y,
    # where the paper's roll is 90 deg
    result = _spun(block, [0.0, 0.0, 1.56], [0.05, 5.0, 0.05], 6.0, integrator)
    inertia = block.bodies["block"].inertia
    omega = result.states[:, 9:12]
    energy = 0.5 * np.einsum("ni,ij,nj->n", omega, inertia, omega)
    momentum = np.einsum("nij,jk,nk->ni", _matrices(result), inertia, omega)
    # the intermediate axis is unstable: the spin flips (q changes sign) and back
    assert omega[:, 1].min() < -4.0
    assert np.abs(np.degrees(result.states[:, 6])).max() > 89.5
    assert np.abs(energy / energy[0] - 1).max() < MOMENTUM_DRIFT[integrator] * 10
    drift = np.linalg.norm(momentum - momentum[0], axis=1).max() / np.linalg.norm(momentum[0])
    assert drift < MOMENTUM_DRIFT[integrator]


def test_the_output_channels_follow_the_bodys_sequence_and_the_reconstruction_reads_them(block):
    result = _spun(block, [0.0, 0.2, 0.5], [6.0, 0.0, 0.0], 1.0)
    table = result.table
    T = matrix_from_angles(table["block.roll"], table["block.pitch"], table["block.yaw"], "ZYX")
    assert np.abs(T - _matrices(result)).max() < 1e-12
    # ZYX's roll is the last turn, about the body's own I: the spin's angle itself (mod 2 pi)
    turned = np.angle(np.exp(1j * (6.0 * result.time + table["block.roll"][0])))
    assert np.abs(np.angle(np.exp(1j * (table["block.roll"] - turned)))).max() < 1e-7
    names, positions = marker_positions(result)
    read, _ = trajectory_from_markers(names, positions, 200.0, rig=block, method="svd", smoothing="none")
    for q in ("roll", "pitch", "yaw"):
        assert np.abs(np.angle(np.exp(1j * (read[f"block.{q}"] - table[f"block.{q}"])))).max() < 1e-9


def test_a_release_pose_is_in_the_bodys_output_sequence(block, tmp_path):
    text = RIG.read_text() + '\n[release.block]\nposition = [0.0, 0.0, -1.0]\nangles_deg = [10.0, 20.0, 30.0]\n'
    (tmp_path / "rig.toml").write_text(text)
    rig = load_rig(tmp_path / "rig.toml")
    result = simulate(rig, duration=0.01, rate_hz=100.0)
    T = body_to_inertial(*result.states[0, 6:9])
    assert np.allclose(T, matrix_from_angles(*np.radians([10.0, 20.0, 30.0]), "ZYX"), atol=1e-9)
    assert np.allclose(euler_from_matrix(T), result.states[0, 6:9])


def test_a_sequence_that_is_not_roll_pitch_yaw_is_refused(tmp_path):
    (tmp_path / "rig.toml").write_text(RIG.read_text().replace('euler_sequence = "ZYX"', 'euler_sequence = "ZXZ"'))
    with pytest.raises(ValueError) as err:
        load_rig(tmp_path / "rig.toml")
    message = str(err.value)
    assert "rig.toml" in message and "euler_sequence" in message and "\n" not in message
