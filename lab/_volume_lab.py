"""A lab placed for any machine: six cameras around the volume its markers sweep.

The built-in lab (``_layout``) was placed for the dragline's dig by a
Cramer-Rao search; another machine works elsewhere and at another scale.
Here the capture volume is the box the trial's markers sweep, grown to
hold the L-frame on the floor below it and made thick enough to wave a
wand through. Six cameras of the built-in lab's kind (1.2 MP, the nominal
7.4 mm lens) stand on a ring about it at the distance where the volume's
bounding sphere fills 80 % of the narrower half field of view, at
azimuths 30 deg off the x-z plane (a planar swing is never seen edge-on)
and alternately 40 and 15 deg up. ``lab_for_rig`` films a rig whose file
says ``lab = "built-in"`` (the dragline's) with the built-in lab, so the
paper's study is filmed as before, and any other about its markers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._layout import (
    IMAGE_SIZE,
    LFRAME_ARMS,
    NOMINAL_FOCAL_PX,
    WAND_LENGTH,
    WAND_VOLUME,
    default_lab_cameras,
    lab_cameras,
    lframe_points,
)

__all__ = ["LabLayout", "lab_for_rig", "volume_lab"]

AZIMUTHS_DEG = (30.0, 90.0, 150.0, 210.0, 270.0, 330.0)
ELEVATIONS_DEG = (40.0, 15.0)
FILL = 0.8
# The box's thinnest side, as a share of its largest: room to wave a wand through a planar swing's volume.
MIN_THICKNESS = 0.4


@dataclass(frozen=True)
class LabLayout:
    """Where the lab's cameras, wand volume and L-frame are (m, inertial, K down)."""

    cameras: list
    wand_volume: np.ndarray  # rows x, y, z as [min, max]
    lframe: np.ndarray  # (4, 3)
    wand_length: float
    kind: str  # "built-in" or "volume"


def volume_lab(box, seed=None):
    """Six cameras, a wand volume and an L-frame for the capture volume ``box`` (rows x, y, z: [min, max], m).

    The L-frame lies on the floor (z = 0) under the box's centre; the box
    is grown to hold it and to be at least ``MIN_THICKNESS`` of its
    largest side in every direction.
    """
    box = np.array(box, float)
    centre = box.mean(axis=1)
    corner = np.array([centre[0] - 0.35, centre[1] - 0.2, 0.0])
    lframe = corner + LFRAME_ARMS
    box[:, 0] = np.minimum(box[:, 0], lframe.min(axis=0))
    box[:, 1] = np.maximum(box[:, 1], lframe.max(axis=0))
    side = box[:, 1] - box[:, 0]
    grow = np.maximum(0.0, MIN_THICKNESS * side.max() - side) / 2
    box[:, 0] -= grow
    box[:, 1] += grow
    box[2, 1] = max(box[2, 1], 0.0)  # the floor
    centre = box.mean(axis=1)
    radius = 0.5 * float(np.linalg.norm(box[:, 1] - box[:, 0]))
    half_fov = math.atan(0.5 * min(IMAGE_SIZE) / NOMINAL_FOCAL_PX)
    distance = radius / math.sin(FILL * half_fov)
    elevations = np.radians([ELEVATIONS_DEG[i % 2] for i in range(len(AZIMUTHS_DEG))])
    azimuths = np.radians(AZIMUTHS_DEG)
    centres = centre + distance * np.column_stack([np.cos(elevations) * np.cos(azimuths),
                                                   np.cos(elevations) * np.sin(azimuths), -np.sin(elevations)])
    cameras = lab_cameras(centres, np.tile(centre, (len(centres), 1)), seed)
    wand_length = min(WAND_LENGTH, 0.5 * float((box[:, 1] - box[:, 0]).min()))
    return LabLayout(cameras=cameras, wand_volume=box, lframe=lframe, wand_length=wand_length, kind="volume")


def lab_for_rig(rig, markers, seed=None):
    """The rig's lab: the built-in one when its file says ``lab = "built-in"``, else ``volume_lab`` about ``markers``.

    Parameters
    ----------
    rig : Rig
    markers : ndarray (frames, markers, 3)
        The trial's true marker positions (m), NaN allowed.
    """
    if rig.lab == "built-in":
        return LabLayout(cameras=default_lab_cameras(seed), wand_volume=WAND_VOLUME.copy(), lframe=lframe_points(),
                         wand_length=WAND_LENGTH, kind="built-in")
    points = np.asarray(markers, float).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    if not points.size:
        raise ValueError("the trial has no marker to place a lab about")
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = 0.1 * float(np.max(hi - lo)) + 0.05
    return volume_lab(np.column_stack([lo - pad, hi + pad]), seed)
