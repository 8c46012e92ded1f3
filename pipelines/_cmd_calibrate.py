"""``dragline calibrate``: cameras from a session's L-frame and wand takes alone."""

from __future__ import annotations

import sys
import time

from dragline.capture import (
    calibrate,
    camera_centre,
    json_text,
    read_session,
    save_cameras,
    session_file,
)

from ._guard import guard_outputs, session_inputs
from ._options import check_output_path, number


def add_parser(sub):
    p = sub.add_parser("calibrate", help="calibrate the cameras from a session's wand and L-frame takes",
                       description="Calibrate the cameras from the L-frame and wand takes of a session "
                                   "(nothing else is read), write cameras.json and print the quality: "
                                   "reprojection RMS per camera (px), wand length mean and spread (mm).")
    p.add_argument("session", metavar="SESSION_DIR|capture.mcap", help="session directory or its MCAP file")
    p.add_argument("--out", required=True, metavar="cameras.json", help="calibration to write")
    p.add_argument("--max-frames", type=number(integer=True, maximum=1_000_000), default=2000, metavar="N",
                   help="most wand frames in the bundle adjustment (evenly spread; default 2000)")
    p.add_argument("--json", action="store_true", help="print the quality summary as JSON")


def _takes(session, path):
    missing = [name for name, arr in (("L-frame", session.lframe), ("wand", session.wand)) if arr is None]
    if missing:
        what = "no calibration takes" if len(missing) == 2 else f"no {missing[0]} take"
        raise ValueError(f"{path}: {what}; calibration needs the L-frame and the wand takes")
    if session.wand_length is None or session.lframe_points is None:
        raise ValueError(f"{path}: the session lacks the wand length or the L-frame marker positions")


def _text(quality, cameras, path, seconds):
    lines = [f"calibrated {len(cameras)} cameras from {path} in {seconds:.1f} s "
             f"({quality['frames_used']} of {quality['frames_usable']} usable wand frames, "
             f"root camera {quality['root_camera']})",
             f"{'camera':<8} {'RMS px':>7} {'focal px':>9} {'k1':>8} {'centre x, y, z (m)':>26}"]
    for cam in cameras:
        c = camera_centre(cam)
        lines.append(f"{cam.name:<8} {quality['reprojection_rms_px'][cam.name]:7.3f} {cam.K[0, 0]:9.1f} "
                     f"{cam.dist[0]:8.4f}   {c[0]:7.3f} {c[1]:7.3f} {c[2]:7.3f}")
    lines.append(f"{'all':<8} {quality['reprojection_rms_px_all']:7.3f}")
    lines.append(f"wand length {quality['wand_length_mean_mm']:.2f} mm mean, "
                 f"{quality['wand_length_std_mm']:.2f} mm standard deviation")
    lines.append(f"L-frame misfit {quality['lframe_misfit_mm']:.2f} mm RMS")
    return "\n".join(lines)


def run(args):
    check_output_path(args.out)
    guard_outputs(session_inputs(args.session), files=[args.out])
    if args.max_frames < 100:
        raise ValueError(f"--max-frames must be at least 100, got {args.max_frames}")
    path = session_file(args.session)
    session, report = read_session(path)
    if report["lost"] != "nothing":
        print(f"dragline: warning: {path} is {'cut short' if report['truncated'] else 'damaged'}; "
              f"lost: {report['lost']}", file=sys.stderr)
    _takes(session, path)
    t0 = time.perf_counter()
    try:
        cameras, quality = calibrate(session.lframe, session.wand, session.wand_length, session.lframe_points,
                                     session.image_size, session.nominal_focal_px,
                                     names=session.camera_names, max_frames=args.max_frames)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    seconds = time.perf_counter() - t0
    quality = {**quality, "wall_time_s": seconds, "session": path}
    save_cameras(args.out, cameras, quality)
    if args.json:
        print(json_text(quality, indent=2))
    else:
        print(_text(quality, cameras, path, seconds))
        print(f"wrote {args.out}")
    return 0
