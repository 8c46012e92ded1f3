"""``dragline reconstruct``: 2D centroids or 3D markers -> measured trajectory table.

Input is a session directory, its ``capture.mcap``, or a file of labelled 3D
markers: a VICON-style CSV, a C3D or a TRC file. A session needs a
calibration (``--calibration``, or a ``cameras.json`` in the session
directory); a marker file needs none. A session directory without
``capture.mcap`` but with a ``markers.csv`` is read as that CSV.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from dragline.capture import (
    load_cameras,
    resolve_recording,
    write_c3d,
    write_json,
    write_trc,
    write_vicon_csv,
)
from dragline.reconstruct import SMOOTHING_METHODS as SMOOTHINGS
from dragline.reconstruct import TRIANGULATION_METHODS as METHODS
from dragline.reconstruct import (
    reconstruct_marker_file,
    reconstruct_session,
    vicon_name,
)
from dragline.simulate import write_trajectory_csv

from ._guard import guard_outputs, session_inputs
from ._options import add_between_option, between_from_args, check_output_path, number, rig_from_args


def add_parser(sub):
    p = sub.add_parser(
        "reconstruct", help="triangulate a capture and recover bodies, ropes and rates",
        description="Recover the measured trajectory table (mass centres, Euler angles, velocities, "
                    "body rates, rope lengths) from a capture session or a file of labelled 3D markers "
                    "(VICON-style CSV, C3D, TRC).")
    p.add_argument("input", metavar="SESSION_DIR|capture.mcap|MARKERS.csv|.c3d|.trc", help="what to reconstruct")
    p.add_argument("--calibration", metavar="cameras.json",
                   help="camera calibration (default: cameras.json in the session directory)")
    p.add_argument("--out", required=True, metavar="MEASURED.csv", help="trajectory table to write")
    p.add_argument("--vicon-csv", metavar="MARKERS.csv",
                   help="also write the triangulated, labelled markers (before gap filling) as a VICON-style CSV")
    p.add_argument("--c3d", metavar="MARKERS.c3d", help="the same markers as a C3D file (mm, residual -1 in gaps)")
    p.add_argument("--trc", metavar="MARKERS.trc", help="the same markers as a TRC file (mm, empty cells in gaps)")
    p.add_argument("--rig", metavar="FILE", help="rig TOML file (default: the built-in 1/16-scale rig)")
    p.add_argument("--method", choices=METHODS, default="paper",
                   help="body frames: the paper's Eqs. 14-16 or a least-squares rigid fit (default paper)")
    p.add_argument("--smoothing", choices=SMOOTHINGS, default="running_average",
                   help="smoother for velocities and body rates (default: the paper's 12-sample "
                        "running average, centred on i-5...i+6)")
    p.add_argument("--max-gap", type=number("nonnegative", integer=True, maximum=1_000_000), default=10,
                   metavar="FRAMES",
                   help="longest marker gap filled by spline (frames, default 10); longer gaps stay NaN")
    p.add_argument("--outlier-mm", type=number("nonnegative", maximum=1e6), default=20.0, metavar="MM",
                   help="a marker farther than this from the median of its +-3 frames is dropped as an "
                        "outlier before gap filling (default 20; 0 keeps every sample)")
    # Below a hundredth of a pixel even a noiseless centroid's rounding is rejected.
    p.add_argument("--max-reprojection-px", type=number(maximum=1e4, minimum=0.01), default=3.0, metavar="PX",
                   help="views reprojecting worse than this are rejected as outliers (default 3; 0.01-10000)")
    add_between_option(p)
    p.add_argument("--summary-json", metavar="FILE", help="write the reconstruction summary (gap counts, ...) as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def _calibration(args, session_dir, session_path):
    path = args.calibration
    if path is None and session_dir is not None:
        candidate = os.path.join(session_dir, "cameras.json")
        path = candidate if os.path.isfile(candidate) else None
    if path is None:
        raise ValueError(f"{session_path}: no calibration for this session; pass --calibration cameras.json "
                         "(made by 'dragline calibrate')")
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such calibration file")
    return path, load_cameras(path)


def _check_not_empty(table, kind, args, path):
    """A table without one finite value is no reconstruction: say what emptied it instead of writing it."""
    values = table.drop(columns="time").to_numpy(float)
    if values.size and np.isfinite(values).any():
        return
    cause = ("the file holds no finite coordinate of the rig's markers" if kind == "markers" else
             f"no marker survived triangulation with --max-reprojection-px {args.max_reprojection_px:g} "
             "(the right calibration and rig?)")
    raise ValueError(f"{path}: nothing reconstructed, no channel has a finite value: {cause}")


def run(args):
    outputs = [p for p in (args.out, args.vicon_csv, args.c3d, args.trc, args.summary_json) if p]
    for p in outputs:
        check_output_path(p)
    if len(set(map(os.path.abspath, outputs))) != len(outputs):
        raise ValueError("--out, --vicon-csv, --c3d, --trc and --summary-json must name different files")
    if args.max_gap < 0:
        raise ValueError("--max-gap must be >= 0")
    if not args.outlier_mm >= 0:
        raise ValueError("--outlier-mm must be >= 0")
    if not args.max_reprojection_px > 0:
        raise ValueError("--max-reprojection-px must be positive")
    guard_outputs([*session_inputs(args.input, extra=("cameras.json",)), args.calibration, args.rig], files=outputs)
    recording = resolve_recording(args.input)
    kind, path, session_dir = recording.kind, recording.file, recording.directory
    between = between_from_args(args, kind, args.input)
    rig = rig_from_args(args)
    options = dict(rig=rig, method=args.method, smoothing=args.smoothing, max_gap=args.max_gap,
                   max_deviation=args.outlier_mm * 1e-3 if args.outlier_mm > 0 else None)
    notes = []
    marker_outputs = [f"--{k.replace('_', '-')}" for k in ("vicon_csv", "c3d", "trc") if getattr(args, k)]
    if kind == "markers":
        if marker_outputs:
            raise ValueError(f"{marker_outputs[0]} needs a capture session as input (the input is already a "
                             "marker file)")
        if args.calibration:
            notes.append("--calibration ignored: a marker file is already three-dimensional")
        table, summary = reconstruct_marker_file(path, between=between, **options)
        if "cut_short" in summary:
            notes.append(f"{path} is cut short: {summary['cut_short']}; the frames there are read")
        if between:
            cut = summary["cut"]
            notes.append(f"kept frames {cut['frames'][0]}-{cut['frames'][1]}, from event '{cut['start']}' at "
                         f"{cut['start_s']:g} s to '{cut['end']}' at {cut['end_s']:g} s")
    else:
        from dragline.capture import read_session  # noqa: PLC0415

        session, report = read_session(path)
        cal_path, cameras = _calibration(args, session_dir, path)
        try:
            table, names, points, summary = reconstruct_session(
                session, cameras, max_reprojection_px=args.max_reprojection_px,
                calibration_name=cal_path, **options)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
        summary["session"] = {k: report[k] for k in ("path", "truncated", "lost", "frames", "lost_chunks")}
        if report["lost"] != "nothing":
            notes.append(f"{path} is {'cut short' if report['truncated'] else 'damaged'}; lost {report['lost']}")
        labels = [vicon_name(n) for n in names]
        if args.vicon_csv:
            write_vicon_csv(args.vicon_csv, labels, points, session.rate_hz)
        if args.c3d:
            write_c3d(args.c3d, labels, points, session.rate_hz)
        if args.trc:
            write_trc(args.trc, labels, points, session.rate_hz)
    _check_not_empty(table, kind, args, path)
    write_trajectory_csv(args.out, table)
    if args.summary_json:
        write_json(args.summary_json, summary)
    if not args.quiet:
        for note in notes:
            print(f"dragline: note: {note}", file=sys.stderr)
        total = summary["gaps"]["total"]
        print(
            f"reconstructed {summary['frames']} frames at {summary['rate_hz']:g} Hz ({args.method} frames, "
            f"{summary['smoothing']['description']}); {total['outlier_frames']} outlier marker-frames dropped; "
            f"gaps: {total['spline_gaps']} filled by spline, "
            f"{total['rigid_frames']} marker-frames from rigid bodies, {total['open_gaps']} left open "
            f"({total['open_frames']} marker-frames, limit {args.max_gap} frames); wrote {args.out}"
            + "".join(f" and {p}" for p in (args.vicon_csv, args.c3d, args.trc) if p),
            file=sys.stderr,
        )
    return 0
