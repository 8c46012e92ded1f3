"""The synthetic lab: the simulator filmed by six simulated cameras.

Ground truth for everything downstream of a camera: a capture made here has
known cameras, known marker positions and a known model behind it.

- the lab's layout: ``default_lab_cameras`` (six cameras placed for the
  built-in rig), ``lframe_points``, ``wand_motion`` and the constants
  ``IMAGE_SIZE``, ``NOMINAL_FOCAL_PX``, ``WAND_LENGTH``; for any other
  machine ``lab_for_rig`` / ``volume_lab`` (a ``LabLayout`` placed about
  the volume its markers sweep)
- synthetic sessions: ``synthesize_session`` (settings ``SYNTH_DEFAULTS``,
  ``MAX_RATE_HZ``), ``write_truth``, and its realism stages as plain
  functions (``project_views``, ``on_sensor``, ``body_boxes``,
  ``occlusion_mask``)
- ``write_session_dir``: a session folder (``capture.mcap``,
  ``maneuver.csv``), written whole

The lab sits after capture and simulate in the stage order: it films the
model with capture's cameras and writes capture's files.
"""

from ._layout import IMAGE_SIZE, NOMINAL_FOCAL_PX, WAND_LENGTH, default_lab_cameras, lframe_points, wand_motion
from ._volume_lab import LabLayout, lab_for_rig, volume_lab
from ._synth import DEFAULTS as SYNTH_DEFAULTS
from ._synth import MAX_RATE_HZ, body_boxes, occlusion_mask, on_sensor, project_views, synthesize_session, write_truth
from ._session_dir import write_session_dir
