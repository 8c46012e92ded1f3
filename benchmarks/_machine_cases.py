"""The realistic discovery benchmark on machines other than the dragline (``--realism --rig NAME``).

The cases, magnitudes and the right answers were fixed on 2026-11-26
before any of them was run, from what each mechanism plausibly is on a
lab machine of this size, not from any diagnosis:

- air drag: cd 0.45 (a smooth sphere's 0.47) to 3.3 (a rough, tumbling
  box with its fittings);
- rope bending damping: 0.0035 to 0.028 N m s/rad per joint (the dragline
  benchmark's are 0.02-0.07 for ropes five times as thick);
- chain-link friction: mu 0.07 (lubricated) to 0.45 (dry, rusty steel);
- out of the menu: every rope's material damping 2.5 and 3.5 times the
  rig file's (the right answers: "none", naming the update, or
  "unexplained");
- no mechanism: as many cases as make at least ``MIN_CASES`` in all, and
  never fewer than ``MIN_NONE``.

Every mechanism the diagnosis would try on the rig (``candidate_list``,
less those with nothing to act on) runs at four magnitudes. Those start no
lower than where the mechanism moves the rig's markers by ``DETECTABLE``
times what the model's own discretization moves them (baseline against the
truth's ``medium``, the rule the dragline's realistic set follows,
docs/diagnosis.md; fixed on 2026-11-26 after the first run, seed 61, found
bending damping on the slung load and the crane below it, and before any
run with it): below that no diagnosis can tell the effect from the model's
error. ``detectable_magnitudes`` finds that edge on the nominal rig by
bisection; where it lies above the plausible range's top, the mechanism
has no case on the machine and the report says so. Each
case's truth rig is drawn within the rig's tolerances and simulated at
the finer ``medium`` discretization, for the rig's ``[demo]`` duration,
filmed by the rig's own lab (``lab_for_rig``) and diagnosed from its
session directory alone, as on the dragline (``_discovery``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MACHINE_MAGNITUDES", "MACHINE_OUT_OF_MENU", "MIN_CASES", "MIN_NONE", "DETECTABLE", "machine_cases",
           "applicable_candidates", "detectable_magnitudes"]

MACHINE_MAGNITUDES = {
    "aero_drag": (0.45, 0.9, 1.7, 3.3),
    "rope_bending_damping": (0.0035, 0.007, 0.014, 0.028),
    "chain_link_friction": (0.07, 0.14, 0.27, 0.45),
}
MACHINE_OUT_OF_MENU = (("material_damping", 2.5), ("material_damping", 3.5))
MIN_CASES = 20
MIN_NONE = 5
# The smallest case moves the markers this many times as far as the model's own discretization does.
DETECTABLE = 3.0
_BISECTIONS = 8


def _marker_motion(rig, maneuver, level, physics, duration):
    """Every body marker's inertial position over the rig's trial (frames, markers, 3), m."""
    from dragline.simulate import body_marker_positions, simulate

    table = simulate(rig, maneuver, level, physics, duration=duration, rate_hz=100.0).motion_table()
    return np.concatenate([body_marker_positions(table, rig, b) for b in rig.bodies if rig.bodies[b].markers],
                          axis=1)


def _rms(d):
    return float(np.sqrt(np.nanmean(np.sum(d**2, axis=-1))))


def detectable_magnitudes(rig, name, plausible):
    """The case magnitudes of mechanism ``name`` on ``rig``, and how they were found.

    ``plausible``: the four magnitudes physical plausibility gives. The
    smallest becomes the edge where the mechanism moves the markers
    ``DETECTABLE`` times the model's own error (RMS over the trial, baseline
    against ``medium``, nominal rig), when that lies above it; the four then
    run geometrically from the edge to the plausible top. None when the
    top is below the edge.

    Returns
    -------
    values : tuple of float or None
    info : dict
        ``model_error_mm``, ``effect_at_top_mm``, ``edge`` (None when the plausible low end is above it).
    """
    from dragline.simulate import MECHANISMS, default_maneuver, make_mechanism

    from ._discovery import TRUTH_DISCRETIZATION

    maneuver = default_maneuver(rig)
    duration = rig.demo["duration"] if rig.demo else 10.0  # as the cases' truth (``_discovery._run_case``)
    base = _marker_motion(rig, maneuver, "baseline", [], duration)
    own = _rms(_marker_motion(rig, maneuver, TRUTH_DISCRETIZATION, [], duration) - base)
    main = MECHANISMS[name].main

    def effect(value):
        return _rms(_marker_motion(rig, maneuver, "baseline", [make_mechanism(name, **{main: value})], duration)
                    - base)

    lo, hi = float(plausible[0]), float(plausible[-1])
    info = {"model_error_mm": 1e3 * own, "effect_at_top_mm": 1e3 * effect(hi), "edge": None}
    if info["effect_at_top_mm"] < DETECTABLE * info["model_error_mm"]:
        return None, info
    if effect(lo) >= DETECTABLE * own:
        return tuple(float(v) for v in plausible), info
    below, above = lo, hi
    for _ in range(_BISECTIONS):
        mid = float(np.sqrt(below * above))
        below, above = (mid, above) if effect(mid) < DETECTABLE * own else (below, mid)
    info["edge"] = above
    return tuple(float(v) for v in np.geomspace(above, hi, 4)), info


def applicable_candidates(rig):
    """The candidate mechanisms the diagnosis would fit on ``rig``: those with something to act on (a
    mechanism refuses a rig without its kind of site, as the diagnosis finds when it assembles one)."""
    from dragline.compare.diagnose import candidate_list
    from dragline.simulate import assemble, default_maneuver, make_mechanism

    maneuver = default_maneuver(rig)
    names = []
    for c in candidate_list():
        try:
            assemble(rig, maneuver, "baseline", physics=[make_mechanism(c["name"], **{c["main"]: c["range"][1]})])
        except (ValueError, NotImplementedError):
            continue
        names.append(c["name"])
    return names


def machine_cases(rig_name, seed=0, derivation=None):
    """The blind cases of one machine: ``(truth, value, seed, "realistic", rig_name)``.

    ``derivation``: a dict that receives, per candidate, how its magnitudes
    were found (``detectable_magnitudes``' info, its ``plausible`` and
    ``values``).
    """
    from dragline.simulate import MECHANISMS, load_rig

    rig = load_rig(rig_name)
    cases = []
    for name in applicable_candidates(rig):
        plausible = MACHINE_MAGNITUDES.get(name)
        if plausible is None:
            lo, hi = MECHANISMS[name].range
            plausible = tuple(float(v) for v in np.geomspace(lo, hi, 6)[1:5])
        values, info = detectable_magnitudes(rig, name, plausible)
        if derivation is not None:
            derivation[name] = dict(info, plausible=list(plausible), values=None if values is None else list(values))
        cases += [(name, float(v)) for v in values or ()]
    if any(p.field == "viscous_damping" for p in rig.tolerances):
        cases += list(MACHINE_OUT_OF_MENU)
    cases += [(None, 0.0)] * max(MIN_NONE, MIN_CASES - len(cases))
    return [(name, value, seed * 1000 + 700 + k, "realistic", rig_name) for k, (name, value) in enumerate(cases)]
