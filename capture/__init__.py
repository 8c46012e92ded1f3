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
- other labs' files: C3D (``read_c3d``, ``write_c3d``, ``is_c3d``), TRC
  (``read_trc``, ``write_trc``, ``is_trc``), any of them by extension
  (``read_marker_file``, ``MARKER_FILE_EXTENSIONS``)
- the lab: ``default_lab_cameras``; synthetic session settings ``SYNTH_DEFAULTS``,
  ``MAX_RATE_HZ``
- helpers every stage uses: strict JSON (``json_text``, ``json_ready``,
  ``write_json``) and schema messages (``describe_validation_error``,
  ``fields_markdown``, ``key_text``, ``short_repr``)
- ``bench_capture`` (``dragline bench capture``)
"""

# Helpers first: the later stages import them, and capture itself imports simulate.
from ._schema_tools import describe_validation_error, fields_markdown, key_text, short_repr
from ._atomic import atomic_file
from ._strict_json import json_ready, json_text, write_json

from ._calibration import calibrate
from ._cameras import Camera, camera_centre, load_cameras, project_points, save_cameras
from ._foxglove import write_results
from ._mcap_io import CaptureSession, read_session, summarize_mcap, write_session
from ._session_io import (
    OUTPUT_MARKER,
    SESSION_FILES,
    RecordingInput,
    atomic_directory,
    check_directory_target,
    mark_output,
    resolve_recording,
    session_file,
    write_session_dir,
)
from ._synth import DEFAULTS as SYNTH_DEFAULTS
from ._synth import MAX_RATE_HZ, body_boxes, occlusion_mask, project_views, synthesize_session, write_truth
from ._vicon_csv import ViconExport, ViconSection, marker_trajectories, read_vicon_csv, summarize_vicon_csv, write_vicon_csv
from ._c3d import is_c3d, read_c3d, write_c3d
from ._trc import is_trc, read_trc, write_trc
from ._marker_file import MARKER_FILE_EXTENSIONS, read_marker_file
from ._lab import default_lab_cameras
from ._capture_bench import bench_capture
