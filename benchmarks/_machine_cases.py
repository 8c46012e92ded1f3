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
less those with nothing to act on) runs at its four magnitudes. Each
case's truth rig is drawn within the rig's tolerances and simulated at
the finer ``medium`` discretization, for the rig's ``[demo]`` duration,
filmed by the rig's own lab (``lab_for_rig``) and diagnosed from its
session directory alone, as on the dragline (``_discovery``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MACHINE_MAGNITUDES", "MACHINE_OUT_OF_MENU", "MIN_CASES", "MIN_NONE", "machine_cases",
           "applicable_candidates"]

MACHINE_MAGNITUDES = {
    "aero_drag": (0.45, 0.9, 1.7, 3.3),
    "rope_bending_damping": (0.0035, 0.007, 0.014, 0.028),
    "chain_link_friction": (0.07, 0.14, 0.27, 0.45),
}
MACHINE_OUT_OF_MENU = (("material_damping", 2.5), ("material_damping", 3.5))
MIN_CASES = 20
MIN_NONE = 5


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


def machine_cases(rig_name, seed=0):
    """The blind cases of one machine: ``(truth, value, seed, "realistic", rig_name)``."""
    from dragline.simulate import MECHANISMS, load_rig

    rig = load_rig(rig_name)
    cases = []
    for name in applicable_candidates(rig):
        values = MACHINE_MAGNITUDES.get(name)
        if values is None:
            lo, hi = MECHANISMS[name].range
            values = tuple(float(v) for v in np.geomspace(lo, hi, 6)[1:5])
        cases += [(name, float(v)) for v in values]
    if any(p.field == "viscous_damping" for p in rig.tolerances):
        cases += list(MACHINE_OUT_OF_MENU)
    cases += [(None, 0.0)] * max(MIN_NONE, MIN_CASES - len(cases))
    return [(name, value, seed * 1000 + 700 + k, "realistic", rig_name) for k, (name, value) in enumerate(cases)]
