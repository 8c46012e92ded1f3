"""The calibrated camera: OpenCV pinhole model with lens distortion.

A camera maps an inertial point X (m) to pixels by the OpenCV convention:
``x_cam = R @ X + t`` with ``R = Rodrigues(rvec)``, then the pinhole ``K``
and the five distortion coefficients ``(k1, k2, p1, p2, k3)``.

``cameras.json`` (written by ``dragline calibrate`` and by ``synth
--truth-out``)::

    {"format": "dragline.cameras/1",
     "cameras": [{"name": "cam1", "image_size": [1280, 960],
                  "K": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]],
                  "dist": [k1, k2, p1, p2, k3],
                  "rvec": [..3..], "tvec": [..3..]}, ...],
     "quality": {...optional calibration summary...}}
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import cv2
import numpy as np

from ._cameras_schema import CAMERAS_FORMAT, check_cameras_doc
from ._strict_json import write_json

__all__ = ["Camera", "project_points", "camera_centre", "save_cameras", "load_cameras"]


@dataclass(frozen=True)
class Camera:
    """One calibrated camera.

    Attributes
    ----------
    name : str
    image_size : tuple of int
        (width, height) in px.
    K : ndarray, shape (3, 3)
        Intrinsic matrix (px).
    dist : ndarray, shape (5,)
        OpenCV distortion ``(k1, k2, p1, p2, k3)``.
    rvec, tvec : ndarray, shape (3,)
        World-to-camera rotation (Rodrigues, rad) and translation (m).
    """

    name: str
    image_size: tuple
    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    rvec: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tvec: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        object.__setattr__(self, "image_size", tuple(int(v) for v in self.image_size))
        object.__setattr__(self, "K", np.array(self.K, float).reshape(3, 3))
        object.__setattr__(self, "dist", np.array(self.dist, float).reshape(5))
        object.__setattr__(self, "rvec", np.array(self.rvec, float).reshape(3))
        object.__setattr__(self, "tvec", np.array(self.tvec, float).reshape(3))

    @property
    def R(self):
        """World-to-camera rotation matrix, shape (3, 3)."""
        return cv2.Rodrigues(self.rvec)[0]

    def to_dict(self):
        return {
            "name": self.name,
            "image_size": list(self.image_size),
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "rvec": self.rvec.tolist(),
            "tvec": self.tvec.tolist(),
        }

    @classmethod
    def from_dict(cls, d):
        return cls(d["name"], d["image_size"], d["K"], d["dist"], d["rvec"], d["tvec"])


def camera_centre(camera):
    """Camera centre in the inertial frame (m), shape (3,)."""
    return -camera.R.T @ camera.tvec


def project_points(points, camera):
    """Project inertial points to pixels with OpenCV (distortion included).

    Parameters
    ----------
    points : array_like, shape (..., 3)
        Inertial positions (m); NaN rows project to NaN.
    camera : Camera

    Returns
    -------
    pixels : ndarray, shape (..., 2)
        Image coordinates (px). Points behind the camera are NaN.
    """
    pts = np.asarray(points, float)
    flat = pts.reshape(-1, 3)
    out = np.full((flat.shape[0], 2), np.nan)
    depth = flat @ camera.R[2] + camera.tvec[2]
    ok = np.isfinite(flat).all(axis=1) & (depth > 1e-6)
    if ok.any():
        px, _ = cv2.projectPoints(flat[ok], camera.rvec, camera.tvec, camera.K, camera.dist)
        out[ok] = px.reshape(-1, 2)
    return out.reshape(pts.shape[:-1] + (2,))


def save_cameras(path, cameras, quality=None):
    """Write ``cameras.json`` atomically (temporary name, then rename)."""
    doc = {"format": CAMERAS_FORMAT, "cameras": [c.to_dict() for c in cameras]}
    if quality is not None:
        doc["quality"] = quality
    write_json(path, doc, indent=2)


def load_cameras(path):
    """Read ``cameras.json``.

    Raises
    ------
    ValueError
        If the file is not a dragline cameras file, or breaks its schema
        (``_cameras_schema``, docs/schemas.md): one line naming the file,
        the camera and the field.
    """
    with open(path, encoding="utf-8") as fh:
        try:
            doc = json.load(fh)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not a JSON cameras file ({exc.msg})") from None
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not a JSON cameras file: not UTF-8 text (byte {exc.start}: "
                             f"0x{exc.object[exc.start]:02x}; JSON is UTF-8)") from None
    check_cameras_doc(doc, path)
    return [Camera.from_dict(c) for c in doc["cameras"]]
