"""Capture: six calibrated cameras, synthetic lab sessions, wand calibration, files.

- cameras: ``Camera``, ``project_points``, ``camera_centre``, ``save_cameras``, ``load_cameras``
- synthetic sessions: ``synthesize_session``, ``write_truth`` (and the stages:
  ``project_views``, ``occlusion_mask``, ``body_boxes``)
- calibration: ``calibrate``
- files: VICON-style CSV (``read_vicon_csv``, ``marker_trajectories``,
  ``write_vicon_csv``, ``summarize_vicon_csv``) and MCAP (``CaptureSession``,
  ``write_session``, ``read_session``, ``write_results``, ``summarize_mcap``)
- session folders: ``session_file``, ``write_session_dir``, ``atomic_directory``,
  ``check_directory_target``, ``mark_output`` (``OUTPUT_MARKER``: the file
  that lets ``--force`` replace a folder dragline wrote)
"""

from ._calibration import calibrate
from ._cameras import Camera, camera_centre, load_cameras, project_points, save_cameras
from ._foxglove import write_results
from ._mcap_io import CaptureSession, read_session, summarize_mcap, write_session
from ._session_io import (
    OUTPUT_MARKER,
    SESSION_FILES,
    atomic_directory,
    check_directory_target,
    mark_output,
    session_file,
    write_session_dir,
)
from ._synth import body_boxes, occlusion_mask, project_views, synthesize_session, write_truth
from ._vicon_csv import ViconExport, ViconSection, marker_trajectories, read_vicon_csv, summarize_vicon_csv, write_vicon_csv
