"""An independent check of the three-drone flights: is their misfit the simulator's, or the recordings'?

`dragline diagnose` leaves every excerpt of `tests/data/hmer101/` 5-20 times the noise away
(`docs/real-recordings.md`). This script fits the same excerpt with a model written apart from the
project's simulator - one rigid box on three elastic cables under the drones' measured tracks,
integrated by scipy's DOP853, fitted by scipy's least squares - with more freedom than the rig file
gives (the box's mass centre, the three lid points, its inertia, a linear yaw damping and a linear
drag, each cable's length), and optionally over windows each with its own start (multiple shooting):
a misfit that a window of one second cannot remove is not a drift accumulated over the trial.

    python tools/slung_box_check.py tests/data/hmer101/2025_07_30_14_36_05_hold.csv --window 15

Frames as the excerpts: z up, the tracker's x and y; angles roll, pitch, yaw about the fixed axes.
Slow (pure Python right-hand side): 8-25 minutes an excerpt on one core. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix
from scipy.spatial.transform import Rotation

GRAVITY = 9.81
# The authors' measured box (aruco_box/model_measured.sdf), and the lid points of their simulated
# world, 0.1 m out towards each drone (z up here: the lid 0.03 m above the tracked origin).
MASS = 1.6868
INERTIA = np.array([0.011747, 0.015939, 0.0210])
LID_POINTS = np.array([[0.1, 0.0, 0.03], [-0.05, 0.0866, 0.03], [-0.05, -0.0866, 0.03]])
# A braided cord's guessed EA and a damping that settles the cables' stretch within a few tenths of a
# second; at 10 Hz the recording sees neither (the stretch under 6 N is 0.7 mm).
STIFFNESS_EA = 2.0e4
CABLE_DAMPING = 30.0
# Scales of the residual (m, rad): the noise the diagnosis reads on these excerpts is 0.2-0.9 mm and
# 2-8 mrad; these round it up, so chi2 per sample is an upper bound on the misfit in noise units.
POSITION_SCALE = 1e-3
ANGLE_SCALE = 5e-3

FREEDOMS = {
    "geometry": [("length", 3), ("yaw_damping", 1), ("drag", 1), ("lid_xy", 6), ("centre_xy", 2),
                 ("ln_inertia_z", 1)],
    "full": [("length", 3), ("yaw_damping", 1), ("drag", 1), ("lid_xy", 6), ("lid_z", 3), ("centre", 3),
             ("ln_inertia", 3)],
}
START = [("position", 3), ("rotvec", 3), ("velocity", 3), ("rates", 3)]


def read_excerpt(path):
    table = pd.read_csv(path)
    time_s = table["time"].to_numpy() - table["time"].iloc[0]
    position = table[["box.x", "box.y", "box.z"]].to_numpy()
    attitude = Rotation.from_euler("xyz", table[["box.roll", "box.pitch", "box.yaw"]].to_numpy())
    drones = np.stack([table[[f"drone{i}.{c}" for c in "xyz"]].to_numpy() for i in (1, 2, 3)], axis=1)
    return time_s, position, attitude, drones


def _split(values, layout):
    out, k = {}, 0
    for name, n in layout:
        out[name] = values[k:k + n]
        k += n
    return out


def _quaternion_rate(q, rates):
    w, x, y, z = q
    p, r, s = rates
    return 0.5 * np.array([-x * p - y * r - z * s, w * p + y * s - z * r, w * r - x * s + z * p, w * s + x * r - y * p])


def _rhs(tracks, lengths, lid, centre, inertia, yaw_damping, drag):
    def rhs(t, state):
        x, q, v, rates = state[:3], state[3:7], state[7:10], state[10:13]
        turn = Rotation.from_quat(q[[1, 2, 3, 0]]).as_matrix()
        force = np.array([0.0, 0.0, -MASS * GRAVITY]) - drag * v
        torque = np.zeros(3)
        top, top_rate = tracks(t), tracks(t, 1)
        for i in range(3):
            arm = turn @ (lid[i] - centre)
            chord = top[i] - (x + arm)
            length = np.linalg.norm(chord)
            if length <= lengths[i]:
                continue                               # slack: no force
            unit = chord / length
            stretch_rate = unit @ (top_rate[i] - v - np.cross(turn @ rates, arm))
            tension = max(STIFFNESS_EA / lengths[i] * (length - lengths[i]) + CABLE_DAMPING * stretch_rate, 0.0)
            force += tension * unit
            torque += np.cross(arm, tension * unit)
        body_torque = turn.T @ torque
        body_torque[2] -= yaw_damping * rates[2]
        rates_dot = (body_torque - np.cross(rates, inertia * rates)) / inertia
        return np.r_[v, _quaternion_rate(q, rates), force / MASS, rates_dot]
    return rhs


def simulate_window(time_s, tracks, start, rig):
    """The tracked origin's position and attitude over ``time_s`` from ``start`` (that origin's pose and rates)."""
    lid = LID_POINTS.copy()
    lid[:, :2] += rig.get("lid_xy", np.zeros(6)).reshape(3, 2)
    lid[:, 2] += rig.get("lid_z", np.zeros(3))
    centre = np.zeros(3)
    if "centre" in rig:
        centre = np.asarray(rig["centre"], dtype=float)
    elif "centre_xy" in rig:
        centre[:2] = rig["centre_xy"]
    inertia = INERTIA * np.exp(rig["ln_inertia"]) if "ln_inertia" in rig else INERTIA.copy()
    if "ln_inertia_z" in rig:
        inertia[2] *= np.exp(rig["ln_inertia_z"][0])
    turn0 = Rotation.from_rotvec(start["rotvec"])
    rates = start["rates"]
    x0 = start["position"] + turn0.apply(centre)
    v0 = start["velocity"] + np.cross(turn0.apply(rates), turn0.apply(centre))
    q0 = turn0.as_quat()[[3, 0, 1, 2]]
    rhs = _rhs(tracks, rig["lengths"], lid, centre, inertia, rig.get("yaw_damping", [0.0])[0],
               rig.get("drag", [0.0])[0])
    sol = solve_ivp(rhs, (time_s[0], time_s[-1]), np.r_[x0, q0, v0, rates], t_eval=time_s, method="DOP853",
                    rtol=1e-6, atol=1e-8)
    if sol.y.shape[1] != len(time_s):
        return None, None
    attitude = Rotation.from_quat(sol.y[[4, 5, 6, 3]].T)
    return sol.y[:3].T - attitude.apply(centre), attitude


def _rest_lengths(position, attitude, drones):
    lids = position[:, None, :] + np.stack([attitude.apply(p) for p in LID_POINTS], axis=1)
    reach = np.linalg.norm(drones - lids, axis=2).mean(axis=0)
    return reach - 6.0 * reach / STIFFNESS_EA            # taut at about 6 N each


def _start_guess(i, time_s, position, attitude):
    dt = time_s[i + 1] - time_s[i]
    velocity = (-3 * position[i] + 4 * position[i + 1] - position[i + 2]) / (2 * dt)
    rates = (4 * (attitude[i].inv() * attitude[i + 1]).as_rotvec()
             - (attitude[i].inv() * attitude[i + 2]).as_rotvec()) / (2 * dt)
    return np.r_[position[i], attitude[i].as_rotvec(), velocity, rates]


def fit(path, window, freedom, max_evaluations=40):
    time_s, position, attitude, drones = read_excerpt(path)
    tracks = CubicSpline(time_s, drones, axis=0)
    lengths0 = _rest_lengths(position, attitude, drones)
    n = len(time_s)
    windows = [(a, min(a + window + 1, n)) for a in range(0, n - 3, window)]
    shared = FREEDOMS[freedom]
    n_shared = sum(k for _, k in shared)

    def residuals(values):
        rig = _split(values[:n_shared], shared)
        rig["lengths"] = lengths0 + rig["length"]
        out = []
        for k, (a, e) in enumerate(windows):
            start = _split(values[n_shared + 12 * k: n_shared + 12 * (k + 1)], START)
            origin, turn = simulate_window(time_s[a:e], tracks, start, rig)
            if origin is None:
                out.append(np.full(6 * (e - a), 1e3))
                continue
            out.append(np.r_[((origin - position[a:e]) / POSITION_SCALE).ravel(),
                             ((attitude[a:e].inv() * turn).as_rotvec() / ANGLE_SCALE).ravel()])
        return np.concatenate(out)

    x0 = np.r_[np.zeros(n_shared), np.concatenate([_start_guess(a, time_s, position, attitude) for a, _ in windows])]
    sparsity = lil_matrix((sum(6 * (e - a) for a, e in windows), len(x0)), dtype=int)
    row = 0
    for k, (a, e) in enumerate(windows):
        sparsity[row:row + 6 * (e - a), :n_shared] = 1
        sparsity[row:row + 6 * (e - a), n_shared + 12 * k: n_shared + 12 * (k + 1)] = 1
        row += 6 * (e - a)
    tic = time.perf_counter()
    first = residuals(x0)
    result = least_squares(residuals, x0, jac_sparsity=sparsity, x_scale="jac", max_nfev=max_evaluations,
                           diff_step=1e-6)
    pos, ang, row = [], [], 0
    for a, e in windows:
        part = result.fun[row: row + 6 * (e - a)].reshape(2, e - a, 3)
        pos.append(part[0])
        ang.append(part[1])
        row += 6 * (e - a)
    pos, ang = np.concatenate(pos), np.concatenate(ang)
    rig = _split(result.x[:n_shared], shared)
    return {
        "excerpt": path, "window_samples": window, "windows": len(windows), "freedom": freedom,
        "chi2_per_sample_start": float(np.mean(first ** 2)), "chi2_per_sample": float(np.mean(result.fun ** 2)),
        "position_rms_mm": (np.sqrt((pos ** 2).mean(axis=0)) * POSITION_SCALE * 1e3).round(2).tolist(),
        "angle_rms_mrad": (np.sqrt((ang ** 2).mean(axis=0)) * ANGLE_SCALE * 1e3).round(1).tolist(),
        "lengths_m": (lengths0 + rig["length"]).round(4).tolist(),
        "fitted": {k: np.round(v, 4).tolist() for k, v in rig.items() if k != "length"},
        "evaluations": int(result.nfev), "seconds": round(time.perf_counter() - tic, 1),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("excerpt")
    parser.add_argument("--window", type=int, default=10 ** 6, help="samples per window, each its own start")
    parser.add_argument("--freedom", choices=sorted(FREEDOMS), default="geometry")
    args = parser.parse_args(argv)
    print(json.dumps(fit(args.excerpt, args.window, args.freedom)))


if __name__ == "__main__":
    sys.exit(main())
