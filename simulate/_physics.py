"""Optional physics mechanisms with values: what the paper's model leaves out.

The kinds of mechanism, one module each behind one interface, are in
``_mechanisms`` (``MECHANISMS``, name -> ``MechanismType``). A
``Mechanism`` is one kind with its parameters in SI units; its ``apply``
sets the coefficients the compiled kernel reads (all zero in the nominal
model, so switching a mechanism on never changes the force assembly).
``make_mechanism`` makes one from values, as the diagnosis does;
``parse_physics("NAME:PARAM=VALUE,...")`` is how the command line names
them (docs/interfaces.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._mechanisms import MECHANISMS

__all__ = ["Mechanism", "MECHANISMS", "parse_physics", "make_mechanism", "mechanism_names", "limits_markdown"]


@dataclass(frozen=True)
class Mechanism:
    """A mechanism and its parameters (SI units; see ``MECHANISMS``)."""

    name: str
    parameters: dict = field(default_factory=dict)

    def apply(self, model):
        MECHANISMS[self.name].apply(model, self.parameters)

    def label(self):
        params = ",".join(f"{k}={v:g}" for k, v in self.parameters.items())
        return f"{self.name}:{params}" if params else self.name


def mechanism_names():
    return sorted(MECHANISMS)


def make_mechanism(name, **parameters):
    """A Mechanism from its name and parameters (the rest at their defaults), checked like ``parse_physics``.

    ``make_mechanism("pulley_friction", mu=0.02)`` is what the diagnosis
    passes around: objects, never ``NAME:PARAM=VALUE`` text.
    """
    if name not in MECHANISMS:
        raise ValueError(f"unknown mechanism {name!r} (choose from {', '.join(mechanism_names())})")
    params = dict(MECHANISMS[name].defaults)
    for key, value in parameters.items():
        if key not in params:
            raise ValueError(f"mechanism {name}: unknown parameter {key!r} (has {', '.join(params)})")
        if not isinstance(params[key], str):
            value = float(value)
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"mechanism {name}: {key} must be a finite non-negative number")
            limit = MECHANISMS[name].limits.get(key)
            if limit is not None and value > limit:
                unit = MECHANISMS[name].units.get(key, "-")
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
    if name not in MECHANISMS:
        raise ValueError(f"unknown mechanism {name!r} (choose from {', '.join(mechanism_names())})")
    defaults = MECHANISMS[name].defaults
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
