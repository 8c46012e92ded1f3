"""Internal friction of a bent rope: viscous damping at every joint."""

from __future__ import annotations

from ._base import MechanismType, segments


class RopeBendingDamping(MechanismType):
    name = "rope_bending_damping"
    main = "c"
    defaults = {"c": 0.01, "segments": "default"}
    units = {"c": "N m s/rad"}
    # The range's top is the plausible top: a fit that wants more is some
    # other loss (a hidden sheave bearing damping of 3e-3 was fitted as
    # c = 0.52 and named, when the range ran to 1.0).
    range = (1e-5, 0.1)
    # A 100 mm steel wire rope's bending stiffness is about 1e4 N m^2; a damping that relaxes it in 100 s is 1e6.
    limits = {"c": 1.0e6}
    doc = ("bending damping per joint (N m s/rad) on ropes (segments=ropes, chains, all or a "
           "name); plausible up to 0.1 for this rig's ropes")

    def apply(self, model, parameters):
        # A moment -c omega_rel at every joint (kernel: _joint_impulses).
        # Exponential (viscous) decay signature.
        for s in segments(model, parameters["segments"], "ropes"):
            model.arrays["seg_bend_c"][s] = parameters["c"]
