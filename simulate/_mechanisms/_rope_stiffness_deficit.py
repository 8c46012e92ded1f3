"""A rope type softer than its rig-file value and tolerance allow: the file's value is wrong (the other sign of
``rope_stiffness_excess``)."""

from __future__ import annotations

from ._base import MechanismType, rope_groups
from ._rope_stiffness_excess import LIMITS, RANGE


class RopeStiffnessDeficit(MechanismType):
    name = "rope_stiffness_deficit"
    main = "deficit"
    defaults = {"deficit": 0.5, "group": "all"}
    site = "group"
    units = {"deficit": "-"}
    range = RANGE
    limits = {"deficit": LIMITS}
    doc = ("static stiffness of a rope type below its rig-file value (-): Ks divided by 1 + deficit; "
           "group = a tolerance group of the rig file, a rope, or all; the rig file's value being wrong (tried "
           "only at its sites)")
    candidate = False
    rig_array = "seg_ks"
    rig_field = "static_stiffness"

    def apply(self, model, parameters):
        for s in rope_groups(model, parameters["group"], self.rig_field):
            model.arrays[self.rig_array][s] /= 1.0 + parameters["deficit"]
