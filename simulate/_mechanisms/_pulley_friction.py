"""Capstan friction where rope slides through a ring pulley."""

from __future__ import annotations

from ._base import MechanismType, rings


class PulleyFriction(MechanismType):
    name = "pulley_friction"
    main = "mu"
    defaults = {"mu": 0.1, "pulley": "all"}
    units = {"mu": "-"}
    range = (0.005, 0.5)
    # No dry contact grips beyond mu of a few (rubber on rubber about 1-4).
    limits = {"mu": 10.0}
    doc = ("ring friction coefficient (-), capstan T_low (e^(mu wrap) - 1) against the rope's "
           "slide (stick or slip); pulley = a ring's name, its rope, or all; plausible 0.02-0.3")

    def apply(self, model, parameters):
        # Capstan friction where the rope slides through a ring (kernel:
        # dissipate): up to T_low (e^(mu beta) - 1) against the slide, with
        # stick when the slide would stop within the step.
        for r in rings(model, parameters["pulley"]):
            model.arrays["ring_mu"][r] = parameters["mu"]
