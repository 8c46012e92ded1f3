"""The dragline simulator: the seed paper's lumped-mass dynamic model."""

from ._kinematics import (
    body_rates_from_euler_rates,
    body_to_inertial,
    euler_from_matrix,
    euler_rates_from_body_rates,
)
from ._table import BODIES, BODY_QUANTITIES, ROPE_CHANNELS, trajectory_columns
