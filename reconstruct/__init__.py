"""The reconstruction stage: from 2D centroids or 3D markers to body motion.

Plain functions over arrays (time-first, SI units): triangulation, body
frames and mass centres (paper Eqs. 10, 14-16), rope length (Eq. 22),
derivatives and smoothing (section 3.3), and gap filling.
"""

from ._bodies import body_frames_paper, body_frames_svd, body_origin, mass_centre, two_marker_position
from ._gaps import fill_gaps, fill_rigid
from ._rates import (
    RunningAverage,
    SavitzkyGolay,
    Smoother,
    body_rates,
    finite_difference,
    make_smoother,
    running_average,
)
from ._pipeline import fill_markers, reconstruct_markers, reconstruct_marker_file, reconstruct_session, reconstruct_vicon_csv, trajectory_from_markers
from ._ropes import rope_length_cubic
from ._tracked import MIN_SMOOTHED_SAMPLES, TRACK_RATE_HZ, smoothed_track, tracked_trajectory, tracked_within_reach
from ._triangulate import triangulate, undistort_detections
from ._pipeline import METHODS as TRIANGULATION_METHODS
from ._pipeline import SMOOTHINGS as SMOOTHING_METHODS
from ._pipeline import vicon_name
