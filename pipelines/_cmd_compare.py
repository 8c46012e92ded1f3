"""``dragline compare``: measured against simulated trajectory tables, as a PDF and JSON."""

from __future__ import annotations

import os
import sys

import numpy as np
from dragline.capture import write_json
from dragline.compare import (
    compare_tables,
    discretization_study,
    machine_picture,
    read_trajectory_table,
    write_report,
)

from ._guard import guard_outputs
from ._options import (
    check_output_path,
    maneuver_from_args,
    number,
    physics_from_args,
    rig_from_args,
)


def add_parser(sub):
    p = sub.add_parser(
        "compare",
        help="compare measured with simulated motion; write a PDF report and JSON metrics",
        description="Compare a measured with a simulated trajectory table (docs/conventions.md): align the clocks "
        "from the rope lengths, compute per-channel metrics, the paper's peak table and the free decay "
        "after the reels stop, and write a PDF report and/or JSON metrics.",
    )
    p.add_argument("measured", metavar="MEASURED.csv", help="measured trajectory table")
    p.add_argument("simulated", metavar="SIMULATED.csv", help="simulated trajectory table")
    p.add_argument("--report", metavar="REPORT.pdf", help="PDF report to write")
    p.add_argument("--json", metavar="METRICS.json", help="metrics to write as JSON")
    p.add_argument("--time-offset", default="auto", metavar="auto|S",
                   help="measured clock minus simulation clock (s); 'auto' estimates it from the rope "
                   "lengths (default); a number is applied as given, the estimate is still reported")
    p.add_argument("--max-offset", type=number("nonnegative", maximum=600), default=None, metavar="S",
                   help="largest |offset| searched (s; default 3, at most a quarter of the record)")
    p.add_argument("--free-decay-start", type=number("finite", maximum=1e6), default=None, metavar="S",
                   help="start of the free decay (s, simulation clock; default: when the reels stop)")
    p.add_argument("--discretization-study", action="store_true",
                   help="also simulate the maneuver at the four discretization levels (Fig. 21; ~30 s)")
    p.add_argument("--rig", metavar="NAME|FILE", help="the machine: its channels, tolerances and figures, and the "
                                                     "study's rig (default: the built-in dragline)")
    p.add_argument("--maneuver", default=None, metavar="dig|FILE.csv",
                   help="the maneuver (the study's, and for a rig without winches when its points stop): "
                        "default the rig's own (the dragline's: the paper's dig)")
    p.add_argument("--physics", action="append", default=[], metavar="NAME[:PARAM=VALUE,...]",
                   help="mechanism switched on in the study's simulations (repeatable)")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def _time_offset(text):
    if text == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--time-offset must be 'auto' or a number of seconds, got {text!r}") from None
    if not np.isfinite(value):
        raise ValueError("--time-offset must be finite")
    return value


def run(args):
    if not args.report and not args.json:
        raise ValueError("compare: give --report REPORT.pdf and/or --json METRICS.json")
    for path in (args.report, args.json):
        if path:
            check_output_path(path)
    guard_outputs([args.measured, args.simulated, getattr(args, "rig", None), getattr(args, "maneuver", None)],
                  files=[args.report, args.json])
    offset = _time_offset(args.time_offset)
    measured = read_trajectory_table(args.measured, "measured")
    simulated = read_trajectory_table(args.simulated, "simulated")

    study = None
    rig = rig_from_args(args)
    maneuver = maneuver_from_args(args, rig)
    if args.discretization_study:
        physics = physics_from_args(args)
        t = np.asarray(simulated["time"], float)
        rate = round(1.0 / float(np.median(np.diff(t))), 6)
        duration = float(t[-1]) - float(maneuver.time[0])
        if not duration > 0:
            raise ValueError("the simulated table ends before the maneuver starts; cannot size the study")
        if not args.quiet:
            print("discretization study: simulating low, baseline, medium, high ...", file=sys.stderr)
        study = discretization_study(rig, maneuver, physics, duration=duration, rate_hz=rate, workers=2)

    try:
        metrics = compare_tables(measured, simulated, time_offset=offset, free_decay_start=args.free_decay_start,
                                 max_offset=args.max_offset, study=study, rig=rig, maneuver=maneuver)
    except ValueError as exc:
        if args.measured in str(exc) or args.simulated in str(exc):
            raise
        raise ValueError(f"{args.measured} against {args.simulated}: {exc}") from None
    if args.json:
        write_json(args.json, metrics)
    if args.report:
        sources = {"measured": os.path.basename(args.measured), "simulated": os.path.basename(args.simulated)}
        write_report(args.report, measured, simulated, metrics, study=study, sources=sources,
                     machine=machine_picture(rig, maneuver))
    if not args.quiet:
        s, off = metrics["summary"], metrics["time_offset"]
        print(
            f"time offset {off['applied']:+.4f} s ({off['source']}); {s['n_pass']} of {s['n_channels']} channels "
            f"within tolerance, {s['n_fail']} outside, {s['n_missing']} missing; wrote "
            + " and ".join(p for p in (args.report, args.json) if p),
            file=sys.stderr,
        )
    return 0
