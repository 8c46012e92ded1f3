"""Gap filling against synthetic trajectories with known truth."""

import numpy as np
import pytest

from dragline.reconstruct import fill_gaps, fill_rigid
from dragline.simulate import body_to_inertial

DT = 0.005  # 200 Hz


def _trajectory(frames=400, markers=3):
    t = np.arange(frames) * DT
    k = np.arange(markers)[None, :]
    x = -3.0 + 0.5 * np.sin(2 * np.pi * 1.0 * t[:, None] + k)
    y = 0.1 * np.cos(2 * np.pi * 0.7 * t[:, None] + 2 * k)
    z = -1.0 + 0.3 * np.sin(2 * np.pi * 1.3 * t[:, None] - k)
    return np.stack([x, y, z], axis=-1)


def test_short_gaps_filled_long_and_edge_gaps_left():
    truth = _trajectory()
    pts = truth.copy()
    pts[50:53, 0] = np.nan  # 3 frames
    pts[100:110, 0] = np.nan  # 10 frames: the limit
    pts[200:211, 0] = np.nan  # 11 frames: too long
    pts[:5, 1] = np.nan  # leading
    pts[390:, 1] = np.nan  # trailing
    pts[150:152, 1] = np.nan
    pts[300, 2, 1] = np.nan  # one coordinate only
    before = pts.copy()
    filled, summary = fill_gaps(pts, max_gap=10)
    np.testing.assert_array_equal(pts, before)

    # Cubic-spline error bound (5/384) h^4 max|x''''|, h the gap's span:
    # ~1.6e-4 m for the 1.3 Hz, 0.3 m z signal over 11 intervals, whereas
    # linear interpolation would be off by ~ x'' h^2 / 8 ~ 8e-3 m.
    d4 = 0.3 * (2 * np.pi * 1.3) ** 4
    for sl, k in ((slice(50, 53), 0), (slice(100, 110), 0), (slice(150, 152), 1), (slice(300, 301), 2)):
        h = (sl.stop - sl.start + 1) * DT
        assert np.max(np.abs(filled[sl, k] - truth[sl, k])) < 5 / 384 * h**4 * d4
    assert np.isnan(filled[200:211, 0]).all()
    assert np.isnan(filled[:5, 1]).all() and np.isnan(filled[390:, 1]).all()
    # Present values are never altered.
    present = np.isfinite(before)
    np.testing.assert_array_equal(filled[present], before[present])
    np.testing.assert_array_equal(summary["filled"], [2, 1, 1])
    np.testing.assert_array_equal(summary["unfilled"], [1, 2, 0])
    np.testing.assert_array_equal(summary["filled_frames"], [13, 2, 1])


def test_marker_with_too_few_samples_is_left_alone():
    pts = np.full((20, 1, 3), np.nan)
    pts[[0, 5, 19], 0] = 1.0
    filled, summary = fill_gaps(pts)
    np.testing.assert_array_equal(np.isnan(filled), np.isnan(pts))
    assert summary["filled"][0] == 0 and summary["unfilled"][0] == 2


def test_fill_rigid_restores_markers_exactly():
    body = np.array([[0.0, -0.15, -0.05], [0.0, 0.15, -0.05], [0.3, -0.15, -0.05], [0.3, 0.15, 0.02]])
    t = np.arange(120) * DT
    T = body_to_inertial(0.1 * np.sin(3 * t), -0.9 + 0.4 * t, 0.2 * np.cos(2 * t))
    ref = np.stack([-3 + 0.5 * t, 0.05 * t, -1 + 0.2 * np.sin(4 * t)], axis=-1)
    truth = ref[:, None, :] + np.einsum("fij,mj->fmi", T, body)
    mk = truth.copy()
    mk[10:40, 2] = np.nan  # 30 frames of one marker: rigidly fillable
    mk[60:63, 0] = np.nan
    mk[60:63, 3] = np.nan  # two missing: only two left, no fit
    mk[80:85, 1] = np.nan
    filled, summary = fill_rigid(mk, body)
    np.testing.assert_allclose(filled[10:40, 2], truth[10:40, 2], atol=1e-12)
    np.testing.assert_allclose(filled[80:85, 1], truth[80:85, 1], atol=1e-12)
    assert np.isnan(filled[60:63, [0, 3]]).all()
    np.testing.assert_array_equal(summary["filled_frames"], [0, 5, 30, 0])
    np.testing.assert_array_equal(summary["unfilled_frames"], [3, 0, 0, 3])
    # max_gap limits which runs are filled.
    filled, summary = fill_rigid(mk, body, max_gap=10)
    assert np.isnan(filled[10:40, 2]).all()
    np.testing.assert_allclose(filled[80:85, 1], truth[80:85, 1], atol=1e-12)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="points"):
        fill_gaps(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="max_gap"):
        fill_gaps(np.zeros((5, 1, 3)), max_gap=-1)
    with pytest.raises(ValueError, match="markers_body"):
        fill_rigid(np.zeros((5, 4, 3)), np.zeros((3, 3)))
