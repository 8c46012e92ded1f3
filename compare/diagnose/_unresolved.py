"""What the recording sees only together: combinations of the rig's parameters it cannot pin.

A parameter the recording cannot see alone may still be seen in a
combination with others: with a load's anchor moved by its measured track,
the load's mass, the rope's weight and every rope force constant scaled by
one factor move nothing (each acceleration, gravity's included, is a force
over a mass), so the recording fixes their ratios and not their common
scale. Which one the fit then moves is decided by the tolerances, not the
data, and a lab is better told the combination and that measuring any one
of its parameters decides the rest.

Found from the data's own information about the shared parameters and
each trial's track offsets (the weighted design's normal matrix, every
nuisance - offsets, clock shift, the model error's amplitudes and each
trial's start - projected out with its prior), in tolerance units: a
direction along which it is below ``SEEN``, a one-tolerance prior that
the recording would not halve (posterior over prior ``1 / sqrt(1 +
information)`` above 0.5), is unresolved. Directions loaded on one
parameter alone are that parameter's "not identifiable" and are not
repeated.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SEEN", "combination_columns", "unresolved_combinations"]

# The data's information along a direction, in one-tolerance units, below which a one-tolerance prior is not
# halved: 1 / sqrt(1 + 3) = 0.5, the identifiability rule's ratio.
SEEN = 3.0
# A parameter is part of a combination when its share of the direction (in its own coordinate) is at least this
# fraction of the largest share.
LOADING = 0.2


def combination_columns(parameters):
    """Which of ``parameters`` (``RigParameter``) a combination is sought among, by index.

    The rig's shared parameters and each trial's track offsets: where a
    rope hangs under a tracked origin is geometry a lab can measure, so a
    shared length it trades with is said together with it. A trial's start
    is not: it is the recording's, not the rig's.
    """
    return [k for k, p in enumerate(parameters) if not p.of_a_trial or p.kind == "track"]


def unresolved_combinations(X, prior_var, columns, tolerances, names):
    """The combinations of the rig's parameters the recording does not pin.

    Parameters
    ----------
    X : ndarray (m, p)
        The weighted design: one column per coordinate (the active
        parameters', then the nuisance's), in noise units.
    prior_var : ndarray (p,)
        Each column's prior variance.
    columns : sequence of int
        The columns asked about: the shared rig parameters and each
        trial's track offsets (the rest is nuisance).
    tolerances : ndarray (len(columns),)
        Their tolerances (one prior standard deviation, coordinate units).
    names : sequence of str
        Their names.

    Returns
    -------
    list of dict
        Per unresolved direction with two or more parameters:
        ``parameters`` (name -> loading in the parameters' own coordinates,
        ln p or metres, the largest 1 in size) and ``information`` (the
        data's, in tolerance units), least seen first.
    """
    asked = np.asarray(columns, int)
    if asked.size < 2:
        return []
    rest = np.setdiff1d(np.arange(X.shape[1]), asked)
    A = X[:, asked].T @ X[:, asked]
    if rest.size:
        B = X[:, asked].T @ X[:, rest]
        C = X[:, rest].T @ X[:, rest] + np.diag(1.0 / np.asarray(prior_var, float)[rest])
        A = A - B @ np.linalg.solve(C, B.T)
    tol = np.asarray(tolerances, float)
    scaled = tol[:, None] * A * tol[None, :]
    info, vectors = np.linalg.eigh(0.5 * (scaled + scaled.T))
    out = []
    for lam, v in zip(info, vectors.T):
        if lam >= SEEN:
            break
        along = tol * v  # back to the parameters' own coordinates
        along = along / along[np.argmax(np.abs(along))]
        members = np.flatnonzero(np.abs(along) >= LOADING)
        if members.size >= 2:
            out.append({"parameters": {names[i]: float(along[i]) for i in members},
                        "information": float(max(lam, 0.0))})
    return out
