"""Viscous damping in a sheave's bearing: not a diagnosis candidate."""

from __future__ import annotations

from ._base import MechanismType, rings


class SheaveBearingDamping(MechanismType):
    name = "sheave_bearing_damping"
    main = "c"
    defaults = {"c": 1e-3, "radius": 0.05, "pulley": "all"}
    site = "pulley"
    units = {"c": "N m s/rad", "radius": "m"}
    range = (1e-5, 0.05)
    # A bearing whose viscous torque is a meganewton-metre per rad/s would hold any sheave still.
    limits = {"c": 1.0e6, "radius": 100.0}
    doc = ("viscous bearing damping of a sheave (N m s/rad), sheave radius (m): a force c / radius^2 "
           "against the rope's slide; not a diagnosis candidate: the realistic benchmark hides it to "
           "test the diagnosis outside its menu")
    candidate = False

    def apply(self, model, parameters):
        # A sheave turning on a greased bearing resists with a torque c_b omega;
        # with omega = v / r that is a viscous force c_b / r^2 against the slide.
        for r in rings(model, parameters["pulley"]):
            model.arrays["ring_visc"][r] += parameters["c"] / parameters["radius"] ** 2
