"""The whole pipeline: capture -> calibration -> reconstruction -> simulation -> comparison.

``run_pipeline(None, out)`` is the built-in demonstration: a synthetic lab
session of the paper's dig maneuver whose hidden "lab truth" holds physics
the nominal model lacks (so that, as on the paper's rig, the recording
damps faster than the model), filmed by six simulated cameras, calibrated
from its own wand takes, reconstructed, and compared with the nominal
simulation. With a session directory, a ``capture.mcap`` or a VICON-style
CSV export it runs the same stages on the user's data.

Everything is written into a temporary sibling of the output directory,
renamed into place only when complete: an interruption leaves nothing
under the final name.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from pathlib import Path

from ._config_schema import RunConfig, validate_config

# The built-in lab truth: friction where the ropes slide through the ring
# pulleys (the paper's section 4 names pulley friction among the causes). It
# is written to OUT/truth, never into the session.
BUILTIN_HIDDEN_PHYSICS = "pulley_friction:mu=0.02"
BUILTIN_DURATION_S = 12.0  # 5.6 s of free decay after the reels stop at 6.44 s
# The lab's rig is not the nominal model: its uncertain parameters are drawn
# within the rig file's tolerances (seeded) and it is simulated finer than
# the model the diagnosis uses, as a real rig's continuum ropes would be.
BUILTIN_TRUTH_DISCRETIZATION = "medium"
BUILTIN_RIG_SEED = 1000


# Options a --config file may set, with their defaults (docs/schemas.md).
DEFAULTS = RunConfig().model_dump()


def read_config(path):
    """Read a ``dragline run --config`` TOML file over the defaults.

    Raises
    ------
    ValueError
        Unreadable file; unknown section or key; a value of the wrong type or
        out of its range (``_config_schema``).
    """
    import tomllib

    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except OSError as exc:
        raise ValueError(f"cannot read config {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"config {path} is not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise ValueError(f"config {path} is not UTF-8 text (TOML is UTF-8)") from None
    return validate_config(doc, path)


class _Stages:
    """Times each stage and shows progress on stderr (a bar on a terminal)."""

    def __init__(self, quiet, verbose=False, total=9):
        self.quiet, self.verbose = quiet, verbose
        self.times = {}
        self.bar = None
        if not quiet and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, file=sys.stderr, unit="stage", leave=False)

    def __call__(self, name, fn, *args, **kwargs):
        if self.bar is not None:
            self.bar.set_description(name)
        elif not self.quiet:
            print(f"[dragline] {name} ...", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        self.times[name] = time.perf_counter() - t0
        if self.bar is not None:
            self.bar.update(1)
        if self.verbose:
            print(f"[dragline] {name}: {self.times[name]:.1f} s", file=sys.stderr, flush=True)
        return out

    def close(self):
        if self.bar is not None:
            self.bar.close()


def run_pipeline(source, out_dir, seed=0, maneuver=None, study=True, quiet=False, force=False, config=None,
                 verbose=False, inputs=(), between=None):
    """Run every stage and write the outputs into ``out_dir``.

    Parameters
    ----------
    source : str or None
        None for the built-in synthetic session, else a session directory,
        a ``capture.mcap`` or a VICON-style CSV export.
    out_dir : str
        Output directory (must not exist, or be empty, unless ``force``).
    seed : int
        Seed of the built-in session.
    maneuver : Maneuver, optional
        Reel table; by default the session's own (the dig for a CSV export).
    study : bool
        Include the discretization study (the paper's Fig. 21) in the report.
    config : dict, optional
        Stage options (``read_config``); ``seed``, ``maneuver`` and ``study``
        given as arguments take precedence.
    inputs : tuple of str
        Other files the caller read (a config file, a maneuver CSV): the
        output directory must neither be one nor hold one.
    between : (str, str), optional
        A marker file's start and end event labels: the trial between them
        (``reconstruct_marker_file``).

    Returns
    -------
    dict
        Summary: files written, stage times (s), headline comparison figures.
    """
    from dragline.capture import OUTPUT_MARKER, mark_output

    from ._guard import guard_outputs, session_inputs

    out = Path(out_dir)
    settings = (config or DEFAULTS)["simulate"]
    guard_outputs([*session_inputs(source), settings.get("rig"), settings.get("maneuver"), *inputs], folders=[out])
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not force)):
        raise ValueError(f"output {out} exists and is not empty (use --force to replace it)")
    if out.is_dir() and any(out.iterdir()) and not (out / OUTPUT_MARKER).exists():
        raise ValueError(f"{out} was not written by dragline (no {OUTPUT_MARKER} in it); --force replaces only a "
                         "folder dragline wrote: remove it yourself or choose another name")
    parent = out.resolve().parent
    try:
        # An output directory is made like `mkdir -p`: scripts name nested
        # result folders (dragline-out/dig/seed3) on a fresh clone.
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output folder {parent}: {exc.strerror}") from None
    if not os.access(parent, os.W_OK):
        raise ValueError(f"output folder {parent} is not writable")
    tmp = parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    config = config or {section: dict(values) for section, values in DEFAULTS.items()}
    stages = _Stages(quiet, verbose)
    try:
        summary = _run_into(source, tmp, seed, maneuver, study, stages, config, between)
        mark_output(tmp, "run")
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    finally:
        stages.close()
        shutil.rmtree(tmp, ignore_errors=True)
    summary["out"] = str(out)
    return summary


def _run_into(source, tmp, seed, maneuver, study, stage, config, between=None):
    from dragline.capture import (
        calibrate,
        read_session,
        resolve_recording,
        save_cameras,
        write_json,
    )
    from dragline.compare import compare_tables, discretization_study, write_report, write_results
    from dragline.reconstruct import reconstruct_marker_file, reconstruct_session
    from dragline.simulate import (
        default_maneuver,
        dig_maneuver,
        load_rig,
        read_maneuver_csv,
        simulate,
        write_trajectory_csv,
    )

    sim, rec = config["simulate"], config["reconstruct"]
    rig = load_rig(sim["rig"])
    if maneuver is None and sim["maneuver"] is not None:
        maneuver = dig_maneuver() if sim["maneuver"] == "dig" else read_maneuver_csv(sim["maneuver"])
    options = {"method": rec["method"], "smoothing": rec["smoothing"], "max_gap": int(rec["max_gap"])}
    files = {}
    points = names = None
    if source is None:
        session, maneuver = stage("synthesise the lab session", _builtin_session, tmp, seed, rig)
        files["session"] = str(tmp / "session")
        files["truth"] = str(tmp / "truth")
    elif (recording := resolve_recording(source)).kind == "markers":
        maneuver = maneuver or default_maneuver(rig)
        measured, _ = stage("reconstruct the marker file", reconstruct_marker_file, recording.file, rig,
                            between=between, **options)
        session = None
    else:
        path = recording.file
        session, report = read_session(path)
        if session.wand is None or session.lframe is None:
            raise ValueError(f"{path}: no calibration takes (wand and L-frame) to calibrate the cameras from")
        if session.wand_length is None or session.lframe_points is None:
            raise ValueError(f"{path}: the session lacks the wand length or the L-frame marker positions")
        if maneuver is None:
            csv = Path(path).parent / "maneuver.csv"
            maneuver = read_maneuver_csv(csv) if csv.exists() else _maneuver_of(session)
    if session is not None:
        try:
            cameras, quality = stage(
                "calibrate the cameras", calibrate, session.lframe, session.wand, session.wand_length,
                session.lframe_points, session.image_size, session.nominal_focal_px, names=session.camera_names,
            )
        except ValueError as exc:  # the user's session: name its file, as calibrate does
            if source is None:
                raise
            raise ValueError(f"{path}: {exc}") from None
        save_cameras(tmp / "cameras.json", cameras, quality)
        files["cameras"] = str(tmp / "cameras.json")
        try:
            measured, names, points, _ = stage("reconstruct", reconstruct_session, session, cameras, rig,
                                               **options)
        except ValueError as exc:  # the session's markers: name its file, as reconstruct does
            if source is None:
                raise
            raise ValueError(f"{path}: {exc}") from None
    write_trajectory_csv(tmp / "measured.csv", measured)
    files["measured"] = str(tmp / "measured.csv")

    duration = float(measured["time"].iloc[-1] - measured["time"].iloc[0])
    discretization = sim["discretization"]
    result = stage("simulate the nominal model", simulate, rig, maneuver, discretization, duration=duration, rate_hz=200.0)
    simulated = result.table
    write_trajectory_csv(tmp / "simulated.csv", simulated)
    files["simulated"] = str(tmp / "simulated.csv")

    studied = stage("discretization study", discretization_study, rig, maneuver, duration=duration,
                    workers=2) if study else None
    metrics = stage("compare", compare_tables, measured, simulated, study=studied, rig=rig, maneuver=maneuver)
    write_json(tmp / "metrics.json", metrics)
    files["metrics"] = str(tmp / "metrics.json")
    stage("write the report", write_report, tmp / "report.pdf", measured, simulated, metrics, study=studied,
          sources={"measured": "measured.csv", "simulated": f"nominal model, {discretization} discretization"})
    files["report"] = str(tmp / "report.pdf")

    summary = {"files": files, "stage_seconds": stage.times, "comparison": _headline(metrics)}
    if config["run"]["diagnose"]:
        from dragline.compare import (
            diagnose,
            executor_from,
            write_diagnosis_json,
            write_diagnosis_report,
        )

        executor = executor_from(2, config["run"].get("scheduler"))
        found = stage("diagnose the missing physics", diagnose, measured, maneuver, rig, discretization,
                      workers=executor, seed=seed)
        write_diagnosis_json(tmp / "diagnosis.json", found.doc)
        write_diagnosis_report(tmp / "diagnosis.pdf", found)
        files["diagnosis"] = str(tmp / "diagnosis.json")
        files["diagnosis_report"] = str(tmp / "diagnosis.pdf")
        summary["diagnosis"] = _verdict(found.doc)

    ropes = {"simulated/" + r: result.rope_nodes(r) for r in rig.ropes}
    markers = {"measured": points} if points is not None else None
    start_ns = None if session is None else session.recorded_ns
    stage("write results.mcap", write_results, tmp / "results.mcap", {"measured": measured, "simulated": simulated},
          markers=markers, ropes=ropes, start_ns=start_ns,
          body_sizes={name: body.size for name, body in rig.bodies.items()})
    files["results"] = str(tmp / "results.mcap")
    return summary


def _builtin_session(tmp, seed, rig):
    import numpy as np
    from dragline.lab import lab_for_rig, synthesize_session, write_session_dir, write_truth
    from dragline.simulate import (
        apply_parameters,
        default_maneuver,
        draw_parameters,
        marker_positions,
        parse_physics,
        simulate,
    )

    # The rig's own trial (the dragline's: the dig) with the mechanism its file hides ([demo]).
    demo = rig.demo or {"physics": BUILTIN_HIDDEN_PHYSICS, "duration": BUILTIN_DURATION_S}
    maneuver = default_maneuver(rig)
    hidden = [parse_physics(demo["physics"])]
    coords = draw_parameters(rig.tolerances, np.random.default_rng(BUILTIN_RIG_SEED + seed))
    lab_rig, lab_maneuver = apply_parameters(rig, maneuver, rig.tolerances, coords)
    truth_run = simulate(lab_rig, lab_maneuver, BUILTIN_TRUTH_DISCRETIZATION, physics=hidden,
                         duration=demo["duration"], rate_hz=200.0)
    lab = lab_for_rig(rig, marker_positions(truth_run)[1], seed)
    # Filmed now: the results are dated from this moment, as a lab's from its recording.
    session, truth = synthesize_session(truth_run, lab.cameras, seed=seed,
                                        metadata={"generator": "dragline run", "rig": rig.name},
                                        recorded_ns=time.time_ns(), wand_volume=lab.wand_volume,
                                        lframe=lab.lframe, wand_length=lab.wand_length)
    write_session_dir(tmp / "session", session, maneuver)
    (tmp / "truth").mkdir()
    write_truth(tmp / "truth", truth, {"physics": [{"name": m.name, "parameters": dict(m.parameters)} for m in hidden],
                                       "seed": seed, "duration_s": demo["duration"],
                                       "discretization": BUILTIN_TRUTH_DISCRETIZATION,
                                       "rig_parameters": [{"parameter": p.name, "nominal": p.nominal,
                                                           "value": p.value(x), "shift_in_tolerances": x / p.tolerance}
                                                          for p, x in zip(rig.tolerances, coords)]})
    return session, maneuver


def _maneuver_of(session):
    from dragline.simulate import maneuver_from_table

    m = session.maneuver
    if not m or "time" not in m:
        raise ValueError("the session holds no maneuver table: give one with --maneuver")
    return maneuver_from_table(m, "the session's maneuver")


def _verdict(doc):
    """The diagnosis in brief: the verdict and the best hypothesis's fit."""
    out = {"verdict": doc.get("verdict"), "reason": doc.get("reason")}
    if doc.get("hypotheses"):
        best = doc["hypotheses"][0]
        out["best"] = {k: best.get(k) for k in ("name", "parameters", "rms_before", "rms_after")}
    return out


def _headline(metrics):
    """The figures the summary line prints: channel verdicts and the free decay."""
    out = {"channels": metrics.get("summary", {})}
    decay = metrics.get("free_decay_summary", {}).get("damping_ratio_ratio")
    if decay:
        out["damping_ratio_measured_over_model"] = decay.get("median")
    return out
