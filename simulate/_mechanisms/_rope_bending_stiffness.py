"""A rope's bending stiffness: a spring at every joint between its elements, a law at a site only."""

from __future__ import annotations

from ._base import MechanismType, segments


class RopeBendingStiffness(MechanismType):
    name = "rope_bending_stiffness"
    main = "share"
    defaults = {"share": 0.05, "segments": "default"}
    site = "segments"
    site_kind = "ropes"
    units = {"share": "-"}
    # A rope's EI as a share of a solid rod's with the rope's own axial stiffness and diameter, EA d^2 / 16 (the
    # radius of gyration of a disc): its wires bending each alone give about (wire / rope diameter)^2, 1/400 for
    # a 6x19 rope and 1/80 for a 7x7 wire, and strands locked under load tend towards the rod. The range runs from
    # a loose rope's wires to the rod, the same on every rig (absolute EI spans a fishing line's 1e-5 N m^2 to a
    # crane rope's 1e4).
    range = (1e-3, 1.0)
    # Ten times the rod: beyond it a rope would bend stiffer than a rod of its own steel.
    limits = {"share": 10.0}
    doc = ("bending stiffness of ropes (segments=ropes, chains, all or a name), as a share of EA d^2 / 16 (a "
           "solid rod's EI with the rope's axial stiffness EA and diameter d): a moment EI / l times the bend at "
           "each joint between a rope's elements (l their mean length), none where a rope meets a body; from "
           "about 0.003 (loose wires) to 1; a law at a site only (diagnose --candidates rope_bending_stiffness@* "
           "or *@*)")
    candidate = False

    def apply(self, model, parameters):
        # EI per rope, not a moment per joint: the joint's EI / l adapts to the discretization, so a finer rope
        # keeps the same elastica energy, the sum of EI theta^2 / 2 l.
        for s in segments(model, parameters["segments"], self.site_kind):
            rope = model.rig.ropes[model.seg_names[s]]
            model.arrays["seg_bend_k"][s] = parameters["share"] * rope.static_stiffness * rope.diameter**2 / 16.0
