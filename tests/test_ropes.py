"""Rope length by the cubic fit of Eq. 22, against analytic curves."""

import numpy as np
import pytest
from scipy.integrate import quad

from dragline.reconstruct import rope_length_cubic

U = np.array([np.cos(0.5), np.sin(0.5), 0.0])  # the rope plane's horizontal direction
N = np.array([-np.sin(0.5), np.cos(0.5), 0.0])  # horizontal normal of that plane


def _in_plane(origin, s, z):
    """Inertial points at horizontal distance s along U from origin, height z."""
    s, z = np.broadcast_arrays(np.asarray(s, float), np.asarray(z, float))
    p = origin + s[..., None] * U
    p[..., 2] = z
    return p


def test_straight_line_is_exact():
    a = np.array([[-5.5, 0.2, -4.0], [-1.0, -0.3, -0.5]])
    b = np.array([[-1.0, -0.1, -0.6], [-4.0, 0.6, -2.5]])
    frac = np.array([0.1, 0.3, 0.45, 0.8])
    markers = a[:, None, :] + frac[None, :, None] * (b - a)[:, None, :]
    length = rope_length_cubic(markers, a, b)
    np.testing.assert_allclose(length, np.linalg.norm(b - a, axis=1), rtol=1e-13)
    # The markers alone determine a line too.
    length = rope_length_cubic(markers, a, b, include_ends=False)
    np.testing.assert_allclose(length, np.linalg.norm(b - a, axis=1), rtol=1e-13)


def _catenary(k, s0, start):
    """z(s) of a hanging rope through start: height c + k cosh((s - s0) / k), z = -height."""
    c = -start[2] - k * np.cosh(s0 / k)
    return lambda s: -(c + k * np.cosh((s - s0) / k))


def test_catenary_length_in_a_rotated_plane():
    k, s0, span = 5.0, 2.2, 4.0
    start = np.array([-1.0, 0.5, -1.5])
    z = _catenary(k, s0, start)
    end = _in_plane(start, span, z(span))
    s_m = np.linspace(0.8, 3.2, 6)
    # Markers on short rods sideways off the rope: projection removes that.
    markers = _in_plane(start, s_m, z(s_m)) + 0.02 * N
    exact = k * (np.sinh((span - s0) / k) - np.sinh(-s0 / k))
    chord = np.linalg.norm(end - start)
    length = rope_length_cubic(markers[None], start[None], end[None])[0]
    # A cubic misses the catenary's quartic term: the error is a small
    # fraction of what the sag adds over the chord (here 0.11 m).
    assert abs(length - exact) < 0.01 * (exact - chord)


def test_matches_independent_polyfit_and_quadrature():
    rng = np.random.default_rng(0)
    k, s0, span = 3.0, 2.6, 4.0
    start = np.array([-2.0, -0.3, -3.0])
    z = _catenary(k, s0, start)
    s_m = np.sort(rng.uniform(0.3, 3.7, 7))
    z_m = z(s_m) + rng.normal(0, 0.01, s_m.size)
    markers = _in_plane(start, s_m, z_m)
    end = _in_plane(start, span, z(span))
    co = np.polyfit(np.r_[0.0, span, s_m], np.r_[start[2], end[2], z_m], 3)
    d = np.polyder(co)
    want = quad(lambda s: np.sqrt(1 + np.polyval(d, s) ** 2), 0, span, epsabs=1e-13)[0]
    got = rope_length_cubic(markers[None], start[None], end[None])[0]
    assert abs(got - want) < 1e-10


def test_too_few_points_and_vertical_span_give_nan():
    a = np.array([[0.0, 0, -2], [0, 0, -2], [0, 0, -2]])
    b = np.array([[2.0, 0, -1], [2, 0, -1], [0, 0, 0]])  # frame 2: vertical span
    m = np.full((3, 3, 3), np.nan)
    m[0, :2] = [[0.5, 0, -1.9], [1.5, 0, -1.3]]  # 2 markers + 2 ends = 4 points
    m[1, 0] = [0.5, 0, -1.9]  # 1 marker + 2 ends = 3 points
    m[2, :2] = [[0, 0, -1.5], [0, 0, -0.5]]
    length = rope_length_cubic(m, a, b)
    assert np.isfinite(length[0])
    assert np.isnan(length[1]) and np.isnan(length[2])
    assert np.isnan(rope_length_cubic(m, a, b, include_ends=False)[0])


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="start and end"):
        rope_length_cubic(np.zeros((2, 3, 3)), np.zeros((3, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="rope_markers"):
        rope_length_cubic(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)))
