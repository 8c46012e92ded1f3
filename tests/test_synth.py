"""Synthetic lab sessions: geometry of visibility, error statistics, determinism, no truth leaks.

Independent truth: a brute-force walk along each camera-to-marker segment
for occlusion, OpenCV's projection for the exact views, binomial and
Gaussian statistics for the injected errors, the raw records of the MCAP
files (read with the mcap package) for what a session holds.
"""

import json
import os

import numpy as np
import pytest
from mcap.reader import make_reader

from dragline.capture import Camera, atomic_directory, camera_centre, project_points, read_session, session_file
from dragline.lab import WAND_LENGTH, default_lab_cameras, lframe_points, synthesize_session, write_session_dir
from dragline.lab._synth import (
    GHOST_OFFSET_PX,
    add_ghosts,
    body_boxes,
    drop_detections,
    fov_radius,
    occlusion_mask,
    project_views,
)
from dragline.simulate import BODIES, body_to_inertial, marker_names, parse_physics, simulate

WAND = 300  # wand frames where the test does not calibrate


@pytest.fixture(scope="module")
def run():
    return simulate(duration=0.5, rate_hz=200.0)


@pytest.fixture(scope="module")
def run_drag():
    """The same maneuver with air drag on: a different physics, the same lab."""
    return simulate(duration=0.5, rate_hz=200.0, physics=[parse_physics("aero_drag:cd=2.0")])


@pytest.fixture(scope="module")
def cams():
    return default_lab_cameras(0)


def _records(path):
    """Every schema, channel, message payload and metadata record of an MCAP file."""
    out = {"schemas": [], "channels": [], "messages": {}, "metadata": []}
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        for schema, channel, message in reader.iter_messages():
            out["messages"].setdefault(channel.topic, []).append(bytes(message.data))
            if schema is not None and schema.name not in [s[0] for s in out["schemas"]]:
                out["schemas"].append((schema.name, bytes(schema.data)))
            if channel.topic not in out["channels"]:
                out["channels"].append(channel.topic)
        out["metadata"] = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
    return out


# ---------------------------------------------------------------- geometry

def _brute_hidden(origin, point, centre, axes, half, n=20001):
    """Whether any of n points along the segment, where it passes the box's bounding sphere, is inside the box."""
    d = point - origin
    # |origin + s d - centre| <= |half|: the only stretch where the box can be.
    a, b, c = d @ d, 2 * d @ (origin - centre), (origin - centre) @ (origin - centre) - half @ half
    disc = b * b - 4 * a * c
    if disc < 0:
        return False
    lo, hi = max((-b - np.sqrt(disc)) / (2 * a), 0.0), min((-b + np.sqrt(disc)) / (2 * a), 1.0)
    if lo > hi:
        return False
    s = np.linspace(lo, hi, n)[:, None]
    local = (origin + s * d - centre) @ axes
    return bool((np.abs(local) <= half).all(axis=1).any())


def test_marker_behind_a_box_is_hidden_from_that_camera_only(cams):
    marker = np.array([-3.0, 0.1, -0.8])
    c0 = camera_centre(cams[0])
    centre = (c0 + marker) / 2  # the box sits on camera 1's line of sight, halfway
    axes = body_to_inertial(0.3, -0.4, 0.7)
    half = np.array([0.06, 0.04, 0.05])
    hidden = occlusion_mask(marker[None, None], cams, centre[None, None], axes[None, None], half[None])
    assert hidden.shape == (6, 1, 1)
    assert hidden[0, 0, 0]
    assert not hidden[1:].any()
    # Moved off the line of sight by more than its half-diagonal, it hides nothing.
    side = np.cross(marker - c0, [0.0, 0.0, 1.0])
    shifted = centre + 0.2 * side / np.linalg.norm(side)
    assert not occlusion_mask(marker[None, None], cams, shifted[None, None], axes[None, None], half[None]).any()


def test_slab_test_agrees_with_walking_the_segment(cams):
    rng = np.random.default_rng(5)
    n = 60
    points = rng.uniform([-4.0, -0.6, -1.5], [-2.0, 0.6, -0.2], (n, 1, 3))
    # Boxes near the segments so that both outcomes occur often.
    centres = points[:, :1] + rng.normal(0.0, 0.25, (n, 1, 3))
    axes = body_to_inertial(*rng.uniform(-1.5, 1.5, (3, n)))[:, None]
    half = np.array([[0.19, 0.10, 0.076]])
    hidden = occlusion_mask(points, cams, centres, axes, half)
    expected = np.array([[_brute_hidden(camera_centre(cam), points[i, 0], centres[i, 0], axes[i, 0], half[0])
                          for i in range(n)] for cam in cams])
    assert 0.1 < expected.mean() < 0.9
    np.testing.assert_array_equal(hidden[:, :, 0], expected)


