"""Where the rig's motion-capture markers are in a simulated run.

Names: body markers ``<body>.<marker>`` (``bucket.alpha``), rope markers
``<rope>.m<k>`` (``hoist_rope.m1``, k from 1 in the order of the rig's
``marker_distances``, counted from the rope's end at the body). In VICON
CSV files the same names read ``bucket:alpha``.
"""

from __future__ import annotations

import numpy as np

from ._kinematics import matrix_from_angles

__all__ = ["marker_names", "marker_positions", "body_marker_positions"]


def marker_names(rig):
    """All marker names of a rig, bodies first (in rig order), then ropes."""
    names = [f"{b}.{m}" for b, spec in rig.bodies.items() for m in spec.markers]
    names += [f"{r}.m{k + 1}" for r, spec in rig.ropes.items() for k in range(len(spec.marker_distances))]
    return names


def body_marker_positions(table, rig, body):
    """Inertial positions of one body's markers from a trajectory table.

    Eq. 10 with the marker's body-frame point: x_B + T_B->I (p - cg), T from the body's output angles.

    Returns
    -------
    ndarray, shape (N, M, 3)
        In the order of ``rig.bodies[body].markers`` (m).
    """
    spec = rig.bodies[body]
    T = matrix_from_angles(table[f"{body}.roll"], table[f"{body}.pitch"], table[f"{body}.yaw"], spec.euler_sequence)
    centre = np.column_stack([table[f"{body}.{q}"] for q in "xyz"])
    arms = np.array([p - spec.cg_body for p in spec.markers.values()]).reshape(-1, 3)
    return centre[:, None, :] + np.einsum("nij,mj->nmi", T, arms)


def marker_positions(result):
    """Every marker's inertial position in a simulated run.

    Parameters
    ----------
    result : SimulationResult

    Returns
    -------
    names : list of str
    positions : ndarray, shape (N, M, 3)
        m; NaN for a rope marker beyond the rope's current length.
    """
    rig = result.model.rig
    table = result.table
    blocks = [body_marker_positions(table, rig, b) for b in rig.bodies if rig.bodies[b].markers]
    for rope, spec in rig.ropes.items():
        if spec.marker_distances:
            blocks.append(result.rope_points(rope, spec.marker_distances))
    return marker_names(rig), np.concatenate(blocks, axis=1)
