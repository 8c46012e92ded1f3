"""The declared schema of a ``dragline run --config`` TOML file.

One place states each key's type, unit and allowed range; the file is
checked against it when it is loaded, and ``docs/schemas.md`` is generated
from it. pydantic v2 in strict mode: a TOML string is never read as a
boolean (``study = "no"`` was once taken as true), an integer key refuses a
float, and an unknown key or section is an error, not a silent no-op.
"""

from __future__ import annotations

from typing import Literal, Optional

from dragline.capture import describe_validation_error, fields_markdown, key_text
from dragline.reconstruct import SMOOTHING_METHODS as SMOOTHINGS
from dragline.reconstruct import TRIANGULATION_METHODS as METHODS
from dragline.simulate import DISCRETIZATION_LEVELS
from pydantic import BaseModel, ConfigDict, Field, ValidationError

__all__ = ["RunConfig", "validate_config", "config_schema_markdown"]

# Longest gap a lab would ask the spline to bridge: 10 s at 100 Hz.
MAX_GAP_LIMIT = 1000


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class RunSection(_Section):
    """[run]: the whole job."""

    seed: int = Field(0, ge=0, le=2**32 - 1, description="seed of the built-in synthetic session")
    study: bool = Field(True, description="discretization study (the paper's Fig. 21) in the report")
    diagnose: bool = Field(True, description="diagnose the missing physics after the comparison")
    scheduler: Optional[str] = Field(None, min_length=1, pattern=r"^\S+$",
                                     description="Dask scheduler address (tcp://host:8786) that runs the "
                                                 "diagnosis's simulations; default: $DRAGLINE_SCHEDULER, else "
                                                 "two local processes")


class SimulateSection(_Section):
    """[simulate]: the nominal model."""

    rig: Optional[str] = Field(None, min_length=1, description="rig TOML file; default: the built-in 1/16-scale rig")
    maneuver: Optional[str] = Field(None, min_length=1,
                                    description='"dig" or a CSV reel table; default: the session\'s own')
    discretization: Literal[DISCRETIZATION_LEVELS] = Field("baseline", description="nodes per rope and chain")


class ReconstructSection(_Section):
    """[reconstruct]: markers to bodies."""

    method: Literal[METHODS] = Field("paper", description='body frames by the paper\'s Eqs. 14-16, or "svd" '
                                                          "(rigid fit)")
    smoothing: Literal[SMOOTHINGS] = Field("running_average", description="the paper's 12-sample average, "
                                                                          "Savitzky-Golay or none")
    max_gap: int = Field(10, ge=0, le=MAX_GAP_LIMIT, description="frames: longer gaps stay NaN")


class RunConfig(_Section):
    """A ``dragline run --config`` file; every section and key is optional."""

    run: RunSection = RunSection()
    simulate: SimulateSection = SimulateSection()
    reconstruct: ReconstructSection = ReconstructSection()


def validate_config(doc, path):
    """The checked configuration of TOML document ``doc`` read from ``path``.

    Returns
    -------
    dict
        ``{section: {key: value}}`` with every default filled in.

    Raises
    ------
    ValueError
        One line naming the file, the key, the value and what was expected.
    """
    try:
        return RunConfig.model_validate(doc).model_dump()
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = err["loc"]
        where = f"[{key_text(loc[0])}]" + (f" {'.'.join(map(key_text, loc[1:]))}" if len(loc) > 1 else "")
        _, value, expected = describe_validation_error(exc)
        if len(loc) == 1 and err["type"] == "extra_forbidden":
            raise ValueError(f"config {path}: unknown section [{key_text(loc[0])}] "
                             f"(has {', '.join(RunConfig.model_fields)})") from None
        if len(loc) == 2 and err["type"] == "extra_forbidden":
            raise ValueError(f"config {path}: unknown key {str(loc[1])!r} in [{key_text(loc[0])}]") from None
        raise ValueError(f"config {path}: {where} = {value!r}: expected {expected}") from None


def config_schema_markdown():
    """The config schema as a Markdown table (``docs/schemas.md`` holds this text)."""
    header = ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    return "\n".join(header + fields_markdown(RunConfig)) + "\n"
