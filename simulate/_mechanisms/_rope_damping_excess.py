"""A rope type's material damping above what its rig-file value and tolerance allow: the file's value is wrong."""

from __future__ import annotations

from ._base import MechanismType, rope_groups


class RopeDampingExcess(MechanismType):
    name = "rope_damping_excess"
    main = "excess"
    defaults = {"excess": 1.0, "group": "all"}
    site = "group"
    units = {"excess": "-"}
    # The updating moves a type's damping within its tolerance (a factor of two on the dragline), so what it
    # cannot reach starts about there: from a twentieth of the file's value on top of the updated one to
    # twenty times it (the paper "matched it iteratively": an order of magnitude is not out of reach).
    range = (0.05, 20.0)
    # Ten thousand times a rope's measured damping would make it a dashpot, not a rope.
    limits = {"excess": 1.0e4}
    doc = ("material damping of a rope type above its rig-file value, as a multiple of it (-): the "
           "Maxwell branch's damping times 1 + excess; group = a tolerance group of the rig file, a rope, "
           "or all; not a missing law but the rig file's value being wrong (tried only at its sites)")
    candidate = False
    rig_array = "seg_relax"
    rig_field = "viscous_damping"

    def apply(self, model, parameters):
        # Kelvin-Maxwell rope (kernel): the branch relaxes at Kv / Cv; more damping, slower relaxation.
        for s in rope_groups(model, parameters["group"], self.rig_field):
            model.arrays[self.rig_array][s] /= 1.0 + parameters["excess"]
