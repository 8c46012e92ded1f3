"""The diagnosis: what physics the model leaves out, proven on the recording itself.

``diagnose`` runs ``_steps.STEPS`` in order over one ``_state.DiagnosisState``;
the work is in one module per concern (docs/diagnosis.md states the method):

- ``_locate``: where and when the nominal model misses (channel x window);
- ``_model_error``: the model's own numerical error (``model_error``);
- ``_updating``: the rig parameters updated within their tolerances
  (``update_model``, ``joint_refit``), on ``_objective`` (chi2 with the
  nuisance projected out, the priors, the robust covariance),
  ``_differences`` (the finite-difference sensitivities) and
  ``_rig_runs`` (one run of the rig, a worker's job); its JSON block is
  ``_calibration_block``'s;
- ``_confounding``: how far a mechanism's signature looks like a change
  of the rig's parameters, and its value's uncertainty with them free;
- ``_hypotheses``: each candidate mechanism fitted through the simulator on
  top of the updated rig and scored on held-out data (``_problem``: the
  objective and its folds), against what noise alone gives (``_null``);
- ``_decide``: the verdict's rules;
- ``_second_round``: the other candidates on top of a named one;
- ``_report``: the diagnosis pages of the PDF;
- ``_recording``: the recording read (a session, a VICON export or a
  trajectory table) and checked against the maneuver;
- ``_summary``: the document's free decay, metrics and calibration sections;
- ``_scale``: the floors, set on the dragline, at any machine's own scale;
- ``_trials``: several trials of one machine stacked as one recording;
- ``_predict``: trials the fit never saw, predicted;
- ``_leave_one_out``: each trial in turn left out and predicted;
- ``_detection``: each candidate's detection threshold on a recording
  (what the rig cannot absorb against the model's own error);
- ``_state`` and ``_steps``: the state object and the steps over it (the
  first, the recording on the model's clock, ``_align_recording``);
- ``_diagnose``: the steps run in order, the document read off the state.
"""

from ._diagnose import (
    Diagnosis,
    diagnose,
    diagnose_path,
    draw_held_out,
    load_recording,
    write_diagnosis_json,
    write_diagnosis_report,
)
from ._decide import DecisionRules, rethresholded, verdict_of_document
from ._second_round import seconds_of_document
from ._steps import SECOND_EXCESS_SHARE
from ._detection import detection_thresholds
from ._floor import recording_floor
from ._hypotheses import REFINE_XATOL, candidate_list
from ._summary import ERROR_ALONG_SIGNATURE, SYSTEMATIC_FLOOR
from ._leave_one_out import leave_one_out
from ._sites import SCREEN_SHARE, SITES_ALIKE
from ._objective import BOUND_TOLERANCES
from ._scale import FREE_HZ, MachineScale, machine_scale

__all__ = ["Diagnosis", "diagnose", "diagnose_path", "load_recording", "write_diagnosis_json",
           "write_diagnosis_report", "candidate_list", "draw_held_out", "leave_one_out", "MachineScale",
           "machine_scale", "FREE_HZ", "detection_thresholds", "recording_floor", "DecisionRules",
           "verdict_of_document", "rethresholded", "seconds_of_document", "SECOND_EXCESS_SHARE",
           "ERROR_ALONG_SIGNATURE", "SYSTEMATIC_FLOOR", "REFINE_XATOL", "SITES_ALIKE", "SCREEN_SHARE",
           "BOUND_TOLERANCES"]
