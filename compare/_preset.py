"""What a comparison singles out for one machine: channels, tolerances, free-decay and figure channels.

The dragline's comparison is the paper's (its rig file says ``[report]
preset = "paper"``): the tolerances of ``_compare.TOLERANCES``, the peak
table, Figs. 8-21. Any other machine gets the same kinds of pages from its
own rig, by the same rules the paper's numbers follow:

- position (and rope length) within 5 % of the machine's largest body
  (the paper's 20 mm is 5 % of its 0.38 m bucket);
- angle within 3 deg (the paper's "close match");
- velocity within 10 % of the measured peak speed, body rate within 20 %
  of the measured peak rate (the paper's 0.1 m/s of 0.99 m/s and 0.5 rad/s
  of 2.4 rad/s);
- the free decay of every position and angle the rig file's ``[report]
  decay_channels`` name (else every body's that the measurement moves in
  by more than ``ISO_MIN_RANGE`` tolerances), the figures its
  ``overlay_channels`` name (else every winch's rope length and every
  body's position and angles, the moving ones).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..simulate import BODY_QUANTITIES, rope_channels, trajectory_columns

__all__ = ["ComparisonPreset", "comparison_preset"]

_PLOTTED = ("x", "y", "z", "roll", "pitch", "yaw")
_AXIS_LABELS = {"position": "{q} position (m)", "angle": "{q} angle (deg)", "velocity": "{q} velocity (m/s)",
                "rate": "{q} body rate (deg/s)", "rope_length": "length (m)"}


@dataclass(frozen=True)
class ComparisonPreset:
    """The channels and tolerances a comparison uses.

    Attributes
    ----------
    name : str
        ``paper`` (the dragline study's) or ``rig`` (built from the rig).
    machine : str
    channels : tuple of str
        Trajectory channels, in the table's order.
    tolerances : dict
        Kind -> ``{"rms", "unit", "reason"}`` (SI).
    decay_channels : tuple of str
    decay_panels : tuple of str
        At most four, drawn on the free-decay page.
    figures : tuple
        ``(label, channel, caption, y label)`` per figure.
    study_channel : str
        The channel of the discretization study's figure.
    """

    name: str
    machine: str
    channels: tuple
    tolerances: dict
    decay_channels: tuple
    decay_panels: tuple
    figures: tuple
    study_channel: str

    def as_json(self):
        return {"name": self.name, "machine": self.machine, "decay_channels": list(self.decay_channels),
                "decay_panels": list(self.decay_panels), "figures": [list(f) for f in self.figures],
                "study_channel": self.study_channel}


def comparison_preset(rig=None, measured=None):
    """The comparison preset of ``rig`` (default the built-in dragline: the paper's).

    Parameters
    ----------
    rig : Rig, optional
    measured : pandas.DataFrame, optional
        The measured table, whose peak speed and rate set the velocity and
        rate tolerances of a rig that is not the paper's.
    """
    from ._compare import TOLERANCES
    from ._paper import FREE_DECAY_CHANNELS
    from ._paper import DECAY_PANELS, FIGURES, STUDY_CHANNEL

    if rig is None or rig.report.get("preset") == "paper":
        return ComparisonPreset(
            "paper", "the paper's 1/16-scale dragline" if rig is None else rig.name,
            tuple(trajectory_columns(rig)[1:]), {k: dict(v) for k, v in TOLERANCES.items()}, FREE_DECAY_CHANNELS,
            DECAY_PANELS, FIGURES, STUDY_CHANNEL)
    channels = tuple(trajectory_columns(rig)[1:])
    bodies = list(rig.bodies)
    tolerances = _rig_tolerances(rig, measured, bodies)
    decay = tuple(c for c in rig.report.get("decay_channels", ()) if c in channels) or _moving(
        tuple(f"{b}.{q}" for b in bodies for q in _PLOTTED), measured, tolerances)
    overlay = tuple(c for c in rig.report.get("overlay_channels", ()) if c in channels) or _moving(
        tuple(rope_channels(rig)) + tuple(f"{b}.{q}" for b in bodies for q in _PLOTTED), measured, tolerances)
    figures = tuple((str(i + 1), ch, f"Measured and predicted {_describe(ch)} vs. time.", _axis_label(ch))
                    for i, ch in enumerate(overlay))
    return ComparisonPreset("rig", rig.name, channels, tolerances, decay, decay[:4], figures, decay[0])


def _moving(channels, measured, tolerances):
    """The channels the measurement moves in by more than ``ISO_MIN_RANGE`` tolerances (all, when none
    does or nothing was measured): a still channel's figure would show noise against noise."""
    from ._compare import ISO_MIN_RANGE, channel_kind

    if measured is None:
        return channels
    moving = []
    for ch in channels:
        values = measured[ch].to_numpy(float) if ch in measured.columns else np.array([])
        values = values[np.isfinite(values)]
        if values.size and np.ptp(values) > ISO_MIN_RANGE * tolerances[channel_kind(ch)]["rms"]:
            moving.append(ch)
    return tuple(moving) or channels


def _rig_tolerances(rig, measured, bodies):
    largest = max(float(np.max(rig.bodies[b].size)) for b in bodies)
    position = 0.05 * largest
    speed = _peak(measured, bodies, ("vx", "vy", "vz"))
    rate = _peak(measured, bodies, ("p", "q", "r"))
    return {
        "position": {"rms": position, "unit": "m",
                     "reason": f"5 % of the largest body ({largest:g} m), the paper's rule (20 mm of a 0.38 m bucket)"},
        "angle": {"rms": math.radians(3.0), "unit": "rad",
                  "reason": "3 deg: the paper's close match of a pitch angle, whatever the machine's size"},
        "velocity": {"rms": 0.1 * speed if speed else 0.1, "unit": "m/s",
                     "reason": f"10 % of the measured peak speed ({speed:.3g} m/s), the paper's rule"
                     if speed else "0.1 m/s: no measured speed to scale from"},
        "rate": {"rms": 0.2 * rate if rate else 0.5, "unit": "rad/s",
                 "reason": f"20 % of the measured peak body rate ({rate:.3g} rad/s), the paper's rule"
                 if rate else "0.5 rad/s: no measured rate to scale from"},
        "rope_length": {"rms": position, "unit": "m", "reason": "as for positions: from the same markers"},
    }


def _peak(measured, bodies, quantities):
    """The largest norm over time of any body's three ``quantities`` as measured; 0 when none is there."""
    if measured is None:
        return 0.0
    best = 0.0
    for body in bodies:
        group = [f"{body}.{q}" for q in quantities]
        if not all(c in measured.columns for c in group):
            continue
        values = np.linalg.norm(measured[group].to_numpy(float), axis=1)
        if np.isfinite(values).any():
            best = max(best, float(np.nanmax(values)))
    return best


def _describe(channel):
    entity, quantity = channel.rsplit(".", 1)
    if quantity == "length":
        return f"{entity} length"
    return f"{entity} {quantity}"


def _axis_label(channel):
    from ._compare import channel_kind

    quantity = channel.rsplit(".", 1)[1]
    return _AXIS_LABELS[channel_kind(channel)].format(q=quantity.capitalize() if quantity in BODY_QUANTITIES else quantity)
