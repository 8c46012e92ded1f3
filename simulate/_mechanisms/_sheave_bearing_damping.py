"""Viscous damping in a sheave's bearing: a law at a site only, outside the default candidates."""

from __future__ import annotations

from ._base import MechanismType, rings


class SheaveBearingDamping(MechanismType):
    name = "sheave_bearing_damping"
    main = "c"
    defaults = {"c": 1e-3, "radius": 0.05, "pulley": "all"}
    site = "pulley"
    units = {"c": "N m s/rad", "radius": "m"}
    # Petroff's law for a greased plain bearing, T / omega = 2 pi r^3 L mu / clearance: a 5 mm shaft 10 mm
    # long, 0.02 mm clearance, an oil's 0.1 Pa s gives 4e-5, a stiff grease's 10 Pa s 4e-3; the range runs
    # from a ball bearing's less to ten times the stiffest grease (a seal dragging as well).
    range = (1e-5, 0.05)
    # A bearing whose viscous torque is a meganewton-metre per rad/s would hold any sheave still.
    limits = {"c": 1.0e6, "radius": 100.0}
    doc = ("viscous bearing damping of a sheave (N m s/rad), sheave radius (m): a force c / radius^2 "
           "against the rope's slide; a law at a site only (diagnose --candidates LAW@SITE or *@*): the realistic "
           "benchmark hides it everywhere to test the diagnosis outside its default list")
    candidate = False

    def apply(self, model, parameters):
        # A sheave turning on a greased bearing resists with a torque c_b omega;
        # with omega = v / r that is a viscous force c_b / r^2 against the slide.
        for r in rings(model, parameters["pulley"]):
            model.arrays["ring_visc"][r] += parameters["c"] / parameters["radius"] ** 2
