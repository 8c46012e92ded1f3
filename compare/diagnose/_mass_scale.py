"""The one thing a motion recording can never weigh: the rig's scale of mass and force.

Newton's law for every body and rope particle, M x'' = F(x, x') + M g,
keeps its solutions when every mass (a body's with its inertia, a rope's
weight per length) and every force coefficient (a rope's static and
viscous stiffness, its damping, a body's air drag) are multiplied by one
factor: gravity is an acceleration, a tracked point's track and a winch's
lengths are kinematic, and the recording measures positions, angles and
rope lengths.
So when the rig's tolerances free every mass and every force coefficient
of its model, that common factor is not identifiable from any recording
of the motion - only a measured force (a rope's tension) or a mass
weighed more tightly decides it. ``tests/test_tolerances.py`` checks the
symmetry on the slung-load rig (all scaled by 1.5: under 1e-9 m apart;
the rope's weight left out: over 0.1 mm).

The updating (``_updating``) simulates the rig once with every such
parameter's ln moved by ``PROBE``: a rig whose model holds a mass or a
force the tolerances leave fixed (a sheave's inertia, a mechanism's drag)
moves, and nothing is concluded; one that is a pure rescaling stays put to
the arithmetic's rounding. Then the scale is gauged: the parameter of the
direction that the lab knows best (the smallest tolerance) is held at its
nominal value and reported not identifiable, the others fitted relative to
it, and its prior added to theirs along the direction. Without the gauge,
finite differences taken over the parts of an exactly flat direction
never sum to zero (each has its own step's error), and the fit read
their remainder as information: on the slung-load flights it called the
load's mass identifiable to 0.04 %.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PROBE", "SCALE_NULL", "scale_direction", "is_pure_rescaling", "gauge_covariance", "scale_block"]

# Rope properties that carry the scale: forces (N, N s) and weight per length (N/m, the rope's mass with it).
SCALING_ROPE_FIELDS = ("static_stiffness", "viscous_stiffness", "viscous_damping", "weight_per_length")
# How far the probe moves every part of the direction, in ln p.
PROBE = 0.01
# The probe's response, over what its parts move the recording one at a time by the same step, below which the
# direction is a pure rescaling: set between the arithmetic's rounding and the share of the rig's forces any part
# a model includes carries, before either was measured. On the slung-load rig's own maneuver (4 s) the whole
# direction read 1e-11; left out of it, the rope's weight 3e-3, its stiffness or the load's mass 0.5 (the Maxwell
# stiffness and damping, which that still maneuver never strains, 7e-12: they carry no force there).
SCALE_NULL = 1e-6


def scale_direction(parameters):
    """Indices of the shared parameters whose ln coordinate scales a mass or a force (``parameters``: the rig's
    ``RigParameter`` list, a trial's own ones included)."""
    return [i for i, p in enumerate(parameters)
            if p.scale == "log" and not p.of_a_trial
            and (p.kind in ("mass", "drag_area") or (p.kind == "rope" and p.field in SCALING_ROPE_FIELDS))]


def is_pure_rescaling(response, parts):
    """Whether a probe's weighted response (sqrt chi2) is the rounding of a pure rescaling.

    ``parts``: each part's own weighted response to the same step (sqrt chi2).
    """
    total = float(np.sum(parts))
    return total > 0.0 and float(response) < SCALE_NULL * total


def gauge_covariance(cov, direction, held, tolerance):
    """The posterior covariance (in coordinates) with the held parameter's prior added along the direction.

    The others were fitted with ``held`` at nominal; the truth along the
    direction is anywhere its prior allows, which moves every part of the
    direction by the same ln. Returns a new array.
    """
    out = np.array(cov, float, copy=True)
    idx = np.ix_(direction, direction)
    out[idx] += tolerance[held] ** 2
    out[held, held] = tolerance[held] ** 2
    return out


def scale_block(parameters, direction, held, response_ratio):
    """The JSON ``calibration.unobservable_scale`` entry: what cannot be weighed, what is held, what would decide."""
    return {
        "parameters": [parameters[i].name for i in direction],
        "held": parameters[held].name,
        "probe_response_ratio": float(response_ratio),
        "why": "every mass and every force coefficient of the model is free: scaled together they leave the motion "
               "unchanged, so no recording of positions, angles and rope lengths can tell their common scale",
        "decided_by": "a measured force (a rope's tension) or a mass weighed more tightly than its tolerance",
    }