def test_marker_inside_a_box_is_hidden_and_nan_points_are_not(cams):
    pts = np.array([[[-3.0, 0.0, -1.0], [np.nan, np.nan, np.nan]]])
    hidden = occlusion_mask(pts, cams, np.array([[[-3.0, 0.0, -1.0]]]), np.eye(3)[None, None],
                            np.array([[0.1, 0.1, 0.1]]))
    assert hidden[:, 0, 0].all() and not hidden[:, 0, 1].any()


def test_body_boxes_centre_on_the_reference_point(run):
    rig = run.model.rig
    names, centres, axes, half = body_boxes(run.table, rig)
    assert names == [b for b in BODIES if b in rig.bodies]
    b = names.index("bucket")
    spec = rig.bodies["bucket"]
    np.testing.assert_allclose(half[b], np.asarray(spec.size) / 2)
    # A marker's body coordinates about the reference point put it at centre + T p.
    from dragline.simulate import body_marker_positions

    alpha = body_marker_positions(run.table, rig, "bucket")[:, 0]
    np.testing.assert_allclose(centres[:, b] + axes[:, b] @ np.asarray(spec.markers["alpha"]), alpha, atol=1e-12)


def test_views_are_nan_behind_the_camera_off_the_sensor_and_beyond_the_lens_fold():
    cam = Camera("c", (1280, 960), [[850, 0, 639.5], [0, 850, 479.5], [0, 0, 1]], dist=[-0.3, 0, 0, 0, 0])
    r_fold = fov_radius(cam)
    assert r_fold == pytest.approx(1 / np.sqrt(0.9), abs=1e-3)  # 1 + 3 k1 r^2 = 0
    # 59 deg off axis: the polynomial folds the point back onto the sensor.
    folded = np.array([1.65, 0.0, 1.0])
    assert 0 <= project_points(folded, cam)[0] <= 1279
    plain = Camera("p", (1280, 960), cam.K)
    assert fov_radius(plain) == np.inf
    pts = np.array([[[0.1, 0.05, 2.0], [0.1, 0.05, -2.0], [1.0, 0.0, 1.0], folded]])
    views = project_views(pts, [cam, plain])
    np.testing.assert_allclose(views[0, 0, 0], project_points(pts[0, 0], cam))
    np.testing.assert_allclose(views[1, 0, 0], project_points(pts[0, 0], plain))
    # Behind: NaN in both; 45 deg off axis: on the sensor through the strong lens, off it without;
    # folded: NaN through the lens that folds it.
    assert np.isnan(views[:, 0, 1]).all()
    assert np.isfinite(views[0, 0, 2]).all() and np.isnan(views[1, 0, 2]).all()
    assert np.isnan(views[0, 0, 3]).all()


# ---------------------------------------------------------------- error statistics

def test_noise_has_the_configured_spread(run, cams):
    session, truth = synthesize_session(run, cams, seed=1, noise_px=0.5, dropout=0.0, ghost_rate=0.0,
                                        occlusion=False, wand_frames=WAND)
    resid = session.trial - truth["exact"]
    ok = np.isfinite(resid).all(axis=-1)
    # Noise loses only views it pushes off the sensor.
    assert ok.sum() > 0.99 * np.isfinite(truth["exact"]).all(axis=-1).sum()
    r = resid[ok]
    assert r.size > 20000
    assert np.std(r) == pytest.approx(0.5, rel=0.03)
    assert abs(r.mean()) < 0.02
    # The wand take too, against the truth's wand path.
    wand_exact = project_views(truth["wand_points"], cams)
    w = (session.wand - wand_exact)[np.isfinite(session.wand).all(axis=-1)]
    assert np.std(w) == pytest.approx(0.5, rel=0.05)
    # No noise: the views are OpenCV's projections exactly.
    clean, truth0 = synthesize_session(run, cams, seed=1, noise_px=0.0, dropout=0.0, ghost_rate=0.0,
                                       occlusion=False, wand_frames=WAND)
    np.testing.assert_array_equal(clean.trial, truth0["exact"])
    seen = np.isfinite(clean.trial[2, 7]).all(axis=-1)
    assert seen.sum() > 10
    np.testing.assert_allclose(clean.trial[2, 7][seen], project_points(truth0["markers"][7], cams[2])[seen])


