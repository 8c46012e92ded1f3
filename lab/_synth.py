"""Synthetic lab sessions: a simulation filmed by the lab's six cameras.

What the cameras of a real lab would record, made from a simulation and the
true cameras of ``lab.default_lab_cameras``. Each realism stage is a plain
function over arrays, applied in this order by :func:`synthesize_session`:

1. :func:`project_views`: exact pixel views, NaN behind a camera, beyond the
   lens's usable field (where its radial distortion would fold back) or off
   the sensor.
2. :func:`occlusion_mask` over :func:`body_boxes`: a marker is hidden from a
   camera when the segment from the camera centre to the marker passes
   through a body's box (``rig.bodies[b].size`` about the body reference
   point; the bucket is the one that matters).
3. :func:`add_detection_noise`: Gaussian centroid noise (px, per axis); a
   centroid pushed off the sensor is lost.
4. :func:`drop_detections`: each detection lost at random.
5. :func:`add_ghosts`: a detection replaced by a wrong centroid, 10-150 px
   from the true one (a reflection or a neighbouring blob taken for the
   marker), so the slot holds a finite, wrong value.

The lens distortion is that of the true cameras; the session records only
the nominal focal length, so calibration must recover the rest.

Takes: the trial gets every stage. The wand take gets noise and dropouts,
and ghosts only at ``wand_ghost_rate`` (0 by default), but no occlusion (the
rig is out of the volume while the wand is waved): ``calibrate`` reports its
quality as the RMS of every view, which a few ghosts of 100 px would push
past its 3 px sanity limit. The L-frame take gets noise and dropouts only:
it is static, and a calibration reads it as one mean view per marker, which
a stray centroid would corrupt (the lab's operator checks it before the
wand take).

Randomness: one ``numpy.random.SeedSequence(seed)`` spawns an independent
stream per take and stage, so changing one rate (say ``ghost_rate``) leaves
every other stage's draws unchanged, and the same seed gives the same
session bit for bit.
"""

from __future__ import annotations

import os

import numpy as np

from ..capture import CaptureSession, camera_centre, project_points, save_cameras, write_json, write_vicon_csv
from ..simulate import marker_positions, matrix_from_angles, write_trajectory_csv
from ._layout import NOMINAL_FOCAL_PX, WAND_LENGTH, WAND_VOLUME, lframe_points, wand_motion

__all__ = [
    "DEFAULTS",
    "MAX_RATE_HZ",
    "project_views",
    "delayed_points",
    "fov_radius",
    "on_sensor",
    "body_boxes",
    "occlusion_mask",
    "add_detection_noise",
    "drop_detections",
    "add_ghosts",
    "synthesize_session",
    "write_truth",
]

DEFAULTS = {
    "noise_px": 0.3,  # px per axis: a good centroid on a 5 mm marker
    "dropout": 0.01,  # fraction of detections lost at random
    "ghost_rate": 0.002,  # fraction of trial detections replaced by a wrong centroid
    "wand_ghost_rate": 0.0,  # the same in the wand take
    "occlusion": True,
    "wand_frames": 2000,
    "wand_rate_hz": 200.0,
    "lframe_frames": 200,
}
"""Default realism settings of :func:`synthesize_session` and ``dragline synth``."""

MAX_RATE_HZ = 1000.0
"""Fastest frame rate the lab's cameras run at (Hz)."""

GHOST_OFFSET_PX = (10.0, 150.0)
"""Range of a ghost's distance from the true centroid (px)."""

_STAGES = ("noise", "dropout", "ghost")


# ------------------------------------------------------------------ projection

