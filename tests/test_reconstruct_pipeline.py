"""The assembled reconstruction against the truth of a short simulation.

Independent truth: the simulated trajectory table and the true marker
positions of ``dragline.simulate``; detections made here by projecting them
through the simulated lab's cameras with Gaussian noise; analytic bounds
(finite-difference truncation error, the Cramer-Rao bound of the camera
geometry, the total variation of the Eq. 22 residual); an independent cubic
fit with numpy's ``polyfit``.
"""

import numpy as np
import pytest

from dragline.capture import write_vicon_csv
from dragline.capture._cameras import Camera, project_points
from dragline.lab import default_lab_cameras
from dragline.reconstruct import (
    RunningAverage,
    fill_markers,
    reconstruct_markers,
    reconstruct_session,
    reconstruct_vicon_csv,
    trajectory_from_markers,
)
from dragline.reconstruct._pipeline import match_cameras
from dragline.simulate import BODIES, body_to_inertial, load_rig, marker_positions, simulate, trajectory_columns

RATE = 200.0
DT = 1.0 / RATE
NOISE_PX = 0.3
RIGID = ("bucket", "spreader_bar", "hoist_cluster")


@pytest.fixture(scope="module")
def sim():
    result = simulate(duration=1.0, rate_hz=RATE)
    names, pos = marker_positions(result)
    assert np.isfinite(pos).all()
    return result, names, pos


@pytest.fixture(scope="module")
def rig():
    return load_rig()


def detections(pos, cameras, noise_px, rng):
    """Project true markers into every camera; NaN outside the image; centroid noise."""
    out = []
    for cam in cameras:
        px = project_points(pos, cam)
        w, h = cam.image_size
        inside = np.isfinite(px).all(-1) & (px[..., 0] >= 0) & (px[..., 0] < w) & (px[..., 1] >= 0) & (px[..., 1] < h)
        px[~inside] = np.nan
        out.append(px + rng.normal(0.0, noise_px, px.shape))
    return np.stack(out)


@pytest.fixture(scope="module")
def noisy(sim):
    _, _, pos = sim
    cams = default_lab_cameras()
    return cams, detections(pos, cams, NOISE_PX, np.random.default_rng(7))


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _rms(x):
    return float(np.sqrt(np.nanmean(np.square(x))))


# ------------------------------------------------------------------ noise-free markers

@pytest.mark.parametrize("method", ["paper", "svd"])
def test_noise_free_markers_give_the_true_poses(sim, rig, method):
    result, names, pos = sim
    truth = result.table
    table, summary = trajectory_from_markers(names, pos, RATE, rig, method=method)
    assert list(table.columns) == trajectory_columns()
    np.testing.assert_allclose(table["time"], truth["time"], atol=1e-12)
    for body in BODIES:
        for q in "xyz":
            np.testing.assert_allclose(table[f"{body}.{q}"], truth[f"{body}.{q}"], rtol=0, atol=1e-9)
    for body in RIGID:
        for q in ("roll", "pitch", "yaw"):
            assert np.max(np.abs(_wrap(table[f"{body}.{q}"] - truth[f"{body}.{q}"]))) < 1e-9, (body, q)
    # Two markers fix an axis only: no orientation, no body rates, never invented.
    for q in ("roll", "pitch", "yaw", "p", "q", "r"):
        assert table[f"drag_cluster.{q}"].isna().all()
    assert np.isfinite(table[[f"drag_cluster.v{q}" for q in "xyz"]].to_numpy()).all()
    assert summary["method"] == method
    assert summary["gaps"]["total"]["open_gaps"] == 0 and summary["gaps"]["total"]["outlier_frames"] == 0


def test_swapping_the_paper_triple_changes_the_pose(sim, rig):
    """Eqs. 14-16 must use alpha -> beta as J: relabelling alpha and beta turns the bucket round."""
    result, names, pos = sim
    swapped = list(names)
    a, b = names.index("bucket.alpha"), names.index("bucket.beta")
    swapped[a], swapped[b] = swapped[b], swapped[a]
    table, _ = trajectory_from_markers(swapped, pos, RATE, rig, method="paper")
    assert np.max(np.abs(_wrap(table["bucket.yaw"] - result.table["bucket.yaw"]))) > 1.0


