"""Optional physics mechanisms with values: what the paper's model leaves out.

The kinds of mechanism, one module each behind one interface, are in
``_mechanisms`` (``MECHANISMS``, name -> ``MechanismType``). A
``Mechanism`` is one kind with its parameters in SI units; its ``apply``
sets the coefficients the compiled kernel reads (all zero in the nominal
model, so switching a mechanism on never changes the force assembly).
``make_mechanism`` makes one from values, as the diagnosis does;
``parse_physics("NAME:PARAM=VALUE,...")`` is how the command line names
them (docs/interfaces.md).

A law at one site is named ``LAW@SITE`` (``pulley_friction@boom``, ``aero_drag@bucket``): the
law's site parameter (``MechanismType.site``) set to the site, the name
kept whole, so that the diagnosis can fit a law at each site as a
candidate of its own (``mechanism_sites`` lists a rig's).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._mechanisms import MECHANISMS
from ._mechanisms._base import rope_group_sites

__all__ = ["Mechanism", "MECHANISMS", "parse_physics", "make_mechanism", "mechanism_names", "mechanism_type",
           "mechanism_sites", "rope_group_sites", "limits_markdown"]


@dataclass(frozen=True)
class Mechanism:
    """A mechanism and its parameters (SI units; see ``MECHANISMS``)."""

    name: str
    parameters: dict = field(default_factory=dict)

    def apply(self, model):
        mechanism_type(self.name).apply(model, self.parameters)

    def label(self):
        """As ``parse_physics`` reads it back (a site in the name is not repeated among the parameters)."""
        site = mechanism_type(self.name).site if "@" in self.name else None
        params = ",".join(f"{k}={v}" if isinstance(v, str) else f"{k}={v:g}"
                          for k, v in self.parameters.items() if k != site)
        return f"{self.name}:{params}" if params else self.name


def mechanism_names():
    return sorted(MECHANISMS)


def mechanism_type(name):
    """The ``MechanismType`` a mechanism's name says: a law (``pulley_friction``) or a law at a site
    (``pulley_friction@boom``, ``aero_drag@bucket``).

    Raises
    ------
    ValueError
        An unknown law, or a site on a law that acts everywhere at once.
    """
    law, at, site = str(name).partition("@")
    if law not in MECHANISMS:
        raise ValueError(f"unknown mechanism {law!r} (choose from {', '.join(mechanism_names())})")
    kind = MECHANISMS[law]
    if at and not kind.site:
        raise ValueError(f"mechanism {law} acts everywhere at once: it has no site ({name!r})")
    if at and not site:
        raise ValueError(f"mechanism {name!r}: no site after '@'")
    return kind


def mechanism_sites(rig, name):
    """The sites of ``rig`` where the law ``name`` can act alone: ring names for a pulley law, the segments
    of its kind for a segment law, bodies for a body law, damping groups for a rope-type law, in the rig
    file's order; [] for a law without sites.

    ``f"{name}@{site}"`` names the law at one of them.
    """
    kind = mechanism_type(name)
    if kind.site == "pulley":
        return list(dict.fromkeys(site for spec in rig.ropes.values() for site in spec.ring_sites))
    if kind.site == "segments":
        from ._mechanisms._base import SELECTOR_KINDS

        return [seg for seg, spec in rig.ropes.items() if spec.kind in SELECTOR_KINDS[kind.site_kind]]
    if kind.site == "body":
        return list(rig.bodies)
    if kind.site == "group":
        return list(rope_group_sites(rig, kind.rig_field))
    return []


def make_mechanism(name, **parameters):
    """A Mechanism from its name and parameters (the rest at their defaults), checked like ``parse_physics``.

    ``make_mechanism("pulley_friction", mu=0.02)`` is what the diagnosis
    passes around: objects, never ``NAME:PARAM=VALUE`` text.
    """
    kind = mechanism_type(name)
    params = dict(kind.defaults)
    site = str(name).partition("@")[2]
    if site:
        if kind.site in parameters and parameters[kind.site] != site:
            raise ValueError(f"mechanism {name}: {kind.site} = {parameters[kind.site]!r} is not its site")
        params[kind.site] = site
    for key, value in parameters.items():
        if key not in params:
            raise ValueError(f"mechanism {name}: unknown parameter {key!r} (has {', '.join(params)})")
        if not isinstance(params[key], str):
            value = float(value)
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"mechanism {name}: {key} must be a finite non-negative number")
            limit = kind.limits.get(key)
            if limit is not None and value > limit:
                unit = kind.units.get(key, "-")
                unit = "" if unit == "-" else f" {unit}"
                raise ValueError(f"mechanism {name}: {key} = {value:g}{unit} is beyond any machine's "
                                 f"(at most {limit:g}{unit})")
        params[key] = value
    if "radius" in params and params["radius"] <= 0:
        raise ValueError(f"mechanism {name}: radius must be positive")
    return Mechanism(name, params)


def parse_physics(spec):
    """Parse ``NAME[:PARAM=VALUE,...]`` into a Mechanism (the command line's form of ``make_mechanism``).

    Raises
    ------
    ValueError
        Unknown mechanism or parameter, or a value that is not a finite
        non-negative number.
    """
    name, _, rest = str(spec).partition(":")
    name = name.strip()
    defaults = mechanism_type(name).defaults
    given = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq:
            raise ValueError(f"mechanism {name}: expected PARAM=VALUE, got {item!r}")
        if key in given:
            raise ValueError(f"mechanism {name}: {key} given twice")
        if key in defaults and not isinstance(defaults[key], str):
            try:
                value = float(value)
            except ValueError:
                raise ValueError(f"mechanism {name}: {key}={value!r} is not a number") from None
        given[key] = value.strip() if isinstance(value, str) else value
    return make_mechanism(name, **given)


def limits_markdown():
    """Each mechanism parameter's door bound as a Markdown table (``docs/schemas.md`` holds this text)."""
    lines = ["| mechanism | parameter | at most | unit |", "|---|---|---|---|"]
    for name in mechanism_names():
        kind = MECHANISMS[name]
        for key, limit in kind.limits.items():
            lines.append(f"| `{name}` | `{key}` | {limit:g} | {kind.units.get(key, '-')} |")
    return "\n".join(lines) + "\n"
