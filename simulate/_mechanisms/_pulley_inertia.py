"""A sheave's inertia, turning with the rope that slides over it."""

from __future__ import annotations

from ._base import MechanismType, rings


class PulleyInertia(MechanismType):
    name = "pulley_inertia"
    main = "inertia"
    defaults = {"inertia": 1e-4, "radius": 0.05, "pulley": "all"}
    site = "pulley"
    units = {"inertia": "kg m^2", "radius": "m"}
    range = (1e-6, 1e-2)
    # The largest sheaves (a 5 m, several-tonne sheave of a mine hoist) are near 1e5 kg m^2 on a radius of metres.
    limits = {"inertia": 1.0e6, "radius": 100.0}
    doc = ("sheave inertia (kg m^2) about its axle, sheave radius (m); adds inertia / radius^2 "
           "to the rope's slide; plausible 1e-5-1e-3 kg m^2 for this rig's sheaves")

    def apply(self, model, parameters):
        # A sheave of inertia J turning with the rope adds J / r^2 to the mass
        # that must be accelerated when rope slides through the ring.
        for r in rings(model, parameters["pulley"]):
            model.arrays["ring_added_mass"][r] += parameters["inertia"] / parameters["radius"] ** 2