def test_noise_free_velocities_are_the_differenced_truth(sim, rig):
    result, names, pos = sim
    truth = result.table
    table, _ = trajectory_from_markers(names, pos, RATE, rig, smoothing="none")
    for body in BODIES:
        for q in "xyz":
            x, v = truth[f"{body}.{q}"].to_numpy(), truth[f"{body}.v{q}"].to_numpy()
            # Second-order differences of the true path, written out here.
            want = np.empty_like(x)
            want[1:-1] = (x[2:] - x[:-2]) / (2 * DT)
            want[0] = (-3 * x[0] + 4 * x[1] - x[2]) / (2 * DT)
            want[-1] = (3 * x[-1] - 4 * x[-2] + x[-3]) / (2 * DT)
            np.testing.assert_allclose(table[f"{body}.v{q}"], want, rtol=0, atol=1e-9)
            # and close to the simulator's own velocity state
            assert _rms(table[f"{body}.v{q}"] - v) <= 0.05 * _rms(v) + 1e-4, (body, q)
    for body in RIGID:
        for q in "pqr":
            w = truth[f"{body}.{q}"]
            assert _rms(table[f"{body}.{q}"] - w) <= 0.1 * _rms(w) + 1e-3, (body, q)


@pytest.mark.parametrize("smoothing", ["none", "running_average", "savgol"])
def test_rates_of_a_spinning_accelerating_bucket(sim, rig, smoothing):
    """Constant body rate and constant acceleration: analytic p, q, r and velocity."""
    from scipy.spatial.transform import Rotation

    _, names, pos = sim
    F = pos.shape[0]
    t = np.arange(F) * DT
    omega = np.array([0.3, -1.2, 0.5])  # rad/s, body frame
    T0 = body_to_inertial(0.1, np.radians(-52.0), 0.2)
    T = T0 @ Rotation.from_rotvec(t[:, None] * omega).as_matrix()  # T' = T [omega]x
    r0, v0, acc = np.array([-3.0, 0.1, -1.0]), np.array([0.4, 0.0, -0.2]), np.array([0.5, 0.1, 0.3])
    ref = r0 + v0 * t[:, None] + 0.5 * acc * t[:, None] ** 2
    spec = rig.bodies["bucket"]
    moved = pos.copy()
    for m, mb in spec.markers.items():
        moved[:, names.index(f"bucket.{m}")] = ref + T @ mb
    table, _ = trajectory_from_markers(names, moved, RATE, rig, smoothing=smoothing)
    w3 = np.linalg.norm(omega) ** 3
    # T''' = T [omega]x^3: the differences err by dt^2/6 |omega|^3 inside, dt^2/3 at the ends.
    pqr = table[["bucket.p", "bucket.q", "bucket.r"]].to_numpy()
    assert np.max(np.linalg.norm(pqr - omega, axis=1)) <= DT**2 / 3 * w3 + 1e-9
    centre = ref + T @ spec.cg_body
    np.testing.assert_allclose(table[["bucket.x", "bucket.y", "bucket.z"]], centre, atol=1e-12)
    r, p, y = (table[f"bucket.{q}"].to_numpy() for q in ("roll", "pitch", "yaw"))
    np.testing.assert_allclose(body_to_inertial(r, p, y), T, atol=1e-12)
    if smoothing == "none":
        # velocity = v0 + a t + T [omega]x cg; the rotating part errs by dt^2/3 |omega|^3 |cg| at most
        want = v0 + acc * t[:, None] + T @ np.cross(omega, spec.cg_body)
        got = table[["bucket.vx", "bucket.vy", "bucket.vz"]].to_numpy()
        assert np.max(np.abs(got - want)) <= DT**2 / 3 * w3 * np.linalg.norm(spec.cg_body) + 1e-9


