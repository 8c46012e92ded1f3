"""The Stormlord slung-load flights (MIT): where they lie, their row rate, and the trial each is cut to.

A flight is a folder holding ``dataset.csv`` (no header, no time column)
and the bag's ``metadata.yaml``, as the repository's
``data_combined_system/rosbag_NN`` folders hold them
(``docs/real-recordings.md``). Its trial is its first ``rows`` rows: the
hover the flight starts from, with the load at rest, then the first moves
- a trial that starts at rest, as the model does - read through the
dataset's mapping at the mean row rate the metadata gives (the clock is
recovered from the motion).
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

__all__ = ["find_flights", "row_rate", "read_flight"]

NAME = "stormlord"
_HERE = Path(__file__).resolve().parent / "real"
RIG = _HERE / "stormlord.toml"
MAPPING = _HERE / "stormlord_mapping.toml"
# The rope whose documented length is put wrong on purpose for the known answer.
KNOWN_ROPES = ("rope",)
# A trial starts at rest, as the model does.
START_FROM_RECORDING = False


def find_flights(data):
    """``(name, (dataset.csv, metadata.yaml))`` of every folder under ``data`` (any depth) holding both, in
    name order."""
    found = []
    for csv in Path(data).rglob("dataset.csv"):
        meta = csv.parent / "metadata.yaml"
        if meta.is_file():
            found.append((csv.parent.name, (csv, meta)))
    return sorted(found)


def row_rate(metadata, topic="/payload/world_pose"):
    """Rows per second of a flight's log: ``topic``'s message count over the bag's duration (rosbag2
    ``metadata.yaml``)."""
    text = Path(metadata).read_text()
    duration = re.search(r"duration:\s*\n\s*nanoseconds:\s*(\d+)", text)
    block = text.split(f"name: {topic}\n", 1)
    count = re.search(r"message_count:\s*(\d+)", block[1]) if len(block) == 2 else None
    if duration is None or count is None:
        raise ValueError(f"{metadata}: no bag duration or no {topic} message count")
    return int(count.group(1)) / (int(duration.group(1)) * 1e-9)


def _mapping_at(rate):
    from dragline.capture import load_tracked_mapping

    mapping = load_tracked_mapping(MAPPING)
    return mapping.model_copy(update={"table": mapping.table.model_copy(update={"rate_hz": float(rate)})})


def shared_frame():
    """Whether the mapping tracks the drone and the load in one frame (no free offset on the load)."""
    return _mapping_at(1.0).table.shared_frame


def read_flight(source, folder, rig, rows):
    """A flight's first ``rows`` rows as ``(rate, trajectory table, maneuver)`` (the drone's measured track the
    maneuver); ``folder`` takes the cut file."""
    from dragline.capture import read_tracked_table
    from dragline.reconstruct import tracked_trajectory

    csv, meta = source
    rate = row_rate(meta)
    with open(csv) as src:
        lines = list(itertools.islice(src, rows))
    path = Path(folder) / f"{Path(csv).parent.name}.csv"
    path.write_text("".join(lines))
    table, maneuver = tracked_trajectory(read_tracked_table(path, _mapping_at(rate)), rig)
    return rate, table, maneuver
