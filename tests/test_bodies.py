"""Body frames: round trips angles -> T -> markers -> frames -> angles."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dragline.reconstruct import (
    body_frames_paper,
    body_frames_svd,
    body_origin,
    mass_centre,
    two_marker_position,
)
from dragline.simulate import body_to_inertial, euler_from_matrix

# Bucket markers in body coordinates (m): alpha, beta left/right of the lower
# hoist chain mount, gamma, delta left/right of the nose; all on rods 5 cm
# above the reference point (K_B is down, so "above" is -z).
BUCKET = np.array([
    [0.00, -0.15, -0.05],  # alpha
    [0.00, 0.15, -0.05],   # beta
    [0.30, -0.15, -0.05],  # gamma
    [0.30, 0.15, -0.05],   # delta
])


def _angles(rng, n):
    roll = np.concatenate([[0.0, 0.1, -0.2], rng.uniform(-1.4, 1.4, n)])
    pitch = np.concatenate([[np.radians(-52.0), np.radians(-52.0), 0.3], rng.uniform(-np.pi, np.pi, n)])
    yaw = np.concatenate([[0.0, 0.05, -2.9], rng.uniform(-np.pi, np.pi, n)])
    return roll, pitch, yaw


def _markers(T, ref, body):
    return ref[:, None, :] + np.einsum("fij,mj->fmi", T, body)


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _assert_angles(T, roll, pitch, yaw):
    r, p, y = euler_from_matrix(T)
    for got, want in ((r, roll), (p, pitch), (y, yaw)):
        assert np.max(np.abs(_wrap(got - want))) < 1e-12


def test_paper_round_trip_including_pitch_minus_52():
    rng = np.random.default_rng(0)
    roll, pitch, yaw = _angles(rng, 500)
    T_true = body_to_inertial(roll, pitch, yaw)
    ref = rng.uniform([-5.5, -0.4, -1.6], [-1.0, 0.4, 0.0], size=(roll.size, 3))
    mk = _markers(T_true, ref, BUCKET)
    T = body_frames_paper(mk[:, 0], mk[:, 1], mk[:, 2])
    assert T.shape == (roll.size, 3, 3)
    _assert_angles(T, roll, pitch, yaw)
    np.testing.assert_allclose(body_origin(mk, BUCKET, T), ref, atol=1e-12)


def test_paper_marker_frame_correction_for_a_low_nose():
    rng = np.random.default_rng(1)
    roll, pitch, yaw = _angles(rng, 200)
    T_true = body_to_inertial(roll, pitch, yaw)
    body = BUCKET.copy()
    body[2:, 2] = 0.12  # nose markers lower than the chain-mount markers
    ref = rng.normal(size=(roll.size, 3))
    mk = _markers(T_true, ref, body)
    T = body_frames_paper(mk[:, 0], mk[:, 1], mk[:, 2], markers_body=body[:3])
    _assert_angles(T, roll, pitch, yaw)
    # Without the correction the marker frame is the body frame pitched nose
    # down (a negative pitch about J_B) by atan(0.17 / 0.3); frame 0 has zero
    # roll and yaw, so the error shows in pitch alone.
    r, p, _ = euler_from_matrix(body_frames_paper(mk[:3, 0], mk[:3, 1], mk[:3, 2]))
    assert abs(_wrap(p[0] - pitch[0]) + np.arctan2(0.17, 0.3)) < 1e-12


def test_paper_nan_and_collinear_frames():
    a = np.array([[0.0, 0, 0], [0, 0, 0], [0, 0, 0]])
    b = np.array([[0.0, 1, 0], [0, 1, 0], [np.nan, 1, 0]])
    g = np.array([[1.0, 0, 0], [0, 2, 0], [1, 0, 0]])  # frame 1 collinear
    T = body_frames_paper(a, b, g)
    np.testing.assert_allclose(T[0], np.eye(3), atol=1e-15)
    assert np.isnan(T[1]).all() and np.isnan(T[2]).all()


def test_svd_round_trip_and_visibility():
    rng = np.random.default_rng(2)
    roll, pitch, yaw = _angles(rng, 500)
    T_true = body_to_inertial(roll, pitch, yaw)
    ref = rng.uniform(-3, 3, size=(roll.size, 3))
    mk = _markers(T_true, ref, BUCKET)
    mk[::3, 1] = np.nan  # three of four visible every third frame
    mk[5, :2] = np.nan  # only two visible: no orientation
    before = mk.copy()
    T, origin = body_frames_svd(mk, BUCKET)
    np.testing.assert_array_equal(mk, before)
    assert np.isnan(T[5]).all() and np.isnan(origin[5]).all()
    keep = np.ones(roll.size, bool)
    keep[5] = False
    np.testing.assert_allclose(np.linalg.det(T[keep]), 1.0, atol=1e-13)
    _assert_angles(T[keep], roll[keep], pitch[keep], yaw[keep])
    np.testing.assert_allclose(origin[keep], ref[keep], atol=1e-12)


def test_svd_collinear_markers_give_nan():
    body = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.3, 0, 0], [0.0, 0.2, 0]])
    T_true = body_to_inertial([0.2, 0.2], [0.4, 0.4], [0.1, 0.1])
    mk = _markers(T_true, np.zeros((2, 3)), body)
    mk[1, 3] = np.nan  # left with three collinear markers
    T, origin = body_frames_svd(mk, body)
    assert np.isfinite(T[0]).all()
    assert np.isnan(T[1]).all() and np.isnan(origin[1]).all()


def test_svd_matches_scipy_on_noisy_markers():
    rng = np.random.default_rng(3)
    roll, pitch, yaw = _angles(rng, 50)
    T_true = body_to_inertial(roll, pitch, yaw)
    mk = _markers(T_true, rng.normal(size=(roll.size, 3)), BUCKET)
    mk += rng.normal(0, 2e-3, mk.shape)
    T, origin = body_frames_svd(mk, BUCKET)
    for f in range(roll.size):
        c_m, c_b = mk[f].mean(axis=0), BUCKET.mean(axis=0)
        rot, _ = Rotation.align_vectors(mk[f] - c_m, BUCKET - c_b)
        np.testing.assert_allclose(T[f], rot.as_matrix(), atol=1e-10)
        np.testing.assert_allclose(origin[f], c_m - rot.as_matrix() @ c_b, atol=1e-10)


def test_mass_centre_and_two_marker_position():
    # Yaw 90 deg: I_B points along inertial +J, so a body offset (1, 0, 0)
    # lands one metre along +J from the reference point.
    T = body_to_inertial(np.zeros(2), np.zeros(2), np.full(2, np.pi / 2))
    origin = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, -1.0]])
    cg = mass_centre(T, origin, [1.0, 0.0, 0.5])
    np.testing.assert_allclose(cg, [[1.0, 3.0, 3.5], [0.0, 1.0, -0.5]], atol=1e-15)

    a = np.array([[0.0, 0.0, -1.0], [np.nan, 0, 0]])
    b = np.array([[0.0, 0.4, -1.0], [1.0, 0, 0]])
    np.testing.assert_allclose(two_marker_position(a, b)[0], [0.0, 0.2, -1.0])
    np.testing.assert_allclose(two_marker_position(a, b, offset=0.05)[0], [0.0, 0.25, -1.0])
    assert np.isnan(two_marker_position(a, b, offset=0.05)[1]).all()


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="markers_body"):
        body_frames_svd(np.zeros((2, 4, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="share a shape"):
        body_frames_paper(np.zeros((2, 3)), np.zeros((3, 3)), np.zeros((2, 3)))
