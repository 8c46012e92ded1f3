"""capture stage of dragline."""
from ._vicon_csv import ViconExport, ViconSection, marker_trajectories, read_vicon_csv, summarize_vicon_csv, write_vicon_csv
from ._mcap_io import CaptureSession, read_session, summarize_mcap, write_results, write_session
from ._calibration import calibrate
from ._synth import body_boxes, occlusion_mask, project_views, synthesize_session, write_truth
