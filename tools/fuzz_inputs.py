"""Command-level fuzzing of every input the ``dragline`` command reads.

Each case takes one valid input (the sample session, its maneuver, the
built-in rig file, a run config, a cameras.json, a trajectory table, a
VICON CSV, a C3D or TRC file, or a command-line option), breaks it one way, and runs a command
that reads it in a forked child with a wall-clock limit and a 4 GiB address
space limit. What comes out is sorted into:

- ``refused``: exit 2 with one ``dragline: error:`` line and no traceback;
  ``unnamed`` counts the refusals of a broken file whose line does not name
  that file (or of a broken option that does not name the option);
- ``accepted``: exit 0 (every JSON written or printed is parsed strictly:
  no NaN or Infinity; ``invalid_json`` counts failures);
- ``accepted_nonsense``: exit 0 (or still running at the limit) on an input
  the fuzzer knows to be nonsense: a number replaced by text, NaN,
  infinity, a list or a table; a negative mass, length, stiffness, rate or
  count; an unknown key where the schema allows none; a non-numeric cell;
- ``traceback``: any other exit code, or a traceback on stderr;
- ``memory``: MemoryError, or killed by the kernel;
- ``hang``: still running at the limit, for a command whose valid run is
  bounded (``inspect``, ``simulate`` of 0.2 s, ``calibrate``,
  ``reconstruct``, ``compare``); ``run``, ``replay``, ``synth`` and ``diagnose``,
  whose valid runs take minutes, are stopped after ``DOOR_S`` and counted
  ``running`` (the input passed the checks at the door) or, for a known
  nonsense input, ``accepted_nonsense``.

The oracle for nonsense is written here from the fields' physical meaning,
not read from the project's schemas. Usage::

    python tools/fuzz_inputs.py --cases 10000 --seed 0 --json fuzz.json

Prints the counts as JSON (and writes them, with every failing case's
command and last stderr line, to ``--json``).
"""

from __future__ import annotations

import argparse
import io
import json
import math
import os
import random
import re
import resource
import shutil
import signal
import sys
import tempfile
import time
import tomllib
import traceback
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MEMORY_LIMIT = 4 * 2**30
BOUNDED = {"inspect", "simulate", "calibrate", "reconstruct", "compare"}
# A run, synth or diagnose still going after this long (s) has passed the checks at the door.
DOOR_S = 6.0
SIM_SHORT = ["--duration", "0.2", "--rate", "50", "--quiet"]
CALIBRATED = ["--calibration", "{SEED}/cameras.json"]
# Fields whose value is a physical size, rate or count: negative is nonsense.
POSITIVE = re.compile(r"(mass|length|stiffness|rate|radius|density|focal|^f[xy]$|count|frames|particles|inertia|"
                      r"diameter|hz|markers|cameras|width|height|duration|^n_|wand)", re.I)
# Free-form places where anything (or null for NaN) is allowed.
FREE_FORM = ("metadata", "quality", "maneuver", "notes", "source")
BAD_SCALARS = [("text", "abc", True), ("nan", math.nan, True), ("inf", math.inf, True), ("-inf", -math.inf, True),
               ("bool", True, True), ("list", [1, 2], True), ("table", {"a": 1}, True),
               ("negative", -1.0, None), ("zero", 0, False), ("huge", 1e300, False), ("tiny", 1e-300, False),
               ("big_int", 10**9, False), ("minus_huge", -1e308, None)]


# ---------------------------------------------------------------- seeds

