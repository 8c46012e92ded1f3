"""``dragline rig``: check a rig file and say what machine it describes.

Loads a rig (a built-in machine's name or a TOML file) through its schema,
then prints what it holds - bodies, points (and which the rig's own
maneuver moves), ropes with their kind and path, winches, ring sites - its
static equilibrium, its lowest small-oscillation modes (the conservative
model linearized there) and the stable time step; ``--figure`` draws it at
rest, ``--json`` writes the same as one JSON object.
"""

from __future__ import annotations

import sys

import numpy as np
from dragline.capture import atomic_file, write_json
from dragline.simulate import (
    StaticsError,
    assemble,
    default_maneuver,
    linear_modes,
    load_rig,
    solve_statics,
    stable_time_step,
)

from dragline.compare import draw_machine, machine_scale, picture_at
from dragline.compare.diagnose import FREE_HZ

from ._guard import guard_outputs
from ._options import check_output_path, discretization_from_args

# Modes listed: a few above the rigid swings is what a user checks a model by.
MODES_SHOWN = 8


def add_parser(sub):
    p = sub.add_parser("rig", help="check a rig file and say what machine it describes",
                       description="Check a rig (a built-in machine's name or a TOML file) and print its bodies, "
                                   "points, ropes and their paths, winches and ring sites, its static equilibrium, "
                                   "lowest modes and stable time step.")
    p.add_argument("rig", metavar="NAME|FILE", help="a built-in machine (dragline, pendulum, ...) or a rig TOML file")
    p.add_argument("--discretization", default="baseline", metavar="LEVEL",
                   help="particles per rope: low, baseline, medium or high (default baseline)")
    p.add_argument("--json", metavar="FILE", help="write the description as JSON")
    p.add_argument("--figure", metavar="FILE.png", help="draw the rig at rest (side and front views)")


def describe_rig(rig, discretization="baseline"):
    """What a rig holds and how it hangs, JSON-ready."""
    maneuver = default_maneuver(rig)
    counts = rig.particle_counts(discretization)
    doc = {
        "name": rig.name, "source": rig.source, "g": rig.g,
        "bodies": {n: {"mass": b.mass, "markers": len(b.markers), "points": sorted(b.points)}
                   for n, b in rig.bodies.items()},
        "points": {n: {"position": list(map(float, p)), "moved_by_maneuver": n in maneuver.points}
                   for n, p in rig.fixed_points.items()},
        "ropes": {n: {"kind": r.kind, "path": [r.start, *r.rings, r.end],
                      "length": r.length, "winch": r.winch,
                      "particles": counts[n]} for n, r in rig.ropes.items()},
        "winches": dict(rig.winches),
        "rings": {site: {"at": at, "rope": n} for n, r in rig.ropes.items() for site, at in zip(r.ring_sites, r.rings)},
        "maneuver": {"source": rig.maneuver or ("dig" if rig.winches else "none (nothing is driven)"), "rows": int(maneuver.time.size),
                     "duration_s": float(maneuver.time[-1] - maneuver.time[0])},
        "starts_from": ("a release of " + ", ".join(rig.release)) if rig.release else "static equilibrium",
        "tolerances": [p.name for p in rig.tolerances],
    }
    model = assemble(rig, maneuver, discretization)
    t0 = float(maneuver.time[0])
    rest = solve_statics(model, t0)
    doc["statics"] = {"residual_n": rest.residual,
                      "bodies": {n: [float(v) for v in rest.state[12 * b: 12 * b + 3]]
                                 for b, n in enumerate(model.body_names)}}
    springs = assemble(rig, maneuver, discretization, dissipation=False)
    modes = linear_modes(springs, solve_statics(springs, t0).state, t0, count=MODES_SHOWN)
    doc["modes"] = [{"frequency_hz": float(f), "dominant": d} for f, d in zip(modes.frequency_hz, modes.dominant)]
    doc["stable_time_step_s"] = float(stable_time_step(model))
    scale = machine_scale(rig, modes=modes)  # the modes above, not computed again
    doc["scale"] = {"reach_m": rig.reach, "slowest_swing_hz": scale.swing_hz, "length": scale.length,
                    "time": scale.time}
    return doc, model, rest.state


