"""The declared schema of a trajectory-table CSV (``compare``, ``diagnose`` and ``inspect`` read one).

Columns as lists: ``time`` (s, finite, strictly increasing, at least 3
rows) and any number of other columns, each a number per row or empty (a
gap, read as NaN: nothing invented, nothing dropped). Not accepted: a cell
that is not a number ('abc' was read as a silent NaN), infinity, values
beyond ``MAX_VALUE``. pydantic v2 in strict mode, as the other declared
inputs (``docs/schemas.md``); which columns a command needs is its own
check (docs/conventions.md names them).
"""

from __future__ import annotations

import math
from typing import Annotated, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ..capture import MIN_TIME_STEP_S, describe_validation_error, fields_markdown, key_text

__all__ = ["TrajectoryColumns", "check_trajectory_columns", "trajectory_markdown", "MAX_ROWS"]

MAX_ROWS = 10_000_000
# Positions in m, angles in rad, speeds in m/s, lengths in m: a lab's values
# are far below this; beyond it a unit or a cell is wrong.
MAX_VALUE = 1e6

_Time = Annotated[float, Field(ge=-1e9, le=1e9, allow_inf_nan=False)]
_Cell = Optional[Annotated[float, Field(ge=-MAX_VALUE, le=MAX_VALUE, allow_inf_nan=False)]]


class TrajectoryColumns(BaseModel):
    """A trajectory table: ``time`` and named channels, one value (or a gap) per row."""

    model_config = ConfigDict(strict=True, frozen=True, extra="forbid")

    time: list[_Time] = Field(min_length=3, max_length=MAX_ROWS,
                              description=f"s, increasing by at least {MIN_TIME_STEP_S:g} s a row")
    channels: dict[str, list[_Cell]] = Field(
        default_factory=dict, description="`<entity>.<quantity>` columns (SI units; docs/conventions.md); "
        f"null is a gap; |value| <= {MAX_VALUE:g}")

    @model_validator(mode="after")
    def _rows(self):
        n = len(self.time)
        for k in range(1, n):
            if not self.time[k] > self.time[k - 1]:
                raise ValueError(f"time is not strictly increasing at row {k + 2}")
            if self.time[k] - self.time[k - 1] < MIN_TIME_STEP_S:
                raise ValueError(f"time steps {self.time[k] - self.time[k - 1]:.3g} s at row {k + 2}: no clock "
                                 f"samples motion faster than every {MIN_TIME_STEP_S:g} s")
        for name, values in self.channels.items():
            if len(values) != n:
                raise ValueError(f"column {name!r} has {len(values)} rows, time {n}")
        return self


def check_trajectory_columns(columns, what):
    """``columns`` (``{"time": [...], "channels": {...}}``) checked; ValueError naming ``what`` otherwise."""

    try:
        TrajectoryColumns.model_validate(columns)
    except ValidationError as exc:
        err = exc.errors()[0]
        _, value, expected = describe_validation_error(exc)
        loc = err["loc"]
        if err["type"] == "value_error" or not loc:
            raise ValueError(f"{what}: {expected}") from None
        if err["type"] == "extra_forbidden" or (loc[0] == "channels" and len(loc) < 2):
            raise ValueError(f"{what}: {key_text(loc[-1])} = {value!r}: expected {expected}") from None
        if loc[0] == "time":
            where = f"column time, row {loc[1] + 2}" if len(loc) > 1 and isinstance(loc[1], int) else "column time"
        else:
            where = f"column {key_text(loc[1])}" + (f", row {loc[2] + 2}" if len(loc) > 2 else "")
        if isinstance(value, float) and math.isnan(value):
            value = "NaN or an empty cell"
        raise ValueError(f"{what}: {where} = {value!r}: expected {expected}") from None
    return columns


def trajectory_markdown():
    """The trajectory-table schema as a Markdown table (``docs/schemas.md`` holds this text)."""

    header = ["| column | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    return "\n".join(header + fields_markdown(TrajectoryColumns)) + "\n"
