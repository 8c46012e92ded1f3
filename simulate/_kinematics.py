"""Euler angles, the body-to-inertial matrix of Eq. 11, and body rates.

Sequence (seed paper section 2.1, docs/conventions.md): from the inertial frame rotate
pitch ``theta`` about J, then roll ``phi`` about the new I, then yaw ``psi``
about the new K::

    T_B->I = R_J(theta) @ R_I(phi) @ R_K(psi)

The columns of ``T`` are the body axes I_B, J_B, K_B in inertial components,
so ``r_inertial = T @ r_body`` (Eq. 10). The inertial K axis points down.

A body's output channels (roll, pitch, yaw: the angles about its I, J and K
axes) may follow another Tait-Bryan sequence, named per body in the rig
(``euler_sequence``): ``matrix_from_angles`` and ``angles_from_matrix``
translate. The simulator's state keeps Eq. 11's sequence whatever the
output's (``_kernel.REBASE_ROLL`` says how it avoids its singularity).

All functions are vectorised over leading (time) axes and never modify their
inputs. Angles in rad, rates in rad/s.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = [
    "PAPER_SEQUENCE",
    "EULER_SEQUENCES",
    "matrix_from_angles",
    "angles_from_matrix",
    "body_to_inertial",
    "euler_from_matrix",
    "body_rates_from_euler_rates",
    "euler_rates_from_body_rates",
]

# Intrinsic rotations about the body's axes, in order: the paper's pitch (J), then roll (I), then yaw (K).
PAPER_SEQUENCE = "YXZ"
# Every sequence of three different axes (Tait-Bryan), so that each angle is a roll, a pitch or a yaw.
EULER_SEQUENCES = ("YXZ", "ZYX", "XYZ", "XZY", "YZX", "ZXY")
_ANGLE_OF_AXIS = {"X": 0, "Y": 1, "Z": 2}  # roll about I, pitch about J, yaw about K


def matrix_from_angles(roll, pitch, yaw, sequence=PAPER_SEQUENCE):
    """T_B->I from a body's output angles in its ``sequence`` (``EULER_SEQUENCES``; Eq. 11 for the paper's).

    Returns
    -------
    T : ndarray, shape ``S + (3, 3)``
    """
    if sequence == PAPER_SEQUENCE:
        return body_to_inertial(roll, pitch, yaw)
    from scipy.spatial.transform import Rotation

    angles = np.stack(np.broadcast_arrays(*(np.asarray(a, float) for a in (roll, pitch, yaw))), axis=-1)
    ordered = angles[..., [_ANGLE_OF_AXIS[a] for a in _checked(sequence)]]
    flat = Rotation.from_euler(sequence, ordered.reshape(-1, 3)).as_matrix()
    return flat.reshape(angles.shape[:-1] + (3, 3))


def angles_from_matrix(T, sequence=PAPER_SEQUENCE):
    """A body's output angles (roll, pitch, yaw, rad) in its ``sequence`` from T_B->I.

    The middle rotation lies in [-90, 90] deg, the others in (-180, 180];
    at the middle one's +-90 deg (the sequence's gimbal lock) the first and
    last are not apart, and the first is set to zero.
    """
    if sequence == PAPER_SEQUENCE:
        return euler_from_matrix(T)
    from scipy.spatial.transform import Rotation

    T = np.asarray(T, float)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Gimbal lock detected")
        ordered = Rotation.from_matrix(T.reshape(-1, 3, 3)).as_euler(_checked(sequence))
    angles = np.empty_like(ordered)
    angles[:, [_ANGLE_OF_AXIS[a] for a in sequence]] = ordered
    angles = angles.reshape(T.shape[:-2] + (3,))
    return angles[..., 0], angles[..., 1], angles[..., 2]


def _checked(sequence):
    if sequence not in EULER_SEQUENCES:
        raise ValueError(f"euler sequence {sequence!r} is none of {', '.join(EULER_SEQUENCES)}")
    return sequence


def body_to_inertial(roll, pitch, yaw):
    """Eq. 11: the matrix T_B->I for Euler angles.

    Parameters
    ----------
    roll, pitch, yaw : array_like
        phi, theta, psi (rad), broadcast together; shape ``S``.

    Returns
    -------
    T : ndarray, shape ``S + (3, 3)``
        Columns are the body axes in inertial components.
    """
    phi, theta, psi = np.broadcast_arrays(
        np.asarray(roll, float), np.asarray(pitch, float), np.asarray(yaw, float)
    )
    sf, cf = np.sin(phi), np.cos(phi)
    st, ct = np.sin(theta), np.cos(theta)
    ss, cs = np.sin(psi), np.cos(psi)
    T = np.empty(phi.shape + (3, 3))
    T[..., 0, 0] = cs * ct + ss * sf * st
    T[..., 0, 1] = -ss * ct + cs * sf * st
    T[..., 0, 2] = cf * st
    T[..., 1, 0] = ss * cf
    T[..., 1, 1] = cs * cf
    T[..., 1, 2] = -sf
    T[..., 2, 0] = -cs * st + ss * sf * ct
    T[..., 2, 1] = ss * st + cs * sf * ct
    T[..., 2, 2] = cf * ct
    return T


def euler_from_matrix(T):
    """Invert Eq. 11: Euler angles from a body-to-inertial matrix.

    Derived from Eq. 11 itself rather than the paper's Eqs. 19-21, which read
    the marker-frame matrix transposed (docs/conventions.md). The atan2 forms keep full
    quadrant information and stay accurate near +-90 deg of pitch; only roll
    = +-90 deg (gimbal lock of this sequence) is singular.

    Parameters
    ----------
    T : array_like, shape ``S + (3, 3)``

    Returns
    -------
    roll, pitch, yaw : ndarray, shape ``S`` (rad)
    """
    T = np.asarray(T, float)
    roll = np.arctan2(-T[..., 1, 2], np.hypot(T[..., 1, 0], T[..., 1, 1]))
    pitch = np.arctan2(T[..., 0, 2], T[..., 2, 2])
    yaw = np.arctan2(T[..., 1, 0], T[..., 1, 1])
    return roll, pitch, yaw


def body_rates_from_euler_rates(roll, yaw, roll_rate, pitch_rate, yaw_rate):
    """Body-frame angular velocity (p, q, r) from Euler-angle rates.

    omega = theta' J_I + phi' I_O + psi' K_T, resolved on the body axes.

    Returns
    -------
    p, q, r : ndarray (rad/s)
    """
    sf, cf = np.sin(roll), np.cos(roll)
    ss, cs = np.sin(yaw), np.cos(yaw)
    p = pitch_rate * ss * cf + roll_rate * cs
    q = pitch_rate * cs * cf - roll_rate * ss
    r = yaw_rate - pitch_rate * sf
    return p, q, r


def euler_rates_from_body_rates(roll, yaw, p, q, r):
    """Eq. 3: Euler-angle rates from body rates (singular at roll = +-90 deg).

    Returns
    -------
    roll_rate, pitch_rate, yaw_rate : ndarray (rad/s)
    """
    sf, cf = np.sin(roll), np.cos(roll)
    ss, cs = np.sin(yaw), np.cos(yaw)
    pitch_rate = (p * ss + q * cs) / cf
    roll_rate = p * cs - q * ss
    yaw_rate = r + pitch_rate * sf
    return roll_rate, pitch_rate, yaw_rate