def build_seeds(folder):
    """The valid inputs every case starts from, in ``folder``."""
    from importlib import resources

    from dragline.capture import write_c3d, write_trc, write_vicon_csv
    from dragline.pipelines.cli import main
    from dragline.simulate import marker_positions, simulate, write_trajectory_csv

    folder = Path(folder)
    shutil.copytree(REPO / "samples" / "dig_sample", folder / "session")
    shutil.copy(REPO / "samples" / "dig_sample" / "capture.mcap", folder / "capture.mcap")
    shutil.copy(REPO / "samples" / "dig_sample" / "maneuver.csv", folder / "maneuver.csv")
    (folder / "rig.toml").write_text(resources.files("dragline.simulate").joinpath("data/rig.toml").read_text())
    (folder / "config.toml").write_text('[run]\nseed = 1\nstudy = false\ndiagnose = false\n\n'
                                        '[reconstruct]\nmax_gap = 10\nmethod = "paper"\n')
    saved = sys.stdout, sys.stderr
    sys.stdout = sys.stderr = io.StringIO()
    try:
        assert main(["calibrate", str(folder / "session"), "--out", str(folder / "cameras.json")]) == 0
        assert main(["reconstruct", str(folder / "session"), "--calibration", str(folder / "cameras.json"),
                     "--out", str(folder / "measured.csv"), "--quiet"]) == 0
    finally:
        sys.stdout, sys.stderr = saved
    run = simulate(duration=2.0, rate_hz=50.0)
    write_trajectory_csv(folder / "simulated.csv", run.table)
    names, points = marker_positions(run)
    write_vicon_csv(folder / "vicon.csv", [n.replace(".", ":", 1) for n in names], points, 50.0)
    write_c3d(folder / "markers.c3d", [n.replace(".", ":", 1) for n in names], points, 50.0)
    write_trc(folder / "markers.trc", [n.replace(".", ":", 1) for n in names], points, 50.0)
    _machine_seeds(folder)
    return folder


# Rig files beside the dragline's, each with the maneuver CSV it names: reeving, winches, moving points, a
# release, a report preset and a hidden mechanism ([demo]).
MACHINE_RIGS = {"gantry_crane.toml": "simulate/data/gantry_crane.csv", "pendulum.toml": "simulate/data/pendulum.csv",
                "slung_load.toml": "simulate/data/slung_load.csv",
                "double_pendulum_release.toml": "tests/data/double_pendulum.csv"}


# The flight table's columns its mapping reads (benchmarks/real/stormlord_mapping.toml): the drone, the load.
FLIGHT_COLUMNS = {0, 1, 2, 14, 15, 16}


def _machine_seeds(folder):
    """The other machines' rig files, a real flight's tracked table with its rig and mapping, and a ROS 2 bag."""
    for rig, maneuver in MACHINE_RIGS.items():
        source = REPO / ("tests/data" if rig.startswith("double") else "simulate/data") / rig
        shutil.copy(source, folder / rig)
        shutil.copy(REPO / maneuver, folder / Path(maneuver).name)
    for name in ("stormlord.toml", "stormlord_hover.csv", "stormlord_mapping.toml"):
        shutil.copy(REPO / "benchmarks" / "real" / name, folder / name)
    shutil.copy(REPO / "tests" / "data" / "stormlord" / "rosbag_15_rows_0_899.csv", folder / "flight.csv")
    # The bag the tests write with the official message definitions: a pendulum's ball and pivot.
    from importlib.util import module_from_spec, spec_from_file_location

    from dragline.simulate import load_rig, simulate

    spec = spec_from_file_location("tracked_tests", REPO / "tests" / "test_tracked_tables.py")
    helpers = module_from_spec(spec)
    sys.path.insert(0, str(REPO / "tests"))
    try:
        spec.loader.exec_module(helpers)
    finally:
        sys.path.remove(str(REPO / "tests"))
    swing = simulate(load_rig("pendulum"), duration=2.0, rate_hz=100.0, discretization="low")
    helpers._write_bag(folder / "take.mcap", swing.table)
    (folder / "take.toml").write_text(helpers.BAG_MAPPING)


# ---------------------------------------------------------------- mutations

def _leaves(doc, path=()):
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _leaves(v, path + (i,))
    else:
        yield path, doc


