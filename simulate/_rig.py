"""The rig description: bodies, rope segments, fixed points, discretization.

One TOML file holds a whole rig (``simulate/data/rig.toml`` is the built-in
1/16-scale dragline). Body points are body-frame coordinates about the body
reference point, like the paper's SL, BL, WL; Eq. 10 subtracts the mass
centre ``cg_body`` from them.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from ._rig_schema import MAX_PARTICLES, check_rig_doc
from ._table import BODIES

__all__ = ["BodySpec", "RopeSpec", "Rig", "load_rig", "rig_from_dict", "DISCRETIZATION_LEVELS"]

DISCRETIZATION_LEVELS = ("low", "baseline", "medium", "high")


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


@dataclass(frozen=True)
class RopeSpec:
    """A rope segment (rope or chain) and its Table 2 properties.

    Stiffness and damping are Table 2's "per metre" values read as those of a
    1 m length: an element of rest length L has k = K * (1 m / L).

    Attributes
    ----------
    start, end : str
        ``"<body>.<point>"`` or ``"fixed.<point>"``.
    ring : str or None
        Ring pulley the rope passes through, same notation.
    reel : str or None
        ``"hoist"`` or ``"drag"`` when the maneuver's reel table sets the
        rope's total unstretched length from ``start``.
    length : float or None
        Unstretched length (m) of a rope not on a reel.
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
    """

    name: str
    start: str
    end: str
    weight_per_length: float
    static_stiffness: float
    viscous_stiffness: float
    viscous_damping: float
    ring: str | None = None
    reel: str | None = None
    length: float | None = None
    marker_distances: tuple = ()
    diameter: float = 0.01


@dataclass(frozen=True)
class Rig:
    """A whole rig. ``bodies`` follow the paper's order (bucket, spreader bar, hoist cluster, drag cluster) (then any others); ``ropes`` the file's."""

    name: str
    g: float
    bodies: dict
    ropes: dict
    fixed_points: dict
    discretization: dict
    source: str = ""
    tolerances: tuple = ()  # RigParameter: what a lab knows only approximately (``_tolerances``)

    def particle_counts(self, discretization="baseline"):
        """Particles per rope segment.

        Parameters
        ----------
        discretization : str or dict
            A level name (low, baseline, medium, high) or a mapping from rope
            name to particle count; ropes not named keep the baseline count.
            ``drag_chain``, ``lower_hoist_chain`` and ``upper_hoist_chain``
            name both sides at once.

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
    """Load a rig TOML file (the built-in rig when ``path`` is None).

    Raises
    ------
    ValueError
        On anything its schema refuses (``_rig_schema``, docs/schemas.md), a
        missing body or an unknown point name: one line naming the file.
    """
    if path is None:
        text = resources.files("dragline.simulate").joinpath("data/rig.toml").read_text()
        source = "built-in rig"
    else:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise ValueError(f"cannot read rig file {path}: {exc.strerror}") from None
        source = str(path)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: not valid TOML ({exc})") from None
    check_rig_doc(doc, source)
    rig = rig_from_dict(doc, source)
    missing = [b for b in BODIES if b not in rig.bodies]
    if missing:
        raise ValueError(f"{source}: a dragline rig needs body {missing[0]!r}")
    return rig


def _rig_from_doc(doc, source):
    bodies = {}
    # the dragline's bodies first, in the paper's order; other rigs may name their own
    doc_bodies = doc.get("bodies", {})
    names = [b for b in BODIES if b in doc_bodies] + [b for b in doc_bodies if b not in BODIES]
    for name in names:
        b = doc_bodies[name]
        inertia = np.diag(_vec(b["inertia_diag"], f"{name}.inertia_diag"))
        if "inertia_offdiag" in b:  # Ixy, Ixz, Iyz (products of inertia, kg m^2)
            ixy, ixz, iyz = _vec(b["inertia_offdiag"], f"{name}.inertia_offdiag")
            inertia[0, 1] = inertia[1, 0] = -ixy
            inertia[0, 2] = inertia[2, 0] = -ixz
            inertia[1, 2] = inertia[2, 1] = -iyz
        if b["mass"] <= 0 or np.any(np.linalg.eigvalsh(inertia) <= 0):
            raise ValueError(f"{source}: body {name!r} needs positive mass and inertia")
        bodies[name] = BodySpec(
            name=name,
            mass=float(b["mass"]),
            cg_body=_vec(b["cg_body"], f"{name}.cg_body"),
            inertia=inertia,
            size=_vec(b.get("size", [0.05, 0.05, 0.05]), f"{name}.size"),
            points={k: _vec(v, f"{name}.points.{k}") for k, v in b.get("points", {}).items()},
            markers={k: _vec(v, f"{name}.markers.{k}") for k, v in b.get("markers", {}).items()},
            position=_vec(b["position"], f"{name}.position") if "position" in b else None,
        )
    fixed = {k: _vec(v, f"fixed_points.{k}") for k, v in doc.get("fixed_points", {}).items()}
    ropes = {}
    for name, r in doc["ropes"].items():
        spec = RopeSpec(
            name=name,
            start=r["start"],
            end=r["end"],
            ring=r.get("ring"),
            reel=r.get("reel"),
            length=r.get("length"),
            weight_per_length=float(r["weight_per_length"]),
            static_stiffness=float(r["static_stiffness"]),
            viscous_stiffness=float(r["viscous_stiffness"]),
            viscous_damping=float(r["viscous_damping"]),
            marker_distances=tuple(float(d) for d in r.get("marker_distances", ())),
            diameter=float(r.get("diameter", 0.01)),
        )
        for ref in (spec.start, spec.end) + ((spec.ring,) if spec.ring else ()):
            _check_ref(ref, bodies, fixed, f"{source}: rope {name!r}")
        if spec.reel not in (None, "hoist", "drag"):
            raise ValueError(f"{source}: rope {name!r}: reel must be 'hoist' or 'drag'")
        if spec.reel is None and not (spec.length and spec.length > 0):
            raise ValueError(f"{source}: rope {name!r} needs a positive length or a reel")
        if min(spec.static_stiffness, spec.viscous_stiffness, spec.viscous_damping) <= 0:
            raise ValueError(f"{source}: rope {name!r} needs positive stiffness and damping")
        ropes[name] = spec
    from ._tolerances import parse_tolerances

    return Rig(
        tolerances=parse_tolerances(doc, bodies, ropes, fixed, source),
        name=doc.get("name", source),
        g=float(doc.get("g", 9.81)),
        bodies=bodies,
        ropes=ropes,
        fixed_points=fixed,
        discretization=_expand_levels(doc["discretization"], list(ropes)) if "discretization" in doc else _single_level(ropes, doc),
        source=source,
    )


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
