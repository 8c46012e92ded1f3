"""The dragline's own maneuver: the seed paper's dig (section 4), as the built-in rig's data.

The one module of the simulator that knows the dragline's winches by name
(``hoist``, ``drag``): the rest reads winches from the rig file.
"""

from __future__ import annotations

import numpy as np

from ._maneuver import Maneuver

__all__ = ["dig_maneuver", "BUILT_IN_MANEUVERS", "DIG_PHASE1_S", "DIG_PHASE3_DRAG_M_S", "DIG_RAMP_S"]

# The text's reading fitted to the paper's published poses and peak table
# (tools/identify_paper_rig.py; docs/model.md, "The dig maneuver").
DIG_PHASE1_S = 2.4312
DIG_PHASE3_DRAG_M_S = 0.4214
DIG_RAMP_S = 0.0119
REEL_SPEED_LIMIT = 1.3  # m/s (seed paper, section 3.1)


def dig_maneuver(phase1_s=DIG_PHASE1_S, phase3_drag_m_s=DIG_PHASE3_DRAG_M_S, ramp_s=DIG_RAMP_S, step_s=0.005):
    """The seed paper's dig maneuver (section 4), read as docs/model.md says.

    What the text fixes: hoist 8.6 -> 10.1 m and drag 4.2 -> 1.4 m; phase 1
    with the hoist paying out at 0.36 m/s and the drag winding in at 0.30
    m/s; phase 2, 1 s, the hoist still and the drag at 0.61 m/s; phase 3,
    2 s; phase 4, 1 s, the hoist still; then both reels stop. Its phase-1
    duration and phase-3 drag speed do not add up with the rest, so they are
    free: the phase-3 hoist speed and the phase-4 drag speed follow from the
    end lengths. The defaults are the reading fitted to the paper's peak
    table; ``phase1_s=2.5, phase3_drag_m_s=0.48, ramp_s=0`` is the literal
    reading (phase 3 hoist 0.30 m/s, phase 4 drag 0.48 m/s, stop at 6.5 s).

    Parameters
    ----------
    phase1_s : float
        Phase 1's duration (s).
    phase3_drag_m_s : float
        The drag's winding speed in phase 3 (m/s).
    ramp_s : float
        Each change of reel speed is spread over this time (s; a motor
        cannot step): the lengths are their moving average over the last
        ``ramp_s``, so the start and end lengths are kept. 0: speed steps.
    step_s : float
        Table spacing (s) where ``ramp_s`` > 0 (with steps, the phase edges
        alone are exact).

    Raises
    ------
    ValueError
        When a derived speed is negative or above the reels' 1.3 m/s.
    """
    hoist3 = (10.1 - 8.6 - 0.36 * phase1_s) / 2.0
    drag4 = 4.2 - 1.4 - 0.30 * phase1_s - 0.61 - 2.0 * phase3_drag_m_s
    for what, speed in (("phase-3 hoist", hoist3), ("phase-3 drag", phase3_drag_m_s), ("phase-4 drag", drag4)):
        if not 0.0 <= speed <= REEL_SPEED_LIMIT:
            raise ValueError(f"this dig reading needs a {what} speed of {speed:.3g} m/s, "
                             f"outside 0-{REEL_SPEED_LIMIT} m/s")
    if not (phase1_s > 0 and ramp_s >= 0 and step_s > 0):
        raise ValueError("the dig's phase-1 duration and table step must be positive and its ramp not negative")
    phases = [(phase1_s, 0.36, -0.30), (1.0, 0.0, -0.61), (2.0, hoist3, -phase3_drag_m_s), (1.0, 0.0, -drag4)]
    edges = np.cumsum([0.0] + [p[0] for p in phases])
    if ramp_s == 0:
        time_s = edges
    else:
        knots = np.append(edges, edges[-1] + ramp_s)  # every phase edge, and the last ramp's end
        grid = np.arange(0.0, knots[-1], step_s)
        time_s = np.union1d(grid[np.min(np.abs(grid[:, None] - knots[None, :]), axis=1) > 1e-6], knots)
    lengths = []
    for column, start in ((1, 8.6), (2, 4.2)):
        at_edges = start + np.concatenate([[0.0], np.cumsum([p[0] * p[column] for p in phases])])
        if ramp_s == 0:
            lengths.append(at_edges)
        else:
            lengths.append((_integral(time_s, edges, at_edges) - _integral(time_s - ramp_s, edges, at_edges)) / ramp_s)
    return Maneuver(time_s, {"hoist": lengths[0], "drag": lengths[1]})


def _integral(t, knots, values):
    """The exact integral up to ``t`` of piecewise-linear ``values``, held outside the knots."""
    pad = 1.0 + max(knots[0] - np.min(t), np.max(t) - knots[-1], 0.0)
    knots = np.concatenate([[knots[0] - pad], knots, [knots[-1] + pad]])
    values = np.concatenate([[values[0]], values, [values[-1]]])
    at_knots = np.concatenate([[0.0], np.cumsum(0.5 * (values[1:] + values[:-1]) * np.diff(knots))])
    i = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2)
    return at_knots[i] + (t - knots[i]) * 0.5 * (values[i] + np.interp(t, knots, values))


# A rig file names one of these as its ``maneuver`` (the built-in dragline: ``"dig"``).
BUILT_IN_MANEUVERS = {"dig": dig_maneuver}
