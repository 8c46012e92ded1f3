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
    doc : str
        One line for users: what it is and what values are plausible.
    candidate : bool
        Whether the diagnosis tries it.
    """

    name: str = ""
    main: str = ""
    defaults: dict = {}
    units: dict = {}
    range: tuple = (0.0, 0.0)
    doc: str = ""
    candidate: bool = True

    def apply(self, model, parameters):
        """Set the kernel's coefficients in ``model.arrays`` for ``parameters`` (a full dict, SI units)."""
        raise NotImplementedError

    def __repr__(self):
        return f"<mechanism {self.name}>"


def rings(model, which):
    """Ring indices a pulley mechanism acts on: the boom pulley, the hoist cluster's, or all."""
    if which == "all":
        return list(model.seg_ring.values())
    names = {"boom": "hoist_rope", "hoist_cluster": "dump_rope"}
    seg = names.get(which, which)
    if seg not in model.seg_ring:
        raise ValueError(f"pulley {which!r} unknown (boom, hoist_cluster or all)")
    return [model.seg_ring[seg]]


def segments(model, which, default_kind):
    """Segments a joint mechanism acts on: ropes, chains, all, or one name."""
    which = default_kind if which == "default" else which
    if which == "all":
        return list(range(len(model.seg_names)))
    if which in ("ropes", "chains"):
        suffix = which[:-1]
        return [s for s, n in enumerate(model.seg_names) if n.endswith(suffix)]
    if which in model.seg_names:
        return [model.seg_names.index(which)]
    raise ValueError(f"unknown segments {which!r} (ropes, chains, all, or a segment name)")
