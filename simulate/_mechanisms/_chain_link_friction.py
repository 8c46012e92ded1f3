"""Coulomb friction between chain links rolling on each other."""

from __future__ import annotations

from ._base import MechanismType, segments


class ChainLinkFriction(MechanismType):
    name = "chain_link_friction"
    main = "mu"
    defaults = {"mu": 0.3, "pin_radius": 0.00475, "segments": "default"}
    site = "segments"
    site_kind = "chains"
    units = {"mu": "-", "pin_radius": "m"}
    range = (0.01, 1.0)
    # No dry contact grips beyond mu of a few (rubber on rubber about 1-4); no link pin is metres thick.
    limits = {"mu": 10.0, "pin_radius": 10.0}
    doc = ("inter-link friction coefficient (-); Coulomb moment mu T pin_radius (m) against "
           "bending at every chain joint (stick or slip); plausible 0.05-0.6 for steel links")

    def apply(self, model, parameters):
        # Links rolling on each other under tension T resist with a Coulomb
        # moment mu T r_pin (kernel: _joint_impulses): the tighter the chain, the
        # more it resists bending. Linear (Coulomb) decay signature.
        for s in segments(model, parameters["segments"], self.site_kind):
            model.arrays["seg_link_mu"][s] = parameters["mu"]
            model.arrays["seg_link_r"][s] = parameters["pin_radius"]
