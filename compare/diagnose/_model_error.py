"""The model's own numerical error on the recording's maneuver.

The nominal model is simulated once more at the next finer discretization
and once with half the time step. Their differences from the model are
the directions in which its numerical error lies on this maneuver; they
are reported (RMS per channel in noise units) and fitted as nuisance
regressors with every candidate, each amplitude within what Richardson
extrapolation allows (``ErrorDirections``), so a mismatch the finer model
also shows is never credited to missing physics, nor a parameter's change
to the model's error; a located mismatch within
``MODEL_ERROR_FACTOR`` times their size in its channel and window is
marked as the model's own error (``mark_model_error``).
"""

from __future__ import annotations

import math

import numpy as np

from ...simulate import DISCRETIZATION_LEVELS
from ._hypotheses import _init, _pool
from ._rig_runs import _rig_job
from ._scale import REFERENCE

__all__ = ["ERROR_AMPLITUDE_SD", "MODEL_ERROR_FACTOR", "ErrorDirections", "richardson_bound", "finer_discretization",
           "model_error", "mark_model_error"]

# The model error's amplitude has a wide prior (its size is set by its
# bounds, ``ErrorDirections``; the prior only keeps the normal equations
# regular): the finer model's difference is its direction, and Richardson's
# factor depends on the order of convergence.
ERROR_AMPLITUDE_SD = 10.0
# A located mismatch no larger than this many times the finer model's
# difference there is the model's own error: the next finer level is not
# converged either, and with counts up by 1.3-2x the nominal model's distance
# from the converged solution is about twice its distance from the next
# level (Richardson, second order).
MODEL_ERROR_FACTOR = 2.0


class ErrorDirections(list):
    """The model's own numerical error directions (``model_error``), each with the most its amplitude can be.

    ``bounds[i]``: direction ``i`` is the next finer model minus the
    nominal one; the nominal model's distance from the converged solution
    is ``R`` times that, ``R = 1 / (1 - (h' / h)^p)`` (Richardson) for a
    step ``h`` refined to ``h'`` at convergence order ``p``. At first order,
    the slowest any of the model's schemes converges, ``R`` is largest:
    ``n' / (n' - n)`` for a rope's particle count ``n`` raised to ``n'``
    (the largest over the ropes), 2 for the halved time step. The
    amplitude lies in ``[0, R]`` - towards the finer model, since the
    levels converge one way. Unbounded, a direction that looks like a
    parameter's change absorbs any amount of it: on a pendulum whose
    discretization error is a shift of its frequency, as the ball's mass
    centre is, amplitude 23 took up four fifths of a tolerance's change,
    which the updating then missed.
    """

    def __init__(self, directions=(), bounds=()):
        super().__init__(directions)
        self.bounds = [float(b) for b in bounds]

    def amplitude_bounds(self):
        """(k, 2): each amplitude's low and high."""
        return np.array([[0.0, b] for b in self.bounds]).reshape(len(self), 2)


def richardson_bound(rig, discretization, finer):
    """First-order Richardson factor of a refinement from ``discretization`` to ``finer`` (see
    ``ErrorDirections``); 1 when no count changes."""
    coarse, fine = rig.particle_counts(discretization), rig.particle_counts(finer)
    ratios = [fine[name] / (fine[name] - n) for name, n in coarse.items() if fine.get(name, n) > n]
    return max(ratios, default=1.0)


def finer_discretization(rig, discretization):
    """The next finer named level, or every count up by half for a custom one."""
    if isinstance(discretization, str) and discretization in DISCRETIZATION_LEVELS:
        i = DISCRETIZATION_LEVELS.index(discretization)
        if i + 1 < len(DISCRETIZATION_LEVELS):
            return DISCRETIZATION_LEVELS[i + 1]
    counts = rig.particle_counts(discretization)
    return {name: int(math.ceil(1.5 * n)) for name, n in counts.items()}


