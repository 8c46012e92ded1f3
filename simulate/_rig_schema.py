"""The declared schema of a rig TOML file (``--rig``; the built-in one is ``data/rig.toml``).

Checked when a rig file is read, before the model is built from it: a
rope's ``start = 5`` once ended in an AttributeError traceback, a
``length = inf`` or a negative mass was accepted and produced nonsense, a
discretization row with a zero built a model with fewer states than the
rig has ropes, and a dump rope of 1e-9 m asked the integrator for steps of
femtoseconds. pydantic v2 in strict mode, as the other declared inputs
(``docs/schemas.md``). Cross-references (a rope's ends naming points that
exist, tolerances naming parameters that exist) are checked by the reader
itself, which knows the rig.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ..capture import describe_validation_error, fields_markdown, short_repr

__all__ = ["RigFile", "check_rig_doc", "rig_markdown", "MAX_PARTICLES", "ROPE_KINDS"]

# What a rope can be made of: the mechanisms choose their segments by it
# (bending damping acts on ropes and cables, link friction on chains).
ROPE_KINDS = ("rope", "cable", "chain")
# A rope of more particles than this is a typo, not a discretization (the
# finest built-in level has 16).
MAX_PARTICLES = 500
# Shorter than this, a rope's elements set a time step of nanoseconds.
MIN_ROPE_LENGTH = 1e-3  # m
MAX_COORDINATE = 1e4  # m
# No body a lab films weighs less than a milligram, or turns about its mass centre with a radius of gyration
# under a micrometre (inertia >= mass x 1e-12 m^2); no rope's visco-elastic branch relaxes faster than a
# microsecond (Cv / Kv; the dragline's ropes 0.01 s). Beyond them a fuzzed rig (an inertia or a damping of
# 1e-300) ran the simulation into non-finite numbers.
MIN_MASS = 1e-6  # kg
MIN_GYRATION = 1e-6  # m
MIN_RELAXATION_S = 1e-6
# A release faster than this is a typo: the simulator calls 100 m/s a blow-up.
MAX_SPEED = 100.0  # m/s
MAX_RATE_DEG = 36000.0  # deg/s: a hundred turns a second
# More sheaves than a 64-part reeving has is a typo (the largest offshore hook blocks run about 20 parts).
MAX_RINGS = 64

_Coordinate = Annotated[float, Field(allow_inf_nan=False, ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
_Vec3 = Annotated[list[_Coordinate], Field(min_length=3, max_length=3)]
_Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, frozen=True, extra="forbid")


class Body(_Strict):
    """A rigid body: mass, mass centre, inertia, points and markers (body frame)."""

    mass: float = Field(ge=MIN_MASS, le=1e6, allow_inf_nan=False, description="kg")
    cg_body: _Vec3 = Field(description="mass centre about the body reference point (m)")
    inertia_diag: list[_Positive] = Field(min_length=3, max_length=3, description="Ixx, Iyy, Izz (kg m^2)")
    inertia_offdiag: Optional[list[Annotated[float, Field(allow_inf_nan=False)]]] = Field(
        None, min_length=3, max_length=3, description="Ixy, Ixz, Iyz (kg m^2)")
    size: Optional[list[_Positive]] = Field(None, min_length=3, max_length=3,
                                            description="box about the reference point (m)")
    drag_area: float = Field(0.0, ge=0.0, le=1e3, allow_inf_nan=False,
                             description="quadratic air drag at the mass centre: drag coefficient times area "
                             "(m^2), a force 0.5 rho cd A v^2 against the velocity, in air of 1.2 kg/m^3; 0: none")
    points: dict[str, _Vec3] = Field(default_factory=dict, description="rope attachment points (m)")
    markers: dict[str, _Vec3] = Field(default_factory=dict, description="marker positions (m)")
    position: Optional[_Vec3] = Field(None, description="starting guess for the statics (m, inertial)")
    euler_sequence: Literal["YXZ", "ZYX", "XYZ", "XZY", "YZX", "ZXY"] = Field(
        "YXZ", description="the order of the intrinsic rotations (about the body's I, J, K axes: X, Y, Z) its "
        "output channels roll, pitch and yaw follow; YXZ is the paper's (pitch, roll, yaw), ZYX the aircraft's")

    @model_validator(mode="after")
    def _turns(self):
        least = self.mass * MIN_GYRATION**2
        if min(self.inertia_diag) < least:
            raise ValueError(f"inertia_diag {min(self.inertia_diag):.3g} kg m^2 is below mass x (1 um)^2 = "
                             f"{least:.3g}: no body turns so easily")
        return self


_Name = Annotated[str, Field(min_length=1, max_length=100, pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")]


class Rope(_Strict):
    """A rope, cable or chain segment with its Table 2 properties."""

    kind: Literal[ROPE_KINDS] = Field("rope", description="what it is made of; the mechanisms act by kind")
    start: str = Field(min_length=1, description='"body.point" or "fixed.point"')
    end: str = Field(min_length=1, description='"body.point" or "fixed.point"')
    ring: Optional[str] = Field(None, min_length=1, description="ring pulley it passes through (one ring)")
    ring_name: Optional[_Name] = Field(None, description="the ring's site name (default: its point's name)")
    rings: list[Annotated[str, Field(min_length=1)]] = Field(
        default_factory=list, max_length=MAX_RINGS,
        description="the rings or sheaves it passes through, in order from its start (reeving)")
    ring_names: list[_Name] = Field(default_factory=list, description="their site names, in the same order "
                                                                     "(default: each one's point's name)")
    reel: Optional[_Name] = Field(None, description="the winch paying it out, in files written before "
                                                    "`[winches]`: the same as `[winches.NAME] rope = ...`")
    length: Optional[float] = Field(None, ge=MIN_ROPE_LENGTH, le=1e3, allow_inf_nan=False,
                                    description="unstretched length (m), ropes not on a reel")
    weight_per_length: float = Field(gt=0, le=1e4, allow_inf_nan=False, description="N/m")
    diameter: float = Field(0.01, gt=0, le=1.0, allow_inf_nan=False, description="projected width (m)")
    static_stiffness: float = Field(gt=0, le=1e10, allow_inf_nan=False, description="Ks, N per unit strain")
    viscous_stiffness: float = Field(gt=0, le=1e10, allow_inf_nan=False, description="Kv, N per unit strain")
    viscous_damping: float = Field(gt=0, le=1e8, allow_inf_nan=False, description="Cv, N s per unit strain")
    marker_distances: list[Annotated[float, Field(ge=0, le=1e3, allow_inf_nan=False)]] = Field(
        default_factory=list, description="rope markers, m of rope from the end")
    particles: Optional[int] = Field(None, ge=1, le=MAX_PARTICLES,
                                     description="particles, rigs without a [discretization] table")

    @model_validator(mode="after")
    def _relaxes(self):
        if self.viscous_damping / self.viscous_stiffness < MIN_RELAXATION_S:
            raise ValueError(f"viscous_damping / viscous_stiffness = {self.viscous_damping / self.viscous_stiffness:.3g} s: "
                             f"no rope relaxes faster than {MIN_RELAXATION_S:g} s")
        return self

    @model_validator(mode="after")
    def _one_spelling(self):
        if self.rings and (self.ring is not None or self.ring_name is not None):
            raise ValueError("give `ring` (one ring) or `rings` (several), not both")
        if self.ring_name is not None and self.ring is None:
            raise ValueError("`ring_name` names the rope's `ring`, and it has none")
        if self.ring_names and len(self.ring_names) != len(self.rings):
            raise ValueError(f"`ring_names` has {len(self.ring_names)} names for {len(self.rings)} rings")
        return self


class Winch(_Strict):
    """A winch: it pays out one rope, as the maneuver's `<winch>_length` column says."""

    rope: _Name = Field(description="the rope it pays out; its length is the rope's whole length from its start")


