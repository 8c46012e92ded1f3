"""How well a lab knows its rig: one stated tolerance per nominal parameter.

A real rig is never its nominal model: masses are weighed to a few percent,
a rope's static stiffness is measured on a test stand, its material damping
is "matched iteratively", the boom pulley is placed with a tape. The rig
file's ``[tolerances]`` table states, for each parameter a lab knows only
approximately, how far the truth may lie from the nominal value (one
standard deviation of the lab's belief). The diagnosis updates the model
within these tolerances before it blames missing physics
(``docs/diagnosis.md``), and the realistic benchmark draws its truth rigs
from them.

A key names what it moves:

- ``bodies.<body>.mass``, ``bodies.<body>.cg_x`` (or ``cg_y``, ``cg_z``),
  ``bodies.<body>.inertia_x`` (or ``inertia_y``, ``inertia_z``: a principal
  moment, about the body's axis; it multiplies what the mass leaves),
  ``bodies.<body>.drag_area`` (its air drag's cd A, m^2)
- ``bodies.<body>.points.<point>.x`` (or ``y``, ``z``): where a rope is
  attached on a body (body frame), as a tape measures it
- ``ropes.<group>.<property>`` with ``<property>`` one of
  ``static_stiffness``, ``viscous_stiffness``, ``viscous_damping``,
  ``weight_per_length`` or ``length`` (the unstretched length of a rope on
  no winch, m), and
  ``<group>`` a rope name or a group of ``[tolerance_groups]`` (one rope
  or chain type, every segment of it moved together)
- ``fixed_points.<point>.x`` (or ``y``, ``z``)
- ``winches.<winch>.zero`` (or ``reels.<winch>.zero``): an offset (m) added to the maneuver's
  length, as a miscounted drum would give
- ``tracks.<point>.x`` (or ``y``, ``z``): a constant offset (m) of a point's
  measured track, each trial its own - where a rope hangs under a tracked
  origin (a drone's markers) can change from flight to flight

and its value is a table with ``relative`` (a fraction of the nominal
value), ``absolute`` (SI units of the parameter) or ``factor`` (the truth
lies within nominal / factor .. nominal * factor, one standard deviation
being ln(factor) in ln p: for quantities known only to their order).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..capture import key_text

__all__ = ["RigParameter", "parse_tolerances", "apply_parameters", "draw_parameters"]

_ROPE_PROPERTIES = ("static_stiffness", "viscous_stiffness", "viscous_damping", "weight_per_length", "length")
_ROPE_UNITS = {"static_stiffness": "N", "viscous_stiffness": "N", "viscous_damping": "N s", "weight_per_length": "N/m",
               "length": "m"}
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class RigParameter:
    """One nominal parameter a lab knows only approximately.

    Attributes
    ----------
    name : str
        The ``[tolerances]`` key, e.g. ``ropes.chain.viscous_damping``.
    kind : str
        ``mass``, ``cg``, ``inertia``, ``point``, ``rope``, ``fixed_point`` or
        ``reel_zero``; ``start`` for a coordinate of a maneuver's start
        (``field`` ``position.K``, ``angles.K``, ``velocity.K`` or
        ``rates.K``, ``targets`` the body); ``track`` for a point's track
        offset. Those two are each trial's own (``of_a_trial``).
    targets : tuple of str
        The bodies, ropes, fixed points or reels it moves.
    field : str
        The property (``mass``, ``static_stiffness``, ...) or axis.
    nominal : float
        The nominal value (SI).
    scale : str
        ``log`` (the parameter is moved in ln p; ``tolerance`` is the
        standard deviation of ln p) or ``linear`` (``tolerance`` in SI).
    tolerance : float
        One standard deviation of the lab's belief, in the parameter's
        coordinate (ln p or SI).
    unit : str
    trial : str, optional
        The one trial it belongs to (a ``start`` coordinate: where that
        trial's recording began, ``compare.diagnose._start``), None for the
        rig's, which every trial shares.
    """

    name: str
    kind: str
    targets: tuple
    field: str
    nominal: float
    scale: str
    tolerance: float
    unit: str
    trial: str | None = None

    @property
    def of_a_trial(self):
        """Whether each trial has its own value (a start, a track's offset), not one the trials share."""
        return self.kind in ("start", "track")

    def value(self, coordinate):
        """The parameter's SI value at ``coordinate`` (the update's variable, 0 = nominal)."""
        return self.nominal * math.exp(coordinate) if self.scale == "log" else self.nominal + coordinate

    def describe(self, coordinate):
        """One phrase: how far ``coordinate`` moves the parameter from nominal."""
        if self.scale == "log":
            return f"{self.name} {math.exp(coordinate):.2f}x the nominal value"
        return f"{self.name} {coordinate * 1000:+.1f} mm" if self.unit == "m" else f"{self.name} {coordinate:+.3g} {self.unit}"


def parse_tolerances(doc, bodies, ropes, fixed, source="rig", winches=None):
    """The ``[tolerances]`` table of a rig document as ``RigParameter`` objects.

    Parameters
    ----------
    doc : dict
        The rig document (TOML layout).
    bodies, ropes, fixed : dict
        The rig's parsed bodies, ropes and fixed points.
    winches : dict, optional
        Winch name -> the rope it pays out.

    Raises
    ------
    ValueError
        An unknown key, body, rope, group, point or reel, or a tolerance that
        is not one positive finite number.
    """

    groups = {k: tuple(v) for k, v in doc.get("tolerance_groups", {}).items()}
    for g, members in groups.items():
        unknown = [m for m in members if m not in ropes]
        if unknown or not members:
            raise ValueError(f"{source}: tolerance group {g!r} names unknown ropes {unknown}")
    out = []
    for key, spec in doc.get("tolerances", {}).items():
        where = f"{source}: tolerances.{key_text(key)}"
        if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in ("relative", "absolute", "factor"):
            raise ValueError(f"{where}: expected one of relative = ..., absolute = ... or factor = ...")
        (how, amount), = spec.items()
        if isinstance(amount, bool) or not isinstance(amount, (int, float)) or not math.isfinite(amount) or amount <= 0 \
                or (how == "factor" and amount <= 1):
            raise ValueError(f"{where}: {how} must be a positive finite number{' above 1' if how == 'factor' else ''}, "
                             f"got {amount!r}")
        parts = key.split(".")
        if parts[0] == "bodies" and len(parts) == 3 and parts[1] in bodies and parts[2] in ("mass", "cg_x", "cg_y", "cg_z"):
            body = bodies[parts[1]]
            if parts[2] == "mass":
                kind, fld, nominal, unit = "mass", "mass", body.mass, "kg"
            else:
                kind, fld, nominal, unit = "cg", parts[2][-1], float(body.cg_body[_AXES[parts[2][-1]]]), "m"
            targets = (parts[1],)
        elif parts[0] == "bodies" and len(parts) == 3 and parts[1] in bodies and parts[2] == "drag_area":
            kind, fld, nominal, unit = "drag_area", "drag_area", bodies[parts[1]].drag_area, "m^2"
            targets = (parts[1],)
        elif parts[0] == "bodies" and len(parts) == 3 and parts[1] in bodies \
                and parts[2] in ("inertia_x", "inertia_y", "inertia_z"):
            k = _AXES[parts[2][-1]]
            kind, fld, nominal, unit = "inertia", parts[2][-1], float(bodies[parts[1]].inertia[k, k]), "kg m^2"
            targets = (parts[1],)
        elif parts[0] == "bodies" and len(parts) == 5 and parts[1] in bodies and parts[2] == "points" \
                and parts[3] in bodies[parts[1]].points and parts[4] in _AXES:
            kind, fld, unit = "point", f"{parts[3]}.{parts[4]}", "m"
            nominal = float(bodies[parts[1]].points[parts[3]][_AXES[parts[4]]])
            targets = (parts[1],)
        elif parts[0] == "ropes" and len(parts) == 3 and parts[2] in _ROPE_PROPERTIES \
                and (parts[1] in groups or parts[1] in ropes):
            targets = groups.get(parts[1], (parts[1],))
            if parts[2] == "length" and any(ropes[t].winch is not None for t in targets):
                raise ValueError(f"{where}: a rope on a winch takes its length from the maneuver; its tolerance "
                                 "is the winch's zero (winches.NAME.zero)")
            values = {getattr(ropes[t], parts[2]) for t in targets}
            if len(values) != 1:
                raise ValueError(f"{where}: the ropes of group {parts[1]!r} differ in {parts[2]}")
            kind, fld, nominal, unit = "rope", parts[2], float(values.pop()), _ROPE_UNITS[parts[2]]
        elif parts[0] == "fixed_points" and len(parts) == 3 and parts[1] in fixed and parts[2] in _AXES:
            kind, fld, nominal, unit, targets = "fixed_point", parts[2], float(fixed[parts[1]][_AXES[parts[2]]]), "m", (parts[1],)
        elif parts[0] == "tracks" and len(parts) == 3 and parts[1] in fixed and parts[2] in _AXES:
            kind, fld, nominal, unit, targets = "track", parts[2], 0.0, "m", (parts[1],)
        elif parts[0] in ("winches", "reels") and len(parts) == 3 and parts[1] in (winches or {}) \
                and parts[2] == "zero":
            kind, fld, nominal, unit, targets = "reel_zero", "zero", 0.0, "m", (parts[1],)
        else:
            raise ValueError(f"{where}: unknown parameter (see docs/rig-file.md for the keys)")
        if how == "absolute":
            scale, tol = "linear", float(amount)
        else:
            if nominal <= 0:
                raise ValueError(f"{where}: a {how} tolerance needs a positive nominal value, got {nominal!r}")
            scale = "log"
            tol = math.log(1.0 + amount) if how == "relative" else math.log(amount)
        out.append(RigParameter(key, kind, targets, fld, float(nominal), scale, tol, unit))
    return tuple(out)


def apply_parameters(rig, maneuver, parameters, coordinates):
    """A rig and maneuver with parameters moved from nominal.

    Parameters
    ----------
    rig : Rig
    maneuver : Maneuver
    parameters : sequence of RigParameter
    coordinates : sequence of float
        Each parameter's coordinate (ln p - ln p_nominal, or SI offset).

    Returns
    -------
    (Rig, Maneuver)
        New objects; the inputs are not modified. A release (a held pose)
        moves with the fixed points and mass centres (``_release_moved``):
        the lab holds the body where the machine truly hangs.
    """
    from ._maneuver import Maneuver

    bodies, ropes, fixed = dict(rig.bodies), dict(rig.ropes), dict(rig.fixed_points)
    lengths, points = dict(maneuver.lengths), dict(maneuver.points)
    start = maneuver.start
    for p, x in zip(parameters, coordinates):
        x = float(x)
        if x == 0.0:
            continue
        value = p.value(x)
        for t in p.targets:
            if p.kind == "start":
                start = _start_moved(start, t, p.field, value)
            elif p.kind == "track" and t in points:
                points[t] = np.asarray(points[t], float) + value * np.eye(3)[_AXES[p.field]]
            elif p.kind == "track":  # a point the maneuver does not move: the rig's place of it
                xyz = fixed[t].copy()
                xyz[_AXES[p.field]] += value
                fixed[t] = xyz
            elif p.kind == "mass":
                b = bodies[t]
                # Inertia scales with the mass (same shape, denser material).
                bodies[t] = dataclasses.replace(b, mass=value, inertia=b.inertia * (value / p.nominal))
            elif p.kind == "inertia":
                inertia = np.array(bodies[t].inertia, float)
                k = _AXES[p.field]
                inertia[k, k] *= value / p.nominal  # on top of the mass's scaling, in either order
                bodies[t] = dataclasses.replace(bodies[t], inertia=inertia)
            elif p.kind == "point":
                name, axis = p.field.split(".")
                xyz = np.array(bodies[t].points[name], float)
                xyz[_AXES[axis]] = value
                bodies[t] = dataclasses.replace(bodies[t], points=dict(bodies[t].points, **{name: xyz}))
            elif p.kind == "cg":
                cg = bodies[t].cg_body.copy()
                cg[_AXES[p.field]] = value
                bodies[t] = dataclasses.replace(bodies[t], cg_body=cg)
            elif p.kind == "rope":
                ropes[t] = dataclasses.replace(ropes[t], **{p.field: value})
            elif p.kind == "drag_area":
                bodies[t] = dataclasses.replace(bodies[t], drag_area=value)
            elif p.kind == "fixed_point":
                xyz = fixed[t].copy()
                xyz[_AXES[p.field]] = value
                fixed[t] = xyz
            else:
                lengths[t] = lengths[t] + value
    moved = dataclasses.replace(rig, bodies=bodies, ropes=ropes, fixed_points=fixed)
    return _release_moved(rig, moved), Maneuver(maneuver.time, lengths, points, start=start)


def _start_moved(start, body, field, value):
    """A copy of a maneuver's ``start`` with ``body``'s ``field`` (``angles.2``, say) set to ``value``."""
    if not start or body not in start:
        raise ValueError(f"a start coordinate of {body!r} needs the maneuver to start {body!r}")
    key, k = field.split(".")
    pose = dict(start[body])
    pose[key] = np.array(pose[key], float)
    pose[key][int(k)] = value
    return dict(start, **{body: pose})


def draw_parameters(parameters, rng, spread=1.0, limit=2.0):
    """Coordinates drawn from the lab's belief: normal, ``spread`` tolerances wide, cut at ``limit``.

    Returns
    -------
    ndarray (k,)
    """
    z = np.clip(rng.normal(size=len(parameters)), -limit, limit)
    return np.array([spread * p.tolerance * zi for p, zi in zip(parameters, z)])


def _release_moved(rig, drawn):
    """``drawn`` (``rig`` with parameters moved) with its release moved as its fixed points and mass
    centres were.

    A lab lets a body go from where the machine truly hangs: the wire taut
    at the angle it meant, whatever the pivot's true height or where the
    body's mass centre truly sits. Holding the nominal pose under a pivot
    drawn a few millimetres away would leave the wire slack (no static pose
    to start from) or stretched far beyond its weight. Each held body keeps
    its points (its rope's eye) where the nominal hold had them, relative to
    the fixed points' mean shift.
    """
    from ._kinematics import matrix_from_angles

    if not rig.release:
        return drawn
    shift = np.zeros(3)
    if rig.fixed_points:
        shift = np.mean([np.asarray(drawn.fixed_points[k], float) - np.asarray(rig.fixed_points[k], float)
                         for k in rig.fixed_points], axis=0)
    release = {}
    for body, pose in rig.release.items():
        turn = matrix_from_angles(*np.asarray(pose["angles"], float), rig.bodies[body].euler_sequence)
        cg_shift = np.asarray(drawn.bodies[body].cg_body, float) - np.asarray(rig.bodies[body].cg_body, float)
        release[body] = dict(pose, position=np.asarray(pose["position"], float) + shift + turn @ cg_shift)
    return dataclasses.replace(drawn, release=release)
