"""The machine drawn: its ropes, bodies and fixed points at one state, for `dragline rig` and the reports' first pages.

A ``MachinePicture`` holds only what a drawing needs (rope polylines, body
boxes, fixed points, in m, inertial axes with K down), so a report can draw
the machine without the model that made it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..simulate import assemble, default_maneuver, solve_statics

__all__ = ["MachinePicture", "machine_picture", "picture_at", "draw_machine"]

ROPE_COLOURS = {"rope": "tab:blue", "cable": "tab:cyan", "chain": "tab:gray"}


@dataclass(frozen=True)
class MachinePicture:
    """A machine at one state.

    Attributes
    ----------
    name : str
    ropes : tuple of (str, str, ndarray (k, 3))
        Each rope's name, kind and nodes along it (m).
    bodies : tuple of (str, ndarray (3,), ndarray (3,))
        Each body's name, mass centre (m) and box size (m).
    fixed : ndarray (F, 3)
        The fixed points (m).
    """

    name: str
    ropes: tuple
    bodies: tuple
    fixed: np.ndarray


def picture_at(model, state, t=0.0):
    """The ``MachinePicture`` of an assembled ``model`` at ``state`` (time ``t``, s)."""
    state = np.asarray(state, float)
    time = np.array([float(t)])
    ropes = tuple((seg, model.rig.ropes[seg].kind, model.node_positions(state[None], seg, time)[0])
                  for seg in model.seg_names)
    bodies = tuple((name, state[12 * b: 12 * b + 3].copy(), np.asarray(model.rig.bodies[name].size, float))
                   for b, name in enumerate(model.body_names))
    return MachinePicture(name=str(model.rig.name), ropes=ropes, bodies=bodies, fixed=model.fixed_positions(time)[0])


def machine_picture(rig, maneuver=None):
    """The rig at rest under its maneuver's first row (default: its own maneuver)."""
    maneuver = default_maneuver(rig) if maneuver is None else maneuver
    t0 = float(maneuver.time[0])
    model = assemble(rig, maneuver, "low")
    return picture_at(model, solve_statics(model, t0).state, t0)


def draw_machine(ax, picture, view=(0, 2)):
    """Draw ``picture`` on ``ax``: ``view`` the two inertial axes shown (0, 2: side; 1, 2: front), height up."""
    from matplotlib.patches import Rectangle

    i, j = view
    for _, kind, nodes in picture.ropes:
        ax.plot(nodes[:, i], -nodes[:, j], "-", lw=2.0 if kind == "chain" else 1.0, color=ROPE_COLOURS.get(kind, "k"))
    for name, p, size in picture.bodies:
        ax.add_patch(Rectangle((p[i] - size[i] / 2, -p[j] - size[j] / 2), size[i], size[j], color="tab:orange",
                               alpha=0.6))
        ax.annotate(name, (p[i], -p[j]), fontsize=7)
    if len(picture.fixed):
        ax.plot(picture.fixed[:, i], -picture.fixed[:, j], "k^", ms=5)
    ax.set_xlabel(f"{'xyz'[i]} (m)")
    ax.set_ylabel("height, -z (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
