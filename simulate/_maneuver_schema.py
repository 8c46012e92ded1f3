"""The declared schema of a maneuver CSV (``--maneuver``; a session's ``maneuver.csv``).

One model per file, its columns as lists: types, units and ranges stated
once, checked when the file is read (pydantic v2 in strict mode, as the
other declared inputs; ``docs/schemas.md``). What needs the rig - a rope
reeled below its elements' length, a reel faster than a reel moves - is
checked when the maneuver meets the rig (``_simulate.check_reel_table``).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ..capture import MIN_TIME_STEP_S, describe_validation_error, fields_markdown, key_text

__all__ = ["ManeuverColumns", "check_maneuver_columns", "maneuver_markdown", "MAX_ROWS", "LENGTH_SUFFIX"]

MAX_ROWS = 1_000_000
# A winch's column is its name and this: winch ``hoist`` -> ``hoist_length``.
LENGTH_SUFFIX = "_length"
MAX_TIME_S = 1e6  # eleven days
MAX_LENGTH_M = 1e4

_Time = Annotated[float, Field(ge=-MAX_TIME_S, le=MAX_TIME_S, allow_inf_nan=False)]
_Length = Annotated[float, Field(gt=0, le=MAX_LENGTH_M, allow_inf_nan=False)]
_Coordinate = Annotated[float, Field(ge=-MAX_LENGTH_M, le=MAX_LENGTH_M, allow_inf_nan=False)]


_Winch = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$", max_length=100)]


class ManeuverColumns(BaseModel):
    """A maneuver table: one row per instant, linearly interpolated between rows."""

    model_config = ConfigDict(strict=True, frozen=True, extra="forbid")

    time: list[_Time] = Field(min_length=1, max_length=MAX_ROWS,
                              description=f"s, increasing by at least {MIN_TIME_STEP_S:g} s a row")
    lengths: dict[_Winch, list[_Length]] = Field(
        default_factory=dict, description="`<winch>_length` columns: rope each winch has paid out (m)")
    points: dict[str, list[Annotated[list[_Coordinate], Field(min_length=3, max_length=3)]]] = Field(
        default_factory=dict, description="optional `<point>.x`, `.y`, `.z` columns moving a fixed point (m)")

    @model_validator(mode="after")
    def _rows(self):
        n = len(self.time)
        for winch, rows in self.lengths.items():
            if len(rows) != n:
                raise ValueError(f"{winch}{LENGTH_SUFFIX} has {len(rows)} rows, time {n}")
        for name, rows in self.points.items():
            if len(rows) != n:
                raise ValueError(f"point {str(name)!r} has {len(rows)} rows, time {n}")
        for k in range(1, n):
            if not self.time[k] > self.time[k - 1]:
                raise ValueError(f"time is not strictly increasing at row {k + 2}")
            if self.time[k] - self.time[k - 1] < MIN_TIME_STEP_S:
                raise ValueError(f"time steps {self.time[k] - self.time[k - 1]:.3g} s at row {k + 2}: rows are "
                                 f"at least {MIN_TIME_STEP_S:g} s apart")
        return self


def _row_of(loc):
    """'column hoist_length, row 7' from a pydantic location (the header is row 1)."""

    if loc and loc[0] == "lengths" and len(loc) >= 2:
        column = f"column {key_text(str(loc[1]) + LENGTH_SUFFIX)}"
        return f"{column}, row {loc[2] + 2}" if len(loc) >= 3 and isinstance(loc[2], int) else column
    if len(loc) >= 2 and isinstance(loc[1], int):
        return f"column {key_text(loc[0])}, row {loc[1] + 2}"
    if loc and loc[0] == "points" and len(loc) >= 3:
        return f"point {key_text(loc[1])}, row {loc[2] + 2}" if isinstance(loc[2], int) else f"point {key_text(loc[1])}"
    return f"column {key_text(loc[0])}" if loc else ""


def check_maneuver_columns(columns, path):
    """``columns`` (``time``, ``<winch>_length`` lists, ``points``) checked against `ManeuverColumns`.

    Raises ValueError with one line naming the file otherwise.
    """

    layout = {"lengths": {}}
    for key, value in columns.items():
        if isinstance(key, str) and key.endswith(LENGTH_SUFFIX) and len(key) > len(LENGTH_SUFFIX):
            layout["lengths"][key[: -len(LENGTH_SUFFIX)]] = value
        else:
            layout[key] = value
    try:
        ManeuverColumns.model_validate(layout)
    except ValidationError as exc:
        err = exc.errors()[0]
        _, value, expected = describe_validation_error(exc)
        where = _row_of(err["loc"])
        if err["type"] == "extra_forbidden":
            raise ValueError(f"maneuver file {path}: unknown column {str(err['loc'][0])!r} (the columns are time, "
                             "<winch>_length for each winch and optional <point>.x, .y, .z)") from None
        if err["type"] == "value_error" or not where:
            raise ValueError(f"maneuver file {path}: {expected}") from None
        if err["type"] == "missing":
            raise ValueError(f"maneuver file {path}: {where}: expected {expected}") from None
        raise ValueError(f"maneuver file {path}: {where} = {value!r}: expected {expected}") from None
    return columns


def maneuver_markdown():
    """The maneuver schema as a Markdown table (``docs/schemas.md`` holds this text)."""

    header = ["| column | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    return "\n".join(header + fields_markdown(ManeuverColumns)) + "\n"