def _set(doc, path, value):
    for k in path[:-1]:
        doc = doc[k]
    doc[path[-1]] = value


def _delete(doc, path):
    for k in path[:-1]:
        doc = doc[k]
    if isinstance(doc, dict):
        del doc[path[-1]]
    else:
        doc.pop(path[-1])


def _field_name(path):
    names = [k for k in path if isinstance(k, str)]
    return names[-1] if names else ""


def mutate_document(doc, rng, strict_keys):
    """One broken copy of a parsed TOML/JSON document: (doc, what, nonsense).

    ``nonsense`` is True when no reading of the document can be right,
    False when it may be valid.
    """
    import copy

    doc = copy.deepcopy(doc)
    leaves = [(p, v) for p, v in _leaves(doc) if p and not any(str(k) in FREE_FORM for k in p)]
    path, value = rng.choice(leaves)
    kind = rng.random()
    where = ".".join(map(str, path))
    if kind < 0.08:
        _delete(doc, path)
        return doc, f"removed {where}", False
    if kind < 0.14 and strict_keys:
        parent = path[:-1]
        target = doc
        for k in parent:
            target = target[k]
        if isinstance(target, dict):
            target["unknown_key_zz"] = 1.0
            return doc, f"unknown key beside {where}", True
    name, bad, nonsense = rng.choice(BAD_SCALARS)
    if isinstance(value, bool):
        nonsense = name != "bool"  # a TOML boolean is a boolean
    elif isinstance(value, (int, float)):
        if nonsense is None:  # a negative: nonsense where the field is a size, rate or count
            nonsense = bool(POSITIVE.search(_field_name(path)))
    elif isinstance(value, str) and name == "text":
        bad, nonsense = value + "zz", False  # a misspelt choice or path: the reader decides
    else:  # text or null: only a list or a table in its place is surely wrong
        nonsense = name in ("list", "table")
    _set(doc, path, bad)
    return doc, f"{where} = {bad!r} ({name})", nonsense


def mutate_csv(text, rng, data_start, sep=",", time_column=None):
    """One broken copy of a CSV (or a TRC, ``sep`` a tab): (text, what, nonsense).

    ``time_column``: the column of a table's times, which a clock mutation scales to steps of picoseconds
    (no lab's clock ticks so fast).
    """
    lines = text.splitlines()
    rows = list(range(data_start, len(lines)))
    if time_column is not None and rng.random() < 0.06:
        for i in rows:
            cells = lines[i].split(sep)
            if len(cells) > time_column:
                try:
                    cells[time_column] = repr(float(cells[time_column]) * 1e-12)
                except ValueError:
                    continue
                lines[i] = sep.join(cells)
        return "\n".join(lines) + "\n", "times scaled by 1e-12 (picosecond steps)", True
    kind = rng.random()
    if kind < 0.08:
        cut = rng.randrange(0, max(len(text), 1))
        return text[:cut], f"truncated at byte {cut}", False
    if kind < 0.14:
        i = rng.choice(rows)
        del lines[i]
        return "\n".join(lines) + "\n", f"line {i + 1} deleted", False
    if kind < 0.2:
        i = rng.choice(rows)
        lines.insert(i, lines[i])
        return "\n".join(lines) + "\n", f"line {i + 1} repeated", False
    if kind < 0.24:
        return "", "empty file", True
    if kind < 0.3 and data_start > 0:
        i = rng.randrange(0, data_start)
        cells = lines[i].split(sep)
        j = rng.randrange(len(cells))
        cells[j] = "zzz"
        lines[i] = sep.join(cells)
        return "\n".join(lines) + "\n", f"header line {i + 1} cell {j + 1} = 'zzz'", False
    i = rng.choice(rows)
    cells = lines[i].split(sep)
    j = rng.randrange(len(cells))
    name, bad, nonsense = rng.choice([("text", "abc", True), ("nan", "nan", False), ("empty", "", False),
                                      ("inf", "inf", True), ("minus_huge", "-1e308", False),
                                      ("huge", "1e300", False), ("negative", "-1", False)])
    cells[j] = bad
    lines[i] = sep.join(cells)
    return "\n".join(lines) + "\n", f"line {i + 1} cell {j + 1} = {bad!r} ({name})", nonsense


