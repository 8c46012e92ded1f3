"""compare stage of dragline: measured versus simulated.

Metrics and free-decay analysis, the validation report, the results MCAP for
Foxglove (``write_results``), the diagnosis (``compare.diagnose``) and the
executors that run its simulations (local processes or Dask).
"""

from ._decay import dominant_mode, envelope_shape, free_decay, matrix_pencil
from ._metrics import (
    channel_metrics,
    iso18571,
    peak,
    peak_error,
    rms_error,
    sprague_geers,
    theil_u,
)

__all__ = [
    "rms_error",
    "peak_error",
    "peak",
    "sprague_geers",
    "iso18571",
    "theil_u",
    "channel_metrics",
    "matrix_pencil",
    "dominant_mode",
    "envelope_shape",
    "free_decay",
]
from ._align import align_tables, estimate_time_offset, read_trajectory_table, reels_stop_time
from ._compare import compare_tables, discretization_study

__all__ += [
    "read_trajectory_table",
    "estimate_time_offset",
    "align_tables",
    "reels_stop_time",
    "compare_tables",
    "discretization_study",
    "write_report",
]
from .diagnose import Diagnosis, diagnose, diagnose_path, load_recording, write_diagnosis_json, write_diagnosis_report
from ._foxglove import write_results
from ._machine_figure import MachinePicture, draw_machine, machine_picture, marked_sites, picture_at
from .diagnose import (
    BOUND_TOLERANCES,
    ERROR_ALONG_SIGNATURE,
    REFINE_XATOL,
    SCREEN_SHARE,
    SECOND_EXCESS_SHARE,
    SITES_ALIKE,
    SYSTEMATIC_FLOOR,
    DecisionRules,
    MachineScale,
    detection_thresholds,
    machine_scale,
    recording_floor,
    rethresholded,
    seconds_of_document,
    verdict_of_document,
)
from ._paper import DIG_PEAKS
from ._executor import DaskExecutor, Executor, ExecutorError, LocalExecutor, as_executor, executor_from

__all__ += ["Diagnosis", "diagnose", "diagnose_path", "load_recording", "write_diagnosis_json",
            "write_diagnosis_report", "write_results", "DIG_PEAKS",
            "MachinePicture", "machine_picture", "picture_at", "draw_machine", "marked_sites", "MachineScale",
            "machine_scale",
            "detection_thresholds", "recording_floor", "DecisionRules", "verdict_of_document", "rethresholded",
            "seconds_of_document",
            "SECOND_EXCESS_SHARE", "ERROR_ALONG_SIGNATURE", "SYSTEMATIC_FLOOR", "REFINE_XATOL",
            "SITES_ALIKE", "SCREEN_SHARE", "BOUND_TOLERANCES",
            "Executor", "LocalExecutor", "DaskExecutor", "ExecutorError", "executor_from", "as_executor"]


def __getattr__(name):
    # The report draws with matplotlib, which costs a diagnosis that writes no PDF 0.4 s to import.
    if name == "write_report":
        from ._report import write_report

        return write_report
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
