"""Convergence: in the time step (RK4) and in the rope discretization (Fig. 21)."""

import numpy as np

from dragline.simulate import assemble, dig_maneuver, simulate, stable_time_step


def _pitch(rig, **kw):
    res = simulate(rig, duration=kw.pop("duration", 10.0), rate_hz=100, **kw)
    return np.degrees(res.table["bucket.pitch"].to_numpy()), res.table


def test_bucket_motion_converges_as_the_step_shrinks(rig):
    dt = stable_time_step(assemble(rig, dig_maneuver()))
    runs = {f: _pitch(rig, dt=dt * f, duration=7.0, integrator="rk4") for f in (1.0, 0.5, 0.125)}
    ref_pitch, ref_table = runs[0.125]
    err_pitch = [np.abs(runs[f][0] - ref_pitch).max() for f in (1.0, 0.5)]
    err_x = [np.abs(runs[f][1]["bucket.x"] - ref_table["bucket.x"]).max() for f in (1.0, 0.5)]
    assert err_pitch[1] < err_pitch[0] and err_x[1] < err_x[0]
    assert err_pitch[0] < 0.01 and err_x[0] < 1e-4  # deg, m at the default step


def test_bucket_pitch_converges_as_the_discretization_is_refined(rig):
    # The paper's Fig. 21: low -> baseline -> medium -> high
    pitch = {lvl: _pitch(rig, discretization=lvl)[0] for lvl in ("low", "baseline", "medium", "high")}
    rms = [np.sqrt(np.mean((pitch[lvl] - pitch["high"]) ** 2)) for lvl in ("low", "baseline", "medium")]
    assert rms[0] > rms[1] > rms[2], rms
    assert rms[2] < 0.1  # deg