def mutate_bytes(data, rng):
    """One broken copy of a binary file: (bytes, what, nonsense)."""
    data = bytearray(data)
    kind = rng.random()
    if kind < 0.3:
        cut = rng.randrange(0, len(data))
        return bytes(data[:cut]), f"truncated at byte {cut}", False
    n = rng.choice([1, 4, 64])
    at = rng.randrange(0, len(data))
    for k in range(at, min(at + n, len(data))):
        data[k] = rng.randrange(256)
    return bytes(data), f"{n} bytes overwritten at {at}", False


def rewrite_session_info(src, dst, info):
    """A copy of a capture.mcap whose session info message is ``info`` (a document, or the message's bytes)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    from dragline.capture._mcap_io import INFO_TOPIC

    with open(src, "rb") as fh, open(dst, "wb") as out:
        writer = Writer(out)
        writer.start()
        schemas, channels = {}, {}
        for schema, channel, message in make_reader(fh).iter_messages(log_time_order=False):
            if schema is not None and schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas.get(channel.schema_id, 0), channel.metadata)
            data = message.data
            if channel.topic == INFO_TOPIC:
                data = info if isinstance(info, bytes) else json.dumps(info, allow_nan=True).encode()
            writer.add_message(channels[channel.id], message.log_time, data, message.publish_time)
        writer.finish()


def session_info(path):
    from mcap.reader import make_reader

    from dragline.capture._mcap_io import INFO_TOPIC

    with open(path, "rb") as fh:
        for _, _, message in make_reader(fh).iter_messages(topics=[INFO_TOPIC]):
            return json.loads(message.data)
    raise ValueError("no session info")


# ---------------------------------------------------------------- cases

OPTION_VALUES = [("nan", True), ("inf", True), ("-1", True), ("0", True), ("abc", True), ("", True),
                 ("1e300", False), ("1e-300", False), ("1e9", False)]
OPTIONS = [  # command, option, base argv (IN/OUT replaced), nonsense for a value that is not a positive number
    ("simulate", "--dt", ["simulate", "--out", "{OUT}/t.csv", *SIM_SHORT]),
    ("simulate", "--duration", ["simulate", "--out", "{OUT}/t.csv", "--rate", "50", "--quiet"]),
    ("simulate", "--rate", ["simulate", "--out", "{OUT}/t.csv", "--duration", "0.2", "--quiet"]),
    ("reconstruct", "--max-gap", ["reconstruct", "{SEED}/session", *CALIBRATED, "--out", "{OUT}/m.csv", "--quiet"]),
    ("reconstruct", "--outlier-mm", ["reconstruct", "{SEED}/session", *CALIBRATED, "--out", "{OUT}/m.csv",
                                     "--quiet"]),
    ("reconstruct", "--max-reprojection-px", ["reconstruct", "{SEED}/session", *CALIBRATED, "--out", "{OUT}/m.csv",
                                              "--quiet"]),
    ("synth", "--noise-px", ["synth", "--out", "{OUT}/s", "--duration", "0.5", "--quiet"]),
    ("synth", "--dropout", ["synth", "--out", "{OUT}/s", "--duration", "0.5", "--quiet"]),
    ("calibrate", "--max-frames", ["calibrate", "{SEED}/session", "--out", "{OUT}/c.json"]),
    ("compare", "--max-offset", ["compare", "{SEED}/measured.csv", "{SEED}/simulated.csv", "--json", "{OUT}/c.json",
                                 "--quiet"]),
]
WORD_OPTIONS = [
    ("--discretization", ["hoist_rope=0", "hoist_rope=-3", "hoist_rope=1000000000", "foo=3", "low,", "hoist_rope=abc",
                          "", "hoist_rope=2.5", "ultra"]),
    ("--physics", ["magic", "aero_drag:cd=-1", "aero_drag:cd=nan", "aero_drag:foo=1", "pulley_friction:mu=abc",
                   "aero_drag:cd=inf", "aero_drag:cd", ":", "aero_drag:cd=1,cd=2"]),
]


def make_case(k, rng, seed, work):
    """(argv, command, input_name, what, nonsense) of case k; writes its broken input into ``work``."""
    work.mkdir()
    out = work / "out"
    out.mkdir()
    pick = rng.random()
    sub = lambda argv, inp="": [a.replace("{OUT}", str(out)).replace("{SEED}", str(seed)).replace("{IN}", inp)
                                for a in argv]
    if pick < 0.14:  # rig TOML: the dragline's or another machine's, beside the maneuver it names
        name = rng.choice(["rig.toml", *MACHINE_RIGS])
        if name in MACHINE_RIGS:
            shutil.copy(seed / Path(MACHINE_RIGS[name]).name, work / Path(MACHINE_RIGS[name]).name)
        doc = tomllib.loads((seed / name).read_text())
        doc, what, nonsense = mutate_document(doc, rng, strict_keys=True)
        path = work / name
        what, nonsense = _write_text(path, _toml(doc), rng, what, nonsense)
        argv = ["simulate", "--rig", str(path), "--out", str(out / "t.csv"), *SIM_SHORT]
        return argv, path.name, what, nonsense
    if pick < 0.22:  # run config
        doc = tomllib.loads((seed / "config.toml").read_text())
        doc, what, nonsense = mutate_document(doc, rng, strict_keys=True)
        path = work / "config.toml"
        path.write_text(_toml(doc))
        argv = ["run", str(seed / "session"), "--config", str(path), "--out", str(out / "run"), "--quiet"]
        return argv, path.name, what, nonsense
    if pick < 0.32:  # cameras.json
        doc = json.loads((seed / "cameras.json").read_text())
        doc, what, nonsense = mutate_document(doc, rng, strict_keys=False)
        path = work / "cameras.json"
        what, nonsense = _write_text(path, json.dumps(doc, allow_nan=True), rng, what, nonsense)
        argv = rng.choice([["reconstruct", str(seed / "session"), "--calibration", str(path), "--out",
                            str(out / "m.csv"), "--quiet"], ["inspect", "--json", str(path)]])
        return argv, path.name, what, nonsense
    if pick < 0.42:  # session info inside capture.mcap
        info = session_info(seed / "capture.mcap")
        info, what, nonsense = mutate_document(info, rng, strict_keys=False)
        path = work / "capture.mcap"
        rewrite_session_info(seed / "capture.mcap", path, info)
        return _capture_argv(rng, path, out), path.name, what, nonsense
    if pick < 0.49:  # capture.mcap bytes
        data, what, nonsense = mutate_bytes((seed / "capture.mcap").read_bytes(), rng)
        path = work / "capture.mcap"
        path.write_bytes(data)
        return _capture_argv(rng, path, out), path.name, what, nonsense
    if pick < 0.57:  # maneuver CSV
        text, what, nonsense = mutate_csv((seed / "maneuver.csv").read_text(), rng, 1, time_column=0)
        path = work / "maneuver.csv"
        path.write_text(text)
        argv = rng.choice([["simulate", "--maneuver", str(path), "--out", str(out / "t.csv"), *SIM_SHORT],
                           ["inspect", "--json", str(path)]])
        return argv, path.name, what, nonsense
    if pick < 0.66:  # trajectory table
        src = rng.choice(["measured.csv", "simulated.csv"])
        text, what, nonsense = mutate_csv((seed / src).read_text(), rng, 1, time_column=0)
        path = work / src
        path.write_text(text)
        other = seed / ("simulated.csv" if src == "measured.csv" else "measured.csv")
        pair = [str(path), str(other)] if src == "measured.csv" else [str(other), str(path)]
        argv = rng.choice([["compare", *pair, "--json", str(out / "c.json"), "--quiet"],
                           ["inspect", "--json", str(path)],
                           ["diagnose", str(path), "--json", str(out / "d.json"), "--candidates", "aero_drag",
                            "--quiet"]])
        return argv, path.name, what, nonsense
    if pick < 0.73:  # a real flight's tracked table (no header, no time column) or its mapping
        table, mapping, path, what, nonsense = _mapped_case(rng, seed, work, "flight.csv", _mutate_flight,
                                                            "stormlord_mapping.toml")
        argv = ["diagnose", str(table), "--rig", str(seed / "stormlord.toml"), "--mapping", str(mapping),
                "--json", str(out / "d.json"), "--candidates", "aero_drag", "--quiet"]
        return argv, path.name, what, nonsense
    if pick < 0.78:  # a ROS 2 bag of pose topics (its bytes) or its mapping
        bag, mapping, path, what, nonsense = _mapped_case(rng, seed, work, "take.mcap", _mutate_bag, "take.toml")
        argv = ["diagnose", str(bag), "--rig", "pendulum", "--mapping", str(mapping), "--json", str(out / "d.json"),
                "--candidates", "aero_drag", "--quiet"]
        return argv, path.name, what, nonsense
    if pick < 0.83:  # VICON CSV
        text = (seed / "vicon.csv").read_text()
        # Data rows follow the Frame line and the units line (the rate line is a number too).
        lines = text.splitlines()
        start = next(i for i, line in enumerate(lines) if line.startswith("Frame")) + 2
        text, what, nonsense = mutate_csv(text, rng, start)
        path = work / "vicon.csv"
        path.write_text(text)
        argv = rng.choice([["reconstruct", str(path), "--out", str(out / "m.csv"), "--quiet"],
                           ["inspect", "--json", str(path)]])
        return argv, path.name, what, nonsense
    if pick < 0.89:  # C3D (bytes) or TRC (cells) of the same markers
        if pick < 0.86:
            data, what, nonsense = mutate_bytes((seed / "markers.c3d").read_bytes(), rng)
            path = work / "markers.c3d"
            path.write_bytes(data)
        else:
            text, what, nonsense = mutate_csv((seed / "markers.trc").read_text(), rng, 6, sep="\t")
            path = work / "markers.trc"
            path.write_text(text)
        argv = rng.choice([["reconstruct", str(path), "--out", str(out / "m.csv"), "--quiet"],
                           ["inspect", "--json", str(path)]])
        return argv, path.name, what, nonsense
    if pick < 0.97:  # a numeric option
        command, option, base = rng.choice(OPTIONS)
        value, nonsense = rng.choice(OPTION_VALUES)
        if option in ("--max-gap", "--dropout", "--noise-px", "--max-offset", "--outlier-mm") and value == "0":
            nonsense = False  # zero is a meaningful setting there (no gap filled, no search, no noise)
        return sub(base) + [option, value], option, f"{option} {value!r}", nonsense
    option, values = rng.choice(WORD_OPTIONS)
    value = rng.choice(values)
    return ["simulate", option, value, "--out", str(out / "t.csv"), *SIM_SHORT], option, f"{option} {value!r}", True


def _mapped_case(rng, seed, work, data_name, mutate_data, mapping_name):
    """A recording read through a mapping, one of the two broken: (data, mapping, broken file, what, nonsense)."""
    data, mapping = seed / data_name, seed / mapping_name
    if rng.random() < 0.6:
        path = data = work / data_name
        what, nonsense = mutate_data(seed / data_name, path, rng)
    else:
        doc, what, nonsense = mutate_document(tomllib.loads(mapping.read_text()), rng, strict_keys=True)
        path = mapping = work / mapping_name
        what, nonsense = _write_text(path, _toml(doc), rng, what, nonsense)
    return data, mapping, path, what, nonsense


def _mutate_flight(src, dst, rng):
    text, what, nonsense = mutate_csv(src.read_text(), rng, 0)
    cell = re.search(r"cell (\d+) =", what)
    if cell and int(cell.group(1)) - 1 not in FLIGHT_COLUMNS:
        nonsense = False  # a column the mapping does not read: the diagnosis never sees it
    dst.write_text(text)
    return what, nonsense


def _mutate_bag(src, dst, rng):
    data, what, nonsense = mutate_bytes(src.read_bytes(), rng)
    dst.write_bytes(data)
    return what, nonsense


def _write_text(path, text, rng, what, nonsense):
    """Write a document's text, now and then in UTF-16 (which no reader of a TOML or JSON file may take)."""
    if rng.random() < 0.04:
        path.write_bytes(text.encode("utf-16"))
        return f"{what}, written in UTF-16", True
    path.write_text(text)
    return what, nonsense


