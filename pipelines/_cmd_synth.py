"""``dragline synth``: film a simulated trial in the simulated lab, write a session directory.

The session directory gets only what a lab records (``capture.mcap``,
``maneuver.csv``); the truth (trajectories, true cameras, the physics used)
goes to ``--truth-out`` and nowhere else.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np
from dragline.capture import atomic_directory, check_directory_target
from dragline.lab import MAX_RATE_HZ, lab_for_rig, synthesize_session, write_session_dir, write_truth
from dragline.lab import SYNTH_DEFAULTS as DEFAULTS
from dragline.simulate import marker_positions, simulate

from ._guard import guard_outputs
from ._options import (
    add_model_options,
    discretization_from_args,
    maneuver_from_args,
    number,
    physics_from_args,
    rig_from_args,
)


def add_parser(sub):
    p = sub.add_parser(
        "synth", help="synthesise a lab session (2D centroids, calibration takes) from a simulation",
        description="Simulate a maneuver (with any --physics), film it with the lab's six cameras "
                    "(noise, occlusion, dropouts, ghosts, lens distortion) and write a session "
                    "directory; the truth goes only to --truth-out.")
    add_model_options(p)
    p.add_argument("--seed", type=number("nonnegative", integer=True, maximum=2**32 - 1), default=0, metavar="N",
                   help="seeds the cameras' intrinsics, the wand path and every random stage (default 0)")
    p.add_argument("--noise-px", type=number("nonnegative", maximum=1e3), default=DEFAULTS["noise_px"], metavar="SIGMA",
                   help=f"centroid noise per axis (px, default {DEFAULTS['noise_px']})")
    p.add_argument("--dropout", type=number("fraction"), default=DEFAULTS["dropout"], metavar="P",
                   help=f"fraction of detections lost at random (default {DEFAULTS['dropout']})")
    p.add_argument("--ghost-rate", type=number("fraction"), default=DEFAULTS["ghost_rate"], metavar="P",
                   help=f"fraction of trial detections replaced by a wrong centroid (default {DEFAULTS['ghost_rate']})")
    p.add_argument("--wand-ghost-rate", type=number("fraction"), default=DEFAULTS["wand_ghost_rate"], metavar="P",
                   help=f"the same in the wand take (default {DEFAULTS['wand_ghost_rate']})")
    p.add_argument("--no-occlusion", action="store_true", help="do not hide markers behind the rig's bodies")
    p.add_argument("--distortion-scale", type=number("nonnegative", maximum=100), default=1.0, metavar="S",
                   help="multiply the true lenses' distortion (0: ideal lenses; default 1)")
    p.add_argument("--rate", type=number(), default=200.0, metavar="HZ",
                   help=f"trial frame rate (Hz, default 200, at most {MAX_RATE_HZ:g})")
    p.add_argument("--duration", type=number(), default=10.0, metavar="S", help="trial length (s, default 10)")
    p.add_argument("--wand-frames", type=number("nonnegative", integer=True, maximum=100_000), default=DEFAULTS["wand_frames"], metavar="N",
                   help=f"frames of the wand take (default {DEFAULTS['wand_frames']}; 0: none)")
    p.add_argument("--wand-rate", type=number(maximum=1e4), default=DEFAULTS["wand_rate_hz"], metavar="HZ",
                   help=f"frame rate of the calibration takes (Hz, default {DEFAULTS['wand_rate_hz']:g})")
    p.add_argument("--lframe-frames", type=number("nonnegative", integer=True, maximum=100_000), default=DEFAULTS["lframe_frames"], metavar="N",
                   help=f"frames of the static L-frame take (default {DEFAULTS['lframe_frames']}; 0: none)")
    p.add_argument("--out", required=True, metavar="SESSION_DIR", help="session directory to create")
    p.add_argument("--truth-out", metavar="DIR",
                   help="directory for the truth: trajectories.csv, cameras.json, physics.json, markers.csv")
    p.add_argument("--force", action="store_true", help="replace existing non-empty output directories")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def _check_args(args):
    if not 0 < args.rate <= MAX_RATE_HZ:
        raise ValueError(f"--rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {args.rate:g}")
    if not args.duration > 0:
        raise ValueError(f"--duration must be positive, got {args.duration:g}")
    if not args.noise_px >= 0:
        raise ValueError(f"--noise-px must be >= 0, got {args.noise_px:g}")
    for flag, value in (("--dropout", args.dropout), ("--ghost-rate", args.ghost_rate),
                        ("--wand-ghost-rate", args.wand_ghost_rate)):
        if not 0 <= value < 1:
            raise ValueError(f"{flag} must be a fraction in [0, 1), got {value:g}")
    if not (np.isfinite(args.distortion_scale) and args.distortion_scale >= 0):
        raise ValueError(f"--distortion-scale must be >= 0, got {args.distortion_scale:g}")
    if args.wand_frames < 0 or args.lframe_frames < 0:
        raise ValueError("--wand-frames and --lframe-frames must be >= 0")
    if not 0 < args.wand_rate <= MAX_RATE_HZ:
        raise ValueError(f"--wand-rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {args.wand_rate:g}")
    guard_outputs([args.rig, args.maneuver], folders=[args.out, args.truth_out])
    check_directory_target(args.out, args.force)
    if args.truth_out is not None:
        check_directory_target(args.truth_out, args.force)


def run(args):
    _check_args(args)
    rig = rig_from_args(args)
    maneuver = maneuver_from_args(args, rig)
    discretization = discretization_from_args(args, rig)
    physics = physics_from_args(args)
    t0 = time.perf_counter()
    result = simulate(rig, maneuver, discretization, physics, duration=args.duration, rate_hz=args.rate)
    # The lab the rig file names: the dragline's own, or one placed about the machine's markers.
    lab = lab_for_rig(rig, marker_positions(result)[1], args.seed)
    cameras = [dataclasses.replace(c, dist=c.dist * args.distortion_scale) for c in lab.cameras]
    session, truth = synthesize_session(
        result, cameras, seed=args.seed, noise_px=args.noise_px, dropout=args.dropout,
        ghost_rate=args.ghost_rate, wand_ghost_rate=args.wand_ghost_rate, occlusion=not args.no_occlusion,
        wand_frames=args.wand_frames, wand_rate_hz=args.wand_rate, lframe_frames=args.lframe_frames,
        metadata={"generator": "dragline synth", "rig": rig.name}, wand_volume=lab.wand_volume,
        lframe=lab.lframe, wand_length=lab.wand_length)
    write_session_dir(args.out, session, result.model.maneuver, overwrite=args.force)
    if args.truth_out is not None:
        described = {
            "physics": [{"name": m.name, "parameters": dict(m.parameters)} for m in physics],
            "rig": args.rig or "built-in",
            "maneuver": args.maneuver or "the rig's own",
            "discretization": args.discretization,
            "duration_s": args.duration,
            "rate_hz": args.rate,
            "camera_seed": args.seed,
            "distortion_scale": args.distortion_scale,
        }
        atomic_directory(args.truth_out, lambda tmp: write_truth(tmp, truth, described), args.force)
    if not args.quiet:
        seen = np.isfinite(session.trial).all(axis=-1).sum(axis=0) >= 2
        print(f"synthesised {session.trial.shape[1]} frames x {len(session.marker_names)} markers x "
              f"{len(cameras)} cameras at {session.rate_hz:g} Hz ({100 * seen.mean():.1f} % of marker-frames "
              f"seen by two cameras or more), wand take {args.wand_frames} frames, L-frame take "
              f"{args.lframe_frames} frames, in {time.perf_counter() - t0:.1f} s; wrote {args.out}"
              + (f" and truth {args.truth_out}" if args.truth_out else ""), file=sys.stderr)
    return 0