_Counts = Annotated[list[Annotated[int, Field(ge=1, le=MAX_PARTICLES)]], Field(min_length=1)]


class Discretization(_Strict):
    """Table 3: particles per rope (right chains as left) at each level."""

    order: list[str] = Field(min_length=1, description="rope names the rows follow")
    low: _Counts = Field(description=f"particles per rope, 1-{MAX_PARTICLES} each, in `order`")
    baseline: _Counts = Field(description="the same, the simulator's default level")
    medium: _Counts = Field(description="the same")
    high: _Counts = Field(description="the same, the finest level")

    @model_validator(mode="after")
    def _rows(self):
        for level in ("low", "baseline", "medium", "high"):
            row = getattr(self, level)
            if len(row) != len(self.order):
                raise ValueError(f"discretization.{level} has {len(row)} counts for {len(self.order)} ropes")
        return self


class RoughPose(_Strict):
    """A rough hanging pose the statics start from: the bodies as one block, hung and held back by two ropes.

    Without it, each body starts at its ``position``.
    """

    hang: _Name = Field(description="winch rope through a fixed ring; the block hangs from its span below the ring")
    hold: _Name = Field(description="winch rope from a fixed point that holds the block back when taut")
    offsets: dict[str, _Vec3] = Field(min_length=1, description="each body's mass centre from the first one's (m)")