def test_running_average_is_centred_half_a_sample_ahead(sim, rig):
    """A constant acceleration added to every marker shows the smoother's alignment exactly."""
    result, names, pos = sim
    F = pos.shape[0]
    t = np.arange(F) * DT
    acc = 0.8  # m/s^2 along x
    shifted = pos.copy()
    shifted[..., 0] += 0.5 * acc * t[:, None] ** 2
    inner = slice(11, F - 11)
    for smoothing, lag in ((RunningAverage(12, centred=True), -0.5), (RunningAverage(12, centred=False), 5.5)):
        base, _ = trajectory_from_markers(names, pos, RATE, rig, smoothing=smoothing)
        moved, summary = trajectory_from_markers(names, shifted, RATE, rig, smoothing=smoothing)
        for body in BODIES:
            dv = (moved[f"{body}.vx"] - base[f"{body}.vx"]).to_numpy()
            np.testing.assert_allclose(dv[inner], acc * (t[inner] - lag * DT), atol=1e-9)
            # Positions and angles are not smoothed.
            np.testing.assert_allclose(moved[f"{body}.x"] - base[f"{body}.x"], 0.5 * acc * t**2, atol=1e-9)
        assert "12 samples" in summary["smoothing"]["description"]
    default, summary = trajectory_from_markers(names, shifted, RATE, rig)  # the paper's, centred
    centred, _ = trajectory_from_markers(names, shifted, RATE, rig, smoothing=RunningAverage(12, centred=True))
    assert default.equals(centred) and summary["smoothing"]["name"] == "running_average"
    assert "i-5 ... i+6" in summary["smoothing"]["description"] or "trailing" in summary["smoothing"]["description"]


# ------------------------------------------------------------------ ropes

def _plane_fit_length(points, start, end, nodes=4001):
    """Independent Eq. 22: numpy polyfit of z(s) in the vertical plane of the span; trapezoid arc length."""
    u = (end - start)[:2] / np.linalg.norm((end - start)[:2])
    L = np.linalg.norm((end - start)[:2])
    pts = np.vstack([start, end, points])
    s = (pts[:, :2] - start[:2]) @ u
    coef = np.polynomial.polynomial.polyfit(s, pts[:, 2], 3)
    grid = np.linspace(0.0, L, nodes)
    slope = np.polynomial.polynomial.polyval(grid, np.polynomial.polynomial.polyder(coef))
    return np.trapezoid(np.sqrt(1 + slope**2), grid), coef, u


def _residual_variation(coef, nodes, start, u):
    """Total variation of the residual e(s) = z_true(s) - z_cubic(s) along the true rope polyline.

    The length of a curve z(s) changes by at most the total variation of a
    change in z (|d sqrt(1 + z'^2) / dz'| <= 1); the true rope is straight
    between its nodes, so evaluating e at the nodes and on a fine grid
    between them captures that variation.
    """
    fine = np.concatenate([a + np.linspace(0, 1, 50, endpoint=False)[:, None] * (b - a)
                           for a, b in zip(nodes[:-1], nodes[1:])] + [nodes[-1:]])
    s = (fine[:, :2] - start[:2]) @ u
    e = fine[:, 2] - np.polynomial.polynomial.polyval(s, coef)
    return np.abs(np.diff(e)).sum()


def _drag_attachment(rig, truth_row, m1):
    """Where the pipeline is specified to put the drag-rope attachment (position-only cluster)."""
    spec = rig.bodies["drag_cluster"]
    a, b = (np.array(spec.markers[k]) for k in ("left", "right"))
    T = body_to_inertial(truth_row["drag_cluster.roll"], truth_row["drag_cluster.pitch"], truth_row["drag_cluster.yaw"])
    cg = np.array([truth_row[f"drag_cluster.{q}"] for q in "xyz"])
    ref = cg - T @ spec.cg_body
    ma, mb_ = ref + T @ a, ref + T @ b
    j = (mb_ - ma) / np.linalg.norm(mb_ - ma)
    off = np.array(spec.points["drag_rope"]) - 0.5 * (a + b)
    along = off @ (b - a) / np.linalg.norm(b - a)
    normal = np.linalg.norm(off - along * (b - a) / np.linalg.norm(b - a))
    base = 0.5 * (ma + mb_) + along * j
    d = m1 - base
    d -= (d @ j) * j
    return base + normal * d / np.linalg.norm(d), ref + T @ np.array(spec.points["drag_rope"])


