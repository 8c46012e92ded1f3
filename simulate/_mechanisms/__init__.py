"""Optional physics mechanisms: one module each, one interface (``MechanismType``), one registry.

A new mechanism is a ``MechanismType`` subclass in a module of its own,
added to ``MECHANISMS`` below; the kernel coefficients it sets must exist in
``simulate._model`` (zero in the nominal model).
"""

from ._aero_drag import AeroDrag
from ._base import MechanismType
from ._chain_link_friction import ChainLinkFriction
from ._linear_drag import LinearDrag
from ._pulley_friction import PulleyFriction
from ._pulley_inertia import PulleyInertia
from ._rope_bending_damping import RopeBendingDamping
from ._rope_bending_stiffness import RopeBendingStiffness
from ._rope_damping_excess import RopeDampingExcess
from ._rope_stiffness_deficit import RopeStiffnessDeficit
from ._rope_stiffness_excess import RopeStiffnessExcess
from ._sheave_bearing_damping import SheaveBearingDamping
from ._sheave_bearing_friction import SheaveBearingFriction

__all__ = ["MECHANISMS", "MechanismType"]

MECHANISMS = {kind.name: kind for kind in (ChainLinkFriction(), LinearDrag(), PulleyFriction(), PulleyInertia(),
                                           RopeBendingDamping(), RopeBendingStiffness(), RopeDampingExcess(),
                                           RopeStiffnessExcess(), RopeStiffnessDeficit(), SheaveBearingDamping(),
                                           SheaveBearingFriction(), AeroDrag())}
