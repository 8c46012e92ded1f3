"""``dragline replay``: a recorded session (MCAP) through the whole pipeline."""

from __future__ import annotations


def add_parser(sub):
    p = sub.add_parser("replay", help="run a recorded capture.mcap through the whole pipeline",
                       description="Replay a recorded session (capture.mcap) through every stage.")
    p.add_argument("mcap", metavar="capture.mcap")
    p.add_argument("--out", required=True, metavar="OUT_DIR")
    p.add_argument("--maneuver", metavar="dig|FILE.csv")
    p.add_argument("--no-study", action="store_true")
    p.add_argument("--no-diagnose", action="store_true")
    p.add_argument("--force", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--json", action="store_true")


def run(args):
    from pathlib import Path

    from . import _cmd_run

    if not Path(args.mcap).is_file():
        raise ValueError(f"{args.mcap}: no such file")
    args.source, args.seed, args.config, args.verbose = args.mcap, 0, None, False
    return _cmd_run.run(args)
