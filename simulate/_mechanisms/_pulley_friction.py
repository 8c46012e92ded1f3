"""Capstan friction where rope slides through a ring pulley."""

from __future__ import annotations

from ._base import MechanismType, rings


class PulleyFriction(MechanismType):
    name = "pulley_friction"
    main = "mu"
    defaults = {"mu": 0.1, "pulley": "all"}
    site = "pulley"
    units = {"mu": "-"}
    # From a sheave on a rolling bearing (the bearing's friction 0.001-0.005
    # times its bore over the sheave's radius, 0.2-0.3: 0.001 x 0.22 at the
    # least; the benchmarks' truths sit off the fit's grid with 0.22) to a
    # rope dragged through a dry ring.
    range = (2.2e-4, 0.5)
    # No dry contact grips beyond mu of a few (rubber on rubber about 1-4).
    limits = {"mu": 10.0}
    doc = ("ring friction coefficient (-), capstan T_low (e^(mu wrap) - 1) against the rope's "
           "slide (stick or slip); pulley = a ring's name, its rope, or all; plausible 2.2e-4 (a bearing) to 0.5")

    def apply(self, model, parameters):
        # Capstan friction where the rope slides through a ring (kernel:
        # dissipate): up to T_low (e^(mu beta) - 1) against the slide, with
        # stick when the slide would stop within the step.
        for r in rings(model, parameters["pulley"]):
            model.arrays["ring_mu"][r] = parameters["mu"]