def test_dropout_and_ghost_rates_are_as_configured(run, cams):
    session, truth = synthesize_session(run, cams, seed=2, noise_px=0.3, dropout=0.1, ghost_rate=0.05,
                                        wand_frames=WAND)
    visible = np.isfinite(truth["exact"]).all(axis=-1) & ~truth["hidden"]
    seen = np.isfinite(session.trial).all(axis=-1)
    n = visible.sum()
    assert n > 10000
    assert not (seen & ~visible).any()  # nothing appears where the marker cannot be seen
    lost = 1 - seen[visible].mean()
    assert lost == pytest.approx(0.1, abs=4 * np.sqrt(0.1 * 0.9 / n) + 1e-3)
    # Ghosts read from the data alone: a centroid far from the exact view.
    dist = np.linalg.norm(session.trial - truth["exact"], axis=-1)[seen]
    far = dist > 5.0
    assert far.mean() == pytest.approx(0.05, abs=4 * np.sqrt(0.05 * 0.95 / seen.sum()))
    lo, hi = GHOST_OFFSET_PX
    assert dist[far].min() > lo - 2 and dist[far].max() < hi + 2
    np.testing.assert_array_equal(truth["ghosts"][seen], far)
    # The wand take has no ghosts by default, and the L-frame never does.
    wand_dist = np.linalg.norm(session.wand - project_views(truth["wand_points"], cams), axis=-1)
    assert np.nanmax(wand_dist) < 3.0
    lf = np.linalg.norm(session.lframe - project_views(np.broadcast_to(lframe_points(), (1, 4, 3)), cams),
                        axis=-1)
    assert np.nanmax(lf) < 3.0


def test_ghosts_stay_on_the_sensor_and_dropouts_only_remove():
    rng = np.random.default_rng(0)
    det = rng.uniform(0, [1279, 959], (3, 400, 5, 2))
    det[:, :, 0] = [0.0, 0.0]  # corner: every direction but one quadrant leaves the sensor
    det[0, :10] = np.nan
    ghosted, ghosts = add_ghosts(det, 0.5, np.random.default_rng(1), (1280, 960))
    assert not ghosts[0, :10].any()
    assert np.isfinite(ghosted[ghosts]).all()
    assert ((ghosted[ghosts] >= 0) & (ghosted[ghosts] <= [1279, 959])).all()
    d = np.linalg.norm(ghosted - det, axis=-1)[ghosts]
    assert (d >= GHOST_OFFSET_PX[0] - 1e-9).all() and (d <= GHOST_OFFSET_PX[1] + 1e-9).all()
    np.testing.assert_array_equal(ghosted[~ghosts], det[~ghosts])
    dropped_det, dropped = drop_detections(det, 0.3, np.random.default_rng(2))
    assert np.isnan(dropped_det[dropped]).all()
    np.testing.assert_array_equal(dropped_det[~dropped], det[~dropped])
    assert np.isfinite(det[:, 10:]).all()  # inputs untouched


