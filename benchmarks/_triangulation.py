"""Triangulation benchmark: ours against pairwise OpenCV triangulation.

``bench_triangulation`` takes the simulated lab's six cameras, draws
random points in the box x in [-6, 0], y in [-1.5, 1.5], z in [-2.5, 0] m
(``VOLUME``) that all six cameras see, projects them with distortion, adds
centroid noise, and times

* ``triangulate`` (all views at once, vectorised), and
* the common alternative: ``cv2.triangulatePoints`` on every camera pair of
  undistorted points, then the per-point median of the pair estimates.

Both timings include undistorting the centroids, which both need.
"""

from __future__ import annotations

import itertools
import os
import time

import cv2
import numpy as np

from dragline.capture import project_points
from dragline.lab import default_lab_cameras
from dragline.reconstruct import triangulate, undistort_detections

__all__ = ["bench_triangulation", "bench_cameras"]

VOLUME = np.array([[-6.0, -1.5, -2.5], [0.0, 1.5, 0.0]])  # m, min and max corner

def bench_cameras():
    """The six cameras of the simulated lab (``lab.default_lab_cameras``), 1280 x 960 px."""
    return list(default_lab_cameras())


def _in_image(px, cam):
    w, h = cam.image_size
    return (px[..., 0] >= 0) & (px[..., 0] < w) & (px[..., 1] >= 0) & (px[..., 1] < h)


def _pairwise_median(detections, cameras):
    norm = undistort_detections(detections, cameras)
    C = len(cameras)
    pts = norm.reshape(C, -1, 2)
    P = [np.hstack([cam.R, cam.tvec[:, None]]) for cam in cameras]
    est = []
    for i, j in itertools.combinations(range(C), 2):
        h = cv2.triangulatePoints(P[i], P[j], pts[i].T, pts[j].T)
        est.append((h[:3] / h[3]).T)
    return np.median(np.stack(est), axis=0).reshape(detections.shape[1:3] + (3,))


def _median_time(fn, repeats):
    """Median wall and process-CPU time of ``repeats`` calls, and the last output.

    On a shared machine the CPU time says what the code costs; the wall time
    also carries the other jobs' load.
    """
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall)), float(np.median(cpu)), out


def bench_triangulation(seed=0, frames=5000, markers=40, noise_px=0.3, repeats=5):
    """Time and score our triangulation against pairwise OpenCV + median.

    Parameters
    ----------
    seed : int
    frames, markers : int
        Problem size; ``frames * markers`` marker-frames, each seen by all
        six cameras (points outside any image are redrawn).
    noise_px : float
        Gaussian centroid noise per axis (px).
    repeats : int
        Timings are the median of this many runs.

    Returns
    -------
    dict
        ``marker_frames``; ``ours_per_s`` (median wall time),
        ``ours_per_cpu_s`` (median process CPU time), ``ours_rms_mm`` (3D RMS
        error, mm); the same three for ``opencv_pairs_*``; ``speedup`` (ours /
        OpenCV wall throughput); ``cameras`` (count); ``camera_layout``;
        ``noise_px``; ``load_average_1min`` of the machine before timing.
    """
    rng = np.random.default_rng(seed)
    cams, layout = bench_cameras(), "lab.default_lab_cameras"
    n = frames * markers
    pts = np.empty((0, 3))
    for _ in range(50):
        if pts.shape[0] >= n:
            break
        cand = rng.uniform(VOLUME[0], VOLUME[1], size=(2 * n, 3))
        ok = np.ones(len(cand), bool)
        for cam in cams:
            px = project_points(cand, cam)
            ok &= np.isfinite(px).all(axis=-1) & _in_image(px, cam)
        pts = np.vstack([pts, cand[ok]])
    else:
        raise ValueError("bench cameras: too few points of the volume are seen by all six cameras")
    truth = pts[:n].reshape(frames, markers, 3)
    det = np.stack([project_points(truth, cam) for cam in cams])
    det = det + rng.normal(0.0, noise_px, det.shape)

    load = os.getloadavg()[0]
    t_ours, c_ours, (ours, _) = _median_time(lambda: triangulate(det, cams), repeats)
    t_cv, c_cv, theirs = _median_time(lambda: _pairwise_median(det, cams), repeats)

    def rms_mm(est):
        return float(1e3 * np.sqrt(np.nanmean(np.sum((est - truth) ** 2, axis=-1))))

    return {
        "marker_frames": n,
        "cameras": len(cams),
        "camera_layout": layout,
        "noise_px": noise_px,
        "ours_per_s": n / t_ours,
        "ours_per_cpu_s": n / c_ours,
        "ours_rms_mm": rms_mm(ours),
        "opencv_pairs_per_s": n / t_cv,
        "opencv_pairs_per_cpu_s": n / c_cv,
        "opencv_pairs_rms_mm": rms_mm(theirs),
        "speedup": t_cv / t_ours,
        "load_average_1min": load,
    }
