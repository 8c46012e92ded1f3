"""Command-line options shared by several subcommands, and their parsing."""

from __future__ import annotations

import argparse
import math
import os

from dragline.simulate import (
    BUILT_IN_RIGS,
    DISCRETIZATION_LEVELS,
    default_maneuver,
    dig_maneuver,
    load_rig,
    parse_physics,
    read_maneuver_csv,
)


_RANGES = {
    "positive": (lambda v: v > 0, "a positive"),
    "nonnegative": (lambda v: v >= 0, "a non-negative"),
    "fraction": (lambda v: 0 <= v <= 1, "a fraction (0 to 1) as a"),
    "finite": (lambda v: True, "a"),
}


def number(kind="positive", integer=False, maximum=None, minimum=None):
    """An argparse ``type``: a finite number in ``kind``'s range, within ``minimum``-``maximum`` in size
    (the door's bounds: what no lab can use) (argparse names the option)."""
    ok, words = _RANGES[kind]

    def parse(text):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            value = None
        if value is None or not math.isfinite(value) or not ok(value):
            raise argparse.ArgumentTypeError(f"expected {words} {'whole number' if integer else 'finite number'}, "
                                             f"got {text!r}")
        if maximum is not None and abs(value) > maximum:
            raise argparse.ArgumentTypeError(f"expected at most {maximum:g}, got {text!r}")
        if minimum is not None and value != 0 and abs(value) < minimum:
            raise argparse.ArgumentTypeError(f"expected at least {minimum:g}, got {text!r}")
        return value

    return parse


def add_model_options(parser, physics=True):
    parser.add_argument("--rig", metavar="NAME|FILE",
                        help=f"a built-in machine ({', '.join(BUILT_IN_RIGS)}; default {next(iter(BUILT_IN_RIGS))}) "
                             "or a rig TOML file")
    parser.add_argument("--maneuver", default=None, metavar="dig|FILE.csv",
                        help="maneuver: a CSV with time and a <winch>_length column per winch (and moving points' "
                             ".x, .y, .z), or the paper's dig; default: the rig's own")
    parser.add_argument("--discretization", default="baseline", metavar="LEVEL|ROPE=N,...",
                        help=f"particles per rope: {', '.join(DISCRETIZATION_LEVELS)}, or counts like hoist_rope=20,drag_chain=6")
    if physics:
        parser.add_argument("--physics", action="append", default=[], metavar="NAME[:PARAM=VALUE,...]",
                            help="switch on an optional mechanism (repeatable)")


def rig_from_args(args):
    return load_rig(args.rig)


def maneuver_from_args(args, rig):
    """The --maneuver option: a built-in maneuver's name, a CSV, or (None) the rig's own."""
    if args.maneuver is None:
        return default_maneuver(rig)
    return dig_maneuver() if args.maneuver == "dig" else read_maneuver_csv(args.maneuver)


def discretization_from_args(args, rig=None):
    """The --discretization option: a level name or per-rope counts (checked against ``rig`` when given)."""
    try:
        counts = _discretization(args.discretization)
        if rig is not None:
            rig.particle_counts(counts)
    except ValueError as exc:
        raise ValueError(f"--discretization: {exc}") from None
    return counts


def _discretization(text):
    if "=" not in text:
        if text not in DISCRETIZATION_LEVELS:
            raise ValueError(f"unknown discretization {text!r} (choose {', '.join(DISCRETIZATION_LEVELS)} or ROPE=N,...)")
        return text
    counts = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        try:
            counts[name.strip()] = int(value)
        except ValueError:
            raise ValueError(f"discretization {item!r}: particle count must be an integer") from None
    return counts


def physics_from_args(args):
    try:
        return [parse_physics(spec) for spec in getattr(args, "physics", [])]
    except ValueError as exc:
        raise ValueError(f"--physics: {exc}") from None


def check_output_path(path):
    """Fail early (exit 2) when an output file cannot be written."""
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(folder):
        raise ValueError(f"output folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"output folder {folder} is not writable")
    if os.path.isdir(path):
        raise ValueError(f"output {path} is a directory")


def add_between_option(parser):
    parser.add_argument("--between", nargs=2, metavar=("START", "END"),
                        help="a marker file only: keep the trial from its event START to the first END after it "
                             "(labels as NAME or CONTEXT:NAME; 'dragline inspect' lists a file's events); time 0 "
                             "is then the start event")


def between_from_args(args, kind, source):
    """The ``--between`` pair, refused when ``source`` (of ``kind``) is no marker file with events."""
    between = getattr(args, "between", None)
    if between is not None and kind != "markers":
        raise ValueError(f"--between cuts a marker file (VICON CSV, C3D, TRC) at its events; {source} is not one")
    return tuple(between) if between else None


def add_scheduler_option(parser):
    """``--scheduler ADDRESS``: run the simulations on a Dask cluster (docs/interfaces.md)."""
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="Dask scheduler (for example tcp://host:8786) that runs the simulations; default: "
                             "$DRAGLINE_SCHEDULER, else local processes (pip install 'dragline[dask]')")


def executor_from_args(args):
    """The executor the options ask for: ``--scheduler``/``DRAGLINE_SCHEDULER`` (Dask), else ``--workers``."""
    from dragline.compare import executor_from  # noqa: PLC0415 - compare is heavy; only these commands need it

    scheduler = getattr(args, "scheduler", None)
    if scheduler is not None and not scheduler.strip():
        raise ValueError("--scheduler: expected a Dask scheduler address such as tcp://host:8786")
    return executor_from(getattr(args, "workers", 2), scheduler)
