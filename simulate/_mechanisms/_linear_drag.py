"""Linear (viscous) drag on a body: a force against its mass centre's velocity, in proportion to it."""

from __future__ import annotations

from ._base import MechanismType, bodies


class LinearDrag(MechanismType):
    name = "linear_drag"
    main = "c"
    defaults = {"c": 0.1, "body": "all"}
    site = "body"
    units = {"c": "N s/m"}
    # From air's own drag on the dragline's bucket linearized at its swing speed (0.5 rho cd A |v|: 1.2 kg/m^3,
    # cd 1, 0.03 m^2, 0.5 m/s: about 0.01; the bottom, a tenth of it) to the same bucket moving through water
    # (1000 kg/m^3: about 8; the top, a few times more, for a load swinging in mud or brushing a guide).
    range = (1e-3, 30.0)
    # A meganewton per m/s would hold any body still.
    limits = {"c": 1.0e6}
    doc = ("linear drag (N s/m): a force -c v on a body's mass centre (a generic viscous law: a fluid at low "
           "speed, a damper, a guide); body = a body's name (several joined by +) or all; a law at a site only "
           "(diagnose --candidates linear_drag@* or *@*)")
    candidate = False

    def apply(self, model, parameters):
        for b in bodies(model, parameters["body"]):
            model.arrays["body_lin_drag"][b] = parameters["c"]
