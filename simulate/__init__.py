"""The dragline simulator: the seed paper's lumped-mass dynamic model.

``simulate()`` runs a maneuver from static equilibrium and returns a
``SimulationResult`` whose ``table`` is the trajectory table of docs/conventions.md.
"""

from pathlib import Path as _Path

from ._numba_cache import use_source_keyed_cache as _use_source_keyed_cache

_use_source_keyed_cache(_Path(__file__).parent)  # before any compiled module is imported

from ._kinematics import (
    EULER_SEQUENCES,
    PAPER_SEQUENCE,
    angles_from_matrix,
    body_rates_from_euler_rates,
    body_to_inertial,
    euler_from_matrix,
    euler_rates_from_body_rates,
    matrix_from_angles,
)
from ._markers import body_marker_positions, marker_names, marker_positions
from ._maneuver import Maneuver, default_maneuver, maneuver_from_table, read_maneuver_csv, write_maneuver_csv
from ._dig import dig_maneuver
from ._model import Model, assemble
from ._modes import Modes, body_frequencies, linear_modes
from ._physics import (
    MECHANISMS,
    Mechanism,
    make_mechanism,
    mechanism_names,
    mechanism_sites,
    mechanism_type,
    parse_physics,
    rope_group_sites,
)
from ._release import POSE_COORDINATES, unresolved_coordinates
from ._rig import BUILT_IN_RIGS, DISCRETIZATION_LEVELS, Rig, load_rig, rig_from_dict
from ._simulate import SimulationError, SimulationResult, simulate
from ._sensitivity import Sensitivities, TangentUnavailable, simulate_sensitivities
from ._statics import Equilibrium, StaticsError, solve_statics
from ._time_step import stable_time_step
from ._tolerances import RigParameter, apply_parameters, draw_parameters
from ._table import BODIES, BODY_QUANTITIES, ROPE_CHANNELS, rope_channels, trajectory_columns, write_trajectory_csv
from ._table_schema import MAX_ROWS as MAX_TABLE_ROWS
from ._table_schema import check_trajectory_columns
