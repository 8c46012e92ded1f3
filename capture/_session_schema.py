"""The declared schema of a session's info message (``/session/info`` in ``capture.mcap``).

Checked when a session is read, before any array is sized from it: a hand
edit that drops ``rate_hz`` once ended in a KeyError traceback, and
``markers = 10**9`` asked for 35 TiB. pydantic v2 in strict mode (a string
is not a number; see ``docs/schemas.md``).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ._schema_tools import describe_validation_error, fields_markdown, short_repr

__all__ = ["SessionInfo", "check_session_info", "session_info_markdown"]

SESSION_FORMAT = "dragline.session/1"
MAX_RATE_HZ = 100_000.0
MAX_FRAMES = 10_000_000  # 28 h at 100 Hz
MAX_MARKERS = 1000
MAX_CAMERAS = 256
# Centroid arrays (cameras x frames x markers x 2 doubles) of all takes together.
MAX_CENTROID_BYTES = 2 * 2**30


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, frozen=True)


class Take(_Strict):
    """One take's frame layout."""

    topic: str = Field(description="MCAP topic of its frames")
    frames: int = Field(ge=0, le=MAX_FRAMES, description="frames written")
    markers: int = Field(ge=1, le=MAX_MARKERS, description="markers per frame")
    rate_hz: float = Field(gt=0, le=MAX_RATE_HZ, allow_inf_nan=False, description="Hz")
    start_ns: int = Field(ge=0, description="log time of frame 0 (ns)")


class Takes(_Strict):
    lframe: Take
    wand: Take
    trial: Take


class SessionInfo(_Strict):
    """Rates, names, sizes, calibration constants and maneuver of a session."""

    format: Literal[SESSION_FORMAT] = Field(description="file format and version")
    rate_hz: float = Field(gt=0, le=MAX_RATE_HZ, allow_inf_nan=False, description="trial frame rate (Hz)")
    camera_names: list[str] = Field(min_length=2, max_length=MAX_CAMERAS, description="unique, non-empty")
    image_size: list[int] = Field(min_length=2, max_length=2, description="width, height (px)")
    nominal_focal_px: float = Field(gt=0, le=1e6, allow_inf_nan=False, description="px")
    marker_names: list[str] = Field(min_length=1, max_length=MAX_MARKERS,
                                    description="unique, non-empty; as many as the trial take's markers")
    wand_rate_hz: Optional[float] = Field(None, gt=0, le=MAX_RATE_HZ, allow_inf_nan=False, description="Hz")
    wand_length: Optional[float] = Field(None, gt=0, le=100.0, allow_inf_nan=False,
                                        description="distance between the wand's two markers (m)")
    lframe_points: Optional[list[Annotated[list[Annotated[float, Field(ge=-1000.0, le=1000.0,
                                                                       allow_inf_nan=False)]],
                                           Field(min_length=3, max_length=3)]]] = Field(
        None, min_length=4, max_length=4, description="four L-frame marker positions (m), each coordinate within 1000 m")
    maneuver: dict[str, list[Optional[float]]] = Field(default_factory=dict,
                                                       description="reel table columns (s, m); null is NaN")
    metadata: dict[str, Any] = Field(default_factory=dict, description="the lab's own notes")
    recorded_ns: Optional[int] = Field(None, ge=0, lt=2**63,
                                       description="when the trial's first frame was recorded (ns since the Unix "
                                                   "epoch); null when not known")
    takes: Takes

    @model_validator(mode="after")
    def _sizes(self):
        if any(not name for name in self.camera_names + self.marker_names):
            raise ValueError("camera and marker names must be non-empty")
        if len(set(self.camera_names)) != len(self.camera_names):
            raise ValueError("camera names must be unique")
        if len(set(self.marker_names)) != len(self.marker_names):
            raise ValueError("marker names must be unique")
        if not all(0 < v <= 100_000 for v in self.image_size):
            raise ValueError(f"image_size {list(self.image_size)} must be 1-100000 px")
        if self.takes.trial.markers != len(self.marker_names):
            raise ValueError(f"the trial take has {self.takes.trial.markers} markers per frame but "
                             f"{len(self.marker_names)} marker names")
        need = sum(len(self.camera_names) * t.frames * t.markers * 16
                   for t in (self.takes.lframe, self.takes.wand, self.takes.trial))
        if need > MAX_CENTROID_BYTES:
            raise ValueError(f"its takes would need {need / 2**30:.3g} GiB of centroids, more than the "
                             f"{MAX_CENTROID_BYTES / 2**30:g} GiB allowed")
        return self


def check_session_info(info, path):
    """``info`` checked against `SessionInfo`; ValueError with one line naming the file otherwise."""
    if not isinstance(info, dict):
        raise ValueError(f"{path}: session info is not a JSON object")
    try:
        SessionInfo.model_validate(info)
    except ValidationError as exc:
        where, value, expected = describe_validation_error(exc)
        if not where:  # a whole-document check (sizes, names)
            raise ValueError(f"{path}: session info: {expected}") from None
        shown = short_repr(value)
        if exc.errors()[0]["type"] == "missing":
            raise ValueError(f"{path}: session info {where}: expected {expected}") from None
        raise ValueError(f"{path}: session info {where} = {shown}: expected {expected}") from None
    return info


def session_info_markdown():
    """The session info schema as a Markdown table (``docs/schemas.md`` holds this text)."""
    header = ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    return "\n".join(header + fields_markdown(SessionInfo)) + "\n"