def _lines(doc):
    out = [f"rig: {doc['name']}  ({doc['source']})"]
    out.append(f"bodies ({len(doc['bodies'])}): " + "; ".join(
        f"{n} {b['mass']:g} kg, {b['markers']} markers, points {', '.join(b['points']) or '-'}"
        for n, b in doc["bodies"].items()))
    out.append(f"points ({len(doc['points'])}): " + "; ".join(
        f"{n}{' (moved by the maneuver)' if p['moved_by_maneuver'] else ''}" for n, p in doc["points"].items()))
    out.append(f"ropes ({len(doc['ropes'])}):")
    for n, r in doc["ropes"].items():
        length = f"winch {r['winch']}" if r["winch"] else f"{r['length']:g} m"
        out.append(f"  {n} ({r['kind']}): {' -> '.join(r['path'])}, {length}, {r['particles']} particles")
    out.append("winches: " + (", ".join(f"{w} pays out {r}" for w, r in doc["winches"].items()) or "none"))
    out.append("ring sites: " + (", ".join(f"{s} ({r['at']}, rope {r['rope']})" for s, r in doc["rings"].items())
                                 or "none"))
    m = doc["maneuver"]
    out.append(f"maneuver: {m['source']} ({m['rows']} row{'s' if m['rows'] != 1 else ''}, {m['duration_s']:g} s); "
               f"starts from {doc['starts_from']}")
    out.append(f"statics: largest imbalance {doc['statics']['residual_n']:.2g} N; " + "; ".join(
        f"{n} at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m" for n, p in doc["statics"]["bodies"].items()))
    out.append("lowest modes (Hz): " + ", ".join(
        (f"{e['frequency_hz']:.4g}" if e["frequency_hz"] >= FREE_HZ else "0, free") + f" ({e['dominant']})"
        for e in doc["modes"]))
    out.append(f"stable time step: {doc['stable_time_step_s']:.3g} s")
    s = doc["scale"]
    out.append(f"scale: reaches {s['reach_m']:.3g} m; slowest swing {s['slowest_swing_hz']:.4g} Hz, so the "
               f"diagnosis's floors are the dragline's x {s['length']:g} in length and its low-pass x {s['time']:g} "
               "in time (docs/diagnosis.md)")
    out.append(f"tolerances: {len(doc['tolerances'])} parameters" + (
        f" ({', '.join(doc['tolerances'])})" if doc["tolerances"] else ""))
    return out


def draw_rig(path, model, state):
    """The rig at ``state``: side (x-z) and front (y-z) views, K down drawn downward, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    picture = picture_at(model, state)
    fig, axes = plt.subplots(1, 2, figsize=(10, 5))
    for ax, view, title in zip(axes, ((0, 2), (1, 2)), ("side (x-z)", "front (y-z)")):
        draw_machine(ax, picture, view)
        ax.set_title(title)
    fig.suptitle(model.rig.name)
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def run(args):
    for out in (args.json, args.figure):
        if out:
            check_output_path(out)
    guard_outputs([args.rig], files=[p for p in (args.json, args.figure) if p])
    rig = load_rig(args.rig)
    try:
        doc, model, state = describe_rig(rig, discretization_from_args(args, rig))
    except StaticsError as exc:
        raise ValueError(f"{rig.source}: {exc}") from None
    print("\n".join(_lines(doc)))
    if args.json:
        write_json(args.json, doc)
    if args.figure:
        draw_rig(args.figure, model, np.asarray(state))
    if args.json or args.figure:
        print(f"wrote {', '.join(p for p in (args.json, args.figure) if p)}", file=sys.stderr)
    return 0
