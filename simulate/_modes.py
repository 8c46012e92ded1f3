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

import math
from dataclasses import dataclass

import numpy as np

from . import _kernel
from ._kinematics import euler_rates_from_body_rates
from ._model import kernel_model
from ._statics import _at_rest, _frozen, _unknown_index

__all__ = ["Modes", "linear_modes", "body_frequencies"]

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
    index, jac = _jacobian(model, state, t)
    values, vectors = np.linalg.eig(-jac)
    omega2 = np.clip(values.real, 0.0, None)
    order = np.argsort(omega2)[: count or values.size]
    dominant = [model.describe_state_index(int(index[np.argmax(np.abs(vectors[:, j]))])) for j in order]
    return Modes(frequency_hz=np.sqrt(omega2[order]) / (2 * np.pi), dominant=dominant)


def _jacobian(model, state, t):
    """The position coordinates' state indices (``_statics._unknown_index``) and their accelerations' Jacobian."""
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
    return index, jac


def body_frequencies(model, state, t=0.0):
    """Each body's own small-oscillation frequencies and its pose coordinates' (Hz): two (n_bodies, 6) arrays.

    The ropes follow the body statically (the Schur complement of their
    block of the stiffness: massless ropes), the other bodies held. The
    first array: the body's six modes' frequencies, lowest first; the
    second: each pose coordinate (x, y, z, Eq. 11's angles) moved alone,
    its other five held - how stiffly the ropes hold it. A box on three
    splayed cables: three modes on the cables' stretch (tens of Hz: its
    height and tilts), three on gravity (about 1 Hz: sway and turn); 0
    where nothing resists.
    """
    index, jac = _jacobian(model, state, t)
    stiff = -jac
    ropes = np.arange(6 * model.n_bodies, index.size)
    modes, alone = np.zeros((model.n_bodies, 6)), np.zeros((model.n_bodies, 6))
    for b in range(model.n_bodies):
        own = np.arange(6 * b, 6 * b + 6)
        k = stiff[np.ix_(own, own)]
        if ropes.size:
            k = k - stiff[np.ix_(own, ropes)] @ np.linalg.lstsq(stiff[np.ix_(ropes, ropes)], stiff[np.ix_(ropes, own)],
                                                                rcond=1e-12)[0]
        modes[b] = np.sort(np.sqrt(np.clip(np.linalg.eigvals(k).real, 0.0, None))) / (2 * math.pi)
        alone[b] = np.sqrt(np.clip(np.diag(k), 0.0, None)) / (2 * math.pi)
    return modes, alone
