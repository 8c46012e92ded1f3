"""Quadratic air drag on bodies and ropes."""

from __future__ import annotations

from ._base import MechanismType, bodies


class AeroDrag(MechanismType):
    name = "aero_drag"
    main = "cd"
    defaults = {"cd": 1.0, "air_density": 1.2, "body": "all"}
    site = "body"
    units = {"cd": "-", "air_density": "kg/m^3"}
    range = (0.1, 50.0)
    # No shape drags more than a few times its area (a flat plate 2, a parachute 2.5); no fluid is denser than
    # mercury (13,600 kg/m^3).
    limits = {"cd": 100.0, "air_density": 2.0e4}
    doc = ("quadratic drag coefficient (-); air density (kg/m^3); body = one body's name (that body alone; "
           "several joined by +) or all (every body and rope); plausible 0.5-2 in air (larger values stand in "
           "for a denser fluid)")

    def apply(self, model, parameters):
        # Quadratic drag 0.5 rho cd A |v| v. Bodies: A is the mean face area of
        # the body's box (a tumbling-average frontal area); ropes: the rope's
        # projected width times the length each particle stands for.
        a = model.arrays
        which = parameters["body"]
        for b in bodies(model, which):
            sx, sy, sz = model.rig.bodies[model.body_names[b]].size
            # on top of the drag the rig file gives the body (its drag_area)
            a["body_cda"][b] += parameters["cd"] * (sx * sy + sy * sz + sx * sz) / 3.0
        for s, name in enumerate(model.seg_names if which == "all" else ()):
            a["seg_cda"][s] = parameters["cd"] * model.rig.ropes[name].diameter
        a["air_density"] = parameters["air_density"]
