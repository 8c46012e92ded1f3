"""Letting go of held bodies, at rest or moving: a free decay, or a trial that starts mid-motion."""

from __future__ import annotations

import numpy as np

from ._kernel import KIND_FIXED, KIND_PARTICLE
from ._kinematics import body_to_inertial

__all__ = ["let_go"]

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
