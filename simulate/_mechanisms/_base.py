"""The one interface every optional mechanism has (``MechanismType``), and the lookups they share."""

from __future__ import annotations


class MechanismType:
    """A kind of physics the paper's model leaves out.

    A subclass (one module each) says what the mechanism is called, its
    parameters with their defaults and units, which parameter the diagnosis
    fits and over what plausible range, and how its parameters enter the
    model: ``apply`` sets coefficients the compiled kernel reads, all zero in
    the nominal model, so switching a mechanism on never changes the force
    assembly. A ``Mechanism`` (``simulate._physics``) is one with values.

    Attributes
    ----------
    name : str
    main : str
        The parameter the diagnosis fits.
    defaults : dict
        Every parameter and its default (SI units; a string for a choice
        such as which pulley).
    units : dict
        Each numeric parameter's unit.
    range : tuple of float
        Plausible range of ``main``: what the diagnosis searches (the one
        table of ranges).
    limits : dict
        Each numeric parameter's largest possible value: beyond it no
        material or machine has it, and the input is refused at the door
        (not a plausible range: the diagnosis never decides by these).
    doc : str
        One line for users: what it is and what values are plausible.
    candidate : bool
        Whether the diagnosis tries it.
    site : str
        The parameter that says where it acts (``pulley``, ``segments``, ``body``),
        so that ``LAW@SITE`` names it at one site; "" for a law that acts
        everywhere at once.
    site_kind : str
        For a segment law: the selector its ``default`` means (``ropes``,
        ``chains``), the segments its sites are.
    rig_array : str
        For a law that says a rig-file value is wrong rather than that physics
        is missing: the kernel array of that value, which it scales (the one
        exception to "zero in the nominal model"); "" otherwise.
    rig_field : str
        For such a law: the field of the rig-file tolerance it continues
        beyond its bounds (``RigParameter.field``, the site a tolerance group),
        so that a value moved within them reads as that parameter's update.
    """

    name: str = ""
    main: str = ""
    defaults: dict = {}
    units: dict = {}
    range: tuple = (0.0, 0.0)
    limits: dict = {}
    doc: str = ""
    candidate: bool = True
    site: str = ""
    site_kind: str = ""
    rig_array: str = ""
    rig_field: str = ""

    def apply(self, model, parameters):
        """Set the kernel's coefficients in ``model.arrays`` for ``parameters`` (a full dict, SI units)."""
        raise NotImplementedError

    def __repr__(self):
        return f"<mechanism {self.name}>"


def rings(model, which):
    """Ring indices a pulley mechanism acts on: ``all``, or the rings of one site name, point or rope, or of
    several joined by ``+`` (``boom+hoist_cluster``).

    A ring's site name is its ``ring_names`` entry in the rig file, else the
    name of the point it sits at (``boom_pulley`` for ``fixed.boom_pulley``);
    a rope's name selects every ring it is reeved through.
    """
    if not model.seg_rings:
        raise ValueError("the rig has no ring or sheave for a pulley mechanism to act at")
    if which == "all":
        return list(range(model.n_rings))
    if "+" in which:
        return sorted({r for part in which.split("+") for r in rings(model, part)})
    sites = {}
    for seg, indices in model.seg_rings.items():
        spec = model.rig.ropes[seg]
        for ring, site, point in zip(indices, spec.ring_sites, spec.rings):
            for name in (site, point, point.partition(".")[2], seg):
                sites.setdefault(name, []).append(ring)
    if which not in sites:
        names = sorted(set(model.ring_sites))
        raise ValueError(f"pulley {which!r} unknown ({', '.join(names + ['all'])})")
    return sorted(set(sites[which]))


def bodies(model, which):
    """Body indices a body mechanism acts on: ``all``, or one body's name, or several joined by ``+``."""
    chosen = set(model.body_names if which == "all" else which.split("+"))
    if chosen - set(model.body_names):
        raise ValueError(f"body {which!r} unknown ({', '.join([*model.body_names, 'all'])})")
    return [b for b, name in enumerate(model.body_names) if name in chosen]


# What a segment selector names: the kinds of the rig file (``_rig_schema.ROPE_KINDS``).
SELECTOR_KINDS = {"ropes": ("rope", "cable"), "chains": ("chain",)}


def segments(model, which, default_kind):
    """Segments a joint mechanism acts on: ``ropes`` (kinds rope and cable), ``chains``, ``all``, or one name,
    or several joined by ``+``."""
    which = default_kind if which == "default" else which
    if which == "all":
        return list(range(len(model.seg_names)))
    if "+" in which:
        return sorted({s for part in which.split("+") for s in segments(model, part, default_kind)})
    if which in SELECTOR_KINDS:
        kinds = SELECTOR_KINDS[which]
        found = [s for s, n in enumerate(model.seg_names) if model.rig.ropes[n].kind in kinds]
        if not found:
            raise ValueError(f"the rig has no rope of kind {' or '.join(kinds)} for a mechanism on {which} to act on")
        return found
    if which in model.seg_names:
        return [model.seg_names.index(which)]
    raise ValueError(f"unknown segments {which!r} (ropes, chains, all, or a segment name)")


def rope_group_sites(rig, field="viscous_damping"):
    """A rig's rope groups for one rope property, name -> its ropes: each tolerance group (or rope) whose
    ``field`` (``viscous_damping``, ``static_stiffness``) has a tolerance, then each rope in none of them on its
    own, in the rig file's order."""
    groups = {p.name.split(".")[1]: tuple(p.targets) for p in rig.tolerances if p.field == field}
    covered = {seg for targets in groups.values() for seg in targets}
    groups.update({seg: (seg,) for seg in rig.ropes if seg not in covered})
    return groups


def rope_groups(model, which, field):
    """Segments a rope-type mechanism acts on: ``all``, a rope group's (``rope_group_sites`` of ``field``) or one
    rope's, or several joined by ``+``."""
    if which == "all":
        return list(range(len(model.seg_names)))
    groups = rope_group_sites(model.rig, field)
    found = set()
    for part in which.split("+"):
        targets = groups.get(part, (part,) if part in model.seg_names else None)
        if targets is None:
            raise ValueError(f"unknown rope group {part!r} ({', '.join([*groups, 'all'])})")
        found |= {model.seg_names.index(seg) for seg in targets}
    return sorted(found)
