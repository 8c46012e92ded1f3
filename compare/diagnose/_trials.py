"""Several trials of one machine, fitted as one recording.

The trials are stacked side by side: trial ``k``'s channel ``load.x`` is
the stacked channel ``"k/load.x"``, and its rows are the trial's own
samples from its own start (row ``i`` is ``i`` samples after each trial's
first). Everything the diagnosis does per channel - each channel's noise,
its constant offset, its weight - is then per trial and channel, so each
trial keeps its own offsets while the rig's parameters and a mechanism's are
shared. A shorter trial's rows past its end are unmeasured (weight 0; its
simulation held at its last value there, so that a rate taken across the
end stays finite). What stays shared is the fine clock shift (at most
``MAX_SHIFT``) fitted on top of each trial's own alignment.

A simulation context (``ctx``) of several trials holds ``trials`` (one dict
per trial: ``name``, ``time``, ``channels``, ``duration``, ``rows``,
``columns``) and tuples in ``maneuver`` and ``initial_state``;
``trial_contexts`` gives each trial's context as a one-trial diagnosis
would have it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...simulate import apply_parameters

__all__ = ["SEPARATOR", "split_channel", "trial_contexts", "stack_trials", "joined_states", "apply_to_trials",
           "first_maneuver", "each_trials_own"]

SEPARATOR = "/"


def split_channel(channel):
    """``(trial or None, channel)``: a stacked channel's trial and its trajectory-table name."""
    trial, sep, name = channel.rpartition(SEPARATOR)
    return (trial, name) if sep else (None, channel)


def trial_contexts(ctx, states=None):
    """Each trial's own simulation context (the context itself for one trial).

    ``states``: per-trial equilibria to start from or guess with (a tuple for
    several trials), in place of ``ctx["initial_state"]``.
    """
    states = ctx["initial_state"] if states is None else states
    if "trials" not in ctx:
        return [dict(ctx, initial_state=states)]
    return [dict(ctx, maneuver=m, initial_state=s, time=t["time"], channels=t["channels"], duration=t["duration"])
            for t, m, s in zip(ctx["trials"], ctx["maneuver"], states)]


def stack_trials(ctx, sims):
    """The trials' channel arrays side by side, (n, c) as the stacked recording; None if any is None."""
    if any(s is None for s in sims):
        return None
    if "trials" not in ctx:
        return sims[0]
    n = max(t["rows"] for t in ctx["trials"])
    out = np.empty((n, sum(len(t["columns"]) for t in ctx["trials"])))
    for t, s in zip(ctx["trials"], sims):
        cols = t["columns"]
        out[: t["rows"], cols] = s
        out[t["rows"]:, cols] = s[-1]
    return out


def joined_states(ctx, states):
    """Per-trial equilibria as the context holds them (one state, or a tuple)."""
    return tuple(states) if "trials" in ctx else states[0]


def apply_to_trials(ctx, parameters, coords):
    """``apply_parameters`` on the rig and every trial's maneuver: ``(rig, maneuver or tuple of maneuvers)``;
    a parameter of one trial (``RigParameter.trial``) moves that trial's maneuver only."""
    if "trials" not in ctx:
        return apply_parameters(ctx["rig"], ctx["maneuver"], parameters, coords)
    out = []
    for trial, m in zip(ctx["trials"], ctx["maneuver"]):
        # a trial's own coordinates (its start) move its maneuver alone
        own = [(p, x) for p, x in zip(parameters, coords) if p.trial in (None, trial["name"])]
        out.append(apply_parameters(ctx["rig"], m, [p for p, _ in own], [x for _, x in own]))
    return out[0][0], tuple(m for _, m in out)


def first_maneuver(ctx):
    """The first trial's maneuver (the one maneuver of a one-trial context): what a cost estimate assembles."""
    return ctx["maneuver"][0] if "trials" in ctx else ctx["maneuver"]


def each_trials_own(parameters, names):
    """The rig's parameters with each one a trial has its own of (``RigParameter.of_a_trial``: a track's
    offset) repeated for every trial, ``tracks.drone.z`` becoming ``tracks.TRIAL.drone.z``."""
    out = []
    for p in parameters:
        if not p.of_a_trial:
            out.append(p)
            continue
        head, _, rest = p.name.partition(".")
        out += [dataclasses.replace(p, name=f"{head}.{name}.{rest}", trial=name) for name in names]
    return tuple(out)
