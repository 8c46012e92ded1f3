"""The machine's own scale: the diagnosis's floors, set on the dragline, carried to any rig by similarity.

The diagnosis's absolute constants were set for the paper's 1/16-scale
dragline: the floors below which a low-passed mismatch is not physics
(``_locate.STRUCTURE_FLOOR``: the reconstruction's own systematic errors,
a fraction of a millimetre in its lab), the lowest noise level believed
(``NOISE_FLOOR``), the offsets marker placement and calibration may leave
(``_objective.OFFSET_PRIOR``) and those that are a finding
(``OFFSET_FINDING``, ``_steps.OFFSET_LIMIT``), and the low-pass that
separates structure from noise (``LOWPASS_S``: it passes the dragline's
swings, 0.6-2.5 Hz, about seven times its slowest).

A machine's slowest swing sets both its scales under Froude similarity
(gravity and the geometry's proportions the same): its pendulum length,
l = g / (2 pi f1)^2, and its period 1 / f1. A capture volume, a marker's
placement and a calibration's systematic error grow with the machine, so
the length constants scale by l / l_ref; the low-pass by the period ratio,
so that it passes the same band of the machine's own swings; angles are the
same at every scale. A 50 m crane swinging once in 14 s gets floors 25
times the dragline's and a 0.5 s low-pass; the dragline gets its own
values exactly (its slowest swing is ``REFERENCE_SWING_HZ``, computed the
same way).
"""

from __future__ import annotations

from dataclasses import dataclass

from ...simulate import assemble, default_maneuver, linear_modes, solve_statics

__all__ = ["MachineScale", "machine_scale", "REFERENCE", "FREE_HZ"]

# The built-in dragline's slowest swing (Hz) at rest under the dig's first row (baseline discretization, springs
# Ks + Kv): ``machine_scale(load_rig())`` gives it to 1e-10 (the last digits are the LAPACK build's; the scale's
# three-digit rounding of its ratios leaves the dragline's own constants exact either way).
REFERENCE_SWING_HZ = 0.35231780232859233
REFERENCE_G = 9.81
# Below this a mode is a motion nothing resists (a body spinning about its rope: the differences' noise), not a
# swing; `dragline rig` prints such a mode as free.
FREE_HZ = 1e-3
LENGTH_KINDS = ("position", "rope_length")


@dataclass(frozen=True)
class MachineScale:
    """A machine's slowest swing (Hz) under its gravity (m/s^2), and the scales it sets against the dragline's."""

    swing_hz: float = REFERENCE_SWING_HZ
    g: float = REFERENCE_G

    @property
    def length(self):
        """The machine's pendulum length over the dragline's (three significant digits)."""
        return _rounded((self.g / REFERENCE_G) * (REFERENCE_SWING_HZ / self.swing_hz) ** 2)

    @property
    def time(self):
        """The machine's slowest period over the dragline's (three significant digits)."""
        return _rounded(REFERENCE_SWING_HZ / self.swing_hz)

    def floor(self, table, kind, default=None):
        """``table[kind]`` (a constant set on the dragline: m, rad) at this machine's scale."""
        value = table.get(kind, default)
        if value is None:
            return None
        return value * self.length if kind in LENGTH_KINDS else value

    def lowpass_width(self, lowpass_s, dt):
        """Samples of the structure low-pass (odd, at least 3) for a dragline duration ``lowpass_s`` at step ``dt``."""
        return max(3, int(round(lowpass_s * self.time / dt)) | 1)


def _rounded(ratio):
    """A scale ratio to three significant digits: the scale law is good to a few percent, and a recording's own
    maneuver (its first row read back from a CSV) must not move the floors in their last digits."""
    return float(f"{ratio:.3g}")


# The dragline's own scale: every constant as it was set.
REFERENCE = MachineScale()


def machine_scale(rig, maneuver=None, modes=None):
    """The rig's ``MachineScale``: its slowest swing at rest under the maneuver's first row (default: its own),
    from ``modes`` when they are already at hand (``simulate.linear_modes``, lowest first, the slowest swing among
    them), else computed at the baseline discretization.

    A swing is a mode above ``FREE_HZ`` that a body dominates; a rig with none (a line between fixed
    points, whose slowest mode is elastic, not a swing under gravity) keeps the dragline's scale.
    """
    if modes is None:
        maneuver = default_maneuver(rig) if maneuver is None else maneuver
        t0 = float(maneuver.time[0])
        model = assemble(rig, maneuver, "baseline", dissipation=False)
        modes = linear_modes(model, solve_statics(model, t0).state, t0)
    swings = [float(f) for f, what in zip(modes.frequency_hz, modes.dominant)
              if f >= FREE_HZ and what.startswith("body ")]
    if not swings:
        return MachineScale(g=REFERENCE_G)
    return MachineScale(swing_hz=min(swings), g=float(rig.g))
