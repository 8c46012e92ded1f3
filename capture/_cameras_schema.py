"""The declared schema of ``cameras.json`` (``dragline calibrate`` writes it; users edit it).

Checked when the file is read, before any camera is built: a camera without
``K`` once ended in a KeyError traceback, a negative focal length or a
rotation vector of inf was accepted and every reconstructed cell came out
NaN. pydantic v2 in strict mode, as the other declared inputs
(``docs/schemas.md``).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ._schema_tools import describe_validation_error, fields_markdown, key_text, short_repr

__all__ = ["CamerasFile", "check_cameras_doc", "cameras_markdown"]

CAMERAS_FORMAT = "dragline.cameras/1"
MAX_CAMERAS = 256
MAX_FOCAL_PX = 1e6
MAX_IMAGE_PX = 100_000
# A pinhole's view across its image's larger side: wider than 170 deg is a fish-eye, which this lens model
# (five distortion terms) cannot describe; narrower than 0.5 deg is a telescope, not a motion-capture lens.
# With the image's larger side W (px) they bound the focal length: W / (2 tan(85 deg)) <= f <= W / (2 tan(0.25 deg)).
MAX_VIEW_DEG = 170.0
MIN_VIEW_DEG = 0.5
# A lens model beyond these is not a lens (OpenCV's own fits stay within a few units).
MAX_DISTORTION = 1e3
# A camera further than this from the lab's origin does not film the rig (m).
MAX_DISTANCE_M = 1e4

_Finite = Annotated[float, Field(allow_inf_nan=False)]
_Row3 = Annotated[list[_Finite], Field(min_length=3, max_length=3)]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, frozen=True)


class CameraEntry(_Strict):
    """One calibrated camera (OpenCV pinhole with five distortion terms)."""

    name: str = Field(min_length=1, description="unique among the cameras")
    image_size: list[int] = Field(min_length=2, max_length=2, description="width, height (px)")
    K: list[_Row3] = Field(min_length=3, max_length=3,
                           description="intrinsic matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] (px)")
    dist: list[_Finite] = Field(min_length=5, max_length=5, description="k1, k2, p1, p2, k3")
    rvec: list[_Finite] = Field(min_length=3, max_length=3,
                                description="world-to-camera rotation, Rodrigues vector (rad)")
    tvec: list[_Finite] = Field(min_length=3, max_length=3, description="world-to-camera translation (m)")

    @model_validator(mode="after")
    def _physical(self):
        if not all(0 < v <= MAX_IMAGE_PX for v in self.image_size):
            raise ValueError(f"image_size {list(self.image_size)} must be 1-{MAX_IMAGE_PX} px")
        (fx, _, cx), (k10, fy, cy), bottom = self.K
        if not (0 < fx <= MAX_FOCAL_PX and 0 < fy <= MAX_FOCAL_PX):
            raise ValueError(f"focal lengths fx = {fx:g}, fy = {fy:g} px must be > 0 and <= {MAX_FOCAL_PX:g}")
        side = max(self.image_size)
        low, high = (side / (2 * math.tan(math.radians(v / 2))) for v in (MAX_VIEW_DEG, MIN_VIEW_DEG))
        if not (low <= min(fx, fy) and max(fx, fy) <= high):
            raise ValueError(f"focal lengths fx = {fx:g}, fy = {fy:g} px on a {side} px wide image make a view "
                             f"outside {MIN_VIEW_DEG:g}-{MAX_VIEW_DEG:g} deg (f from {low:.3g} to {high:.3g} px): "
                             "no motion-capture lens")
        if k10 != 0 or list(bottom) != [0, 0, 1]:
            raise ValueError("K's lower rows must be [0, fy, cy] and [0, 0, 1]")
        width, height = self.image_size
        if not (0 <= cx <= width and 0 <= cy <= height):
            raise ValueError(f"principal point ({cx:g}, {cy:g}) px lies outside the {width} x {height} px image: "
                             "a lens's axis meets its own sensor")
        if max(abs(d) for d in self.dist) > MAX_DISTORTION:
            raise ValueError(f"distortion coefficients beyond +-{MAX_DISTORTION:g}")
        if math.hypot(*self.rvec) > 4 * math.pi:
            raise ValueError("rvec is longer than 4 pi rad (a Rodrigues vector's angle is its length)")
        if math.hypot(*self.tvec) > MAX_DISTANCE_M:
            raise ValueError(f"tvec puts the lab's origin more than {MAX_DISTANCE_M:g} m from the camera")
        return self


class CamerasFile(_Strict):
    """A calibrated camera set."""

    format: Literal[CAMERAS_FORMAT] = Field(description="file format and version")
    cameras: list[CameraEntry] = Field(min_length=2, max_length=MAX_CAMERAS,
                                       description="two or more; names unique")
    quality: dict[str, Any] = Field(default_factory=dict, description="the calibration's own summary")

    @model_validator(mode="after")
    def _unique(self):
        names = [c.name for c in self.cameras]
        if len(set(names)) != len(names):
            raise ValueError("camera names must be unique")
        return self


def check_cameras_doc(doc, path):
    """``doc`` (parsed JSON) checked against `CamerasFile`; ValueError with one line naming the file otherwise."""
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: not a dragline cameras file (a JSON object expected)")
    if doc.get("format") != CAMERAS_FORMAT:
        raise ValueError(f"{path}: not a dragline cameras file (format {CAMERAS_FORMAT} expected)")
    try:
        CamerasFile.model_validate(doc)
    except ValidationError as exc:
        where, value, expected = describe_validation_error(exc)
        if exc.errors()[0]["type"] == "value_error" or not where:
            # A camera-level check: say which camera.
            loc = exc.errors()[0]["loc"]
            camera = _camera_label(doc, loc)
            raise ValueError(f"{path}: {camera or 'cameras'}: {expected}") from None
        shown = short_repr(value)
        if exc.errors()[0]["type"] == "missing":
            raise ValueError(f"{path}: {_where(doc, exc)}: expected {expected}") from None
        raise ValueError(f"{path}: {_where(doc, exc)} = {shown}: expected {expected}") from None
    return doc


def _camera_label(doc, loc):
    if len(loc) >= 2 and loc[0] == "cameras" and isinstance(loc[1], int):
        try:
            return f"camera {str(doc['cameras'][loc[1]].get('name', loc[1]))!r}"
        except (AttributeError, IndexError, KeyError, TypeError):
            return f"camera {loc[1]}"
    return None


def _where(doc, exc):
    loc = exc.errors()[0]["loc"]
    camera = _camera_label(doc, loc)
    rest = ".".join(map(key_text, loc[2:] if camera else loc))
    return f"{camera} {rest}" if camera and rest else (camera or rest)


def cameras_markdown():
    """The cameras.json schema as Markdown tables (``docs/schemas.md`` holds this text)."""
    header = ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    top = [r for r in fields_markdown(CamerasFile) if not r.startswith("| `cameras` |")]
    rows = top + ["| `cameras` | list of objects | required | 2 to 256 items | one per camera, below |"]
    return "\n".join(header + rows + [""] + header + fields_markdown(CameraEntry, "cameras[].")) + "\n"