def fov_radius(camera, r_limit=5.0):
    """Largest normalised radius up to which the lens's radial distortion is monotonic.

    Beyond the first zero of d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)] the
    polynomial folds back, and points far outside the field of view would
    land on the sensor; a real lens never shows them.

    Parameters
    ----------
    camera : Camera
    r_limit : float
        Radius (normalised, ``|(x, y)| / z``) searched up to.

    Returns
    -------
    float
        The radius, ``inf`` if the slope stays positive up to ``r_limit``.
    """
    k1, k2, _, _, k3 = camera.dist
    r = np.linspace(0.0, r_limit, 50001)[1:]
    r2 = r * r
    slope = 1 + r2 * (3 * k1 + r2 * (5 * k2 + 7 * k3 * r2))
    bad = slope <= 0
    return float(r[np.argmax(bad)]) if bad.any() else np.inf


def on_sensor(pixels, image_size):
    """Whether centroids lie on the sensor, ``0 <= u <= w - 1`` and ``0 <= v <= h - 1``.

    Parameters
    ----------
    pixels : array_like, shape (..., 2)
        Centroids (px).
    image_size : tuple of int
        (width, height) in px.

    Returns
    -------
    ndarray of bool, shape (...)
        False for NaN centroids.
    """
    px = np.asarray(pixels, float)
    w, h = image_size
    with np.errstate(invalid="ignore"):
        return (px[..., 0] >= 0) & (px[..., 0] <= w - 1) & (px[..., 1] >= 0) & (px[..., 1] <= h - 1)


def project_views(points, cameras):
    """Exact pixel views of 3D points in every camera.

    Parameters
    ----------
    points : array_like, shape (frames, markers, 3)
        Inertial positions (m); NaN rows stay NaN.
    cameras : sequence of Camera

    Returns
    -------
    detections : ndarray, shape (cameras, frames, markers, 2)
        Pixels (px), NaN behind a camera, beyond its :func:`fov_radius` or
        off its sensor.
    """
    pts = np.asarray(points, float)
    out = np.full((len(cameras),) + pts.shape[:-1] + (2,), np.nan)
    for c, cam in enumerate(cameras):
        px = project_points(pts, cam)
        xc = pts @ cam.R.T + cam.tvec
        with np.errstate(invalid="ignore", divide="ignore"):
            radius = np.hypot(xc[..., 0], xc[..., 1]) / xc[..., 2]
            px[~(radius < fov_radius(cam))] = np.nan
        px[~on_sensor(px, cam.image_size)] = np.nan
        out[c] = px
    return out


# ------------------------------------------------------------------ occlusion

def body_boxes(table, rig, bodies=None):
    """Oriented boxes of rig bodies in every frame of a trajectory table.

    A body's box has the size ``rig.bodies[b].size`` (m) and is centred on
    the body reference point, which lies at ``x_cg - T @ cg_body`` (Eq. 10
    with the point 0).

    Parameters
    ----------
    table : pandas.DataFrame
        Trajectory table (docs/conventions.md) with ``<body>.x y z roll pitch yaw``.
    rig : Rig
    bodies : sequence of str, optional
        Bodies to box; by default every rig body the table has a pose for.

    Returns
    -------
    names : list of str
    centres : ndarray, shape (frames, bodies, 3)
        Box centres (m).
    axes : ndarray, shape (frames, bodies, 3, 3)
        ``T_B->I``: columns are the box axes in inertial components.
    half_sizes : ndarray, shape (bodies, 3)
        Half edge lengths along the box axes (m).
    """
    pose = ("x", "y", "z", "roll", "pitch", "yaw")
    if bodies is None:
        bodies = [b for b in rig.bodies if all(f"{b}.{q}" in table.columns for q in pose)]
    names = list(bodies)
    centres, axes = [], []
    for b in names:
        T = matrix_from_angles(*(np.asarray(table[f"{b}.{q}"], float) for q in ("roll", "pitch", "yaw")),
                               rig.bodies[b].euler_sequence)
        x_cg = np.column_stack([np.asarray(table[f"{b}.{q}"], float) for q in "xyz"])
        centres.append(x_cg - T @ np.asarray(rig.bodies[b].cg_body, float))
        axes.append(T)
    n = len(table)
    half = np.array([np.asarray(rig.bodies[b].size, float) / 2 for b in names]).reshape(-1, 3)
    if not names:
        return names, np.zeros((n, 0, 3)), np.zeros((n, 0, 3, 3)), half
    return names, np.stack(centres, axis=1), np.stack(axes, axis=1), half