def test_rope_lengths_against_the_truth_and_the_reel_table(sim, rig):
    result, names, pos = sim
    truth = result.table
    table, _ = trajectory_from_markers(names, pos, RATE, rig)
    fp = rig.fixed_points
    hoist_fixed = np.linalg.norm(fp["boom_pulley"] - fp["hoist_reel"])
    hc = rig.bodies["hoist_cluster"]
    hoist_nodes = result.rope_nodes("hoist_rope")
    drag_nodes = result.rope_nodes("drag_rope")
    for i in range(0, pos.shape[0], 10):
        row = truth.iloc[i]
        # hoist rope: boom pulley to the hoist cluster's rope point (full pose known)
        T = body_to_inertial(row["hoist_cluster.roll"], row["hoist_cluster.pitch"], row["hoist_cluster.yaw"])
        ref = np.array([row[f"hoist_cluster.{q}"] for q in "xyz"]) - T @ hc.cg_body
        end = ref + T @ hc.points["hoist_rope"]
        mk = pos[i, [names.index(f"hoist_rope.m{k}") for k in range(1, 6)]]
        length, coef, u = _plane_fit_length(mk, fp["boom_pulley"], end)
        got = table["hoist_rope.length"].iloc[i]
        assert abs(got - (hoist_fixed + length)) < 1e-6
        tv = _residual_variation(coef, hoist_nodes[i, 1:], fp["boom_pulley"], u)
        assert abs(got - row["hoist_rope.length"]) <= tv + 1e-6, (i, got - row["hoist_rope.length"], tv)
        # drag rope: drag reel to the attachment placed towards the first rope marker
        mk = pos[i, [names.index(f"drag_rope.m{k}") for k in range(1, 5)]]
        end, true_end = _drag_attachment(rig, row, mk[0])
        length, coef, u = _plane_fit_length(mk, fp["drag_reel"], end)
        got = table["drag_rope.length"].iloc[i]
        assert abs(got - length) < 1e-6
        tv = _residual_variation(coef, drag_nodes[i], fp["drag_reel"], u)
        # Two markers cannot fix the cluster's roll about their axis: the attachment, 3 cm off that axis, is
        # placed towards the first rope marker, so it misses by the rope's turn between them (1.5 cm: 29 deg).
        miss = np.linalg.norm(end - true_end)
        assert miss < 0.015
        assert abs(got - row["drag_rope.length"]) <= tv + miss + 1e-6, (i, got - row["drag_rope.length"], tv, miss)
    # The reel table: at rest (frame 0, static equilibrium) the measured length
    # is the reel length stretched by the mean tension, L (1 + F / Ks).
    row = truth.iloc[0]
    for rope in ("hoist_rope", "drag_rope"):
        F = 0.5 * (row[f"{rope}.tension_start"] + row[f"{rope}.tension_end"])
        expected = row[f"{rope}.reel_length"] * (1 + F / rig.ropes[rope].static_stiffness)
        assert abs(table[f"{rope}.length"].iloc[0] - expected) < 3e-3, rope
    # ... and it grows with the reel: hoist paid out, drag wound in.
    dh = table["hoist_rope.length"].iloc[-1] - table["hoist_rope.length"].iloc[0]
    dd = table["drag_rope.length"].iloc[-1] - table["drag_rope.length"].iloc[0]
    assert dh > 0.8 * (truth["hoist_rope.reel_length"].iloc[-1] - truth["hoist_rope.reel_length"].iloc[0]) > 0
    assert dd < 0.8 * (truth["drag_rope.reel_length"].iloc[-1] - truth["drag_rope.reel_length"].iloc[0]) < 0


