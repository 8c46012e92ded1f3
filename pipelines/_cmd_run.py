"""``dragline run``: the whole pipeline, on the built-in rig or on a user's capture."""

from __future__ import annotations

from dragline.capture import json_text, resolve_recording

from ._options import BUILT_IN_RIGS, add_between_option, between_from_args, number


def add_parser(sub):
    p = sub.add_parser("run", help="the whole pipeline: capture, calibrate, reconstruct, simulate, compare",
                       description="Run every stage. With no input: a synthetic lab session of the paper's dig "
                       "maneuver whose hidden lab truth damps faster than the nominal model.")
    p.add_argument("source", nargs="?", metavar="SESSION_DIR|capture.mcap|MARKERS.csv|.c3d|.trc",
                   help="a capture to process (default: the built-in synthetic session)")
    p.add_argument("--out", default="dragline-out", metavar="OUT_DIR", help="output directory (default ./dragline-out)")
    p.add_argument("--rig", metavar="NAME|FILE",
                   help=f"the machine: a built-in one ({', '.join(BUILT_IN_RIGS)}) or a rig TOML file; default "
                        "the config's, else the dragline")
    p.add_argument("--maneuver", metavar="dig|FILE.csv", help="reel table (default: the session's own)")
    p.add_argument("--config", metavar="FILE.toml", help="stage options (see the README's Configuration)")
    p.add_argument("--seed", type=number("nonnegative", integer=True, maximum=2**32 - 1), default=None,
                   help="seed of the built-in session (default 0)")
    add_between_option(p)
    p.add_argument("--no-study", action="store_true", help="skip the discretization study (Fig. 21)")
    p.add_argument("--no-diagnose", action="store_true", help="skip the missing-physics diagnosis")
    p.add_argument("--verbose", action="store_true", help="print each stage's time as it ends")
    p.add_argument("--force", action="store_true", help="replace a non-empty output directory")
    p.add_argument("--quiet", action="store_true", help="print only the final summary")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")


def run(args):
    from dragline.simulate import dig_maneuver, read_maneuver_csv

    from ._run import DEFAULTS, read_config, run_pipeline

    config = read_config(args.config) if getattr(args, "config", None) else {k: dict(v) for k, v in DEFAULTS.items()}
    between = None
    if getattr(args, "between", None):
        kind = resolve_recording(args.source).kind if args.source else "session"
        between = between_from_args(args, kind, args.source or "the built-in session")
    maneuver = None
    if args.maneuver:
        maneuver = dig_maneuver() if args.maneuver == "dig" else read_maneuver_csv(args.maneuver)
    if getattr(args, "rig", None):
        config["simulate"]["rig"] = args.rig
    seed = args.seed if args.seed is not None else int(config["run"]["seed"])
    study = config["run"]["study"] and not args.no_study
    config["run"]["diagnose"] = config["run"]["diagnose"] and not getattr(args, "no_diagnose", False)
    summary = run_pipeline(args.source, args.out, seed=seed, maneuver=maneuver, study=study, quiet=args.quiet,
                           force=args.force, config=config, verbose=getattr(args, "verbose", False),
                           inputs=(getattr(args, "config", None), args.maneuver), between=between)
    if args.json:
        print(json_text(summary, indent=2))
        return 0
    print(f"wrote {summary['out']}:", ", ".join(sorted(summary["files"])))
    total = sum(summary["stage_seconds"].values())
    print("stages: " + "; ".join(f"{k} {v:.1f} s" for k, v in summary["stage_seconds"].items()) + f" (total {total:.0f} s)")
    channels = summary["comparison"]["channels"]
    if channels:
        print(f"comparison: {channels.get('n_pass')} of {channels.get('n_channels')} channels within tolerance, "
              f"{channels.get('n_fail')} outside, {channels.get('n_missing')} missing")
    ratio = summary["comparison"].get("damping_ratio_measured_over_model")
    if ratio:
        how = f"{ratio:.1f}x faster than the model" if ratio < 100 else "far faster than the model, which barely damps"
        print(f"free decay after the reels stop: the measurement damps {how} "
              f"(median damping-ratio ratio over the channels: {ratio:.3g})")
    found = summary.get("diagnosis")
    if found:
        line = f"diagnosis: {found['verdict']}"
        best = found.get("best")
        if best and best.get("name") == found["verdict"]:
            params = ", ".join(f"{k}={v:.3g}" for k, v in (best.get("parameters") or {}).items() if isinstance(v, float))
            line += (f" ({params}); held-out residual {best['rms_before']:.2f} -> {best['rms_after']:.2f} "
                     "x the measurement noise")
        elif found.get("reason"):
            line += f" ({found['reason']})"
        print(line)
    print(f"report: {summary['out']}/report.pdf")
    return 0