class Release(_Strict):
    """A body held here, the ropes settled under it, then let go (at rest, or moving): the rig's own trial starts
    so."""

    position: _Vec3 = Field(description="mass centre (m, inertial)")
    angles_deg: Optional[list[Annotated[float, Field(ge=-360, le=360, allow_inf_nan=False)]]] = Field(
        None, min_length=3, max_length=3, description="roll, pitch, yaw (deg), the output sequence; default level")
    velocity: Optional[list[Annotated[float, Field(ge=-MAX_SPEED, le=MAX_SPEED, allow_inf_nan=False)]]] = Field(
        None, min_length=3, max_length=3, description="the mass centre's velocity when let go (m/s); default at rest")
    rates_deg: Optional[list[Annotated[float, Field(ge=-MAX_RATE_DEG, le=MAX_RATE_DEG, allow_inf_nan=False)]]] = Field(
        None, min_length=3, max_length=3, description="body rates p, q, r when let go (deg/s); default none")


class Report(_Strict):
    """Which channels the reports single out (the dragline's: the paper's choice); by default all."""

    decay_channels: list[Annotated[str, Field(min_length=1)]] = Field(
        default_factory=list, description="the diagnosis's free-decay table, `<entity>.<quantity>`")
    overlay_channels: list[Annotated[str, Field(min_length=1)]] = Field(
        default_factory=list, description="the reports' measured-against-model pages")
    preset: Optional[Literal["paper"]] = Field(
        None, description="`paper`: the dragline study's comparison (its tolerances, peak table, Figs. 8-21); "
                          "otherwise the comparison is built from the rig's own channels and sizes")


class Demo(_Strict):
    """What `dragline run` films when it is given no recording: a mechanism hidden from the model."""

    physics: Annotated[str, Field(min_length=1)] = Field(
        description="the hidden mechanism, as `--physics` writes it (`aero_drag:cd=1.5`)")
    duration: float = Field(12.0, gt=0, le=600, allow_inf_nan=False, description="seconds filmed")


class RigFile(_Strict):
    """A whole rig."""

    name: Optional[str] = Field(None, description="shown in reports")
    g: float = Field(9.81, gt=0, le=100, allow_inf_nan=False,
                     description="gravity (m/s^2); > 0: weights per length become masses through it")
    bodies: dict[str, Body] = Field(default_factory=dict, description="rigid bodies by name")
    fixed_points: dict[str, _Vec3] = Field(default_factory=dict, description="points fixed in the lab (m)")
    ropes: dict[str, Rope] = Field(min_length=1, description="rope and chain segments by name")
    winches: dict[_Name, Winch] = Field(default_factory=dict, description="winches by name, below")
    discretization: Optional[Discretization] = Field(None, description="Table 3, below")
    maneuver: Optional[str] = Field(None, min_length=1, description="the rig's own maneuver: a CSV beside the file, "
                                                                     "or a built-in generator's name")
    rough_pose: Optional[RoughPose] = Field(None, description="where the statics start, below")
    report: Optional[Report] = Field(None, description="the reports' channels, below")
    demo: Optional[Demo] = Field(None, description="the synthetic trial `dragline run` films, below")
    lab: Literal["built-in", "volume"] = Field("volume", description="the synthetic lab that films it: the "
                                               "built-in one placed for the dig, or six cameras about its markers' volume")
    release: dict[str, Release] = Field(default_factory=dict, description="the rig's own trial starts from a "
                                                                        "release of these bodies, below")
    tolerances: dict[str, Any] = Field(default_factory=dict, description="docs/rig-file.md")
    tolerance_groups: dict[str, list[str]] = Field(default_factory=dict, description="docs/rig-file.md")


def check_rig_doc(doc, source):
    """``doc`` (parsed TOML) checked against `RigFile`; ValueError with one line naming the file otherwise."""

    try:
        RigFile.model_validate(doc)
    except ValidationError as exc:
        where, value, expected = describe_validation_error(exc)
        if exc.errors()[0]["type"] == "value_error" or not where:
            raise ValueError(f"{source}: {where + ': ' if where else ''}{expected}") from None
        shown = short_repr(value)
        if exc.errors()[0]["type"] == "missing":
            raise ValueError(f"{source}: {where}: expected {expected}") from None
        raise ValueError(f"{source}: {where} = {shown}: expected {expected}") from None
    return doc


def rig_markdown():
    """The rig file schema as Markdown tables (``docs/schemas.md`` holds this text)."""

    header = ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    blocks = [header + fields_markdown(RigFile)]
    for model, prefix in ((Body, "bodies.NAME."), (Rope, "ropes.NAME."), (Winch, "winches.NAME."), (Discretization, "discretization."),
                          (RoughPose, "rough_pose."), (Release, "release.BODY."), (Report, "report."), (Demo, "demo.")):
        blocks.append(header + fields_markdown(model, prefix))
    return "\n\n".join("\n".join(b) for b in blocks) + "\n"