# ------------------------------------------------------------------ noisy 2D

def _cramer_rao_rms(pos, cameras, seen, noise_px):
    """RMS 3D error (m) of an unbiased estimator from these views: sqrt(mean trace(inv(Fisher)))."""
    info = np.zeros(pos.shape[:-1] + (3, 3))
    for c, cam in enumerate(cameras):
        R = cam.R
        Xc = pos @ R.T + cam.tvec
        z = Xc[..., 2:3]
        x, y = Xc[..., 0:1] / z, Xc[..., 1:2] / z
        Jx = cam.K[0, 0] / z * (R[0] - x * R[2])
        Jy = cam.K[1, 1] / z * (R[1] - y * R[2])
        w = seen[c][..., None, None]
        info += w * (Jx[..., :, None] * Jx[..., None, :] + Jy[..., :, None] * Jy[..., None, :])
    ok = seen.sum(axis=0) >= 2
    cov = np.linalg.inv(info[ok]) * noise_px**2
    return float(np.sqrt(np.trace(cov, axis1=-2, axis2=-1).mean()))


def test_triangulated_markers_reach_the_camera_geometry_limit(sim, noisy):
    _, _, pos = sim
    cams, det = noisy
    points, info = reconstruct_markers(det, cams)
    err = points - pos
    assert np.isfinite(points).all()
    rms3 = _rms(np.linalg.norm(err, axis=-1))
    bound = _cramer_rao_rms(pos, cams, np.isfinite(det[..., 0]), NOISE_PX)
    # The issue's 1 mm target holds per coordinate; in 3D the geometry's own floor
    # at 0.3 px is above 1 mm, and the triangulation must come close to that floor.
    assert _rms(err) < 1e-3
    assert bound * 0.9 < rms3 < 1.1 * bound, (rms3, bound)
    assert info["summary"]["rejected_views"] < 0.001 * det[..., 0].size


@pytest.mark.parametrize("method", ["paper", "svd"])
def test_noisy_detections_within_the_issue_targets(sim, rig, noisy, method):
    result, names, _ = sim
    truth = result.table
    cams, det = noisy
    points, _ = reconstruct_markers(det, cams)
    table, _ = trajectory_from_markers(names, points, RATE, rig, method=method)
    cg = np.column_stack([table[f"bucket.{q}"] - truth[f"bucket.{q}"] for q in "xyz"])
    assert _rms(np.linalg.norm(cg, axis=1)) < 1e-3
    assert np.degrees(_rms(_wrap(table["bucket.pitch"] - truth["bucket.pitch"]))) < 0.2
    for rope in ("hoist_rope", "drag_rope"):
        assert np.max(np.abs(table[f"{rope}.length"] - truth[f"{rope}.length"])) < 5e-3, rope
    # Differencing 0.15 deg of pitch noise alone gives ~0.4 rad/s RMS; the
    # running average must bring the pitch-rate error far below the signal.
    q_err = _rms(table["bucket.q"] - truth["bucket.q"])
    assert q_err < min(0.1, 0.3 * _rms(truth["bucket.q"]))


def test_a_marker_seen_by_one_camera_is_nan_never_invented(sim, rig, noisy):
    _, names, pos = sim
    cams, det = noisy
    det = det.copy()
    k = names.index("hoist_rope.m3")
    c = next(c for c in range(len(cams)) if np.isfinite(det[c, 50:60, k]).all())
    det[np.arange(len(cams)) != c, 50:60, k] = np.nan  # only camera c sees it in these frames
    points, info = reconstruct_markers(det, cams)
    assert np.isnan(points[50:60, k]).all()
    assert (info["n_views"][50:60, k] == 0).all()
    assert np.isfinite(np.delete(points, np.s_[50:60], axis=0)[:, k]).all()
    _, summary = trajectory_from_markers(names, points, RATE, rig, max_gap=5)
    gaps = summary["gaps"]["markers"]["hoist_rope.m3"]
    assert (gaps["open_gaps"], gaps["open_frames"], gaps["spline_gaps"]) == (1, 10, 0)