def _capture_argv(rng, path, out):
    return rng.choice([["inspect", "--json", str(path)], ["calibrate", str(path), "--out", str(out / "c.json")],
                       ["reconstruct", str(path), "--calibration", str(path.parent.parent / "seed" / "cameras.json"),
                        "--out", str(out / "m.csv"), "--quiet"],
                       ["replay", str(path), "--out", str(out / "replay"), "--no-study", "--no-diagnose", "--quiet"]])


def _toml(doc):
    """TOML text of a parsed document (nan and inf as TOML writes them; mixed arrays allowed)."""
    lines = []
    _toml_table(doc, (), lines)
    return "\n".join(lines) + "\n"


def _key(k):
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"


def _toml_table(doc, path, lines):
    scalars = {k: v for k, v in doc.items() if not isinstance(v, dict)}
    if path and (scalars or not doc):
        lines.append("[" + ".".join(_key(k) for k in path) + "]")
    for k, v in scalars.items():
        lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in doc.items():
        if isinstance(v, dict):
            _toml_table(v, path + (k,), lines)


# ---------------------------------------------------------------- running

def _child(argv, work):
    os.setpgid(0, 0)
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    fd_out = os.open(work / "stdout", os.O_WRONLY | os.O_CREAT)
    fd_err = os.open(work / "stderr", os.O_WRONLY | os.O_CREAT)
    os.dup2(fd_out, 1)
    os.dup2(fd_err, 2)
    sys.stdout = io.TextIOWrapper(os.fdopen(1, "wb", buffering=0), write_through=True)
    sys.stderr = io.TextIOWrapper(os.fdopen(2, "wb", buffering=0), write_through=True)
    os.chdir(work)
    code = 1
    try:
        from dragline.pipelines.cli import main

        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except MemoryError:
        sys.stderr.write("MemoryError\n")
        code = 3
    except BaseException:  # noqa: BLE001 - a fault of the tool: what the fuzzer counts
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code if isinstance(code, int) else 1)


