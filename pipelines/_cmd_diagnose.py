"""``dragline diagnose``: locate the mismatch, name the missing physics, fit it, show the fit improve."""

from __future__ import annotations

import sys
import time

from dragline.compare.diagnose import candidate_list, diagnose_path, write_diagnosis_json, write_diagnosis_report

from ._guard import guard_outputs, session_inputs
from dragline.capture import resolve_recording

from ._options import (
    add_between_option,
    add_scheduler_option,
    between_from_args,
    check_output_path,
    discretization_from_args,
    executor_from_args,
    number,
    rig_from_args,
)


def add_parser(sub):
    p = sub.add_parser(
        "diagnose", help="find the physics the nominal model leaves out (JSON verdict, PDF report)",
        description="Compare a recording with the nominal model of its maneuver, locate the mismatch (bodies, "
                    "quantities, time windows, frequencies, free decay), fit every optional mechanism through "
                    "the simulator, score each on held-out data against what measurement noise alone gives, and "
                    "name one, 'none' (the model fits within noise) or 'unexplained'.")
    p.add_argument("input", nargs="+", metavar="SESSION_DIR|capture.mcap|export.csv|.c3d|.trc|MEASURED.csv",
                   help="a session, a VICON-style marker CSV or a measured trajectory table; several: trials of "
                        "the machine fitted together (shared rig and mechanism parameters, each trial its own "
                        "offsets and clock)")
    p.add_argument("--leave-one-out", action="store_true",
                   help="with several recordings: each in turn left out, the others fitted together and it "
                        "predicted (verdict agreement, the parameters' spread, held-out improvement)")
    p.add_argument("--predict", action="append", default=[], metavar="RECORDING",
                   help="a trial of the same machine the fit never sees, predicted by the nominal, the updated and "
                        "the named model (repeatable; read as INPUT is)")
    p.add_argument("--maneuver", default=None, metavar="dig|FILE.csv",
                   help="reel table of the recording (default: the session's; for a CSV, maneuver.csv beside "
                        "it, else the dig maneuver); always checked against the recorded rope lengths")
    p.add_argument("--calibration", metavar="cameras.json",
                   help="camera calibration of a session (default: cameras.json in it, else calibrated from "
                        "its L-frame and wand takes)")
    p.add_argument("--rig", metavar="NAME|FILE", help="a built-in machine or a rig TOML file (default: the dragline)")
    p.add_argument("--mapping", metavar="MAPPING.toml",
                   help="read INPUT as a table of tracked poses (a tracker's CSV export) mapped onto the rig's "
                        "bodies and points by this file (docs/schemas.md)")
    p.add_argument("--start", choices=("rig", "recording"), default="rig",
                   help="where each trial starts: the rig's own start (its statics, or its release; the default), "
                        "or where the recording's first samples have the tracked bodies, moving as they move "
                        "there (a recording cut from the middle of a motion)")
    p.add_argument("--discretization", default="baseline", metavar="LEVEL|ROPE=N,...",
                   help="discretization of every simulation (default baseline)")
    p.add_argument("--candidates", metavar="NAME,...",
                   help="mechanisms to try (default: every candidate the simulator has); LAW@SITE tries a law at "
                        "one site (pulley_friction@boom), LAW@* at each of the rig's sites, *@* every law at each "
                        "of its sites, 'default' the default list (default,*@*: both)")
    p.add_argument("--workers", type=number(integer=True, maximum=256), default=2, metavar="N",
                   help="simulation processes (default 2)")
    add_between_option(p)
    add_scheduler_option(p)
    p.add_argument("--seed", type=number("nonnegative", integer=True, maximum=2**32 - 1), default=0, metavar="N",
                   help="seeds the null test's surrogates (default 0)")
    p.add_argument("--json", required=True, metavar="DIAGNOSIS.json", help="diagnosis to write")
    p.add_argument("--report", metavar="REPORT.pdf", help="PDF report to write")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def run(args):
    outputs = [p for p in (args.json, args.report) if p]
    for path in outputs:
        check_output_path(path)
    recordings = [*args.input, *args.predict]
    guard_outputs([*(p for path in recordings for p in session_inputs(path, extra=("cameras.json",))), args.maneuver,
                   args.calibration, args.rig, args.mapping], files=outputs)
    if args.workers < 1:
        raise ValueError("--workers must be at least 1")
    if args.leave_one_out and len(args.input) < 2:
        raise ValueError("--leave-one-out needs at least two recordings")
    names = None
    if args.candidates:
        names = [n.strip() for n in args.candidates.split(",") if n.strip()]
    between = None
    for path in recordings if args.between else ():
        between = between_from_args(args, resolve_recording(path, tables=True).kind, path)
    rig = rig_from_args(args)
    if names:
        candidate_list(names, rig)  # unknown names and sites the rig has not: exit 2 before any work
    discretization = discretization_from_args(args, rig)
    say = (lambda msg: None) if args.quiet else (lambda msg: print(f"dragline: {msg}", file=sys.stderr))
    t0 = time.perf_counter()
    result = diagnose_path(args.input if len(args.input) > 1 else args.input[0], maneuver=args.maneuver, rig=rig,
                           calibration=args.calibration, discretization=discretization, candidates=names,
                           workers=executor_from_args(args), seed=args.seed, progress=say, between=between,
                           mapping=args.mapping, held_out=args.predict, leave_one_out=args.leave_one_out,
                           start_from_recording=args.start == "recording")
    write_diagnosis_json(args.json, result.doc)
    if args.report:
        write_diagnosis_report(args.report, result)
    if not args.quiet:
        doc = result.doc
        top = doc["hypotheses"][0] if doc["hypotheses"] else None
        fit = ""
        if doc["verdict"] not in ("none", "unexplained") and top is not None:
            p = top["main_parameter"]
            u = top["uncertainty"].get("std")
            fit = f" ({p} = {top['parameters'][p]:.4g}" + (f" +- {u:.2g})" if u is not None else ")")
        print(f"verdict: {doc['verdict']}{fit}; {doc['reason']}", file=sys.stderr)
        for entry in doc["held_out"]:
            rms = ", ".join(f"{k} {v:.3g}" if v is not None else f"{k} failed" for k, v in entry["rms_noise"].items())
            print(f"held-out {entry['trial']}: RMS residual in noise units: {rms}", file=sys.stderr)
        loo = doc.get("leave_one_out")
        if loo:
            better = loo["updated_better_share"]
            print(f"leave one out: verdicts {loo['verdicts']}; the update predicts the trial left out better than "
                  f"the nominal model in {'-' if better is None else f'{100 * better:.0f} %'} of "
                  f"{len(loo['splits'])} splits", file=sys.stderr)
        print(f"{doc['timing']['simulations']} simulations in {time.perf_counter() - t0:.0f} s; wrote "
              + " and ".join(outputs), file=sys.stderr)
    return 0
