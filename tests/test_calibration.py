"""Calibration from L-frame and wand takes, against the synthetic lab's truth.

The truth is the lab's cameras (lab.default_lab_cameras); the takes are their
projections (capture._cameras.project_points, OpenCV) plus Gaussian centroid
noise, points off the image dropped. Nothing here is compared with numbers
taken from calibrate's own output.
"""

import numpy as np
import pytest

from dragline.capture._calibration import calibrate, triangulate_views
from dragline.benchmarks._calibration import synthesise_takes
from dragline.capture._cameras import camera_centre, project_points
from dragline.lab._layout import (
    IMAGE_SIZE,
    NOMINAL_FOCAL_PX,
    WAND_LENGTH,
    WAND_VOLUME,
    default_lab_cameras,
    lframe_points,
    wand_motion,
)
from dragline.lab._synth import project_views
from dragline.simulate import marker_positions

NOISE_PX = 0.3
N_FRAMES = 2000


def _calibrate(lframe_px, wand_px, wand_length=WAND_LENGTH, lframe=None):
    return calibrate(lframe_px, wand_px, wand_length, lframe_points() if lframe is None else lframe,
                     IMAGE_SIZE, NOMINAL_FOCAL_PX)


def _centres(cameras):
    return np.array([camera_centre(c) for c in cameras])


@pytest.fixture(scope="module")
def truth():
    return default_lab_cameras(seed=0)


@pytest.fixture(scope="module")
def takes(truth):
    rng = np.random.default_rng(0)
    return synthesise_takes(truth, N_FRAMES, NOISE_PX, rng)


@pytest.fixture(scope="module")
def calibrated(takes):
    lframe_px, wand_px, _ = takes
    return _calibrate(lframe_px, wand_px)


# ------------------------------------------------------------------ the lab

def test_lab_layout_covers_the_dig(truth, dig_baseline):
    centres = _centres(truth)
    assert len(truth) == 6
    assert all(c.image_size == (1280, 960) for c in truth)
    height = np.sort(-centres[:, 2])
    assert np.all((height[:2] > 0.4) & (height[:2] < 0.7)), "two low cameras"
    assert np.all((height[2:] > 3.5) & (height[2:] < 4.05)), "four high cameras"
    assert np.all(np.abs(centres[:, 1]) >= 1.5 - 1e-9), "no camera in or near the rig's plane"
    assert all(abs(c.dist[0]) <= 0.08 for c in truth)
    # Every marker of the dig (bucket, clusters, spreader bar, rope markers)
    # is in view of two cameras or more, nearly always three, occlusion aside.
    _, markers = marker_positions(dig_baseline)
    markers = markers[::10]
    exists = np.isfinite(markers).all(axis=-1)
    n = np.isfinite(project_views(markers, truth)).all(axis=-1).sum(axis=0)[exists]
    assert n.min() >= 2
    assert (n >= 3).mean() > 0.99
    # The markers' box is the wand's volume, so calibration is tight where they are.
    flat = markers[exists]
    assert np.all(flat >= WAND_VOLUME[:, 0] - 0.05) and np.all(flat <= WAND_VOLUME[:, 1] + 0.05)
    lframe_views = np.isfinite(project_views(lframe_points()[None], truth)[:, 0]).all(axis=-1)
    assert lframe_views.sum(axis=0).min() >= 5, "each L-frame marker seen by five cameras or six"
    # No optical axis points (nearly) at another camera.
    for i, cam in enumerate(truth):
        to_others = np.delete(centres, i, axis=0) - centres[i]
        cos = to_others @ cam.R[2] / np.linalg.norm(to_others, axis=1)
        assert np.degrees(np.arccos(cos.max())) > 10


