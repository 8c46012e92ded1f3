"""Command-line options shared by several subcommands, and their parsing."""

from __future__ import annotations

import os

from dragline.simulate import (
    DISCRETIZATION_LEVELS,
    dig_maneuver,
    load_rig,
    parse_physics,
    read_maneuver_csv,
)


def add_model_options(parser, physics=True):
    parser.add_argument("--rig", metavar="FILE", help="rig TOML file (default: the built-in 1/16-scale rig)")
    parser.add_argument("--maneuver", default="dig", metavar="dig|FILE.csv",
                        help="reel table: the paper's dig maneuver or a CSV with time, hoist_length, drag_length")
    parser.add_argument("--discretization", default="baseline", metavar="LEVEL|ROPE=N,...",
                        help=f"particles per rope: {', '.join(DISCRETIZATION_LEVELS)}, or counts like hoist_rope=20,drag_chain=6")
    if physics:
        parser.add_argument("--physics", action="append", default=[], metavar="NAME[:PARAM=VALUE,...]",
                            help="switch on an optional mechanism (repeatable)")


def rig_from_args(args):
    return load_rig(args.rig)


def maneuver_from_args(args):
    return dig_maneuver() if args.maneuver == "dig" else read_maneuver_csv(args.maneuver)


def discretization_from_args(args):
    text = args.discretization
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
    return [parse_physics(spec) for spec in getattr(args, "physics", [])]


def check_output_path(path):
    """Fail early (exit 2) when an output file cannot be written."""
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(folder):
        raise ValueError(f"output folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"output folder {folder} is not writable")
    if os.path.isdir(path):
        raise ValueError(f"output {path} is a directory")