def test_gap_filling_and_its_summary(sim, rig):
    result, names, pos = sim
    holes = {  # marker: (frames, expected fate)
        "hoist_rope.m3": (slice(20, 25), "spline"),
        "hoist_rope.m2": (slice(60, 90), "open"),
        "bucket.delta": (slice(100, 150), "rigid"),
        "spreader_bar.top": (slice(30, 45), "open"),  # three-marker body: no rigid fill
        "drag_rope.m1": (slice(0, 5), "open"),  # at the start: nothing to interpolate from
    }
    jumps = {  # marker: (frames, offset m): ghosts two cameras agreed on
        "hoist_rope.m1": (slice(120, 121), 0.5),
        "spreader_bar.left": (slice(150, 152), -0.03),
    }
    gappy = pos.copy()
    for name, (rows, _) in holes.items():
        gappy[rows, names.index(name)] = np.nan
    for name, (rows, offset) in jumps.items():
        gappy[rows, names.index(name), 2] += offset
    filled, summary = fill_markers(names, gappy, rig, max_gap=10)
    for name, (rows, fate) in holes.items():
        k, n = names.index(name), rows.stop - rows.start
        s = summary["markers"][name]
        assert s["missing_frames"] == n and s["outlier_frames"] == 0
        assert (s["spline_gaps"], s["spline_frames"]) == ((1, n) if fate == "spline" else (0, 0)), name
        assert s["rigid_frames"] == (n if fate == "rigid" else 0), name
        expected_open = (1, n, n) if fate == "open" else (0, 0, 0)
        assert (s["open_gaps"], s["open_frames"], s["longest_open_gap"]) == expected_open, name
        if fate == "open":
            assert np.isnan(filled[rows, k]).all()
        else:
            tol = 1e-9 if fate == "rigid" else 2e-4  # spline over 25 ms of a vibrating rope: well under the noise
            np.testing.assert_allclose(filled[rows, k], pos[rows, k], atol=tol)
    for name, (rows, _) in jumps.items():
        k, n = names.index(name), rows.stop - rows.start
        s = summary["markers"][name]
        assert (s["missing_frames"], s["outlier_frames"], s["spline_gaps"], s["spline_frames"]) == (0, n, 1, n), name
        np.testing.assert_allclose(filled[rows, k], pos[rows, k], atol=2e-4)
    total = summary["total"]
    assert (total["open_gaps"], total["open_frames"], total["outlier_frames"]) == (3, 30 + 15 + 5, 3)
    kept = ~np.isnan(gappy)
    for name, (rows, _) in jumps.items():
        kept[rows, names.index(name)] = False
    assert np.array_equal(filled[kept], gappy[kept])  # measured values never change
    # Without the outlier test the jumps stay in.
    raw, s2 = fill_markers(names, gappy, rig, max_gap=10, max_deviation=None)
    k = names.index("hoist_rope.m1")
    assert s2["total"]["outlier_frames"] == 0 and raw[120, k, 2] == gappy[120, k, 2]
    # In the table: the spreader bar has no pose while its top marker is missing,
    # and the gap costs only its own frames.
    table, tsum = trajectory_from_markers(names, gappy, RATE, rig, max_gap=10)
    sb = table["spreader_bar.x"].isna().to_numpy()
    assert np.array_equal(np.flatnonzero(sb), np.arange(30, 45))
    assert np.array_equal(np.flatnonzero(table["spreader_bar.vx"].isna().to_numpy()), np.arange(30, 45))
    assert tsum["gaps"] == summary and tsum["nan_frames"]["spreader_bar.pitch"] == 15
    np.testing.assert_allclose(table["bucket.x"], result.table["bucket.x"], atol=1e-9)


# ------------------------------------------------------------------ CSV, sessions, bad input