def test_wand_motion_is_smooth_and_fills_the_volume():
    rate = 200.0
    wand = wand_motion(2000, np.random.default_rng(5), rate_hz=rate)
    assert wand.shape == (2000, 2, 3)
    np.testing.assert_allclose(np.linalg.norm(wand[:, 1] - wand[:, 0], axis=1), WAND_LENGTH, rtol=1e-12)
    flat = wand.reshape(-1, 3)
    assert np.all(flat >= WAND_VOLUME[:, 0]) and np.all(flat <= WAND_VOLUME[:, 1])
    assert flat[:, 2].max() < 0, "markers stay above the floor"
    extent = flat.max(axis=0) - flat.min(axis=0)
    assert np.all(extent > 0.8 * (WAND_VOLUME[:, 1] - WAND_VOLUME[:, 0]))
    speed = np.linalg.norm(np.diff(wand, axis=0), axis=-1) * rate
    assert speed.max() < 6.0, "a hand-waved wand, not a teleporting one"
    direction = (wand[:, 1] - wand[:, 0]) / WAND_LENGTH
    assert np.abs(direction).max(axis=0).min() > 0.8, "the wand points along every axis at some time"


# --------------------------------------------------------------- recovery

def test_recovers_the_true_cameras(truth, takes, calibrated):
    cams, quality = calibrated
    _, wand_px, wand_true = takes
    assert [c.name for c in cams] == [c.name for c in truth]
    # Target: reprojection RMS <= 1.2x the injected noise (per axis).
    for name, rms in quality["reprojection_rms_px"].items():
        assert rms <= 1.2 * NOISE_PX, name
    # Target: camera-centre error <= 5 mm, with the frame fixed by the L-frame only.
    err = np.linalg.norm(_centres(cams) - _centres(truth), axis=1)
    assert err.max() <= 5e-3, err
    for cam, true in zip(cams, truth):
        assert abs(cam.K[0, 0] / true.K[0, 0] - 1) < 2e-3
        assert np.hypot(*(cam.K[:2, 2] - true.K[:2, 2])) < 3.0
    # Intrinsics and distortion together: noise-free views of fresh points
    # through the calibrated volume reproject where the true cameras put
    # them (wherever a true lens gives a view at all).
    rng = np.random.default_rng(11)
    points = rng.uniform(WAND_VOLUME[:, 0], WAND_VOLUME[:, 1], (3000, 3))
    for cam, true, want in zip(cams, truth, project_views(points, truth)):
        got = project_points(points, cam)
        inside = np.isfinite(want).all(axis=1)
        assert np.sqrt(np.mean((got[inside] - want[inside]) ** 2)) < 0.3, cam.name


def test_wand_length_statistics(truth, takes, calibrated):
    cams, quality = calibrated
    _, wand_px, wand_true = takes
    assert abs(quality["wand_length_mean_mm"] - 1000 * WAND_LENGTH) < 0.2
    # The spread is centroid noise: the same views through the TRUE cameras
    # spread as much. The calibration's own share: noise-free views.
    ends = triangulate_views(wand_px, truth)
    floor = 1000 * np.nanstd(np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1))
    assert quality["wand_length_std_mm"] <= 1.05 * floor
    ends = triangulate_views(project_views(wand_true, truth), cams)
    assert 1000 * np.nanstd(np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)) < 0.5


def test_axes_from_the_lframe_with_k_down(truth, takes, calibrated):
    cams, _ = calibrated
    # K down: the cameras hang above the floor (negative z), and a point 1 m
    # above the floor triangulates to z = -1.
    np.testing.assert_allclose(_centres(cams)[:, 2], _centres(truth)[:, 2], atol=5e-3)
    above = np.array([[-3.0, 0.2, -1.0], [-1.5, -0.3, -1.0]])
    views = np.array([project_points(above, c) for c in truth])
    np.testing.assert_allclose(triangulate_views(views, cams), above, atol=2e-3)
    # The same takes, the L-frame declared elsewhere (turned 90 deg about K and
    # moved): the whole calibration follows the L-frame's declared pose.
    lframe_px, wand_px, _ = takes
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    shift = np.array([1.0, -2.0, 0.0])
    moved, _ = _calibrate(lframe_px, wand_px, lframe=lframe_points() @ turn.T + shift)
    np.testing.assert_allclose(_centres(moved), _centres(cams) @ turn.T + shift, atol=1e-3)
    np.testing.assert_allclose(_centres(moved), _centres(truth) @ turn.T + shift, atol=5e-3)


