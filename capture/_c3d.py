"""C3D files in and out, through ezc3d.

ezc3d (pyomeca, MIT licence, wheels on PyPI) reads the processor formats
(Intel, DEC, MIPS), integer and float storage, point scaling and the
``LABELS2``-style continuations that Vicon, Qualisys, Optotrak and Motion
Analysis files use, and it writes C3D as well; it is maintained and used by
the biomechanics community (pyomeca, OpenSim pipelines). The pure-Python
``c3d`` package was the alternative; its reader covers fewer of the
variants that real labs produce.

Reading: POINT:LABELS (and LABELS2, ...), POINT:RATE, POINT:UNITS (mm when
absent, the C3D default), the header's first frame. A point whose residual
is negative is a gap (NaN), as the C3D format defines it; so is a point
the library returns as NaN. Analog channels are described (labels, rate,
units, frames), not used.
"""

from __future__ import annotations

import os
import struct

import numpy as np

from ._atomic import atomic_file
from ._marker_file import MAX_FRAMES, MarkerFile, metres_per_unit

__all__ = ["read_c3d", "write_c3d", "is_c3d"]

# Byte 2 of every C3D file (the header's "key"); byte 1 points at the parameter block.
_KEY = 0x50
_BLOCK = 512


def is_c3d(path):
    """True when ``path`` starts like a C3D file (header key 0x50, parameter block inside the file)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(2)
        size = os.path.getsize(path)
    except OSError:
        return False
    return len(head) == 2 and head[1] == _KEY and 1 <= head[0] and head[0] * _BLOCK <= size


def _param(params, group, name, default=None):
    try:
        return params[group][name]["value"]
    except KeyError:
        return default


def _labels(params, n):
    """POINT:LABELS then LABELS2, LABELS3, ... (files with more than 255 points), cut to ``n``."""
    labels = list(_param(params, "POINT", "LABELS", []) or [])
    k = 2
    while len(labels) < n and _param(params, "POINT", f"LABELS{k}") is not None:
        labels += list(_param(params, "POINT", f"LABELS{k}"))
        k += 1
    labels = [str(x).strip() for x in labels[:n]]
    labels += [f"point{i + 1}" for i in range(len(labels), n)]  # unlabelled points keep a name
    return labels


def _parse(path):
    """What ``read_c3d`` needs of a C3D file, as plain picklable data (runs in a child process)."""
    import ezc3d  # noqa: PLC0415 - only C3D input needs it

    c3d = ezc3d.c3d(path, extract_forceplat_data=False)
    params = {group: {name: c3d["parameters"][group][name] for name in c3d["parameters"][group]
                      if name != "__METADATA__"}
              for group in ("POINT", "ANALOG", "MANUFACTURER", "EVENT") if group in c3d["parameters"]}
    data = {"points": np.asarray(c3d["data"]["points"]),
            "meta_points": {"residuals": np.asarray(c3d["data"].get("meta_points", {}).get(
                "residuals", np.zeros((1, 0, 0))))},
            "analog_channels": int(np.asarray(c3d["data"]["analogs"]).shape[1]),
            "analog_frames": int(np.asarray(c3d["data"]["analogs"]).shape[2])}
    header = {"points": dict(c3d["header"]["points"])}
    return params, data, header


# The child's limits: a damaged header can send ezc3d into an endless loop (a byte-level property run
# found one) or ask it for gigabytes. A real file parses at tens of MB/s, so its own size bounds both.
_CHILD_SECONDS = 10.0  # plus one second per MB of file
_CHILD_BYTES = 2 * 2**30  # address space beyond the parent's, plus 64 bytes per byte of file


def _child(conn, path, address_space):
    import faulthandler  # noqa: PLC0415
    import resource  # noqa: PLC0415

    faulthandler.disable()  # a crash here is reported by the parent in one line, not as a stack dump
    try:
        resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
    except (ValueError, OSError):
        pass  # a platform without the limit still gets the time limit
    try:
        conn.send(("ok", _parse(path)))
    except BaseException as exc:  # noqa: BLE001 - the library raises RuntimeError, IndexError, MemoryError, ...
        conn.send(("error", " ".join(f"{type(exc).__name__}: {exc}".split())[:120]))
    finally:
        conn.close()


def _address_space_now():
    try:
        with open("/proc/self/status") as fh:
            return next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmSize:"))
    except (OSError, StopIteration, ValueError):
        return None


def _parse_isolated(path):
    """``_parse`` in a forked child with a time and memory limit: ezc3d is C++, and some damaged files
    crash it, loop in it or make it allocate without end - each must end in a one-line error, not kill
    or hang the command."""
    import multiprocessing  # noqa: PLC0415

    size = os.path.getsize(path)
    seconds = _CHILD_SECONDS + size / 1e6
    now = _address_space_now()
    address_space = now + _CHILD_BYTES + 64 * size if now else -1
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    context = multiprocessing.get_context(method)
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(send, path, address_space), daemon=True)
    child.start()
    send.close()
    try:
        message = receive.recv() if receive.poll(seconds) else None
    except (EOFError, OSError):
        message = ("crash", None)
    finally:
        receive.close()
        if child.is_alive():
            child.kill()
        child.join()
    if message is None:
        raise ValueError(f"{path}: unreadable C3D file (the C3D library was still parsing it after "
                         f"{seconds:.0f} s; a damaged header?)")
    if message[0] == "crash":
        raise ValueError(f"{path}: unreadable C3D file (the C3D library crashed on its bytes)")
    if message[0] == "error":
        raise ValueError(f"{path}: unreadable C3D file ({message[1]})")
    return message[1]


def read_c3d(path):
    """Read the 3D points of a C3D file.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    MarkerFile
        Positions in metres (from POINT:UNITS), NaN where the residual is
        negative or the point is missing.

    Raises
    ------
    ValueError
        One line starting with the path: not a C3D file, unreadable, no 3D
        points, a bad rate or unit, duplicate labels.
    """
    path = os.fspath(path)
    if not is_c3d(path):
        raise ValueError(f"{path}: not a C3D file (no C3D header)")
    params, data, header = _parse_isolated(path)
    points = np.asarray(data["points"], dtype=float)
    n_points = points.shape[1] if points.ndim == 3 else 0
    if n_points == 0:
        raise ValueError(f"{path}: the C3D file holds no 3D points")
    if points.shape[2] > MAX_FRAMES:
        raise ValueError(f"{path}: {points.shape[2]} frames is more than this tool reads ({MAX_FRAMES})")
    promised = _declared_frames(path, params)
    rate = float((_param(params, "POINT", "RATE") or [header["points"]["frame_rate"]])[0])
    if not (np.isfinite(rate) and rate > 0):
        raise ValueError(f"{path}: POINT:RATE is {rate:g}; a frame rate must be positive")
    units_list = [str(u).strip() for u in (_param(params, "POINT", "UNITS") or []) if str(u).strip()]
    units = units_list[0] if units_list else "mm"
    if len(set(units_list)) > 1:
        raise ValueError(f"{path}: POINT:UNITS mixes {', '.join(sorted(set(units_list)))}")
    scale = metres_per_unit(units, f"{path}: POINT:UNITS")
    names = _labels(params, n_points)
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"{path}: point label {dup[0]!r} appears more than once")
    xyz = np.transpose(points[:3], (2, 1, 0)) * scale  # (frames, points, 3): time first
    residuals = np.asarray(data.get("meta_points", {}).get("residuals", np.zeros((1, n_points, 0))), float)
    gap = ~np.isfinite(xyz).all(axis=-1)
    if residuals.shape[1:] == (n_points, xyz.shape[0]):
        gap |= residuals[0].T < 0
    xyz[gap] = np.nan
    analog_labels = [str(x).strip() for x in (_param(params, "ANALOG", "LABELS") or [])]
    analog = {"channels": analog_labels[: data["analog_channels"]],
              "rate_hz": float((_param(params, "ANALOG", "RATE") or [0.0])[0]),
              "units": [str(u).strip() for u in (_param(params, "ANALOG", "UNITS") or [])][: len(analog_labels)],
              "frames": data["analog_frames"]}
    info = {}
    if promised is not None and points.shape[2] < promised:
        # What is there is read, as a damaged session's frames are: the user is told, not refused.
        info["cut_short"] = f"the header promises {promised} frames, the data end after {points.shape[2]}"
    for key in ("COMPANY", "SOFTWARE", "VERSION_LABEL"):
        value = _param(params, "MANUFACTURER", key)
        if value:
            info[key.lower()] = " ".join(str(v) for v in value).strip()
    return MarkerFile(path=path, format="c3d", names=names, positions=xyz, rate_hz=rate,
                      # ezc3d counts from 0; the file (and every lab's software) from 1.
                      first_frame=int(header["points"]["first_frame"]) + 1, units=units, analog=analog, info=info,
                      events=_events(params))


def _declared_frames(path, params):
    """The frame count the file's own header declares (None when it defers to a parameter that is absent).

    ezc3d trims its header's last frame to the frames it could read, so a file cut short would read as a
    shorter one without a word: the header block's words 4 and 5 (first and last frame, 16 bits, in the
    byte order of the processor the parameter section names: 86 is big-endian MIPS) are read here.
    """
    with open(path, "rb") as fh:
        head = fh.read(512)
        fh.seek(max(head[0] - 1, 0) * 512)
        section = fh.read(4)
    order = ">" if len(section) == 4 and section[3] == 86 else "<"
    first, last = struct.unpack_from(order + "HH", head, 6)
    if last == 0xFFFF:  # more frames than 16 bits hold: the count is POINT:FRAMES (or another parameter)
        frames = _param(params, "POINT", "FRAMES")
        return int(frames[0]) if frames and float(frames[0]) > 0 else None
    return last - first + 1 if last >= first else None


def _events(params):
    """The EVENT group's labelled times (TIMES holds minutes and seconds per event), in file order."""
    times = _param(params, "EVENT", "TIMES")
    times = np.asarray([] if times is None else times, dtype=float)
    n = times.size // 2
    if n == 0:
        return []
    times = times.reshape(2, n)

    def texts(name):
        values = _param(params, "EVENT", name)
        values = [] if values is None else [str(v).strip() for v in values]
        return values + [""] * (n - len(values))

    labels, contexts, subjects, descriptions = (texts(k) for k in ("LABELS", "CONTEXTS", "SUBJECTS", "DESCRIPTIONS"))
    return [{"subject": subjects[k], "context": contexts[k], "name": labels[k],
             "time_s": float(60.0 * times[0, k] + times[1, k]), "description": descriptions[k]}
            for k in range(n) if np.isfinite(times[:, k]).all()]