def occlusion_mask(points, cameras, box_centres, box_axes, box_half_sizes):
    """Which markers each camera cannot see because a box is in the way.

    Slab test of the segment from the camera centre to the marker against
    each oriented box: a marker is hidden when the segment enters a box
    before reaching the marker (a marker inside a box is hidden too).

    Parameters
    ----------
    points : array_like, shape (frames, markers, 3)
        Marker positions (m).
    cameras : sequence of Camera
    box_centres : array_like, shape (frames, boxes, 3)
        Box centres (m).
    box_axes : array_like, shape (frames, boxes, 3, 3)
        Columns are the box axes in inertial components.
    box_half_sizes : array_like, shape (boxes, 3)
        Half edge lengths (m).

    Returns
    -------
    hidden : ndarray of bool, shape (cameras, frames, markers)
        False for NaN points.
    """
    pts = np.asarray(points, float)
    centres = np.asarray(box_centres, float)
    axes = np.asarray(box_axes, float)
    half = np.asarray(box_half_sizes, float)[None, None]  # (1, 1, B, 3)
    hidden = np.zeros((len(cameras),) + pts.shape[:2], bool)
    if centres.shape[1] == 0:
        return hidden
    # Marker positions in each box's frame, (frames, markers, boxes, 3).
    p_loc = np.einsum("nbji,nmj->nmbi", axes, pts) - np.einsum("nbji,nbj->nbi", axes, centres)[:, None]
    for c, cam in enumerate(cameras):
        o_loc = np.einsum("nbji,nbj->nbi", axes, camera_centre(cam) - centres)[:, None]  # (n, 1, B, 3)
        d = p_loc - o_loc
        parallel = d == 0
        with np.errstate(divide="ignore", invalid="ignore"):
            t_a = (-half - o_loc) / d
            t_b = (half - o_loc) / d
        # A segment parallel to a slab is inside it for every t or for none.
        inside = np.abs(o_loc) <= half
        t_near = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(t_a, t_b)).max(axis=-1)
        t_far = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(t_a, t_b)).min(axis=-1)
        with np.errstate(invalid="ignore"):
            hit = (t_near <= t_far) & (t_far > 0) & (t_near < 1)
        hidden[c] = hit.any(axis=-1)
    return hidden


# ------------------------------------------------------------------ detection errors

def add_detection_noise(detections, noise_px, rng):
    """Gaussian centroid noise on every seen detection.

    Parameters
    ----------
    detections : array_like, shape (cameras, frames, markers, 2)
        Centroids (px), NaN where unseen.
    noise_px : float
        Standard deviation per axis (px), >= 0.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, same shape
        A fresh array; NaN stays NaN.
    """
    det = np.asarray(detections, float)
    if not noise_px >= 0:
        raise ValueError(f"noise must be >= 0 px, got {noise_px}")
    return det + rng.normal(0.0, float(noise_px), det.shape)


def _check_rate(name, rate):
    if not 0 <= rate < 1:
        raise ValueError(f"{name} must be a fraction in [0, 1), got {rate}")


def drop_detections(detections, dropout, rng):
    """Lose each seen detection with probability ``dropout``.

    Parameters
    ----------
    detections : array_like, shape (cameras, frames, markers, 2)
    dropout : float
        Probability in [0, 1).
    rng : numpy.random.Generator
        One draw per slot, seen or not, so the pattern does not depend on
        what was seen.

    Returns
    -------
    detections : ndarray, same shape
        A fresh array with the dropped detections NaN.
    dropped : ndarray of bool, shape (cameras, frames, markers)
    """
    det = np.array(detections, float)
    _check_rate("dropout", dropout)
    seen = np.isfinite(det).all(axis=-1)
    dropped = seen & (rng.random(seen.shape) < dropout)
    det[dropped] = np.nan
    return det, dropped


