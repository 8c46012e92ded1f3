"""Benchmark of ``calibrate`` against the synthetic lab's truth.

Run ``python -m dragline.benchmarks._calibration [n_frames]`` for a
printed summary.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from dragline.capture import calibrate, camera_centre, triangulate_views
from dragline.lab import (
    IMAGE_SIZE,
    NOMINAL_FOCAL_PX,
    WAND_LENGTH,
    default_lab_cameras,
    lframe_points,
    on_sensor,
    project_views,
    wand_motion,
)

__all__ = ["bench_calibration", "synthesise_takes"]

LFRAME_FRAMES = 200
"""Frames of the static L-frame take (1 s at 200 Hz)."""


def _observe(points, cameras, noise_px, rng):
    """Noisy pixel views (cameras, ..., 2) of points (..., 3).

    NaN where ``project_views`` finds no view (behind the camera, beyond the
    lens's usable field, off the sensor) or noise pushes the centroid off
    the sensor.
    """
    px = project_views(points, cameras)
    px = px + rng.normal(0.0, noise_px, px.shape)
    for c, cam in enumerate(cameras):
        px[c][~on_sensor(px[c], cam.image_size)] = np.nan
    return px


def synthesise_takes(cameras, n_frames, noise_px, rng, lframe_frames=LFRAME_FRAMES, rate_hz=200.0,
                     wand_length=WAND_LENGTH, lframe=None, wand_points=None):
    """The L-frame and wand takes as the cameras would see them.

    Parameters
    ----------
    cameras : list of Camera
        True cameras.
    n_frames : int
        Wand frames.
    noise_px : float
        Gaussian centroid noise (px, per coordinate).
    rng : numpy.random.Generator
    lframe_frames : int
        Frames of the static L-frame take.
    rate_hz : float
        Wand take frame rate (Hz).
    wand_length : float
        True marker separation (m).
    lframe : array_like, shape (4, 3), optional
        True L-frame marker positions (m); ``lframe_points()`` by default.
    wand_points : array_like, shape (frames, 2, 3), optional
        True wand marker positions (m) instead of ``wand_motion``.

    Returns
    -------
    lframe_px : ndarray, shape (cameras, lframe_frames, 4, 2)
    wand_px : ndarray, shape (cameras, frames, 2, 2)
    wand_points : ndarray, shape (frames, 2, 3)
        The true wand markers.
    """
    lpts = lframe_points() if lframe is None else np.asarray(lframe, float)
    if wand_points is None:
        wand_points = wand_motion(n_frames, rng, rate_hz=rate_hz, wand_length=wand_length)
    static = np.broadcast_to(lpts, (lframe_frames, 4, 3))
    return _observe(static, cameras, noise_px, rng), _observe(wand_points, cameras, noise_px, rng), wand_points


def bench_calibration(seed=0, n_frames=2000, noise_px=0.3):
    """Calibrate the synthetic lab from noisy takes and compare with the truth.

    Parameters
    ----------
    seed : int
        Seeds the true intrinsics, the wand path and the noise.
    n_frames : int
        Wand frames (200 Hz).
    noise_px : float
        Gaussian centroid noise (px, per coordinate).

    Returns
    -------
    figures : dict
        ``wall_time_s`` (calibrate alone); ``reprojection_rms_px`` (per
        camera) and ``reprojection_rms_px_all`` (RMS of x and y residuals);
        ``wand_length_mean_mm``, ``wand_length_std_mm`` (calibrated cameras,
        noisy views); ``wand_length_std_true_cameras_mm`` (the same views
        triangulated with the true cameras: the noise floor);
        ``wand_length_std_noise_free_mm`` (noise-free views, calibrated
        cameras: the calibration's own contribution); ``centre_error_mm``
        per camera and ``centre_error_max_mm`` (no alignment beyond the
        L-frame's); ``focal_error_px``, ``principal_point_error_px``;
        ``heldout_rms_3d_mm`` (2000 random points in the bucket's work
        volume, noisy views triangulated with the calibrated cameras),
        ``heldout_rms_3d_true_cameras_mm`` (same views, true cameras) and
        ``heldout_rms_3d_noise_free_mm`` (noise-free views, calibrated
        cameras); ``frames_used``, ``iterations``.
    """
    rng = np.random.default_rng(seed)
    truth = default_lab_cameras(seed)
    lframe_px, wand_px, wand_true = synthesise_takes(truth, n_frames, noise_px, rng)

    t0 = time.perf_counter()
    cams, quality = calibrate(lframe_px, wand_px, WAND_LENGTH, lframe_points(), IMAGE_SIZE, NOMINAL_FOCAL_PX)
    wall = time.perf_counter() - t0

    def wand_std(views, cameras):
        ends = triangulate_views(views, cameras)
        length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
        return float(1000 * np.nanstd(length))

    clean = _observe(wand_true, truth, 0.0, rng)
    centre = {c.name: float(1000 * np.linalg.norm(camera_centre(c) - camera_centre(t))) for c, t in zip(cams, truth)}

    held = rng.uniform([-5.5, -0.4, -1.6], [-1.0, 0.4, 0.0], (2000, 3))
    held_noisy = _observe(held, truth, noise_px, rng)
    held_clean = _observe(held, truth, 0.0, rng)

    def rms3d(views, cameras):
        err = triangulate_views(views, cameras) - held
        return float(1000 * np.sqrt(np.nanmean((err ** 2).sum(axis=1))))

    return {
        "seed": seed,
        "n_frames": n_frames,
        "noise_px": noise_px,
        "wall_time_s": wall,
        "reprojection_rms_px": quality["reprojection_rms_px"],
        "reprojection_rms_px_all": quality["reprojection_rms_px_all"],
        "wand_length_mean_mm": quality["wand_length_mean_mm"],
        "wand_length_std_mm": quality["wand_length_std_mm"],
        "wand_length_std_true_cameras_mm": wand_std(wand_px, truth),
        "wand_length_std_noise_free_mm": wand_std(clean, cams),
        "centre_error_mm": centre,
        "centre_error_max_mm": max(centre.values()),
        "focal_error_px": {c.name: float(c.K[0, 0] - t.K[0, 0]) for c, t in zip(cams, truth)},
        "principal_point_error_px": {c.name: float(np.hypot(*(c.K[:2, 2] - t.K[:2, 2]))) for c, t in zip(cams, truth)},
        "heldout_rms_3d_mm": rms3d(held_noisy, cams),
        "heldout_rms_3d_true_cameras_mm": rms3d(held_noisy, truth),
        "heldout_rms_3d_noise_free_mm": rms3d(held_clean, cams),
        "frames_used": quality["frames_used"],
        "iterations": quality["iterations"],
    }


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    print(json.dumps(bench_calibration(n_frames=n), indent=1))
