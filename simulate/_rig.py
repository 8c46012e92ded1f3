"""The rig description: bodies, rope segments, fixed points, discretization.

One TOML file holds a whole rig (``simulate/data/rig.toml`` is the built-in
1/16-scale dragline). Body points are body-frame coordinates about the body
reference point, like the paper's SL, BL, WL; Eq. 10 subtracts the mass
centre ``cg_body`` from them.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from ._kinematics import PAPER_SEQUENCE
from ._rig_schema import MAX_PARTICLES, check_rig_doc

__all__ = ["BodySpec", "RopeSpec", "Rig", "RoughPose", "load_rig", "rig_from_dict", "DISCRETIZATION_LEVELS",
           "BUILT_IN_RIGS"]

DISCRETIZATION_LEVELS = ("low", "baseline", "medium", "high")
# The machines that ship with the tool, by name (``--rig NAME``); the first is the default.
BUILT_IN_RIGS = {"dragline": "data/rig.toml", "pendulum": "data/pendulum.toml", "slung_load": "data/slung_load.toml",
                 "gantry_crane": "data/gantry_crane.toml", "hook_block_crane": "data/hook_block_crane.toml"}


@dataclass(frozen=True)
class BodySpec:
    """A rigid body: mass (kg), mass centre and points (m, body frame), inertia (kg m^2)."""

    name: str
    mass: float
    cg_body: np.ndarray
    inertia: np.ndarray
    size: np.ndarray
    points: dict = field(default_factory=dict)
    markers: dict = field(default_factory=dict)
    position: np.ndarray | None = None  # starting guess for the statics (rigs other than the dragline)
    euler_sequence: str = PAPER_SEQUENCE  # its output channels' rotation order (``_kinematics.EULER_SEQUENCES``)
    drag_area: float = 0.0  # quadratic air drag's cd A (m^2) at the mass centre


@dataclass(frozen=True)
class RopeSpec:
    """A rope segment (rope or chain) and its Table 2 properties.

    Stiffness and damping are Table 2's "per metre" values read as those of a
    1 m length: an element of rest length L has k = K * (1 m / L).

    Attributes
    ----------
    start, end : str
        ``"<body>.<point>"`` or ``"fixed.<point>"``.
    rings : tuple of str
        The ring pulleys or sheaves the rope passes through, in order from
        ``start``, same notation (reeving).
    winch : str or None
        The winch whose maneuver column (``<winch>_length``) sets the
        rope's total unstretched length from ``start``.
    length : float or None
        Unstretched length (m) of a rope on no winch.
    weight_per_length : float
        N/m.
    static_stiffness, viscous_stiffness : float
        Ks, Kv: N per unit strain (N/m for a 1 m length).
    viscous_damping : float
        Cv: N s per unit strain.
    marker_distances : tuple of float
        Rope markers, unstretched m of rope from the ``end``.
    diameter : float
        Projected width per unit length (m), for air drag.
    kind : str
        ``rope``, ``cable`` or ``chain`` (``_rig_schema.ROPE_KINDS``): the
        mechanisms choose their segments by it, never by the name.
    ring_names : tuple of str
        The rings' site names in the same order; empty: each one's point's name.
    """

    name: str
    start: str
    end: str
    weight_per_length: float
    static_stiffness: float
    viscous_stiffness: float
    viscous_damping: float
    rings: tuple = ()
    winch: str | None = None
    length: float | None = None
    marker_distances: tuple = ()
    diameter: float = 0.01
    kind: str = "rope"
    ring_names: tuple = ()

    @property
    def ring_sites(self):
        """Each ring's site name (its ``ring_names`` entry, else its point's name), in order from ``start``."""
        return self.ring_names or tuple(ring.partition(".")[2] for ring in self.rings)


@dataclass(frozen=True)
class RoughPose:
    """The statics' starting pose: the bodies as one block (``offsets`` from the first body's mass centre, m)
    hanging from the span of winch rope ``hang`` below its fixed ring, held back by winch rope ``hold``."""

    hang: str
    hold: str
    offsets: dict


@dataclass(frozen=True)
class Rig:
    """A whole rig: ``bodies``, ``ropes`` and ``winches`` in the file's order.

    ``winches`` maps each winch to the rope it pays out, in the order the
    file declares them (its ``[winches]`` table, after any rope's older
    ``reel`` key); ``maneuver`` names the rig's own maneuver (a CSV path,
    resolved against the file's folder, or a built-in generator's name;
    None: the dig).
    """

    name: str
    g: float
    bodies: dict
    ropes: dict
    fixed_points: dict
    discretization: dict
    source: str = ""
    tolerances: tuple = ()  # RigParameter: what a lab knows only approximately (``_tolerances``)
    winches: dict = field(default_factory=dict)
    maneuver: str | None = None
    rough_pose: RoughPose | None = None
    release: dict | None = None  # body -> {"position", "angles"}: where the rig's own trial lets go
    report: dict = field(default_factory=dict)  # decay_channels, overlay_channels, preset: the reports' choice
    demo: dict | None = None  # {"physics", "duration"}: the trial ``dragline run`` films with no recording
    lab: str = "volume"  # the synthetic lab that films it: "built-in" (the dig's) or "volume" (about its markers)

    @property
    def reach(self):
        """How far the machine reaches (m): the spread of its fixed points (once more for each winch rope,
        which spans among them), every rope's length and every body's size, summed: no part of it, however
        it moves, is further than this from its fixed points."""
        points = np.array(list(self.fixed_points.values()), float).reshape(-1, 3)
        spread = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0
        ropes = sum(spread if r.winch is not None else float(r.length) for r in self.ropes.values())
        return spread + ropes + sum(float(np.max(b.size)) for b in self.bodies.values())

    def particle_counts(self, discretization="baseline"):
        """Particles per rope segment.

        Parameters
        ----------
        discretization : str or dict
            A level name (low, baseline, medium, high) or a mapping from rope
            name to particle count; ropes not named keep the baseline count.
            A name ``X`` also names the ropes ``left_X`` and ``right_X``
            (a pair of sides, as the discretization table's rows do).

        Returns
        -------
        dict
            Rope name -> particle count (>= 1).
        """
        counts = dict(self.discretization["baseline"])
        if isinstance(discretization, str):
            if discretization not in self.discretization:
                raise ValueError(
                    f"unknown discretization {discretization!r} "
                    f"(choose one of {', '.join(self.discretization)})"
                )
            counts = dict(self.discretization[discretization])
        else:
            for name, n in dict(discretization).items():
                targets = [r for r in self.ropes if r in (name, f"left_{name}", f"right_{name}")]
                if not targets:
                    raise ValueError(f"unknown rope {name!r} in discretization")
                if int(n) != n or not 1 <= n <= MAX_PARTICLES:
                    raise ValueError(f"particle count for {name!r} must be an integer from 1 to {MAX_PARTICLES}, "
                                     f"got {n}")
                for t in targets:
                    counts[t] = int(n)
        return counts


def _vec(value, what, n=3):
    arr = np.asarray(value, float)
    if arr.shape != (n,) or not np.isfinite(arr).all():
        raise ValueError(f"{what}: expected {n} finite numbers, got {value!r}")
    return arr


def _expand_levels(table, rope_names):
    order = table["order"]
    levels = {}
    for level in DISCRETIZATION_LEVELS:
        if level not in table:
            raise ValueError(f"discretization level {level!r} missing")
        row = dict(zip(order, table[level]))
        counts = {}
        for rope in rope_names:
            key = rope
            for side in ("left_", "right_"):
                if rope.startswith(side):
                    key = rope[len(side):]
            if key not in row:
                raise ValueError(f"discretization has no count for rope {rope!r}")
            counts[rope] = int(row[key])
        levels[level] = counts
    return levels


def rig_from_dict(doc, source="rig"):
    """Build a rig from a parsed TOML document (a dict of the file's layout)."""
    try:
        return _rig_from_doc(doc, source)
    except KeyError as exc:
        raise ValueError(f"{source}: missing key {exc}") from None
    except ValueError as exc:
        if str(exc).startswith(f"{source}:"):
            raise
        raise ValueError(f"{source}: {exc}") from None


def load_rig(path=None):
    """Load a rig TOML file: a path, a built-in machine's name (``BUILT_IN_RIGS``), or None for the dragline.

    Raises
    ------
    ValueError
        On anything its schema refuses (``_rig_schema``, docs/schemas.md),
        an unknown point, body or winch name: one line naming the file.
    """
    if path is None or str(path) in BUILT_IN_RIGS:
        name = "dragline" if path is None else str(path)
        text = resources.files("dragline.simulate").joinpath(BUILT_IN_RIGS[name]).read_text()
        source, folder = ("built-in rig" if path is None else f"built-in rig {name!r}"), None
    else:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise ValueError(f"cannot read rig file {path}: {exc.strerror}") from None
        except UnicodeDecodeError:
            raise ValueError(f"rig file {path} is not UTF-8 text") from None
        source, folder = str(path), Path(path).parent
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: not valid TOML ({exc})") from None
    check_rig_doc(doc, source)
    rig = rig_from_dict(doc, source)
    if rig.maneuver is not None and rig.maneuver.endswith(".csv"):
        if folder is None:
            located = resources.files("dragline.simulate").joinpath("data", rig.maneuver)
        else:
            located = folder / rig.maneuver
        rig = dataclasses.replace(rig, maneuver=str(located))
    return rig


def _rig_from_doc(doc, source):
    bodies = {name: _body(name, b, source) for name, b in doc.get("bodies", {}).items()}
    fixed = {k: _vec(v, f"fixed_points.{k}") for k, v in doc.get("fixed_points", {}).items()}
    ropes, winches = {}, {}
    for name, r in doc["ropes"].items():
        spec = RopeSpec(
            name=name,
            start=r["start"],
            end=r["end"],
            rings=tuple(r.get("rings", ())) or ((r["ring"],) if r.get("ring") else ()),
            ring_names=tuple(r.get("ring_names", ())) or ((r["ring_name"],) if r.get("ring_name") else ()),
            winch=r.get("reel"),
            length=r.get("length"),
            weight_per_length=float(r["weight_per_length"]),
            static_stiffness=float(r["static_stiffness"]),
            viscous_stiffness=float(r["viscous_stiffness"]),
            viscous_damping=float(r["viscous_damping"]),
            marker_distances=tuple(float(d) for d in r.get("marker_distances", ())),
            diameter=float(r.get("diameter", 0.01)),
            kind=r.get("kind", "rope"),
        )
        for ref in (spec.start, spec.end) + spec.rings:
            _check_ref(ref, bodies, fixed, f"{source}: rope {name!r}")
        if spec.winch is not None:  # a file written before [winches]
            if spec.winch in winches:
                raise ValueError(f"{source}: ropes {winches[spec.winch]!r} and {name!r} both name reel "
                                 f"{spec.winch!r}; a winch pays out one rope")
            winches[spec.winch] = name
        if min(spec.static_stiffness, spec.viscous_stiffness, spec.viscous_damping) <= 0:
            raise ValueError(f"{source}: rope {name!r} needs positive stiffness and damping")
        ropes[name] = spec
    for winch, w in doc.get("winches", {}).items():
        rope = ropes.get(w["rope"])
        if rope is None:
            raise ValueError(f"{source}: winches.{winch}.rope = {w['rope']!r}: no such rope")
        if rope.winch is not None:
            raise ValueError(f"{source}: winches.{winch}.rope = {w['rope']!r}: rope {w['rope']!r} is already paid "
                             f"out by winch {rope.winch!r}")
        winches[winch] = rope.name
        ropes[rope.name] = dataclasses.replace(rope, winch=winch)
    for name, spec in ropes.items():
        if spec.winch is None and not (spec.length and spec.length > 0):
            raise ValueError(f"{source}: rope {name!r} needs a positive length or a winch")
    _check_sites(ropes, source)
    _check_held(bodies, ropes, source)
    from ._tolerances import parse_tolerances

    return Rig(
        tolerances=parse_tolerances(doc, bodies, ropes, fixed, source, winches),
        name=doc.get("name", source),
        g=float(doc.get("g", 9.81)),
        bodies=bodies,
        ropes=ropes,
        fixed_points=fixed,
        discretization=_expand_levels(doc["discretization"], list(ropes)) if "discretization" in doc else _single_level(ropes, doc),
        source=source,
        winches=winches,
        maneuver=doc.get("maneuver"),
        rough_pose=_rough_pose(doc.get("rough_pose"), bodies, ropes, source),
        release=_release(doc.get("release"), bodies, source),
        report={k: v if isinstance(v, str) else tuple(v) for k, v in doc.get("report", {}).items() if v is not None},
        demo=_demo(doc.get("demo"), source),
        lab=doc.get("lab", "volume"),
    )


def _body(name, b, source):
    inertia = np.diag(_vec(b["inertia_diag"], f"{name}.inertia_diag"))
    if "inertia_offdiag" in b:  # Ixy, Ixz, Iyz (products of inertia, kg m^2)
        ixy, ixz, iyz = _vec(b["inertia_offdiag"], f"{name}.inertia_offdiag")
        inertia[0, 1] = inertia[1, 0] = -ixy
        inertia[0, 2] = inertia[2, 0] = -ixz
        inertia[1, 2] = inertia[2, 1] = -iyz
    if b["mass"] <= 0 or np.any(np.linalg.eigvalsh(inertia) <= 0):
        raise ValueError(f"{source}: body {name!r} needs positive mass and inertia")
    return BodySpec(
        name=name,
        mass=float(b["mass"]),
        cg_body=_vec(b["cg_body"], f"{name}.cg_body"),
        inertia=inertia,
        size=_vec(b.get("size", [0.05, 0.05, 0.05]), f"{name}.size"),
        points={k: _vec(v, f"{name}.points.{k}") for k, v in b.get("points", {}).items()},
        markers={k: _vec(v, f"{name}.markers.{k}") for k, v in b.get("markers", {}).items()},
        position=_vec(b["position"], f"{name}.position") if "position" in b else None,
        euler_sequence=b.get("euler_sequence", PAPER_SEQUENCE),
        drag_area=float(b.get("drag_area", 0.0)),
    )


def _check_sites(ropes, source):
    """Ring site names are unique, and never the name of a rope (a mechanism's ``pulley`` takes either)."""
    seen = {}
    for name, spec in ropes.items():
        for site, ring in zip(spec.ring_sites, spec.rings):
            if site in seen and seen[site] != ring:
                raise ValueError(f"{source}: ring name {site!r} of rope {name!r} names another ring too")
            if site in ropes and site != name:
                raise ValueError(f"{source}: ring name {site!r} of rope {name!r} is also a rope's name")
            seen[site] = ring
        if len(set(spec.rings)) < len(spec.rings):
            raise ValueError(f"{source}: rope {name!r} passes the same ring twice")


def _check_held(bodies, ropes, source):
    """Every body hangs from a rope: one that nothing holds falls forever."""
    held = {ref.partition(".")[0] for spec in ropes.values() for ref in (spec.start, spec.end) + spec.rings}
    for name in bodies:
        if name not in held:
            raise ValueError(f"{source}: body {name!r} is held by no rope")


def _demo(table, source):
    """The demo trial's table, its hidden mechanism checked as ``--physics`` checks one."""
    if not table:
        return None
    from ._physics import parse_physics

    try:
        parse_physics(table["physics"])
    except ValueError as exc:
        raise ValueError(f"{source}: demo.physics: {exc}") from None
    return {"physics": table["physics"], "duration": float(table.get("duration", 12.0))}


def _release(table, bodies, source):
    if not table:
        return None
    out = {}
    for name, pose in table.items():
        if name not in bodies:
            raise ValueError(f"{source}: release.{name}: no such body")
        out[name] = {"position": _vec(pose["position"], f"release.{name}.position"),
                     "angles": np.radians(_vec(pose.get("angles_deg", [0.0, 0.0, 0.0]), f"release.{name}.angles_deg")),
                     "velocity": _vec(pose.get("velocity", [0.0, 0.0, 0.0]), f"release.{name}.velocity"),
                     "rates": np.radians(_vec(pose.get("rates_deg", [0.0, 0.0, 0.0]), f"release.{name}.rates_deg"))}
    return out


def _rough_pose(table, bodies, ropes, source):
    if table is None:
        return None
    for key in ("hang", "hold"):
        rope = ropes.get(table[key])
        if rope is None or rope.winch is None or not rope.start.startswith("fixed."):
            raise ValueError(f"{source}: rough_pose.{key} = {table[key]!r}: expected a rope on a winch from a "
                             "fixed point")
    hang_rings = ropes[table["hang"]].rings
    if len(hang_rings) != 1 or not hang_rings[0].startswith("fixed."):
        raise ValueError(f"{source}: rough_pose.hang = {table['hang']!r}: expected a rope through one fixed ring")
    offsets = {}
    for name, off in table["offsets"].items():
        if name not in bodies:
            raise ValueError(f"{source}: rough_pose.offsets names no body {name!r}")
        offsets[name] = _vec(off, f"rough_pose.offsets.{name}")
    for key in ("hang", "hold"):
        owner = ropes[table[key]].end.partition(".")[0]
        if owner not in offsets:
            raise ValueError(f"{source}: rough_pose.offsets lacks body {owner!r}, which rope {table[key]!r} holds")
    return RoughPose(hang=table["hang"], hold=table["hold"], offsets=offsets)


def _single_level(ropes, doc):
    """Rigs without a Table 3: every level uses each rope's own ``particles``."""
    counts = {name: int(doc["ropes"][name].get("particles", 1)) for name in ropes}
    return {level: dict(counts) for level in DISCRETIZATION_LEVELS}


def _check_ref(ref, bodies, fixed, where):
    owner, _, point = ref.partition(".")
    if owner == "fixed":
        if point not in fixed:
            raise ValueError(f"{where}: unknown fixed point {point!r}")
    elif owner in bodies:
        if point not in bodies[owner].points:
            raise ValueError(f"{where}: body {owner!r} has no point {point!r}")
    else:
        raise ValueError(f"{where}: unknown end {ref!r}")