def add_ghosts(detections, ghost_rate, rng, image_size, offset_px=GHOST_OFFSET_PX):
    """Replace seen detections by wrong centroids with probability ``ghost_rate``.

    A ghost lies a random distance in ``offset_px`` from the true centroid in
    a random direction; an axis that would leave the sensor is mirrored
    (``u - du`` instead of ``u + du``), which keeps the distance.

    Parameters
    ----------
    detections : array_like, shape (cameras, frames, markers, 2)
    ghost_rate : float
        Probability in [0, 1).
    rng : numpy.random.Generator
    image_size : tuple of int
        (width, height) in px; the offsets must be shorter than both.
    offset_px : tuple of float
        (smallest, largest) ghost distance (px).

    Returns
    -------
    detections : ndarray, same shape
        A fresh array.
    ghosts : ndarray of bool, shape (cameras, frames, markers)
    """
    det = np.array(detections, float)
    _check_rate("ghost rate", ghost_rate)
    seen = np.isfinite(det).all(axis=-1)
    u = rng.random(seen.shape)
    dist = rng.uniform(offset_px[0], offset_px[1], seen.shape)
    angle = rng.uniform(0.0, 2 * np.pi, seen.shape)
    ghosts = seen & (u < ghost_rate)
    delta = np.stack([dist * np.cos(angle), dist * np.sin(angle)], axis=-1)[ghosts]
    true = det[ghosts]
    moved = true + delta
    limit = np.asarray(image_size, float) - 1
    off = (moved < 0) | (moved > limit)
    det[ghosts] = np.where(off, true - delta, moved)
    return det, ghosts


def delayed_points(points, time, delay):
    """What a camera whose frames show the scene ``delay`` seconds late sees at each frame time.

    ``points`` (frames, markers, 3) at ``time`` (frames,): each frame's
    positions at ``time - delay``, linearly interpolated between frames and
    held at the first frame before the take starts.
    """
    pts = np.asarray(points, float)
    flat = pts.reshape(pts.shape[0], -1)
    t = np.asarray(time, float) - float(delay)
    out = np.column_stack([np.interp(t, time, flat[:, j]) for j in range(flat.shape[1])])
    return out.reshape(pts.shape)


def _observe(points, cameras, rngs, noise_px, dropout, ghost_rate, hidden=None, time=None, delays=None):
    """Run the stages on one take; return (detections, exact views, masks).

    ``delays`` (s, one per camera) with the frames' ``time``: each camera
    sees the take that late (``delayed_points``).
    """
    if delays is None:
        exact = project_views(points, cameras)
    else:
        exact = np.stack([project_views(delayed_points(points, time, d), [cam])[0]
                          for cam, d in zip(cameras, delays)])
    det = exact.copy()
    if hidden is not None:
        det[hidden] = np.nan
    det = add_detection_noise(det, noise_px, rngs["noise"])
    for c, cam in enumerate(cameras):
        det[c][~on_sensor(det[c], cam.image_size)] = np.nan
    det, dropped = drop_detections(det, dropout, rngs["dropout"])
    det, ghosts = add_ghosts(det, ghost_rate, rngs["ghost"], cameras[0].image_size)
    return det, exact, dropped, ghosts


# ------------------------------------------------------------------ sessions

def _rate_of(time):
    dt = np.diff(np.asarray(time, float))
    if dt.size == 0 or not (dt > 0).all():
        raise ValueError("the simulation needs at least two frames at increasing times")
    return float(np.round(1.0 / np.median(dt), 9))


