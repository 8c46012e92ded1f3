"""A rope type softer than its rig-file value and tolerance allow: the file's value is wrong (the other sign of
``rope_stiffness_excess``)."""

from __future__ import annotations

from ._rope_stiffness_excess import LIMITS, RopeStiffnessExcess


class RopeStiffnessDeficit(RopeStiffnessExcess):
    name = "rope_stiffness_deficit"
    main = "deficit"
    defaults = {"deficit": 0.5, "group": "all"}
    units = {"deficit": "-"}
    limits = {"deficit": LIMITS}
    doc = ("static stiffness of a rope type below its rig-file value (-): Ks divided by 1 + deficit; "
           "group = a tolerance group of the rig file, a rope, or all; the rig file's value being wrong (tried "
           "only at its sites)")

    @staticmethod
    def factor(value):
        return 1.0 / (1.0 + value)
