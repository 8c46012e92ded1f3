"""Capture: calibrated cameras, wand calibration, the files a capture lives in.

- cameras: ``Camera``, ``project_points``, ``camera_centre``, ``save_cameras``, ``load_cameras``
- calibration: ``calibrate`` (and ``triangulate_views``, its linear first guess)
- files: VICON-style CSV (``read_vicon_csv``, ``marker_trajectories``,
  ``write_vicon_csv``, ``summarize_vicon_csv``) and MCAP (``CaptureSession``,
  ``write_session``, ``read_session``, ``summarize_mcap``, ``MCAP_CHUNK_SIZE``)
- session folders: ``session_file`` (``SESSION_FILE``, ``MANEUVER_FILE``),
  ``resolve_recording``, ``atomic_directory``, ``check_directory_target``,
  ``mark_output`` (``OUTPUT_MARKER``: the file that lets ``--force`` replace a
  folder dragline wrote)
- other labs' files: C3D (``read_c3d``, ``write_c3d``, ``is_c3d``), TRC
  (``read_trc``, ``write_trc``, ``is_trc``), any of them by extension
  (``read_marker_file``, ``MARKER_FILE_EXTENSIONS``) into one record
  (``MarkerFile``), and a trial cut between two of a file's labelled events
  (``between_events``, ``event_frame``); tables of tracked rigid-body poses
  read through a declared mapping (``read_tracked_table``, and a ROS 2
  bag's pose topics ``read_tracked_bag``,
  ``load_tracked_mapping``: ``TrackedPoses``, ``TrackedMapping``), and the
  clock of a log written without timestamps recovered from its motion
  (``recover_clock``)
- helpers every stage uses: strict JSON (``json_text``, ``json_ready``,
  ``write_json``), schema messages (``describe_validation_error``,
  ``fields_markdown``, ``key_text``, ``short_repr``) and the column
  colouring of a sparse finite-difference Jacobian (``column_groups``: the
  bundle adjustment's, and the simulator's statics)

The synthetic lab that films the simulator (cameras placed for the rig,
wand, synthetic sessions) is the ``lab`` package; the results MCAP for
Foxglove is written by ``compare.write_results``. Capture imports no other
stage.
"""

# Helpers first: every later stage imports them.
from ._schema_tools import MIN_TIME_STEP_S, describe_validation_error, fields_markdown, key_text, short_repr
from ._atomic import atomic_file
from ._strict_json import json_ready, json_text, write_json

from ._bundle import column_groups
from ._calibration import calibrate, triangulate_views
from ._cameras import Camera, camera_centre, load_cameras, project_points, save_cameras
from ._mcap_io import CHUNK_SIZE as MCAP_CHUNK_SIZE
from ._mcap_io import SESSION_FILE, CaptureSession, read_session, summarize_mcap, write_session
from ._session_io import (
    MANEUVER_FILE,
    OUTPUT_MARKER,
    SESSION_FILES,
    RecordingInput,
    atomic_directory,
    check_directory_target,
    mark_output,
    resolve_recording,
    session_file,
)
from ._vicon_csv import ViconExport, ViconSection, marker_trajectories, read_vicon_csv, summarize_vicon_csv, write_vicon_csv
from ._c3d import is_c3d, read_c3d, write_c3d
from ._trc import is_trc, read_trc, write_trc
from ._marker_file import MARKER_FILE_EXTENSIONS, MarkerFile, between_events, event_frame, read_marker_file
from ._tracked import (
    TrackedMapping,
    TrackedPoses,
    frame_rotation,
    load_tracked_mapping,
    read_tracked_bag,
    read_tracked_table,
)
from ._clock import recover_clock