def synthesize_session(result, cameras, seed=0, noise_px=DEFAULTS["noise_px"], dropout=DEFAULTS["dropout"],
                       ghost_rate=DEFAULTS["ghost_rate"], wand_ghost_rate=DEFAULTS["wand_ghost_rate"],
                       occlusion=DEFAULTS["occlusion"],
                       wand_frames=DEFAULTS["wand_frames"], wand_rate_hz=DEFAULTS["wand_rate_hz"],
                       lframe_frames=DEFAULTS["lframe_frames"], metadata=None, recorded_ns=None,
                       wand_volume=WAND_VOLUME, lframe=None, wand_length=WAND_LENGTH, camera_delay_s=None):
    """Film a simulation: the calibration takes and the trial's 2D centroids.

    Parameters
    ----------
    result : SimulationResult
        The lab-truth run; its record times set the trial's frames and rate.
    cameras : sequence of Camera
        True cameras (``default_lab_cameras(seed)``), one image size for all.
    seed : int
        Seeds the wand path and every random stage.
    noise_px : float
        Centroid noise, standard deviation per axis (px).
    dropout : float
        Fraction of detections lost at random.
    ghost_rate : float
        Fraction of trial detections replaced by a wrong centroid.
    wand_ghost_rate : float
        The same for the wand take.
    occlusion : bool
        Hide trial markers behind the rig's body boxes.
    wand_frames : int
        Frames of the wand take (0: no wand take).
    wand_rate_hz : float
        Frame rate of the calibration takes (Hz).
    lframe_frames : int
        Frames of the static L-frame take (0: no L-frame take).
    metadata : dict, optional
        Notes for the session; must not reveal the physics.
    recorded_ns : int, optional
        When the trial's first frame counts as recorded (ns since the Unix
        epoch); None leaves the session undated (and its files seed-exact).
    wand_volume, lframe, wand_length
        Where the wand is waved (m, rows x, y, z as [min, max]), the
        L-frame's four markers (m, (4, 3); ``lframe_points()`` by default)
        and the wand's length (m): the built-in lab's by default, a
        ``LabLayout``'s for another machine.
    camera_delay_s : sequence of float, optional
        Per camera, how late (s) its trial frames show the scene against
        their time stamps: cameras out of sync (a latency the lab did not
        correct). The calibration takes are static or slow and unaffected.

    Returns
    -------
    session : CaptureSession
        What the lab records, nothing more: no physics, no true cameras.
    truth : dict
        ``cameras``, ``marker_names``, ``time`` (frames,), ``markers``
        (frames, markers, 3) m, ``exact`` (cameras, frames, markers, 2) noise-
        free views (NaN where not visible for geometric reasons, occlusion
        aside), ``hidden``, ``dropped``, ``ghosts`` (cameras, frames, markers)
        bool, ``wand_points`` (wand_frames, 2, 3) m, ``wand_ghosts``,
        ``table`` (the trajectory table), ``settings`` (the arguments).
    """
    cameras = list(cameras)
    if not cameras:
        raise ValueError("synthesize_session needs at least one camera")
    if len({c.image_size for c in cameras}) != 1:
        raise ValueError("the cameras must share one image size")
    wand_frames, lframe_frames = int(wand_frames), int(lframe_frames)
    if wand_frames < 0 or lframe_frames < 0:
        raise ValueError("take lengths must be >= 0 frames")
    if not wand_rate_hz > 0:
        raise ValueError(f"wand rate must be positive, got {wand_rate_hz}")
    settings = {"seed": int(seed), "noise_px": float(noise_px), "dropout": float(dropout),
                "ghost_rate": float(ghost_rate), "wand_ghost_rate": float(wand_ghost_rate),
                "occlusion": bool(occlusion),
                "wand_frames": wand_frames, "wand_rate_hz": float(wand_rate_hz),
                "lframe_frames": lframe_frames}
    seq = np.random.SeedSequence(int(seed))
    wand_seq, *take_seqs = seq.spawn(4)
    rngs = {take: dict(zip(_STAGES, (np.random.default_rng(s) for s in ts.spawn(len(_STAGES)))))
            for take, ts in zip(("lframe", "wand", "trial"), take_seqs)}

    table = result.table
    rig = result.model.rig
    names, markers = marker_positions(result)
    hidden = None
    if occlusion:
        _, centres, axes, half = body_boxes(table, rig)
        hidden = occlusion_mask(markers, cameras, centres, axes, half)
    delays = None
    if camera_delay_s is not None:
        delays = np.asarray(camera_delay_s, float).reshape(-1)
        if delays.size != len(cameras) or not np.isfinite(delays).all():
            raise ValueError(f"camera_delay_s needs one finite delay per camera ({len(cameras)})")
        settings["camera_delay_s"] = delays.tolist()
    trial, exact, dropped, ghosts = _observe(markers, cameras, rngs["trial"], noise_px, dropout,
                                             ghost_rate, hidden, time=np.asarray(result.time, float), delays=delays)

    wand_points = wand_motion(wand_frames, np.random.default_rng(wand_seq), rate_hz=wand_rate_hz,
                              wand_length=wand_length, volume=wand_volume)
    wand, _, _, wand_ghosts = _observe(wand_points, cameras, rngs["wand"], noise_px, dropout,
                                      wand_ghost_rate)
    lpts = lframe_points() if lframe is None else np.asarray(lframe, float)
    static = np.broadcast_to(lpts, (lframe_frames, 4, 3))
    lframe, _, _, _ = _observe(static, cameras, rngs["lframe"], noise_px, dropout, 0.0)

    maneuver = result.model.maneuver.to_frame()
    session = CaptureSession(
        rate_hz=_rate_of(result.time),
        camera_names=[c.name for c in cameras],
        image_size=cameras[0].image_size,
        nominal_focal_px=NOMINAL_FOCAL_PX,
        marker_names=list(names),
        trial=trial,
        wand=wand if wand_frames else None,
        wand_rate_hz=float(wand_rate_hz),
        wand_length=float(wand_length) if wand_frames else None,
        lframe=lframe if lframe_frames else None,
        lframe_points=lpts,
        maneuver={col: maneuver[col].to_numpy(float) for col in maneuver.columns},
        metadata=dict(metadata or {}),
        recorded_ns=recorded_ns,
    )
    truth = {"cameras": cameras, "marker_names": list(names), "time": np.asarray(result.time, float),
             "markers": markers, "exact": exact,
             "hidden": np.zeros(exact.shape[:3], bool) if hidden is None else hidden,
             "dropped": dropped, "ghosts": ghosts, "wand_points": wand_points, "wand_ghosts": wand_ghosts,
             "table": table, "settings": settings}
    return session, truth


