"""Letting go of held bodies, at rest or moving: a free decay, or a trial that starts mid-motion."""

from __future__ import annotations

import numpy as np

from ._kernel import KIND_FIXED, KIND_PARTICLE
from ._kinematics import body_to_inertial

__all__ = ["let_go", "POSE_COORDINATES", "unresolved_coordinates"]

# A body's pose coordinates as a release's ``settled`` names them: its mass centre and Eq. 11's angles.
POSE_COORDINATES = ("x", "y", "z", "roll", "pitch", "yaw")

# A fixed point's velocity at the start: its track differenced over this (s).
_TRACK_STEP_S = 1e-4


def let_go(model, state, t, release):
    """``state`` (bodies held where ``release`` says, ropes settled) with the released bodies set moving.

    Each body of ``release`` takes its ``velocity`` (m/s, mass centre) and
    ``rates`` (rad/s, body axes); every rope particle moves with its rope:
    its velocity interpolated, by its distance along the rope, between
    the nodes on either side that are not particles (a body's attachment
    point, v + T (omega x r); a fixed point on its track). A ring's slide
    starts at rest. With every velocity zero, ``state`` itself.

    Returns
    -------
    ndarray, shape (n_state,)
        A new array; ``state`` is not modified.
    """
    moving = {model.body_names.index(name): (np.asarray(pose.get("velocity", np.zeros(3)), float),
                                             np.asarray(pose.get("rates", np.zeros(3)), float))
              for name, pose in release.items()}
    if not any(np.any(v) or np.any(w) for v, w in moving.values()):
        return state
    y = np.array(state, float)
    for b, (v, w) in moving.items():
        y[12 * b + 3: 12 * b + 6] = v
        y[12 * b + 9: 12 * b + 12] = w
    track = (model.fixed_positions([t + _TRACK_STEP_S]) - model.fixed_positions([t]))[0] / _TRACK_STEP_S
    turn = {b: body_to_inertial(*y[12 * b + 6: 12 * b + 9]) for b in range(model.n_bodies)}
    for segment, nodes in model.seg_nodes.items():
        along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(model.node_positions(y, segment, [t])[0], axis=0),
                                                    axis=1))]
        ends = {}
        for j, (kind, idx, arm) in enumerate(nodes):
            if kind == KIND_FIXED:
                ends[j] = track[idx]
            elif kind != KIND_PARTICLE:
                ends[j] = y[12 * idx + 3: 12 * idx + 6] + turn[idx] @ np.cross(y[12 * idx + 9: 12 * idx + 12], arm)
        known = sorted(ends)
        for j, (kind, idx, _) in enumerate(nodes):
            if kind != KIND_PARTICLE:
                continue
            a = max(k for k in known if k < j)
            b = min(k for k in known if k > j)
            share = (along[j] - along[a]) / (along[b] - along[a]) if along[b] > along[a] else 0.5
            o = model.o_vel + 3 * idx
            y[o: o + 3] = (1.0 - share) * ends[a] + share * ends[b]
    return y


def unresolved_coordinates(model, state, t, rate_hz, frequencies=None):
    """Per body, the pose coordinates a recording at ``rate_hz`` cannot set a start in: body -> tuple of names.

    A body's modes (``body_frequencies``: its ropes following statically)
    above the recording's Nyquist frequency (``rate_hz`` / 2) are not
    resolved by it: a start read from the recording leaves them at rest,
    settled by the ropes. As many coordinates are settled as the body has
    such modes, those the ropes hold most stiffly alone: a box on three
    splayed cables filmed at 10 Hz has three (15-22 Hz, its height and
    tilts on the cables' stretch) and keeps its sway and turn (0.6-0.9 Hz)
    where the recording has them. ``frequencies``: ``body_frequencies``'s
    result at ``state``, where the caller has it already.
    """
    from ._modes import body_frequencies

    modes, alone = body_frequencies(model, state, t) if frequencies is None else frequencies
    out = {}
    for b, name in enumerate(model.body_names):
        fast = int(np.sum(modes[b] > 0.5 * rate_hz))
        stiffest = np.argsort(-alone[b], kind="stable")[:fast]
        out[name] = tuple(POSE_COORDINATES[k] for k in sorted(stiffest))
    return out
