"""A rope type stiffer than its rig-file value and tolerance allow: the file's value is wrong.

Stiffness can be wrong either way, so the law comes in two signs, each with
a positive parameter the diagnosis searches on a log scale: a rope stiffer
than the file says (here: Ks (1 + excess)) and one softer
(``rope_stiffness_deficit``: Ks / (1 + deficit)).
"""

from __future__ import annotations

from ._base import MechanismType, rope_groups

# The updating moves a type's stiffness within its tolerance (15-20 % on the built-in rigs, three tolerances at
# most), so what it cannot reach starts about there: from a twentieth beyond the updated value to ten times (a
# rope's EA is rated within tens of per cent, but a chain's or a rope's bedding-in can halve it and a spliced
# or doubled rope double it).
RANGE = (0.05, 10.0)
# Ten thousand times a rope's rated stiffness either way is a rod or a thread, not that rope.
LIMITS = 1.0e4


class RopeStiffnessExcess(MechanismType):
    name = "rope_stiffness_excess"
    main = "excess"
    defaults = {"excess": 0.5, "group": "all"}
    site = "group"
    units = {"excess": "-"}
    range = RANGE
    limits = {"excess": LIMITS}
    doc = ("static stiffness of a rope type above its rig-file value, as a multiple of it (-): Ks times "
           "1 + excess; group = a tolerance group of the rig file, a rope, or all; the rig file's value being "
           "wrong (tried only at its sites)")
    candidate = False
    rig_array = "seg_ks"
    rig_field = "static_stiffness"

    def apply(self, model, parameters):
        for s in rope_groups(model, parameters["group"], self.rig_field):
            model.arrays[self.rig_array][s] *= self.factor(parameters[self.main])

    @staticmethod
    def factor(value):
        """The rig file's stiffness multiplied by this (-)."""
        return 1.0 + value
