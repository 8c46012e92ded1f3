"""A simulation's derivatives with respect to its rig's parameters, from the scheme's own tangent (``_tangent``).

Three links, each exact or nearly so:
1. the kernel arrays' derivatives (``tangent_model``): central differences of
   the assembly, which is algebra (no simulation), over ``ASSEMBLY_STEP``
   (a ten-thousandth) of each coordinate's scale: the arrays a parameter
   moves linearly (lengths, stiffnesses, masses, lever arms) come out exact
   to rounding, the rest to the step squared (a millionth of the scale was
   tried first: its rounding, 1e-16 of a metre over a 2e-9 m step, was
   then the error);
2. the starting pose's (``statics_tangent``): the equilibrium's own
   derivative, -G_q^-1 G_p, with G the static balance, its Jacobians from
   the tangent of the right-hand side;
3. the trajectory's (``integrate_tangent``): the Verlet steps'
   derivative, on the step schedule the plain run took.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import _kernel
from ._simulate import _held_pose, simulate
from ._model import assemble
from ._statics import _accel_index, _unknown_index
from ._tangent import TANGENT_FIELDS, TangentModel, integrate_tangent, make_tangent_work, rhs_tangent_at

__all__ = ["Sensitivities", "TangentUnavailable", "simulate_sensitivities", "tangent_model", "statics_tangent"]

# The assembly's difference step, in each direction's own scale (``simulate_sensitivities``'s ``steps``).
ASSEMBLY_STEP = 1e-4
# Singular values of the static balance's Jacobian below this share of its largest are neutral directions.
NEUTRAL_RCOND = 1e-10


class TangentUnavailable(ValueError):
    """The run starts in a way the tangent does not carry (``_tangent``): use finite differences."""


def tangent_model(model, plus, minus, steps):
    """The kernel arrays' derivatives, (field shape, nd) each, from models assembled at +-``steps`` per direction.

    Raises
    ------
    ValueError
        When a direction changes what is not a parameter (the discretization, the topology).
    """
    nd = len(steps)
    fields = {}
    for f in TANGENT_FIELDS:
        base = np.asarray(model.arrays[f], float)
        out = np.empty(base.shape + (nd,))
        for j, (p, m, h) in enumerate(zip(plus, minus, steps)):
            a, b = np.asarray(p.arrays[f], float), np.asarray(m.arrays[f], float)
            if a.shape != base.shape or b.shape != base.shape:
                raise ValueError(f"direction {j} changes the shape of the model's {f}")
            out[..., j] = (a - b) / (2.0 * h)
        fields[f] = out
    for f, value in model.arrays.items():
        if f in TANGENT_FIELDS or not isinstance(value, np.ndarray) or value.dtype.kind != "i":
            continue
        if any(not np.array_equal(value, other.arrays[f]) for other in (*plus, *minus)):
            raise ValueError(f"a direction changes the model's topology ({f})")
    return TangentModel(**fields)


def statics_tangent(model, y0, t0, dm, held=(), dheld=None):
    """The equilibrium's tangents (n_state, nd): G(q, p) = 0 differentiated, q the unknowns of the statics.

    ``held``: indices of bodies held at a pose; ``dheld`` (n_state, nd) their
    poses' tangents (rows 12 b .. 12 b + 8), zero elsewhere.
    """
    nd = next(iter(dm)).shape[-1]
    m = model.kernel_tuple()
    work = _kernel.make_work(m)
    unknown, rows = _unknown_index(model, held), _accel_index(model, held)
    dY = np.zeros((model.n_state, nd)) if dheld is None else np.array(dheld, float)
    _, dacc = rhs_tangent_at(t0, y0, dY, m, dm, work, make_tangent_work(m, nd))
    G_p = dacc[rows]
    seeds = np.zeros((model.n_state, len(unknown)))
    seeds[unknown, np.arange(len(unknown))] = 1.0
    zero = TangentModel(*(np.zeros(np.shape(a)[:-1] + (len(unknown),)) for a in dm))
    _, dacc = rhs_tangent_at(t0, y0, seeds, m, zero, work, make_tangent_work(m, len(unknown)))
    G_q = dacc[rows]
    # A rest pose can be neutral in some direction (a load on one rope turns freely about it): the statics keep
    # such a coordinate where their start put it, so its tangent is zero, the least-squares solution's choice.
    dY[unknown] = -np.linalg.lstsq(G_q, G_p, rcond=NEUTRAL_RCOND)[0]
    return dY


class Sensitivities:
    """A simulation and its states' derivatives along directions in its parameters.

    Attributes
    ----------
    result : SimulationResult
    tangents : ndarray (N, n_state, nd)
        d states / d coordinate j, per record (absolute Euler angles, as ``result.states``).
    scales : ndarray (nd,)
        Each coordinate's scale (``simulate_sensitivities``'s ``steps``).
    """

    def __init__(self, result, tangents, steps, plus, minus):
        self.result = result
        self.tangents = tangents
        self._steps, self._plus, self._minus = steps, plus, minus
        self.scales = np.asarray(steps, float) / ASSEMBLY_STEP

    def horizon(self):
        """The time (s) from which the tangent is no guide to a change of one scale in some direction (inf: never).

        That is the first record at which one scale of some coordinate (a
        tolerance, say) moves a body's mass centre or a rope's particle, by
        the tangent, further than the machine's size (the diagonal of the box
        around them and the fixed points at the start): no change of that
        size can be linear.
        Where ropes or chains turn slack and taut element by element, the
        scheme itself can be that sensitive - the derivative is exact, and
        differences over ever smaller steps grow with it - while any finite
        change ends within a fraction of a millimetre of the same motion
        (docs/sensitivities.md, "Where the derivative is no guide"). A fit
        over such an episode needs differences over its own step, not the
        tangent.
        """
        model = self.result.model
        rows = np.r_[[12 * b + c for b in range(model.n_bodies) for c in range(3)],
                     np.arange(model.o_part, model.o_vel)].astype(int)
        points = np.asarray(model.arrays["point_pos"], float)
        start = np.vstack([self.result.states[0, rows].reshape(-1, 3), points[0].reshape(-1, 3)])
        size = float(np.linalg.norm(start.max(axis=0) - start.min(axis=0)))
        moved = np.abs(self.tangents[:, rows, :] * self.scales).max(axis=(1, 2))
        beyond = np.flatnonzero(moved > size)
        return float(self.result.time[beyond[0]]) if len(beyond) else math.inf

    def of(self, output):
        """d output(result) / d coordinate j for each j: ``output`` maps a ``SimulationResult`` to an array.

        The output's own dependence on the states and on the rig (a marker's
        offset from the mass centre) is differenced centrally over the
        assembly's step, along the states' tangent: algebra, no simulation.
        """
        cols = []
        for j, h in enumerate(self._steps):
            up = dataclasses.replace(self.result, states=self.result.states + h * self.tangents[..., j],
                                     model=self._plus[j])
            down = dataclasses.replace(self.result, states=self.result.states - h * self.tangents[..., j],
                                       model=self._minus[j])
            cols.append((np.asarray(output(up), float) - np.asarray(output(down), float)) / (2.0 * h))
        return cols


def simulate_sensitivities(build, coords, steps, *, discretization="baseline", duration=10.0,
                           rate_hz=200.0, dt=None, statics_guess=None):
    """``simulate`` at ``build(coords)`` and its states' derivatives along each coordinate.

    Parameters
    ----------
    build : callable
        coords (k,) -> (Rig, Maneuver, physics): a mechanism's parameter can be a coordinate.
    coords : ndarray (k,)
    steps : ndarray (k,)
        Each coordinate's scale (a tolerance, say): the assembly is differenced
        over ``ASSEMBLY_STEP`` times it.

    Raises
    ------
    TangentUnavailable
        A release (the rig's, or the maneuver's ``start``) that sets bodies
        moving or settles some of their coordinates.
    """
    coords = np.asarray(coords, float)
    h = ASSEMBLY_STEP * np.asarray(steps, float)
    rig, maneuver, physics = build(coords)
    release = maneuver.start or rig.release or {}
    if any(np.any(p.get("velocity", 0)) or np.any(p.get("rates", 0)) or p.get("settled") for p in release.values()):
        raise TangentUnavailable("a release that sets bodies moving or settles some of their coordinates has no "
                                 "tangent yet")
    result = simulate(rig, maneuver, discretization, physics, duration=duration, rate_hz=rate_hz, dt=dt,
                      statics_guess=statics_guess)
    model = result.model
    m = model.kernel_tuple()
    plus, minus, dheld = [], [], np.zeros((model.n_state, len(coords)))
    held_names = tuple(release)
    for j in range(len(coords)):
        pair = []
        for sign in (1.0, -1.0):
            x = coords.copy()
            x[j] += sign * h[j]
            r, mv, ph = build(x)
            pair.append((r, assemble(r, mv, discretization, physics=ph), mv.start or r.release))
        plus.append(pair[0][1])
        minus.append(pair[1][1])
        if held_names:
            hp, hm = _held_pose(pair[0][0], pair[0][2]), _held_pose(pair[1][0], pair[1][2])
            for name in held_names:
                b = model.body_names.index(name)
                dheld[12 * b: 12 * b + 3, j] = (hp[name][0] - hm[name][0]) / (2.0 * h[j])
                dheld[12 * b + 6: 12 * b + 9, j] = (hp[name][1] - hm[name][1]) / (2.0 * h[j])
    dm = tangent_model(model, plus, minus, h)
    held = tuple(model.body_names.index(name) for name in held_names)
    t0 = float(result.time[0])
    dY0 = statics_tangent(model, result.states[0], t0, dm, held, dheld)
    out_dt = 1.0 / rate_hz
    _, tangents = integrate_tangent(result.states[0], dY0, t0, out_dt, result.substeps, m, dm,
                                    _kernel.make_work(m), make_tangent_work(m, len(coords)))
    return Sensitivities(result, tangents, h, plus, minus)
