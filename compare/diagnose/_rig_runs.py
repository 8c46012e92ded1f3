"""One run of the rig with its uncertain parameters at given coordinates: the job a pool's worker runs.

Every simulation the updating, the model-error estimate and the joint
refits ask for is this job, in the worker's context (``_hypotheses._CTX``,
set by ``_hypotheses._init``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...simulate import SimulationError, StaticsError, make_mechanism, simulate
from ._hypotheses import channels_on
from ._trials import apply_to_trials, joined_states, stack_trials, trial_contexts


class _Run(NamedTuple):
    """What ``_rig_job`` returns: the channels (n, c), the trials' equilibria and step schedules (None: failed)."""

    sim: np.ndarray | None
    state: object
    schedules: tuple | None


def _rig_job(coords, discretization=None, dt_factor=None, guess=None, schedules=None, accurate=False):
    """The rig with its parameters at ``coords``: a ``_Run``, its channels None when the simulation fails.

    ``schedules``: each trial's step schedule (``SimulationResult.schedule``)
    to step on, at the model's own discretization and step (the module's
    *Step schedule*). ``accurate``: a trial whose rope turned slack where
    the schedule had not refined is run again on its own schedule (a point
    a fit may move to, not a finite difference). The ``_Run``'s schedules
    are those its runs took: what a finite difference at it steps on.
    """
    from ._hypotheses import _CTX as ctx

    physics = list(ctx.get("base_physics", ()))
    joint = ctx.get("joint_mechanism")
    if joint is not None:
        # The last coordinate is the mechanism's ln value about its first fit (``joint_refit``).
        name, main, value0 = joint
        physics.append(make_mechanism(name, **{main: value0 * math.exp(coords[-1])}))
        coords = coords[:-1]
    rig, maneuvers = apply_to_trials(ctx, ctx["parameters"], coords)
    dt = None
    if dt_factor is not None:
        dt = ctx["nominal_dt"] * dt_factor
    trials = trial_contexts(dict(ctx, maneuver=maneuvers), guess)
    if schedules is None or discretization is not None or dt is not None:
        schedules = [None] * len(trials)
    sims, states, taken = [], [], []
    for trial, schedule in zip(trials, schedules):
        def run(steps):
            return simulate(rig, trial["maneuver"], discretization or ctx["discretization"],
                            physics, duration=trial["duration"], rate_hz=ctx["rate_hz"],
                            dt=dt, statics_guess=trial["initial_state"] if discretization is None else None,
                            schedule=steps)

        try:
            res = run(schedule)
            if accurate and res.unrefined_slack:
                res = run(None)
        except (SimulationError, StaticsError, FloatingPointError):
            return _Run(None, None, None)
        sims.append(channels_on(res, trial))
        states.append(res.states[0])
        taken.append(res.schedule)
    return _Run(stack_trials(ctx, sims), joined_states(ctx, states), tuple(taken))
