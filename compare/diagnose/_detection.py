"""Each candidate's detection threshold on a recording: what the rig cannot absorb, against the model's own error.

A candidate's signature at ``p`` is its simulation on the updated rig
minus the updated model's. Its weight is the chi2 of what is left after
the rig's best answer to it (``unabsorbed_chi2``): a fit by every
parameter's sensitivity at its prior cost ``(delta / tolerance)^2``, by
every model-error direction within its amplitude bound, and each
channel's offset. The threshold is the ``p`` at which that weight equals
the model's own numerical error weight (``own_error_weight``), the floor a
mechanism's held-out improvement must clear; found by bisection in ln p
(``threshold_crossing``). A signature grows with its parameter, so the
weight is taken as monotone and the bracket checked.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import lsq_linear

from ._align_recording import aligned_path
from ._confounding import _centred
from ._hypotheses import simulate_channels
from ._model_error import ERROR_AMPLITUDE_SD
from ._steps import locate_nominal, own_error_weight, update_rig

__all__ = ["detection_thresholds", "threshold_crossing", "unabsorbed_chi2"]

# Bisection to this resolution in ln p (1 %).
XTOL = 0.01


def threshold_crossing(weight, target, lo, hi, xtol=XTOL, grid=9):
    """The p in [lo, hi] at which ``weight(p)`` reaches ``target``, by bisection in ln p.

    ``weight`` is taken as increasing. A log grid of ``grid`` points finds
    the bracket first. Returns ``(p, status)``: status ``"found"``,
    ``"below range"`` (the weight already exceeds the target at ``lo``:
    p = lo) or ``"above range"`` (never reached: p = hi).
    """
    points = np.geomspace(lo, hi, grid)
    values = [weight(p) for p in points]
    if values[0] >= target:
        return float(lo), "below range"
    above = [k for k, v in enumerate(values) if v >= target]
    if not above:
        return float(hi), "above range"
    k = above[0]
    a, b = math.log(points[k - 1]), math.log(points[k])
    while b - a > xtol:
        mid = 0.5 * (a + b)
        if weight(math.exp(mid)) >= target:
            b = mid
        else:
            a = mid
    return float(math.exp(0.5 * (a + b))), "found"


def unabsorbed_chi2(problem, signature, columns, precision, bounds):
    """What ``signature`` (n, c) still weighs after the rig's best answer to it.

    The chi2 of the signature less its fit by ``columns`` and each
    channel's offset, plus the fit's prior cost: a column ``k``'s
    coefficient costs ``precision[k] * a_k**2`` and stays within
    ``bounds[k]`` - the parameters within their tolerances, the error
    directions within their amplitude bounds, as the updating and the
    joint refit hold them. A weak signature is absorbed almost whole, a
    strong one cannot be.
    """
    g = _centred(problem, signature).ravel()
    if not columns:
        return float(g @ g)
    J = np.column_stack([_centred(problem, c).ravel() for c in columns])
    A = np.vstack([J, np.diag(np.sqrt(precision))])
    fit = lsq_linear(A, np.r_[g, np.zeros(len(columns))], bounds=(bounds[:, 0], bounds[:, 1]))
    left = g - J @ fit.x
    return float(left @ left + precision @ fit.x**2)


def _updated_state(path, rig, workers, progress):
    state = aligned_path(path, rig, workers, progress)
    for step in (locate_nominal, update_rig):
        state = step(state)
    return state


def detection_thresholds(path, rig, candidates, workers=2, progress=None):
    """Each candidate's detection threshold on the recording at ``path`` (a session directory, say).

    Parameters
    ----------
    path : str
        A recording ``load_recording`` reads, best one with nothing hidden.
    rig : Rig
    candidates : mapping
        Name -> (main parameter, (lo, hi)): where each threshold is sought.
    workers, progress
        As ``diagnose``'s.

    Returns
    -------
    dict
        ``own_error_chi2`` (the target) and per candidate ``threshold``
        (its main parameter's value) and ``status`` (``threshold_crossing``).
    """
    state = _updated_state(path, rig, workers, progress)
    target = own_error_weight(state.model_error_block)
    sensitivities = state.update["sensitivities"] if state.update is not None else []  # a rig with no tolerances
    columns = [*sensitivities, *state.error_directions]
    tol = np.array([p.tolerance for p in state.ctx["parameters"]]) if sensitivities else np.zeros(0)
    precision = np.r_[tol**-2.0, np.full(len(state.error_directions), ERROR_AMPLITUDE_SD**-2.0)]
    bound = state.error_directions.amplitude_bounds()[:, 1]
    bounds = np.vstack([np.tile([-np.inf, np.inf], (len(tol), 1)), np.column_stack([-bound, bound])])
    out = {"own_error_chi2": target, "candidates": {}}
    for name, (main, (lo, hi)) in candidates.items():

        def weight(p, name=name, main=main):
            sim = simulate_channels(name, main, p, ctx=state.ctx)
            return math.inf if sim is None else unabsorbed_chi2(state.problem, sim - state.base_sim, columns,
                                                                  precision, bounds)

        p, status = threshold_crossing(weight, target, lo, hi)
        out["candidates"][name] = {"threshold": p, "status": status}
        if progress:
            progress(f"{name}: {main} = {p:.3g} ({status})")
    return out