def test_occlusion_in_a_real_run_matches_the_bucket_geometry(run, cams):
    session, truth = synthesize_session(run, cams, seed=0, dropout=0.0, ghost_rate=0.0, wand_frames=WAND)
    hidden = truth["hidden"]
    assert hidden.any(), "the bucket should hide some marker from some camera in the dig"
    assert np.isnan(session.trial[hidden]).all()
    names, centres, axes, half = body_boxes(run.table, run.model.rig)
    c, f, m = np.argwhere(hidden)[:: max(1, hidden.sum() // 25)].T
    for ci, fi, mi in zip(c, f, m):
        point = truth["markers"][fi, mi]
        assert any(_brute_hidden(camera_centre(cams[ci]), point, centres[fi, b], axes[fi, b], half[b])
                   for b in range(len(names)))
    open_view, truth_open = synthesize_session(run, cams, seed=0, dropout=0.0, ghost_rate=0.0, occlusion=False,
                                               wand_frames=WAND)
    assert not truth_open["hidden"].any()
    assert np.isfinite(open_view.trial[hidden]).all()


# ---------------------------------------------------------------- sessions

def test_session_holds_the_lab_record(run, cams):
    session, truth = synthesize_session(run, cams, seed=0, wand_frames=WAND, lframe_frames=50)
    assert session.marker_names == marker_names(run.model.rig)
    assert session.trial.shape == (6, len(run.time), len(session.marker_names), 2)
    assert session.rate_hz == 200.0
    assert session.wand.shape == (6, WAND, 2, 2) and session.lframe.shape == (6, 50, 4, 2)
    assert session.wand_length == WAND_LENGTH
    np.testing.assert_array_equal(session.lframe_points, lframe_points())
    np.testing.assert_allclose(np.linalg.norm(np.diff(truth["wand_points"], axis=1), axis=-1), WAND_LENGTH)
    np.testing.assert_array_equal(session.maneuver["hoist_length"], run.model.maneuver.lengths["hoist"])


def test_same_seed_gives_identical_files_and_another_seed_does_not(run, cams, tmp_path):
    paths = []
    for i, seed in enumerate((4, 4, 5)):
        session, _ = synthesize_session(run, cams, seed=seed, wand_frames=WAND)
        paths.append(write_session_dir(tmp_path / f"s{i}", session, run.model.maneuver))
    data = [open(os.path.join(p, "capture.mcap"), "rb").read() for p in paths]
    assert data[0] == data[1]
    assert data[0] != data[2]
    assert sorted(os.listdir(paths[0])) == [".dragline-output", "capture.mcap", "maneuver.csv"]


def test_physics_changes_the_trial_and_nothing_else(run, run_drag, cams, tmp_path):
    """Same seed, different physics: every record but the trial's centroids is byte-identical."""
    recs = []
    for name, result in (("plain", run), ("drag", run_drag)):
        session, _ = synthesize_session(result, cams, seed=3, wand_frames=WAND)
        folder = write_session_dir(tmp_path / name, session, result.model.maneuver)
        recs.append(_records(session_file(folder)))
        with open(os.path.join(folder, "maneuver.csv")) as fh:
            recs[-1]["maneuver"] = fh.read()
    plain, drag = recs
    assert plain["metadata"] == drag["metadata"]
    assert plain["schemas"] == drag["schemas"] and plain["channels"] == drag["channels"]
    assert plain["maneuver"] == drag["maneuver"]
    for topic in ("/session/info", "/calibration/lframe", "/calibration/wand"):
        assert plain["messages"][topic] == drag["messages"][topic], topic
    assert plain["messages"]["/trial/centroids"] != drag["messages"]["/trial/centroids"]
    info = json.loads(drag["messages"]["/session/info"][0])
    text = json.dumps(info).lower()
    for word in ("aero", "drag_coefficient", "physics", "truth", "mechanism"):
        assert word not in text


def test_metadata_naming_the_physics_is_refused(run, cams, tmp_path):
    session, _ = synthesize_session(run, cams, wand_frames=WAND, metadata={"note": "aero_drag cd=2"})
    with pytest.raises(ValueError, match="physics"):
        write_session_dir(tmp_path / "s", session)
    assert not (tmp_path / "s").exists()
    assert os.listdir(tmp_path) == []  # no temporary directory left behind


def test_session_directory_is_created_complete_or_not_at_all(run, cams, tmp_path):
    target = tmp_path / "session"

    def fill(tmp):
        with open(os.path.join(tmp, "capture.mcap"), "wb") as fh:
            fh.write(b"partial")
        raise RuntimeError("crash while writing")

    with pytest.raises(RuntimeError):
        atomic_directory(target, fill)
    assert os.listdir(tmp_path) == []
    session, _ = synthesize_session(run, cams, wand_frames=WAND)
    write_session_dir(target, session, run.model.maneuver)
    back, report = read_session(target)
    assert report["lost"] == "nothing"
    np.testing.assert_array_equal(back.trial, session.trial)
    with pytest.raises(ValueError, match="not empty"):
        write_session_dir(target, session)
    # Replacing keeps the old directory until the new one is complete.
    with pytest.raises(RuntimeError):
        atomic_directory(target, fill, overwrite=True)
    assert sorted(os.listdir(target)) == [".dragline-output", "capture.mcap", "maneuver.csv"]
    assert sorted(os.listdir(tmp_path)) == ["session"]


def test_a_delayed_camera_sees_the_scene_that_late_and_the_others_do_not(run, cams):
    # Against the run's own record: a camera 5 ms late (one record interval at 200 Hz) sees at frame k what
    # the markers were at frame k - 1, projected by OpenCV; a camera with no delay sees frame k itself.
    from dragline.simulate import marker_positions

    _, markers = marker_positions(run)
    delays = np.zeros(len(cams))
    delays[2] = 0.005
    _, truth = synthesize_session(run, cams, seed=0, wand_frames=0, lframe_frames=0, occlusion=False,
                                  camera_delay_s=delays)
    for c in (0, 2):
        shown = markers[:-1] if c == 2 else markers[1:]
        exact = truth["exact"][c, 1:]
        for m in range(markers.shape[1]):
            seen = np.isfinite(exact[:, m, 0])
            want = project_points(shown[seen, m], cams[c])
            assert np.allclose(exact[seen, m], want, atol=1e-6), (c, m)
    assert truth["settings"]["camera_delay_s"] == delays.tolist()
    with pytest.raises(ValueError, match="one finite delay per camera"):
        synthesize_session(run, cams, wand_frames=0, lframe_frames=0, camera_delay_s=[0.001])


def test_delayed_points_interpolate_between_frames_and_hold_the_first():
    from dragline.lab._synth import delayed_points

    time = np.arange(5) * 0.01
    points = np.zeros((5, 1, 3))
    points[:, 0, 0] = 2.0 * time + 1.0  # linear: interpolation is exact
    late = delayed_points(points, time, 0.0025)
    assert np.allclose(late[1:, 0, 0], 2.0 * (time[1:] - 0.0025) + 1.0)
    assert late[0, 0, 0] == 1.0  # before the take: its first frame
    assert np.array_equal(late[:, 0, 1:], points[:, 0, 1:])
