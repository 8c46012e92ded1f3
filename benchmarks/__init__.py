"""Benchmarks: what dragline measures of itself, as figures (JSON), never pass/fail.

``dragline bench WHAT`` is the user's entry; each benchmark is also a plain
function here. They use only the stage packages' public interfaces, so they
measure what a user's code would get.

- ``bench_simulate`` (``simulate_summary_lines``): the simulator's speed and
  accuracy per discretization level, against a converged reference, and
  ``bench_moordyn``, the same line in MoorDyn at equal accuracy
- ``bench_capture``: a synthetic session calibrated from its own takes and
  triangulated; ``bench_calibration``: calibration alone
- ``bench_reconstruction``: marker, body and rope figures against the truth;
  ``bench_triangulation``: speed against OpenCV's pairwise triangulation
- ``bench_diagnosis`` (``diagnosis_summary_lines``): one diagnosis of the
  sample session, timed end to end as the command runs it
- ``bench_detection`` (``detection_summary_lines``): each candidate's
  detection threshold on the dig, from the truth model, which the
  trusted-verdict cases are multiples of
- ``bench_discovery`` (``discovery_command``, ``discovery_summary_lines``):
  blind sessions diagnosed and scored against the physics hidden in them,
  on the dragline or (``--realism --rig NAME``, ``_machine_cases``) another
  built-in machine; ``bench_pairs`` (``--realism --pairs``): two hidden at once;
  ``bench_sites`` (``--realism --sites``): one law hidden at one site
- ``bench_sensitivities`` (``sensitivities_summary_lines``): the states'
  Jacobian from the scheme's tangent against finite differences, timed
- ``calibrate_decisions`` (``decisions_command``): the verdict's
  constants calibrated on kept diagnoses of earlier trusted-verdict runs
- ``bench_real`` (``real_command``): real slung-load flights, each
  predicted by a diagnosis fitted on all the others together

``bench_executor.py`` (a script) measures the executors' scheduling cost.
"""

import importlib

# name -> (module, attribute). Loaded on first use: a benchmark imports only the stages it measures, so
# the simulator's figures (its peak memory too) carry nothing of the lab, the diagnosis or Dask.
_EXPORTS = {
    "bench_simulate": ("_simulator", "bench_simulate"),
    "simulate_summary_lines": ("_simulator", "summary_lines"),
    "bench_moordyn": ("_moordyn_peer", "bench_moordyn"),
    "bench_capture": ("_capture", "bench_capture"),
    "bench_calibration": ("_calibration", "bench_calibration"),
    "bench_triangulation": ("_triangulation", "bench_triangulation"),
    "bench_reconstruction": ("_reconstruction", "bench_reconstruction"),
    "bench_diagnosis": ("_diagnosis", "bench_diagnosis"),
    "diagnosis_summary_lines": ("_diagnosis", "summary_lines"),
    "bench_detection": ("_detection", "bench_detection"),
    "detection_summary_lines": ("_detection", "summary_lines"),
    "bench_discovery": ("_discovery", "bench_discovery"),
    "bench_pairs": ("_pairs", "bench_pairs"),
    "bench_sites": ("_site_cases", "bench_sites"),
    "discovery_command": ("_discovery", "bench_command"),
    "discovery_summary_lines": ("_discovery", "summary_lines"),
    "bench_sensitivities": ("_sensitivities", "bench_sensitivities"),
    "sensitivities_summary_lines": ("_sensitivities", "summary_lines"),
    "calibrate_decisions": ("_decisions", "calibrate_decisions"),
    "decision_records": ("_decisions", "decision_records"),
    "decisions_command": ("_decisions", "bench_command"),
    "bench_real": ("_real", "bench_real"),
    "real_command": ("_real", "bench_command"),
}
__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = _EXPORTS[name]
    return getattr(importlib.import_module(f"{__name__}.{module}"), attribute)


def __dir__():
    return __all__