def write_c3d(path, marker_names, positions, rate_hz, first_frame=1):
    """Write labelled 3D markers as a C3D file (float storage, millimetres).

    Parameters
    ----------
    path : str or path-like
        Written under a temporary name and renamed when complete.
    marker_names : sequence of str
        Labels (``'bucket:alpha'``).
    positions : ndarray, shape (frames, markers, 3)
        Positions (m); NaN marks a gap, written with residual -1.
    rate_hz : float
    first_frame : int
        Number of the first frame, counted from 1 as the file stores it.
    """
    import ezc3d  # noqa: PLC0415

    path = os.fspath(path)
    p = np.asarray(positions, dtype=float)
    names = [str(n) for n in marker_names]
    if p.ndim != 3 or p.shape[1:] != (len(names), 3):
        raise ValueError(f"positions must have shape (frames, {len(names)}, 3), got {p.shape}")
    gap = ~np.isfinite(p).all(axis=-1)
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(rate_hz)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(names)
    c3d.add_parameter("POINT", "UNITS", "mm")
    pts = np.ones((4, len(names), p.shape[0]))
    pts[:3] = np.transpose(np.where(gap[..., None], np.nan, p * 1e3), (2, 1, 0))
    c3d["data"]["points"] = pts
    residuals = np.where(gap.T, -1.0, 0.0)[None]
    c3d["data"]["meta_points"] = {"residuals": residuals,
                                  "camera_masks": np.zeros((7, len(names), p.shape[0]), dtype=bool)}
    c3d["header"]["points"]["first_frame"] = int(first_frame) - 1
    with atomic_file(path, suffix=".c3d") as tmp:  # ezc3d picks the format by extension
        c3d.write(tmp)
    return path
