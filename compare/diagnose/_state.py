"""The one object the diagnosis's steps pass along (``_steps``).

Each step reads what the steps before it filled in and returns a new
state with its own part added (``dataclasses.replace``): the input state
is never modified, so a step can be run, inspected and re-run alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

__all__ = ["Recording", "NullTest", "DiagnosisState"]


@dataclass(frozen=True)
class Recording:
    """The measured channels on the model's clock.

    Attributes
    ----------
    time : ndarray (n,)
        Sample times (s) on the simulation's clock.
    channels : list of str
    values : ndarray (n, c)
        Measured channels, SI.
    noise : ndarray (c,)
        Each channel's measurement noise (SI), from the recording itself.
    rate_hz : float
    t_stop : float
        When the reels stop (s, model clock): the free decay follows.
    stop_method : str
    offset : float
        Recording clock minus model clock (s).
    alignment : dict
        ``align_with_maneuver``'s estimate.
    windows : list of (str, float, float)
        The maneuver's phases and the free decay.
    lowpass_width : int
        Samples of the structure low-pass.
    scale : MachineScale
        The machine's own scale, at which the diagnosis's floors are taken (``_scale``).
    trials : list of dict
        Several trials stacked (``_trials``): each one's ``name``, ``channels``,
        ``rows`` and its own alignment; empty for one recording.
    """

    time: np.ndarray
    channels: list
    values: np.ndarray
    noise: np.ndarray
    rate_hz: float
    t_stop: float
    stop_method: str
    offset: float
    alignment: dict
    windows: list
    lowpass_width: int
    scale: object
    trials: list = field(default_factory=list)


@dataclass(frozen=True)
class NullTest:
    """What noise alone and the model's own error give (``_null.null_threshold``, ``_decide``)."""

    threshold: float
    noise_threshold: float
    surrogate_quantile: float
    kappa: float
    allowance: float
    excess: float
    share: float
    own_error: float
    n_weighted: float | None = None  # the noise expectation the excess is measured from


@dataclass(frozen=True)
class DiagnosisState:
    """A diagnosis in progress: the inputs, then each step's results.

    Inputs: ``measured`` (trajectory table; a list of them for several
    trials of the machine, named by ``trial_names``), ``rig``, ``maneuver``
    (a list, one per trial), ``held_out`` (``(name, table, maneuver)`` of
    trials the fit never sees, predicted at the end),
    ``discretization``, ``candidate_names`` (None: every candidate),
    ``workers`` (int or Executor), ``seed``, ``source``, ``note``
    (progress callable), ``started`` (perf_counter at the start) and
    ``shared_frame`` (the positions measured in the frame the rig is
    driven in: no free offset on them, ``_recording.free_offsets``) and
    ``start_from_recording`` (each trial starts where its first samples have
    the tracked bodies, ``_start``).
    """

    measured: pd.DataFrame
    rig: object
    maneuver: object
    discretization: object = "baseline"
    candidate_names: tuple | None = None
    workers: object = 2
    seed: int = 0
    source: dict | None = None
    note: object = None
    started: float = 0.0
    trial_names: tuple | None = None
    held_out: tuple = ()
    shared_frame: bool = False
    start_from_recording: bool = False

    # align_recording: the recording, the nominal run, the problem on the nominal rig; the held-out trials aligned
    held_aligned: list = field(default_factory=list)
    recording: Recording | None = None
    nominal_run: object = None
    nominal_sim: np.ndarray | None = None
    plain_problem: object = None
    nominal_ctx: dict | None = None
    # locate_nominal
    r_nominal: np.ndarray | None = None
    nominal_nuisance: tuple | None = None
    located_nominal: list = field(default_factory=list)
    # update_rig: the model the mechanisms are fitted on
    problem: object = None
    ctx: dict | None = None
    base_sim: np.ndarray | None = None
    update: dict | None = None
    error_directions: list = field(default_factory=list)
    model_error_block: dict | None = None
    model_error_sims: int = 0
    # locate_updated
    base_eval: dict | None = None
    r_base: np.ndarray | None = None
    located: list = field(default_factory=list)
    structured_before: list = field(default_factory=list)
    # fit_mechanisms, refit_jointly
    candidates: list = field(default_factory=list)
    runnable: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    site_groups: list = field(default_factory=list)  # per law tried at its sites: which the recording joins
    site_screen: list = field(default_factory=list)  # per site candidate: its linearized improvement, fitted or not
    screened_out: list = field(default_factory=list)  # the signatures of the sites not fitted (for the null test)
    site_split: list = field(default_factory=list)  # the sets fitted at each member alone (``split_joined_sites``)
    points: dict = field(default_factory=dict)
    scored: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    # test_against_noise, score_hypotheses
    null: NullTest | None = None
    hypotheses: list = field(default_factory=list)
    fitted_series: dict = field(default_factory=dict)
    residuals: dict = field(default_factory=dict)
    # update_again: the first round (its lead, credit, chi2 before and after, simulations) when updating resumed
    superseded: dict | None = None
    # locate_after, judge_offsets, decide_verdict, test_second_mechanism
    after_name: str | None = None
    located_after: list = field(default_factory=list)
    structured_after: list = field(default_factory=list)
    offsets: dict = field(default_factory=dict)
    offsets_left: dict | None = None
    too_far: list = field(default_factory=list)
    offsets_judged: dict | None = None
    offsets_note: str | None = None
    verdict: str | None = None
    reason: str = ""
    alike_laws: tuple = ()
    second: dict | None = None
    # predict_held_out
    predictions: list = field(default_factory=list)
    predicted_series: list = field(default_factory=list)


def _note(state, message):
    """``message`` to the state's progress callback, where it has one."""
    if state.note is not None:
        state.note(message)
