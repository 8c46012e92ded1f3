"""Internal friction of a bent rope: viscous damping at every joint."""

from __future__ import annotations

from ._base import MechanismType, segments


class RopeBendingDamping(MechanismType):
    name = "rope_bending_damping"
    main = "c"
    defaults = {"c": 0.01, "segments": "default"}
    site = "segments"
    site_kind = "ropes"
    units = {"c": "N m s/rad"}
    # The range is what a wire rope's internal friction can plausibly give,
    # not a decision: c = EI tau / l per joint, the bending stiffness EI of
    # a half-inch wire rope between its wires' (0.5 N m^2) and the solid
    # section's (about 250 N m^2; some 25 under load), a relaxation time
    # tau of 0.01-0.05 s and joints l = 0.3-1 m apart: 0.005 to about 4.
    # (It ran to 0.1 after a hidden sheave bearing damping was fitted as
    # c = 0.52 and named: a range edge standing in for a decision.)
    range = (1e-5, 2.0)
    # A 100 mm steel wire rope's bending stiffness is about 1e4 N m^2; a damping that relaxes it in 100 s is 1e6.
    limits = {"c": 1.0e6}
    doc = ("bending damping per joint (N m s/rad) on ropes (segments=ropes, chains, all or a "
           "name); plausible up to about 2 for a half-inch wire rope")

    def apply(self, model, parameters):
        # A moment -c omega_rel at every joint (kernel: _joint_impulses).
        # Exponential (viscous) decay signature.
        for s in segments(model, parameters["segments"], self.site_kind):
            model.arrays["seg_bend_c"][s] = parameters["c"]