def test_scale_comes_from_the_wand(truth, takes, calibrated):
    cams, _ = calibrated
    lframe_px, wand_px, _ = takes
    # A wand declared 0.5 % long (within the L-frame cross-check) scales the rig by 0.5 %.
    scaled, quality = _calibrate(lframe_px, wand_px, wand_length=1.005 * WAND_LENGTH)
    dist = lambda c: np.linalg.norm(_centres(c)[:, None] - _centres(c)[None], axis=-1)[np.triu_indices(6, 1)]
    np.testing.assert_allclose(dist(scaled) / dist(truth), 1.005, atol=1e-3)
    np.testing.assert_allclose(dist(cams) / dist(truth), 1.0, atol=1e-3)
    assert abs(quality["wand_length_mean_mm"] - 1005 * WAND_LENGTH) < 0.3


def test_a_wand_length_that_disagrees_with_the_lframe_is_refused(takes):
    lframe_px, wand_px, _ = takes
    with pytest.raises(ValueError, match="wand length .* L-frame disagree on scale"):
        _calibrate(lframe_px, wand_px, wand_length=1.03 * WAND_LENGTH)


# --------------------------------------------------------- degenerate takes

def _one_line(err):
    msg = str(err.value)
    assert "\n" not in msg
    return msg


def test_wand_never_seen_by_a_camera(takes):
    lframe_px, wand_px, _ = takes
    wand = wand_px.copy()
    wand[3] = np.nan
    with pytest.raises(ValueError) as err:
        _calibrate(lframe_px, wand)
    msg = _one_line(err)
    assert "wand take" in msg and "cam4 (index 3)" in msg and "never sees" in msg


def test_too_few_wand_frames(takes):
    lframe_px, wand_px, _ = takes
    with pytest.raises(ValueError, match="wand take: too few frames"):
        _calibrate(lframe_px, wand_px[:, ::40])  # 50 frames spread over the take


@pytest.mark.parametrize("axis, value", [(1, 0.0), (2, -1.0)])
def test_wand_moved_in_a_plane(truth, takes, axis, value):
    _, _, wand_true = takes
    centre = wand_true.mean(axis=1)
    direction = wand_true[:, 1] - wand_true[:, 0]
    centre[:, axis], direction[:, axis] = value, 0.0
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    flat = np.stack([centre - WAND_LENGTH / 2 * direction, centre + WAND_LENGTH / 2 * direction], axis=1)
    lframe_px, wand_px, _ = synthesise_takes(truth, 0, NOISE_PX, np.random.default_rng(2), wand_points=flat)
    with pytest.raises(ValueError) as err:
        _calibrate(lframe_px, wand_px)
    assert "wand take: the wand moved in a plane" in _one_line(err)


@pytest.mark.parametrize("missing", ["none", "all_nan", "no_frames"])
def test_lframe_missing(takes, missing):
    lframe_px, wand_px, _ = takes
    lframe = {"none": None, "all_nan": np.full_like(lframe_px, np.nan), "no_frames": lframe_px[:, :0]}[missing]
    with pytest.raises(ValueError) as err:
        _calibrate(lframe, wand_px)
    assert "L-frame take" in _one_line(err)


def test_lframe_marker_seen_by_one_camera(takes):
    lframe_px, wand_px, _ = takes
    lframe = lframe_px.copy()
    lframe[1:, :, 2] = np.nan
    with pytest.raises(ValueError, match="L-frame take: marker 2 is seen by fewer than two cameras"):
        _calibrate(lframe, wand_px)


def test_lframe_markers_out_of_order(takes):
    lframe_px, wand_px, _ = takes
    with pytest.raises(ValueError, match="L-frame take: .*wrong marker order"):
        _calibrate(lframe_px[:, :, [0, 3, 2, 1]], wand_px)


def test_mislabelled_wand_in_one_camera_is_named(takes):
    lframe_px, wand_px, _ = takes
    wand = wand_px.copy()
    wand[2] = wand[2][:, ::-1]
    with pytest.raises(ValueError) as err:
        _calibrate(lframe_px, wand)
    assert "wand take: camera cam3 (index 2) disagrees" in _one_line(err)


def test_inputs_are_not_modified(truth, takes, calibrated):
    # The fixture's takes went through every calibration above; the same
    # seed synthesises them again, bit for bit.
    again = synthesise_takes(truth, N_FRAMES, NOISE_PX, np.random.default_rng(0))
    for used, fresh in zip(takes, again):
        np.testing.assert_array_equal(used, fresh)
