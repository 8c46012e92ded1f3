"""Eq. 11 and the Euler-rate relations, checked against independent constructions."""

import numpy as np
import pytest

from dragline.simulate import (
    body_rates_from_euler_rates,
    body_to_inertial,
    euler_from_matrix,
    euler_rates_from_body_rates,
)


def _rot(axis, angle):
    c, s = np.cos(angle), np.sin(angle)
    if axis == "I":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "J":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_eq11_is_the_composition_of_three_rotations():
    rng = np.random.default_rng(1)
    for roll, pitch, yaw in rng.uniform(-3, 3, size=(50, 3)):
        expected = _rot("J", pitch) @ _rot("I", roll) @ _rot("K", yaw)
        np.testing.assert_allclose(body_to_inertial(roll, pitch, yaw), expected, atol=1e-14)


def test_pitch_rotates_nose_down_for_negative_pitch():
    # K points down: a nose-down bucket (pitch -52 deg) has its I_B axis pointing +z
    T = body_to_inertial(0.0, np.radians(-52.0), 0.0)
    assert T[2, 0] == pytest.approx(np.sin(np.radians(52.0)))


def test_euler_extraction_inverts_eq11_including_pitch_minus_52():
    rng = np.random.default_rng(2)
    angles = np.column_stack([rng.uniform(-1.4, 1.4, 400), rng.uniform(-3.1, 3.1, 400), rng.uniform(-3.1, 3.1, 400)])
    angles[0] = [0.0, np.radians(-52.0), 0.0]
    back = np.column_stack(euler_from_matrix(body_to_inertial(*angles.T)))
    np.testing.assert_allclose(back, angles, atol=1e-12)


def test_body_rates_round_trip_and_match_the_rotation_derivative():
    rng = np.random.default_rng(3)
    roll, pitch, yaw = rng.uniform(-1.2, 1.2, 3)
    rates = rng.normal(size=3)
    p, q, r = body_rates_from_euler_rates(roll, yaw, *rates)
    np.testing.assert_allclose(euler_rates_from_body_rates(roll, yaw, p, q, r), rates, atol=1e-12)
    # independent check: skew(omega_body) = T^T dT/dt by central differences
    h = 1e-6
    angles = np.array([roll, pitch, yaw])
    dT = (body_to_inertial(*(angles + h * rates)) - body_to_inertial(*(angles - h * rates))) / (2 * h)
    W = body_to_inertial(*angles).T @ dT
    np.testing.assert_allclose([W[2, 1], W[0, 2], W[1, 0]], [p, q, r], atol=1e-8)


def test_kernel_rotation_matches_numpy():
    from numba import njit

    from dragline.simulate._kernel import _body_matrix

    @njit
    def kernel_matrix(roll, pitch, yaw):
        T = np.zeros((1, 3, 3))
        _body_matrix(roll, pitch, yaw, T, 0)
        return T[0]

    for angles in [(0.3, -0.9, 0.2), (-1.0, 2.0, -2.5)]:
        np.testing.assert_allclose(kernel_matrix(*angles), body_to_inertial(*angles), atol=1e-15)


def test_eq11_and_its_inverse_agree_with_scipy_rotation():
    """Eq. 11 is the intrinsic sequence pitch about J, roll about I, yaw about K ("YXZ" in scipy);
    the paper's form stays written out (the kernel compiles the same lines) and is held to the library."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4)
    angles = np.column_stack([rng.uniform(-1.4, 1.4, 300), rng.uniform(-3.1, 3.1, 300), rng.uniform(-3.1, 3.1, 300)])
    roll, pitch, yaw = angles.T
    library = Rotation.from_euler("YXZ", np.column_stack([pitch, roll, yaw]))
    np.testing.assert_allclose(body_to_inertial(roll, pitch, yaw), library.as_matrix(), atol=1e-14)
    back = library.as_euler("YXZ")
    np.testing.assert_allclose(np.column_stack(euler_from_matrix(library.as_matrix())), back[:, [1, 0, 2]], atol=1e-12)