def write_truth(folder, truth, physics):
    """Write what only the truth knows into an existing folder, file by file atomically.

    Files: ``trajectories.csv`` (the run's trajectory table, docs/conventions.md columns
    first), ``cameras.json`` (the true cameras, ``save_cameras`` format),
    ``physics.json`` (``physics`` plus the capture settings) and
    ``markers.csv`` (true 3D marker positions, VICON Trajectories CSV in mm,
    names ``body:marker``).

    Parameters
    ----------
    folder : str or path-like
    truth : dict
        As returned by :func:`synthesize_session`.
    physics : dict
        JSON-able description of the generating model (mechanisms, rig,
        discretization, maneuver); stored with ``"capture": truth["settings"]``.

    Returns
    -------
    list of str
        The paths written.
    """
    folder = os.fspath(folder)
    paths = [os.path.join(folder, f) for f in ("trajectories.csv", "cameras.json", "physics.json", "markers.csv")]
    write_trajectory_csv(paths[0], truth["table"])
    save_cameras(paths[1], truth["cameras"])
    doc = {"format": "dragline.synth_truth/1", **physics, "capture": truth["settings"]}
    write_json(paths[2], doc, indent=2)
    vicon_names = [n.replace(".", ":", 1) for n in truth["marker_names"]]
    write_vicon_csv(paths[3], vicon_names, truth["markers"], _rate_of(truth["time"]))
    return paths
