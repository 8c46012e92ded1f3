"""Coulomb friction in a sheave's bearing, in proportion to the bearing's load: a law at a site only."""

from __future__ import annotations

from ._base import MechanismType, rings


class SheaveBearingFriction(MechanismType):
    name = "sheave_bearing_friction"
    main = "mu"
    defaults = {"mu": 0.005, "ratio": 0.25, "pulley": "all"}
    site = "pulley"
    units = {"mu": "-", "ratio": "-"}
    # The bearing's own coefficient, referred to its pin: a rolling bearing 0.001-0.005, a greased plain
    # bronze bushing 0.05-0.15, a dry or corroded pin up to about 0.3.
    range = (1e-3, 0.3)
    # No dry contact grips beyond mu of a few; a pin is never wider than its sheave.
    limits = {"mu": 10.0, "ratio": 1.0}
    doc = ("Coulomb friction in a sheave's bearing (-), referred to its pin, and the pin's radius over the "
           "sheave's (-): a torque mu r_pin |load| against the sheave's turn, the load the two rope sides' pulls "
           "added as vectors (the sheave's own weight left out); a law at a site only (diagnose --candidates "
           "LAW@SITE or *@*); plausible 0.001 (a rolling bearing) to 0.3 (a dry pin)")
    candidate = False

    def apply(self, model, parameters):
        # The rope turns the sheave without slipping on it, so the bearing's torque mu r_pin |N| is a force
        # mu (r_pin / r) |N| against the rope's slide (kernel: dissipate, stick or slip).
        for r in rings(model, parameters["pulley"]):
            model.arrays["ring_bearing_mu"][r] += parameters["mu"] * parameters["ratio"]
