"""Reconstruction benchmark: the assembled pipeline against a synthetic session's truth.

``bench_reconstruction`` simulates the paper's dig maneuver, films it with
the simulated lab's six true cameras, reconstructs it, and scores the result
against the simulation:

* the session: ``lab.synthesize_session`` at its defaults (0.3 px
  centroid noise, occlusion by the bodies, 1 % dropouts, 0.2 % ghosts) when
  that module is present, else Gaussian noise only; a second, noise-only
  session (projection plus Gaussian noise, nothing else) is scored too;
* the cameras are the *true* ones, so the figures isolate reconstruction
  from calibration (``benchmarks._calibration`` scores that);
* figures: marker RMS error (3D and per coordinate) beside the Cramer-Rao
  floor of the views used, raw and after outlier removal and gap filling
  (``fill_markers``, what the table is made from), bucket mass-centre and pitch RMS error, rope
  length RMS and peak error, bucket pitch-rate error unsmoothed, with the
  paper's running average and with Savitzky-Golay, and the running average's
  own bias on noise-free markers; paper (Eqs. 14-16) and svd body frames
  side by side;
* robustness: the same with each camera and each pair of cameras removed
  entirely (worst and median over the 6 and 15 cases);
* speed: ``bench_triangulation`` (ours against pairwise OpenCV) and the
  whole pipeline's frames per second.
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from dragline.lab import SYNTH_DEFAULTS, default_lab_cameras, project_views, synthesize_session
from dragline.reconstruct import fill_markers, reconstruct_markers, trajectory_from_markers
from dragline.simulate import load_rig, marker_positions, simulate

from ._triangulation import bench_triangulation

__all__ = ["bench_reconstruction", "TARGETS"]

TARGETS = {
    "marker_rms_mm": 1.0,
    "bucket_cg_rms_mm": 1.0,
    "bucket_pitch_rms_deg": 0.2,
    "rope_length_error_mm": 5.0,
    "triangulation_marker_frames_per_s": 1e6,
}
"""The issue's targets, in the units of the figures."""


def _rms(x):
    return float(np.sqrt(np.nanmean(np.square(x))))


def _gaussian_session(pos, cameras, noise_px, rng):
    """Views where a true lens gives one (``project_views``), Gaussian centroid noise: nothing else."""
    px = project_views(pos, cameras)
    return px + rng.normal(0.0, noise_px, px.shape)


def _synth_session(result, cameras, seed, noise_px):
    """Trial detections from ``synthesize_session`` (its default realism) and the settings used."""
    noise = SYNTH_DEFAULTS["noise_px"] if noise_px is None else noise_px
    session, _ = synthesize_session(result, cameras, seed=seed, noise_px=noise, wand_frames=0, lframe_frames=0)
    settings = {k: SYNTH_DEFAULTS[k] for k in ("dropout", "ghost_rate", "occlusion")}
    return session.trial, {"noise_px": noise, **settings}


def _cramer_rao_rms_mm(pos, cameras, used, noise_px):
    """RMS 3D error floor (mm) of an unbiased estimate from the views used (pinhole Jacobians)."""
    info = np.zeros(pos.shape[:-1] + (3, 3))
    for c, cam in enumerate(cameras):
        R = cam.R
        Xc = pos @ R.T + cam.tvec
        z = Xc[..., 2:3]
        Jx = cam.K[0, 0] / z * (R[0] - Xc[..., 0:1] / z * R[2])
        Jy = cam.K[1, 1] / z * (R[1] - Xc[..., 1:2] / z * R[2])
        info += used[c][..., None, None] * (Jx[..., :, None] * Jx[..., None, :] + Jy[..., :, None] * Jy[..., None, :])
    ok = used.sum(axis=0) >= 2
    if not ok.any():
        return float("nan")
    cov = np.linalg.inv(info[ok]) * noise_px**2
    return float(1e3 * np.sqrt(np.trace(cov, axis1=-2, axis2=-1).mean()))