def _strict(text):
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")

    json.loads(text, parse_constant=refuse)


def classify(case, status, timed_out, work):
    """One outcome name (and, for a failure, why)."""
    err = (work / "stderr").read_text(errors="replace")
    lines = [line for line in err.strip().splitlines() if line.strip()]
    command = case["argv"][0]
    if timed_out:
        if command in BOUNDED:
            return "hang", "still running at the limit"
        return ("accepted_nonsense", "still running at the limit") if case["nonsense"] else ("running", "")
    if os.WIFSIGNALED(status):
        return "memory", f"killed by signal {os.WTERMSIG(status)}"
    code = os.WEXITSTATUS(status)
    if "MemoryError" in err or code == 3:
        return "memory", lines[-1] if lines else ""
    if "Traceback" in err or code not in (0, 2):
        return "traceback", lines[-1] if lines else f"exit {code}"
    if code == 2:
        errors = [line for line in lines if line.startswith("dragline: error:")]
        if len(errors) != 1:
            return "traceback", f"{len(errors)} error lines"
        if case["input"] not in errors[0]:
            return "unnamed", errors[0]
        return "refused", ""
    prints_json = command in ("inspect", "calibrate", "run", "replay") and "--json" in case["argv"]
    for path in list((work / "out").rglob("*.json")) + ([work / "stdout"] if prints_json else []):
        try:
            _strict(path.read_text())
        except ValueError as exc:
            return "invalid_json", f"{path.name}: {exc}"
    if case["nonsense"]:
        return "accepted_nonsense", "exit 0"
    return "accepted", ""


