"""``dragline bench``: benchmarks that print figures (JSON), never pass/fail."""

from __future__ import annotations

import os
import sys

from dragline.capture import json_text, write_json

from ._options import add_scheduler_option, check_output_path


def add_parser(sub):
    p = sub.add_parser("bench", help="measure speed and accuracy (prints figures)",
                       description="Benchmarks: measured figures as JSON on stdout or in --json FILE.")
    p.add_argument("what", choices=sorted(BENCHES), help="which benchmark")
    p.add_argument("--json", metavar="FILE", help="also write the figures to FILE")
    p.add_argument("--repeats", type=int, default=5, help="timed runs per figure (median reported)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--quick", action="store_true", help="discovery: the reduced case list")
    p.add_argument("--limits", action="store_true", help="discovery: cases at the detection limit (with --realism: the realistic world's)")
    p.add_argument("--realism", action="store_true",
                   help="discovery: truth rigs drawn within the rig's tolerances, simulated finer than the "
                        "diagnosis, with out-of-menu physics among the cases")
    p.add_argument("--verdict-set", action="store_true",
                   help="discovery --realism: the trusted-verdict set, 64 cases (each candidate at 2, 5 and 20 times "
                        "its detection threshold, twice; 20 with nothing added; 14 out of the menu, 10 of them beyond every law)")
    p.add_argument("--pairs", action="store_true",
                   help="discovery --realism: two hidden mechanisms per case (a dominant one at 20 times its "
                        "detection threshold, a second at 5 times), which bound the second round's share from above")
    p.add_argument("--sites", action="store_true",
                   help="discovery --realism: one law hidden at one site per case (friction at a ring, a sheave's "
                        "bearing, drag on a body, a rope type's damping beyond its tolerance; 2, 5 and 20 times "
                        "its detection threshold), diagnosed with every law at each of its sites")
    p.add_argument("--another-rig", action="store_true",
                   help="discovery --realism: truth rigs whose geometry (fixed points, mass centres, reel zeros) lies "
                        "1.5, 3 and 6 times beyond the updating's bounds, beside cases within tolerance, which bound "
                        "the another-rig rule's factor from above and below")
    p.add_argument("--candidates", metavar="NAME,...",
                   help="detection: the candidates whose thresholds are sought (a law, or a law at a site, "
                        "LAW@SITE; default every candidate); discovery --realism: what every case's diagnosis "
                        "tries (default,*@*: every law at each of its sites too; an out-of-menu effect named as "
                        "the generic law that models it is then right)")
    p.add_argument("--rig", metavar="NAME", help="discovery --realism: another built-in machine's cases "
                                                  "(pendulum, slung_load, gantry_crane; with --sites "
                                                  "hook_block_crane; default the dragline); detection: the "
                                                  "machine whose thresholds are sought; sensitivities: the "
                                                  "machine whose parameters are differentiated")
    p.add_argument("--workers", type=int, default=2, help="discovery, diagnosis: parallel processes")
    p.add_argument("--session", metavar="DIR",
                   help="diagnosis: the session to diagnose (default: the sample session's recipe, synthesised first)")
    p.add_argument("--run-session", action="store_true",
                   help="diagnosis: the session `dragline run --seed SEED` builds (made first) instead of the sample")
    add_scheduler_option(p)
    p.add_argument("--data", metavar="DIR",
                   help="real: the flights' folder, any depth: the Stormlord flights' rosbag_NN folders "
                        "and/or the three-drone box logs (*_logger1.txt); docs/real-recordings.md")
    p.add_argument("--figure", metavar="FILE.png",
                   help="real: the first flight left out, drawn against each model's prediction")
    p.add_argument("--records", metavar="FILE", nargs="+",
                   help="decisions: calibration records (default: the committed seeds 92 and 94)")
    p.add_argument("--keep-diagnoses", metavar="DIR",
                   help="discovery: keep every case's diagnosis.json in DIR (case<seed>.json)")


def _simulate(args):
    from dragline.benchmarks import bench_simulate, simulate_summary_lines

    report = bench_simulate(repeats=args.repeats)
    return report, simulate_summary_lines(report)


def _capture(args):
    from dragline.benchmarks import bench_capture

    return bench_capture(seed=args.seed), []


def _reconstruct(args):
    from dragline.benchmarks import bench_reconstruction

    return bench_reconstruction(seed=args.seed), []


def _triangulation(args):
    from dragline.benchmarks import bench_triangulation

    return bench_triangulation(seed=args.seed, repeats=args.repeats), []


def _diagnosis(args):
    from dragline.benchmarks import bench_diagnosis, diagnosis_summary_lines

    if args.session is not None and not os.path.isdir(args.session):
        raise ValueError(f"{args.session}: no such session folder")
    if args.session is not None and args.run_session:
        raise ValueError("--session and --run-session name two sessions: give one")
    report = bench_diagnosis(session=args.session, repeats=args.repeats, workers=args.workers,
                             run_seed=args.seed if args.run_session else None)
    return report, diagnosis_summary_lines(report)


def _discovery(args):
    from dragline.benchmarks import discovery_command

    return discovery_command(args)


def _detection(args):
    from dragline.benchmarks import bench_detection, detection_summary_lines

    names = [n.strip() for n in args.candidates.split(",") if n.strip()] if args.candidates else None
    if names:
        from dragline.compare.diagnose import candidate_list
        from dragline.simulate import load_rig

        candidate_list(names, load_rig(args.rig))  # unknown names and sites: exit 2 before any work
    report = bench_detection(candidates=names, workers=args.workers, rig_name=args.rig,
                             progress=lambda line: print(line, file=sys.stderr))
    return report, detection_summary_lines(report)


def _sensitivities(args):
    from dragline.benchmarks import bench_sensitivities, sensitivities_summary_lines

    report = bench_sensitivities(rig_name=args.rig or "dragline", repeats=args.repeats)
    return report, sensitivities_summary_lines(report)


def _decisions(args):
    from dragline.benchmarks import decisions_command

    for path in args.records or ():
        if not os.path.isfile(path):
            raise ValueError(f"{path}: no such records file")
    return decisions_command(args)


def _real(args):
    from dragline.benchmarks import real_command

    return real_command(args)


BENCHES = {"simulate": _simulate, "capture": _capture, "reconstruct": _reconstruct, "triangulation": _triangulation,
           "diagnosis": _diagnosis, "detection": _detection, "discovery": _discovery, "real": _real, "sensitivities": _sensitivities,
           "decisions": _decisions}


def run(args):
    if args.repeats < 1:
        raise ValueError("--repeats must be at least 1")
    if args.json:
        check_output_path(args.json)
    report, lines = BENCHES[args.what](args)
    if args.json:
        write_json(args.json, report, indent=2)
    for line in lines:
        print(line, file=sys.stderr)
    print(json_text(report, indent=2))
    return 0