def _marker_figures(names, points, truth_markers, used, cameras, noise_px):
    """Raw triangulated markers, and the same after outlier removal and gap filling."""
    cleaned, gaps = fill_markers(names, points, load_rig())
    out = {"marker_cramer_rao_rms_mm": _cramer_rao_rms_mm(truth_markers, cameras, used, noise_px)}
    for prefix, p in (("marker", points), ("cleaned_marker", cleaned)):
        err = np.linalg.norm(p - truth_markers, axis=-1)
        found = np.isfinite(err)
        out[f"{prefix}_rms_mm"] = 1e3 * _rms(err)
        out[f"{prefix}_max_mm"] = float(1e3 * np.nanmax(err)) if found.any() else float("nan")
        out[f"{prefix}_frames_missing"] = float(1.0 - found.mean())
        if prefix == "marker":
            out["marker_rms_per_axis_mm"] = 1e3 * _rms(p - truth_markers)
    out["outlier_marker_frames"] = float(gaps["total"]["outlier_frames"])
    return out


def _lead_body():
    """The body the figures follow: the rig's first (the dragline's bucket)."""
    return next(iter(load_rig().bodies))


def _table_figures(table, truth, extra=None):
    lead = _lead_body()
    cg = np.column_stack([table[f"{lead}.{q}"] - truth[f"{lead}.{q}"] for q in "xyz"])
    pitch = (table[f"{lead}.pitch"] - truth[f"{lead}.pitch"] + np.pi) % (2 * np.pi) - np.pi
    out = {
        f"{lead}_cg_rms_mm": 1e3 * _rms(np.linalg.norm(cg, axis=1)),
        f"{lead}_pitch_rms_deg": float(np.degrees(_rms(pitch))),
        f"{lead}_pitch_max_deg": float(np.degrees(np.nanmax(np.abs(pitch)))),
        f"{lead}_frames_missing": float(table[f"{lead}.x"].isna().mean()),
        f"{lead}_vx_rms": _rms(table[f"{lead}.vx"] - truth[f"{lead}.vx"]),
        f"{lead}_pitch_rate_rms": _rms(table[f"{lead}.q"] - truth[f"{lead}.q"]),
    }
    for rope in load_rig().winches.values():
        d = table[f"{rope}.length"] - truth[f"{rope}.length"]
        out[f"{rope}_length_rms_mm"] = 1e3 * _rms(d)
        out[f"{rope}_length_max_mm"] = float(1e3 * np.nanmax(np.abs(d)))
    out.update(extra or {})
    return out


def _score(det, cameras, names, truth_markers, truth, rate_hz, noise_px, rates=False):
    points, info = reconstruct_markers(det, cameras)
    row = {"cameras": [c.name for c in cameras],
           **_marker_figures(names, points, truth_markers, info["used"], cameras, noise_px)}
    for method in ("paper", "svd"):
        table, _ = trajectory_from_markers(names, points, rate_hz, method=method)
        extra = {}
        if rates:
            for sm in ("none", "savgol"):
                t2, _ = trajectory_from_markers(names, points, rate_hz, method=method, smoothing=sm)
                lead = _lead_body()
                extra[f"{lead}_pitch_rate_rms_{sm}"] = _rms(t2[f"{lead}.q"] - truth[f"{lead}.q"])
        row[method] = _table_figures(table, truth, extra)
    return row


def _spread(rows):
    """Worst and median of every figure over camera subsets, and which subset was worst."""
    def flat(row):
        out = {k: v for k, v in row.items() if isinstance(v, float)}
        for m in ("paper", "svd"):
            out.update({f"{m}.{k}": v for k, v in row[m].items()})
        return out

    flats = {name: flat(r) for name, r in rows.items()}
    keys = next(iter(flats.values())).keys()
    worst, median, which = {}, {}, {}
    for k in keys:
        vals = {name: f[k] for name, f in flats.items()}
        finite = {n: v for n, v in vals.items() if np.isfinite(v)}
        name = max(finite, key=finite.get) if finite else None
        worst[k] = finite[name] if name else float("nan")
        which[k] = name
        median[k] = float(np.median(list(finite.values()))) if finite else float("nan")
    return {"worst": worst, "worst_case": which, "median": median}