def run(n_cases, seed_value, workers, limit, keep_failures):
    rng = random.Random(seed_value)
    root = Path(tempfile.mkdtemp(prefix="dragline-fuzz-"))
    started = time.perf_counter()
    seed = build_seeds(root / "seed")
    import dragline.compare.diagnose  # noqa: F401 - loaded once here, shared by every forked child
    import dragline.pipelines.cli  # noqa: F401
    setup_s = time.perf_counter() - started
    counts, by_kind, failures = {}, {}, []
    running = {}
    k = 0
    t0 = time.perf_counter()
    while k < n_cases or running:
        while k < n_cases and len(running) < workers:
            work = root / f"case{k:05d}"
            argv, name, what, nonsense = make_case(k, rng, seed, work)
            case = {"case": k, "argv": argv, "input": name, "what": what, "nonsense": nonsense}
            pid = os.fork()
            if pid == 0:
                _child(argv, work)
            running[pid] = (case, work, time.perf_counter())
            k += 1
        time.sleep(0.005)
        for pid in list(running):
            case, work, since = running[pid]
            done, status = os.waitpid(pid, os.WNOHANG)
            timed_out = False
            if not done:
                if time.perf_counter() - since < (limit if case["argv"][0] in BOUNDED else min(limit, DOOR_S)):
                    continue
                os.killpg(pid, signal.SIGKILL)
                _, status = os.waitpid(pid, 0)
                timed_out = True
            del running[pid]
            outcome, why = classify(case, status, timed_out, work)
            counts[outcome] = counts.get(outcome, 0) + 1
            key = f"{case['argv'][0]} {case['input']}"
            by_kind.setdefault(key, {}).setdefault(outcome, 0)
            by_kind[key][outcome] += 1
            if outcome not in ("refused", "accepted", "running"):
                failures.append(dict(case, outcome=outcome, why=why, seconds=time.perf_counter() - since))
            if keep_failures and outcome not in ("refused", "accepted", "running"):
                continue
            shutil.rmtree(work, ignore_errors=True)
    elapsed = time.perf_counter() - t0
    if not keep_failures:
        shutil.rmtree(root, ignore_errors=True)
    return {"cases": n_cases, "seed": seed_value, "workers": workers, "limit_s": limit,
            "memory_limit_gib": MEMORY_LIMIT / 2**30, "setup_s": setup_s, "seconds": elapsed,
            "cases_per_second": n_cases / elapsed, "counts": dict(sorted(counts.items())), "by_input": by_kind,
            "failures": failures, "kept": str(root) if keep_failures else None}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--limit", type=float, default=30.0, help="wall-clock seconds per case")
    p.add_argument("--json", help="write the figures and every failure here")
    p.add_argument("--keep-failures", action="store_true", help="keep the failing cases' folders")
    args = p.parse_args(argv)
    result = run(args.cases, args.seed, args.workers, args.limit, args.keep_failures)
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1, default=str))
    summary = {k: v for k, v in result.items() if k not in ("failures", "by_input")}
    summary["failures_shown"] = [f"{f['outcome']}: {' '.join(f['argv'][:2])} [{f['what']}] {f['why']}"
                                 for f in result["failures"][:20]]
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