def model_error(problem, ctx, nominal_sim, workers=2):
    """The nominal model's numerical error on this maneuver.

    Parameters
    ----------
    problem : Problem
    ctx : dict
        Simulation context (``rig``, ``maneuver``, ``discretization``,
        ``duration``, ``rate_hz``, ``time``, ``channels``, ``nominal_dt``).
    nominal_sim : ndarray (n, c)

    Returns
    -------
    directions : list of ndarray (n, c)
        Finer minus nominal simulation, for each estimate that ran.
    block : dict
        JSON-ready: per source (``discretization``, ``time_step``), what it
        compared, its RMS per channel (SI and in noise units) and its chi2
        weight (sum of weighted squares: what a candidate could gain by
        absorbing it).
    """
    _init(ctx)
    finer = finer_discretization(ctx["rig"], ctx["discretization"])
    jobs = [(np.zeros(len(ctx["parameters"])), finer, None), (np.zeros(len(ctx["parameters"])), None, 0.5)]
    pool = _pool(workers, ctx, at_most=len(jobs))
    try:
        results = pool.map(_rig_job, jobs)
    finally:
        pool.close()
    directions, bounds, block = [], [], {}
    described = {"discretization": {"compared": [_level_name(ctx["discretization"]), _level_name(finer)],
                                    "amplitude_bound": richardson_bound(ctx["rig"], ctx["discretization"], finer)},
                 "time_step": {"compared": [f"{ctx['nominal_dt']:.3g} s", f"{0.5 * ctx['nominal_dt']:.3g} s"],
                               "amplitude_bound": 2.0}}
    for (name, entry), (sim, _, _) in zip(described.items(), results):
        if sim is None:
            entry["status"] = "failed"
            block[name] = entry
            continue
        d = sim - nominal_sim
        weighted = np.where(problem.valid, d, 0.0) ** 2 * problem.W
        entry.update(status="ok", chi2=float(weighted.sum()), channels={
            ch: {"rms": float(np.sqrt(np.mean(d[:, j] ** 2))),
                 "rms_noise": float(np.sqrt(np.mean(d[:, j] ** 2)) / problem.sigma[j])}
            for j, ch in enumerate(ctx["channels"])})
        directions.append(d)
        bounds.append(entry["amplitude_bound"])
        block[name] = entry
    block["method"] = ("the nominal model against itself at the next finer discretization and at half the time "
                       "step, on the recording's maneuver; both differences are fitted as nuisance directions with "
                       "every candidate, each amplitude between 0 and its first-order Richardson factor")
    return ErrorDirections(directions, bounds), block


def mark_model_error(entries, time, directions, channels, factor=MODEL_ERROR_FACTOR, scale=REFERENCE):
    """Mark the located mismatch entries that the model's own numerical error could make.

    Parameters
    ----------
    entries : list of dict
        ``_locate.locate_mismatch`` entries (``channel``, ``t_start``,
        ``t_end``, ``rms``) of a residual.
    time : ndarray (n,)
    directions : sequence of ndarray (n, c)
        ``model_error``'s differences.
    channels : sequence of str
        The columns' names.
    factor : float
    scale : MachineScale
        The machine's: its low-pass (default: the dragline's).

    Returns
    -------
    list of dict
        Copies with ``model_error_rms`` (the largest direction's low-passed
        RMS in that channel and window, its mean over the record removed as
        the offsets remove it) and ``within_model_error`` (the entry's RMS
        is at most ``factor`` times it).
    """
    from ._locate import LOWPASS_S, low_pass

    t = np.asarray(time, float)
    width = scale.lowpass_width(LOWPASS_S, float(t[1] - t[0]))
    smooth = [low_pass(d - np.nanmean(d, axis=0), width) for d in directions]
    out = []
    for e in entries:
        sel = (t >= e["t_start"] - 1e-9) & (t <= e["t_end"] + 1e-9)
        j = list(channels).index(e["channel"])
        budget = max((float(np.sqrt(np.nanmean(s[sel, j] ** 2))) for s in smooth), default=0.0)
        out.append(dict(e, model_error_rms=budget, within_model_error=bool(e["rms"] <= factor * budget)))
    return out


def _level_name(discretization):
    return discretization if isinstance(discretization, str) else ",".join(f"{k}={v}" for k, v in discretization.items())
