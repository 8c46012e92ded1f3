"""A rig's lowest modes: the conservative model linearized about a rest state.

At rest the motion's small oscillations obey q'' = -K q in the position
coordinates (bodies' mass centres and Euler angles, particles, ring
slides); K is the negative Jacobian of the accelerations, taken by central
differences of the compiled right-hand side. The Euler angles' second
derivatives are the body rates' first through ``euler_rates_from_body_rates``
(exact at zero velocity). The eigenvalues of K are the squared angular
frequencies; a body free to spin about its rope gives one of zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _kernel
from ._kinematics import euler_rates_from_body_rates
from ._model import kernel_model
from ._statics import _at_rest, _frozen, _unknown_index

__all__ = ["Modes", "linear_modes"]

# Central-difference step (m or rad): far below any element's stretch at rest, far above rounding.
STEP = 1e-7


@dataclass(frozen=True)
class Modes:
    """Small-oscillation modes, lowest first.

    Attributes
    ----------
    frequency_hz : ndarray (k,)
        0 for a rigid-body motion nothing resists (a spin about a rope).
    dominant : list of str
        What moves most in each mode (a body or a rope segment).
    """

    frequency_hz: np.ndarray
    dominant: list


def _accelerations(model, m, work, y, t):
    """Second derivatives of the position coordinates (``_statics._unknown_index``, in its order) at state ``y``
    (velocities zero)."""
    dy = np.zeros_like(y)
    _kernel.rhs(t, y, dy, m, work)
    parts = []
    for b in range(model.n_bodies):
        o = 12 * b
        parts.append(dy[o + 3 : o + 6])
        parts.append(np.array(euler_rates_from_body_rates(y[o + 6], y[o + 8], *dy[o + 9 : o + 12])))
    parts.append(dy[model.o_vel : model.o_force])
    parts.append(dy[model.o_ring + 1 :: 2])
    return np.concatenate(parts)


def linear_modes(model, state, t=0.0, count=None):
    """The lowest small-oscillation modes of ``model`` about rest state ``state``.

    Parameters
    ----------
    model : Model
        Best assembled with ``dissipation=False`` (the springs Ks + Kv, a
        conservative model whose modes are defined).
    state : ndarray
        A rest state (velocities zero), e.g. ``solve_statics(model).state``.
    t : float
        The maneuver's time whose winch lengths hold (s).
    count : int, optional
        How many to return (all by default).

    Returns
    -------
    Modes
    """
    m = kernel_model(_frozen(model, t))
    work = _kernel.make_work(m)
    index = _unknown_index(model)
    y0 = _at_rest(model, state)
    jac = np.empty((index.size, index.size))
    for k, i in enumerate(index):
        up, down = y0.copy(), y0.copy()
        up[i] += STEP
        down[i] -= STEP
        jac[:, k] = (_accelerations(model, m, work, up, t) - _accelerations(model, m, work, down, t)) / (2 * STEP)
    values, vectors = np.linalg.eig(-jac)
    omega2 = np.clip(values.real, 0.0, None)
    order = np.argsort(omega2)[: count or values.size]
    dominant = [model.describe_state_index(int(index[np.argmax(np.abs(vectors[:, j]))])) for j in order]
    return Modes(frequency_hz=np.sqrt(omega2[order]) / (2 * np.pi), dominant=dominant)
