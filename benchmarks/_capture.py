"""Benchmark of the capture chain against a synthetic session's truth.

Synthesise a default session (the dig maneuver, default realism), calibrate
it from its takes alone, triangulate the trial with the calibrated cameras
and compare with what only the truth knows. Run
``python -m dragline.benchmarks._capture [seed]`` for a printed summary.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from dragline.capture import calibrate, camera_centre
from dragline.lab import SYNTH_DEFAULTS as DEFAULTS
from dragline.lab import default_lab_cameras, synthesize_session
from dragline.reconstruct import triangulate
from dragline.simulate import simulate

__all__ = ["bench_capture"]


def _rms_mm(err):
    return float(1000 * np.sqrt(np.mean(err ** 2))) if err.size else float("nan")


def bench_capture(seed=0, duration=10.0, noise_px=DEFAULTS["noise_px"]):
    """Synthesise, calibrate and triangulate a default session; score against the truth.

    Parameters
    ----------
    seed : int
        Seeds the lab cameras' intrinsics and every random stage.
    duration : float
        Trial length (s) of the dig maneuver at 200 Hz.
    noise_px : float
        Centroid noise per axis (px).

    Returns
    -------
    figures : dict
        ``noise_px``; ``reprojection_rms_px`` (per camera) and
        ``reprojection_rms_px_all`` (calibration residuals, compare with
        ``noise_px``); ``wand_length_mean_mm``, ``wand_length_std_mm``;
        ``centre_error_mm`` per camera and ``centre_error_max_mm``;
        ``calibration_wall_time_s``; ``seen_by_two_fraction`` (marker-frames
        whose genuine detections, ghosts excluded, come from two cameras or
        more, over marker-frames that exist); ``triangulated_fraction``
        (marker-frames ``triangulate`` returned); ``rms_3d_mm``,
        ``p99_3d_mm``, ``max_3d_mm`` (triangulated minus true marker
        positions, calibrated cameras); ``rms_3d_true_cameras_mm`` (the same
        detections with the true cameras: the noise floor); ``ghosts``
        (trial ghost detections injected) and ``rejected_views``
        (views ``triangulate`` dropped as outliers); ``synth_wall_time_s``
        (simulation and filming).
    """

    t0 = time.perf_counter()
    result = simulate(duration=duration, rate_hz=200.0)
    truth_cams = default_lab_cameras(seed)
    session, truth = synthesize_session(result, truth_cams, seed=seed, noise_px=noise_px)
    synth_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    cams, quality = calibrate(session.lframe, session.wand, session.wand_length, session.lframe_points,
                              session.image_size, session.nominal_focal_px, names=session.camera_names)
    calib_s = time.perf_counter() - t0
    centre = {c.name: float(1000 * np.linalg.norm(camera_centre(c) - camera_centre(t)))
              for c, t in zip(cams, truth_cams)}

    markers = truth["markers"]
    exists = np.isfinite(markers).all(axis=-1)
    genuine = np.isfinite(session.trial).all(axis=-1) & ~truth["ghosts"]
    seen2 = (genuine.sum(axis=0) >= 2) & exists

    points, info = triangulate(session.trial, cams)
    ok = np.isfinite(points).all(axis=-1) & exists
    err = np.linalg.norm(points - markers, axis=-1)[ok]
    points_true, _ = triangulate(session.trial, truth_cams)
    ok_true = np.isfinite(points_true).all(axis=-1) & exists
    err_true = np.linalg.norm(points_true - markers, axis=-1)[ok_true]

    return {
        "seed": seed,
        "duration_s": duration,
        "frames": int(markers.shape[0]),
        "markers": int(markers.shape[1]),
        "noise_px": noise_px,
        "reprojection_rms_px": quality["reprojection_rms_px"],
        "reprojection_rms_px_all": quality["reprojection_rms_px_all"],
        "wand_length_mean_mm": quality["wand_length_mean_mm"],
        "wand_length_std_mm": quality["wand_length_std_mm"],
        "lframe_misfit_mm": quality["lframe_misfit_mm"],
        "centre_error_mm": centre,
        "centre_error_max_mm": max(centre.values()),
        "calibration_wall_time_s": calib_s,
        "synth_wall_time_s": synth_s,
        "seen_by_two_fraction": float(seen2.sum() / exists.sum()),
        "triangulated_fraction": float(ok.sum() / exists.sum()),
        "rms_3d_mm": _rms_mm(err),
        "p99_3d_mm": float(1000 * np.percentile(err, 99)) if err.size else float("nan"),
        "max_3d_mm": float(1000 * err.max()) if err.size else float("nan"),
        "rms_3d_true_cameras_mm": _rms_mm(err_true),
        "ghosts": int(truth["ghosts"].sum()),
        "rejected_views": int(info["rejected_views"]),
    }


if __name__ == "__main__":
    print(json.dumps(bench_capture(seed=int(sys.argv[1]) if len(sys.argv) > 1 else 0), indent=1))