def test_vicon_csv_round_trip_gives_the_same_table(sim, rig, noisy, tmp_path):
    from dragline.capture import CaptureSession

    _, names, _ = sim
    cams, det = noisy
    session = CaptureSession(rate_hz=RATE, camera_names=[c.name for c in cams][::-1], image_size=(1280, 960),
                             nominal_focal_px=850.0, marker_names=names, trial=det[::-1])
    table, out_names, points, summary = reconstruct_session(session, cams, rig)  # cameras matched by name
    assert out_names == names and summary["triangulation"]["rejected_views"] >= 0
    path = tmp_path / "markers.csv"
    write_vicon_csv(path, [n.replace(".", ":") for n in names], points, RATE)
    again, _ = reconstruct_vicon_csv(path, rig)
    _assert_same_table(table, again)


def _assert_same_table(a, b):
    """Equal to the VICON CSV's precision: 5 decimals of mm, i.e. +-5e-9 m per coordinate.

    Positions move by about that, angles by it over the 0.3 m marker spacing,
    differences by it over 2 dt, i.e. a few 1e-6 per second.
    """
    assert list(a.columns) == list(b.columns)
    tol = {"x": 1e-7, "y": 1e-7, "z": 1e-7, "roll": 1e-6, "pitch": 1e-6, "yaw": 1e-6,
           "vx": 3e-5, "vy": 3e-5, "vz": 3e-5, "p": 3e-4, "q": 3e-4, "r": 3e-4, "length": 1e-6, "time": 1e-12}
    for c in a.columns:
        x, y = a[c].to_numpy(), b[c].to_numpy()
        assert np.array_equal(np.isnan(x), np.isnan(y)), c
        ok = ~np.isnan(x)
        assert np.max(np.abs(x[ok] - y[ok]), initial=0.0) < tol[c.split(".")[-1]], c


def test_missing_rig_markers_are_named(sim, rig, tmp_path):
    _, names, pos = sim
    keep = [k for k, n in enumerate(names) if n not in ("hoist_rope.m5", "bucket.gamma")]
    with pytest.raises(ValueError, match=r"missing 2 of the rig's 21 markers: bucket:gamma, hoist_rope:m5"):
        trajectory_from_markers([names[k] for k in keep], pos[:, keep], RATE, rig)
    path = tmp_path / "other.csv"
    write_vicon_csv(path, ["subject:LFHD", "subject:RFHD"], pos[:, :2], RATE)
    with pytest.raises(ValueError, match=r"other\.csv: missing 21 of the rig's 21 markers: bucket:alpha"):
        reconstruct_vicon_csv(path, rig)


def test_a_calibration_for_other_cameras_is_refused():
    cams = default_lab_cameras()
    with pytest.raises(ValueError, match=r"cams\.json has no camera cam7 of the session"):
        match_cameras(cams, ["cam1", "cam7"], (1280, 960), "cams.json")
    small = [Camera(c.name, (640, 480), c.K, c.dist, c.rvec, c.tvec) for c in cams]
    with pytest.raises(ValueError, match=r"camera cam1 is 640x480 px but the session's images are 1280x960 px"):
        match_cameras(small, ["cam1"], (1280, 960))
    assert [c.name for c in match_cameras(cams, ["cam3", "cam1"])] == ["cam3", "cam1"]


def test_bad_arguments(sim, rig):
    _, names, pos = sim
    with pytest.raises(ValueError, match="unknown body-frame method"):
        trajectory_from_markers(names, pos, RATE, rig, method="quaternion")
    with pytest.raises(ValueError, match="unknown smoothing"):
        trajectory_from_markers(names, pos, RATE, rig, smoothing="kalman")
    with pytest.raises(ValueError, match="at least 3 frames"):
        trajectory_from_markers(names, pos[:2], RATE, rig)
    with pytest.raises(ValueError, match="appears twice"):
        trajectory_from_markers(names[:-1] + ["bucket:alpha"], pos, RATE, rig)
