"""How close any model can come to a recording: a reference motion weighed against it as the diagnosis weighs.

A benchmark knows the motion it filmed. That motion's own chi2 against the
recording made of it, on the clock its own rope lengths give, is what no
model can go below - the capture's error beyond the noise the diagnosis
estimates (its cameras' calibration, the reconstruction) - and so it says,
independently of any verdict, whether a recording can be described to the
rules' standard at all (``ADEQUATE_RMS``, ``LEFTOVER_SHARE``;
docs/diagnosis.md, section 3, "The clock the nominal model gives, and what
it costs").
"""

from __future__ import annotations

import numpy as np

from ._align_recording import aligned_path
from ._hypotheses import channels_on
from ._objective import _fit_residual, _objective_at, _offset_prior
from ._trials import stack_trials, trial_contexts

__all__ = ["recording_floor"]


def recording_floor(path, rig, reference):
    """The chi2 of ``reference`` against the recording at ``path``, per weighted sample, on the diagnosis's terms.

    Parameters
    ----------
    path : str
        A recording ``load_recording`` reads (one trial: a session
        directory, say).
    rig : Rig
        The rig file the recording is read with.
    reference : SimulationResult
        The motion compared (the truth that was filmed); the recording's clock
        is read against its rope lengths, as the diagnosis reads it against
        its model's.

    Returns
    -------
    dict
        ``chi2_per_sample`` (1 where the recording is its reference plus
        the noise the diagnosis estimates), ``n_weighted``, ``per_channel``
        (channel -> its chi2 per weighted sample) and ``worst_channel``; each
        channel's constant offset and the clock shift are fitted with their
        priors first, as in every fit of the diagnosis (no model-error
        directions: the reference has no discretization error of its own).
    """
    state = aligned_path(path, rig, clock_table=reference.table)
    problem, ctx = state.plain_problem, state.nominal_ctx
    trials = trial_contexts(ctx)
    if len(trials) != 1:
        raise ValueError(f"{path}: a floor is of one trial, the recording has {len(trials)}")
    motion = stack_trials(ctx, [channels_on(reference, trials[0])])
    _, chi2, nuisance, _ = _objective_at(problem, motion, np.zeros(0), np.ones(0), _offset_prior(ctx), [])
    residual = _fit_residual(problem, motion, nuisance, [])
    weighed = np.where(problem.valid, problem.W * residual**2, 0.0)
    counted = (problem.W * problem.sigma[None, :] ** 2).sum(axis=0)  # each channel's weighted samples
    per_channel = {ch: float(weighed[:, j].sum() / max(counted[j], 1e-12)) for j, ch in enumerate(ctx["channels"])}
    return {"chi2_per_sample": float(chi2 / problem.n_weighted), "n_weighted": float(problem.n_weighted),
            "per_channel": per_channel, "worst_channel": max(per_channel, key=per_channel.get)}