def bench_reconstruction(seed=0, duration=10.0, rate_hz=200.0, noise_px=None, speed=True):
    """Score the reconstruction against a synthetic session's truth.

    Parameters
    ----------
    seed : int
        Seeds the camera intrinsics, the session's noise and the speed test.
    duration, rate_hz : float
        Length (s) and frame rate (Hz) of the simulated dig maneuver.
    noise_px : float, optional
        Centroid noise (px per axis); the synthetic session's default (0.3).
    speed : bool
        Also run ``bench_triangulation`` (several seconds).

    Returns
    -------
    dict
        ``setup``; ``targets``; ``all_cameras``, ``noise_only`` (marker
        figures plus ``paper`` and ``svd`` table figures); ``smoothing_bias``
        (bucket pitch-rate RMS error of noise-free markers per smoother);
        ``one_camera_removed`` and ``two_cameras_removed`` (``worst``,
        ``worst_case``, ``median``, ``by_removed``); ``speed``. Lengths in
        mm, angles in deg, rates in rad/s and m/s, as the keys say.
    """
    result = simulate(duration=duration, rate_hz=rate_hz)
    names, truth_markers = marker_positions(result)
    truth = result.table
    cameras = list(default_lab_cameras(seed))
    rng = np.random.default_rng(seed)
    det, realism = _synth_session(result, cameras, seed, noise_px)
    noise = realism["noise_px"]
    clean = _gaussian_session(truth_markers, cameras, noise, rng)

    everything = _score(det, cameras, names, truth_markers, truth, rate_hz, noise, rates=True)
    out = {
        "setup": {"seed": seed, "maneuver": "dig", "duration_s": duration, "rate_hz": rate_hz,
                  "frames": int(truth_markers.shape[0]), "markers": len(names), "cameras": len(cameras),
                  "session": realism, "camera_model": "true lab cameras (calibration error excluded)"},
        "targets": dict(TARGETS),
        "all_cameras": everything,
        "noise_only": _score(clean, cameras, names, truth_markers, truth, rate_hz, noise),
        "smoothing_bias": {},
    }
    for sm in ("none", "running_average", "savgol"):
        table, _ = trajectory_from_markers(names, truth_markers, rate_hz, smoothing=sm)
        lead = _lead_body()
        out["smoothing_bias"][f"{lead}_pitch_rate_rms_{sm}"] = _rms(table[f"{lead}.q"] - truth[f"{lead}.q"])

    for k, key in ((1, "one_camera_removed"), (2, "two_cameras_removed")):
        rows = {}
        for gone in itertools.combinations(range(len(cameras)), k):
            keep = [c for c in range(len(cameras)) if c not in gone]
            label = "+".join(cameras[c].name for c in gone)
            rows[label] = _score(det[keep], [cameras[c] for c in keep], names, truth_markers, truth, rate_hz, noise)
        out[key] = {**_spread(rows), "by_removed": rows}

    wall = []
    for _ in range(3):
        t0 = time.perf_counter()
        points, _ = reconstruct_markers(det, cameras)
        trajectory_from_markers(names, points, rate_hz)
        wall.append(time.perf_counter() - t0)
    out["speed"] = {"pipeline_frames_per_s": truth_markers.shape[0] / float(np.median(wall)),
                    "pipeline_note": "2D detections to trajectory table, six cameras, paper frames, median of 3"}
    if speed:
        out["speed"]["triangulation"] = bench_triangulation(seed=seed)
    return out
