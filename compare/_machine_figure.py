"""The machine drawn: its ropes, bodies and fixed points at one state, for `dragline rig` and the reports' first pages.

A ``MachinePicture`` holds only what a drawing needs (rope polylines, body
boxes, fixed points, in m, inertial axes with K down), so a report can draw
the machine without the model that made it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..simulate import assemble, default_maneuver, rope_group_sites, solve_statics

__all__ = ["MachinePicture", "machine_picture", "picture_at", "draw_machine", "marked_sites"]

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
    rings : tuple of (str, ndarray (3,))
        Each ring's site name (``ring_sites``) and position (m).
    rope_groups : dict
        Each rope group's name -> its ropes' names (the sites of a rope-type law: its damping's or its
        stiffness's tolerance groups).
    """

    name: str
    ropes: tuple
    bodies: tuple
    fixed: np.ndarray
    rings: tuple = ()
    rope_groups: dict = field(default_factory=dict)


def picture_at(model, state, t=0.0):
    """The ``MachinePicture`` of an assembled ``model`` at ``state`` (time ``t``, s)."""
    state = np.asarray(state, float)
    time = np.array([float(t)])
    ropes = tuple((seg, model.rig.ropes[seg].kind, model.node_positions(state[None], seg, time)[0])
                  for seg in model.seg_names)
    bodies = tuple((name, state[12 * b: 12 * b + 3].copy(), np.asarray(model.rig.bodies[name].size, float))
                   for b, name in enumerate(model.body_names))
    rings = []
    for seg, _, nodes in ropes:
        rings += [(site, nodes[j].copy()) for site, j in zip(model.rig.ropes[seg].ring_sites, model.ring_nodes(seg))]
    return MachinePicture(name=str(model.rig.name), ropes=ropes, bodies=bodies, fixed=model.fixed_positions(time)[0],
                          rings=tuple(rings), rope_groups=_rope_groups(model.rig))


def _rope_groups(rig):
    """Every rope group a rope-type law can name (its stiffness's and its damping's), name -> its ropes."""
    groups = {}
    for field_name in ("static_stiffness", "viscous_damping"):
        for name, ropes in rope_group_sites(rig, field_name).items():
            groups[name] = tuple(dict.fromkeys((*groups.get(name, ()), *ropes)))
    return groups


def machine_picture(rig, maneuver=None):
    """The rig at rest under its maneuver's first row (default: its own maneuver)."""
    maneuver = default_maneuver(rig) if maneuver is None else maneuver
    t0 = float(maneuver.time[0])
    model = assemble(rig, maneuver, "low")
    return picture_at(model, solve_statics(model, t0).state, t0)


def marked_sites(picture, sites):
    """What of ``picture`` the site names ``sites`` point at: ``(rings, ropes, bodies)``, index lists into
    ``picture.rings``, ``picture.ropes`` and ``picture.bodies`` (a ring by its site name, a rope by its name or
    its damping group's, a body by its name)."""
    sites = set(sites)
    ropes_named = {r for s in sites for r in picture.rope_groups.get(s, (s,))}
    ropes = [k for k, (name, _, _) in enumerate(picture.ropes) if name in ropes_named]
    bodies = [k for k, (name, _, _) in enumerate(picture.bodies) if name in sites]
    rings = [k for k, (site, _) in enumerate(picture.rings) if site in sites]
    return rings, ropes, bodies


def draw_machine(ax, picture, view=(0, 2), sites=()):
    """Draw ``picture`` on ``ax``: ``view`` the two inertial axes shown (0, 2: side; 1, 2: front), height up;
    ``sites`` (names of rings, ropes, damping groups or bodies) drawn in red, where a law was found."""
    from matplotlib.patches import Rectangle

    i, j = view
    rings, ropes, bodies = marked_sites(picture, sites)
    for k, (_, kind, nodes) in enumerate(picture.ropes):
        ax.plot(nodes[:, i], -nodes[:, j], "-", lw=(2.0 if kind == "chain" else 1.0) + 1.5 * (k in ropes),
                color="tab:red" if k in ropes else ROPE_COLOURS.get(kind, "k"))
    for k, (name, p, size) in enumerate(picture.bodies):
        ax.add_patch(Rectangle((p[i] - size[i] / 2, -p[j] - size[j] / 2), size[i], size[j], color="tab:orange",
                               alpha=0.6, ec="tab:red" if k in bodies else None, lw=2.0 if k in bodies else 0.0))
        ax.annotate(name, (p[i], -p[j]), fontsize=7)
    if len(picture.fixed):
        ax.plot(picture.fixed[:, i], -picture.fixed[:, j], "k^", ms=5)
    for k in rings:
        site, p = picture.rings[k]
        ax.plot(p[i], -p[j], "o", ms=12, mfc="none", mec="tab:red", mew=2.0)
        ax.annotate(site, (p[i], -p[j]), xytext=(6, 6), textcoords="offset points", fontsize=7, color="tab:red")
    ax.set_xlabel(f"{'xyz'[i]} (m)")
    ax.set_ylabel("height, -z (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
