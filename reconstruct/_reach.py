"""Where a recorded point can be: within reach of the machine it films."""

from __future__ import annotations

import numpy as np

__all__ = ["MAX_REACHES", "check_within_reach"]

# A capture volume is a few times the machine it films: a marker this many of the machine's reaches from its
# fixed points is a wrong unit or a corrupt cell, not a marker on it.
MAX_REACHES = 100.0


def check_within_reach(positions, names, rig, noun="marker"):
    """ValueError naming the first marker (``noun``) and frame further than ``MAX_REACHES`` reaches from the
    rig's fixed points' centre (positions (frames, markers, 3), m; NaN is a gap)."""
    points = np.array(list(rig.fixed_points.values()), float).reshape(-1, 3)
    centre = points.mean(axis=0) if len(points) else np.zeros(3)
    limit = MAX_REACHES * rig.reach
    with np.errstate(invalid="ignore", over="ignore"):
        far = np.linalg.norm(np.asarray(positions, float) - centre, axis=-1) > limit
    if np.any(far):
        frame, marker = np.argwhere(far)[0]
        value = np.asarray(positions, float)[frame, marker]
        raise ValueError(f"{noun} {names[marker]} at frame {frame + 1} is at ({value[0]:.3g}, {value[1]:.3g}, "
                         f"{value[2]:.3g}) m, more than {limit:.3g} m ({MAX_REACHES:g} times the rig's reach) from "
                         "its fixed points: a unit or a cell is wrong")
