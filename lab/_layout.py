"""The simulated motion-capture lab: six cameras, the L-frame and the wand.

Ground truth for synthetic captures. The layout is chosen for the built-in
1/16-scale rig (inertial frame, K down, so heights are negative z):

- the bucket works over x in [-5.5, -1.0], y in [-0.4, 0.4], z in [-1.6, 0];
- the ropes run from the excavator base (x ~ 0, z ~ -1.5) and from the boom
  pulley (x ~ -5.5, z ~ -4.0) down to the bucket.

Six 1.2 MP cameras (1280 x 960 px) with 7.4 mm lenses (f = 1400 px, a 49 deg
horizontal field): two low (0.5-0.65 m above the floor) beside the
excavator base, looking back along the work area, and four about 4 m up,
1.5-2.5 m to either side of the rig's plane. The poses come from a search
that minimised the Cramer-Rao bound of the trial's marker positions over six
camera poses and the focal length, with this lab's visibility and bucket
occlusion, no camera in the rig's plane: it predicted 0.80 mm RMS at 0.3 px
centroid noise, where a ring of wide-angle (f = 850 px) cameras 3-4 m out
gave 1.59 mm. Every marker-frame of the dig is seen by two cameras or more,
99.6 % by three or more. Shorter lenses see more of the volume from each
camera but resolve it more coarsely; with six 1.2 MP sensors the pixels on
the work area, not the number of views, set the accuracy.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..capture import Camera

__all__ = [
    "IMAGE_SIZE",
    "NOMINAL_FOCAL_PX",
    "WAND_LENGTH",
    "WAND_VOLUME",
    "default_lab_cameras",
    "lab_cameras",
    "lframe_points",
    "wand_motion",
]

IMAGE_SIZE = (1280, 960)
"""Sensor size (width, height) in px: 1.2 MP."""

NOMINAL_FOCAL_PX = 1400.0
"""The lens spec's focal length in px (a 7.4 mm lens on 5.3 um pixels); the
true focal length of each camera differs from it by a few percent."""

WAND_LENGTH = 0.5
"""Distance between the two wand markers (m)."""

WAND_VOLUME = np.array([[-5.4, -0.2], [-0.45, 0.45], [-3.8, -0.05]])
"""Box (m, rows x, y, z as [min, max]) the wand's markers are waved through:
the box that holds the trial's markers, so calibration is tight where the
markers are."""

# Camera centres (m), and a point on each optical axis (m): only the
# direction from the centre matters.
_CENTRES = np.array([
    [0.32, -1.50, -0.65],
    [-1.37, -1.50, -4.00],
    [-5.74, -1.50, -4.00],
    [-6.55, 2.28, -4.00],
    [-2.29, 2.50, -3.71],
    [1.11, 3.09, -0.50],
])
_AIMS = np.array([
    [-2.96, 1.21, -0.65],
    [-2.81, -0.30, -2.02],
    [-3.01, 1.12, -0.42],
    [-2.24, -1.31, -1.13],
    [-3.89, -2.49, 0.43],
    [-4.90, -4.00, -2.22],
])


def _look_at(centre, aim):
    """World-to-camera rotation for a camera at ``centre`` looking at ``aim``.

    The image x axis stays horizontal and the image y axis (down in the
    image) points down in the lab (+K).
    """
    z = aim - centre
    z = z / np.linalg.norm(z)
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def default_lab_cameras(seed=None):
    """The six true cameras of the simulated lab: the fixed layout above, intrinsics as ``lab_cameras`` draws them.

    Parameters
    ----------
    seed : int or None
        Seed for the intrinsics. ``None`` gives the reference lab (the same
        as ``seed=0``), so the default is reproducible.

    Returns
    -------
    cameras : list of Camera
        Named ``cam1`` ... ``cam6``; image size ``IMAGE_SIZE``.
    """
    return lab_cameras(_CENTRES, _AIMS, seed)


def lab_cameras(centres, aims, seed=None):
    """True cameras at ``centres`` looking at ``aims`` (m, one row each), their intrinsics drawn from ``seed``.

    The intrinsics scatter about the nominal lens: focal length within 3 %
    of ``NOMINAL_FOCAL_PX`` (square pixels), principal point within about
    10 px of the image centre, radial distortion ``k1`` in [-0.08, 0.05],
    ``k2`` in [-0.02, 0.02], tangential ``p1, p2`` of order 1e-4, ``k3 = 0``.
    ``None`` is ``seed=0``. Cameras are named ``cam1``, ``cam2``, ...
    """
    rng = np.random.default_rng(0 if seed is None else seed)
    width, height = IMAGE_SIZE
    cameras = []
    for i, (centre, aim) in enumerate(zip(np.asarray(centres, float), np.asarray(aims, float))):
        f = NOMINAL_FOCAL_PX * (1.0 + rng.uniform(-0.03, 0.03))
        cx = (width - 1) / 2 + float(np.clip(rng.normal(0.0, 5.0), -10.0, 10.0))
        cy = (height - 1) / 2 + float(np.clip(rng.normal(0.0, 5.0), -10.0, 10.0))
        k1 = rng.uniform(-0.08, 0.05)
        k2 = rng.uniform(-0.02, 0.02)
        p1, p2 = np.clip(rng.normal(0.0, 2e-4, 2), -5e-4, 5e-4)
        R = _look_at(centre, aim)
        cameras.append(Camera(
            name=f"cam{i + 1}",
            image_size=IMAGE_SIZE,
            K=[[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]],
            dist=[k1, k2, p1, p2, 0.0],
            rvec=cv2.Rodrigues(R)[0].ravel(),
            tvec=-R @ centre,
        ))
    return cameras


# The L-frame's four markers about its corner (m): two on the long arm along +I, one on the short arm along +J.
LFRAME_ARMS = np.array([[0.0, 0.0, 0.0], [0.30, 0.0, 0.0], [0.70, 0.0, 0.0], [0.0, 0.40, 0.0]])


def lframe_points():
    """Inertial positions (m) of the four L-frame markers, shape (4, 3).

    The L-frame lies on the floor (z = 0) in the middle of the bucket's
    work area, where five or six cameras see each marker (calibration needs
    two): marker 0 is the corner, markers 1 and 2 lie on the long arm along
    +I (0.30 m and 0.70 m from the corner, unequal so the arm's direction
    is unambiguous), marker 3 on the short arm along +J (0.40 m). The
    markers define origin and axes; their order is the order of the
    detections in the L-frame take.
    """
    corner = np.array([-3.0, -0.2, 0.0])
    return corner + LFRAME_ARMS


def wand_motion(n_frames, rng, rate_hz=200.0, wand_length=WAND_LENGTH, volume=WAND_VOLUME):
    """A wand waved smoothly through the capture volume.

    The wand's centre follows an incommensurate Lissajous path through
    ``volume`` (``WAND_VOLUME`` by default; periods of a few seconds, like a person walking the
    wand through the lab) with small smooth wobbles; its direction sweeps
    all azimuths and elevations up to about 65 deg, so the calibration sees
    every orientation. Markers never go below the floor.

    Parameters
    ----------
    n_frames : int
    rng : numpy.random.Generator
        Source of the random phases and period jitter.
    rate_hz : float
        Frame rate (Hz); the motion is defined in seconds, so a lower rate
        spreads fewer frames over the same path.
    wand_length : float
        Marker separation (m).
    volume : ndarray (3, 2)
        The box (m, rows x, y, z as [min, max]) the markers stay in.

    Returns
    -------
    markers : ndarray, shape (n_frames, 2, 3)
        Inertial positions (m) of wand markers 0 and 1.
    """
    t = np.arange(int(n_frames)) / float(rate_hz)
    half = wand_length / 2
    volume = np.asarray(volume, float)
    lo, hi = volume[:, 0], volume[:, 1]
    # The centre stays a half-wand inside the box so that both markers do.
    c_lo = lo + np.array([half, half, half])
    c_hi = hi - np.array([half, half, half])
    mid, amp = (c_lo + c_hi) / 2, (c_hi - c_lo) / 2
    periods = np.array([7.3, 2.9, 4.1]) * rng.uniform(0.9, 1.1, 3)
    phases = rng.uniform(0.0, 2 * np.pi, 3)
    wobble = 0.08 * np.sin(2 * np.pi * t[:, None] / np.array([0.83, 1.07, 0.71]) + rng.uniform(0, 2 * np.pi, 3))
    centre = mid + amp * np.sin(2 * np.pi * t[:, None] / periods + phases) * 0.97 + wobble * amp.min()
    centre = np.clip(centre, c_lo, c_hi)

    azimuth = rng.uniform(0, 2 * np.pi) + 2 * np.pi * t / (2.3 * rng.uniform(0.9, 1.1))
    elevation = 1.15 * np.sin(2 * np.pi * t / (1.7 * rng.uniform(0.9, 1.1)) + rng.uniform(0, 2 * np.pi))
    direction = np.stack([
        np.cos(elevation) * np.cos(azimuth),
        np.cos(elevation) * np.sin(azimuth),
        np.sin(elevation),
    ], axis=-1)
    return np.stack([centre - half * direction, centre + half * direction], axis=1)
