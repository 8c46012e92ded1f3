"""Model updating and the model's own error budget (dragline.compare._updating).

The recording is never made by the model that is updated: its truth is the
rig with some parameters moved within their tolerances, simulated at a
finer discretization (medium) than the model (baseline), plus white noise
of a known level. Four of the rig's tolerances are kept so the test stays
fast; one of them (chain material damping) leaves the recording nearly
untouched and must come out as not identifiable, at its nominal value.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dragline.compare._hypotheses import Problem, channels_on
from dragline.compare._locate import DYNAMIC_CHANNELS
from dragline.compare._updating import model_error, nuisance_correlation, update_model
from dragline.simulate import apply_parameters, dig_maneuver, parse_physics, simulate

KEPT = ("reels.hoist.zero", "fixed_points.boom_pulley.z", "bodies.bucket.cg_x", "ropes.chain.viscous_damping")
TRUTH_IN_TOLERANCES = {"reels.hoist.zero": 1.5, "fixed_points.boom_pulley.z": -1.0, "bodies.bucket.cg_x": 1.0,
                       "ropes.chain.viscous_damping": 0.0}
NOISE = {"position": 5e-4, "angle": 5e-3, "rope_length": 5e-4}
DURATION = 8.0


def _channels(result, channels):
    return np.column_stack([np.asarray(result.table[c], float) for c in channels])


@pytest.fixture(scope="module")
def updated(rig):
    small = dataclasses.replace(rig, tolerances=tuple(p for p in rig.tolerances if p.name in KEPT))
    params = small.tolerances
    truth_coords = np.array([TRUTH_IN_TOLERANCES[p.name] * p.tolerance for p in params])
    maneuver = dig_maneuver()
    truth = simulate(*apply_parameters(small, maneuver, params, truth_coords), "medium", duration=DURATION)
    nominal = simulate(small, maneuver, duration=DURATION)
    channels = [c for c in DYNAMIC_CHANNELS if c in nominal.table.columns]
    sigma = np.array([NOISE["angle"] if "pitch" in c else NOISE["position"] for c in channels])
    rng = np.random.default_rng(5)
    # As a lab records it: the bucket's position at the rig file's mass centre.
    reported_cg = {n: b.cg_body for n, b in small.bodies.items()}
    recorded = channels_on(truth, {"time": nominal.time, "channels": channels, "reported_cg": reported_cg})
    measured = recorded + rng.normal(size=(len(truth.time), len(channels))) * sigma
    problem = Problem(nominal.time, measured, sigma, t_stop=6.5)
    ctx = {"rig": small, "maneuver": maneuver, "discretization": "baseline", "duration": DURATION,
           "rate_hz": 200.0, "initial_state": nominal.states[0], "time": nominal.time, "channels": channels,
           "nominal_dt": float(nominal.dt), "parameters": params, "reported_cg": reported_cg}
    nominal_sim = _channels(nominal, channels)
    directions, error_block = model_error(problem, ctx, nominal_sim, workers=2)
    result = update_model(problem, ctx, nominal_sim, directions, workers=2)
    return {"result": result, "truth": truth_coords, "params": params, "problem": problem, "ctx": ctx,
            "nominal_sim": nominal_sim, "error_block": error_block, "directions": directions}


def test_updating_recovers_the_moved_parameters_within_their_stated_uncertainty(updated):
    block = {e["parameter"]: e for e in updated["result"]["block"]["parameters"]}
    for p, x in zip(updated["params"], updated["truth"]):
        entry = block[p.name]
        if p.name == "ropes.chain.viscous_damping":
            continue
        assert entry["identifiable"], p.name
        err = abs(entry["coordinate"] - x)
        # Within three stated standard deviations, or a tenth of a tolerance.
        assert err < max(3 * entry["coordinate_sd"], 0.1 * p.tolerance), (p.name, entry["coordinate"], x)


def test_a_parameter_the_recording_cannot_see_stays_nominal_and_is_said_unidentifiable(updated):
    entry = next(e for e in updated["result"]["block"]["parameters"]
                 if e["parameter"] == "ropes.chain.viscous_damping")
    assert not entry["identifiable"]
    assert entry["posterior_over_prior"] > 0.5
    assert abs(entry["shift_in_tolerances"]) < 0.5


def test_updating_takes_the_misfit_down_to_the_noise(updated):
    it = updated["result"]["block"]["iterations"]
    problem = updated["problem"]
    assert it[0]["chi2"] > 50 * problem.n_weighted  # the nominal model is far off
    best = min(i["chi2"] for i in it if i.get("chi2") is not None)
    assert best < 1.5 * problem.n_weighted
    # Static offsets were explained by the parameters, none left as a finding.
    assert updated["result"]["block"]["unexplained_offsets"] == []


def test_model_error_is_measured_on_the_maneuver(updated):
    block = updated["error_block"]
    assert block["discretization"]["status"] == "ok"
    assert block["discretization"]["compared"] == ["baseline", "medium"]
    # Baseline differs from medium by about the noise on some channel (the paper's Fig. 21), far more than
    # the time step's error, which RK4 at its tracked step keeps far below the noise.
    disc = max(c["rms_noise"] for c in block["discretization"]["channels"].values())
    step = max(c["rms_noise"] for c in block["time_step"]["channels"].values())
    assert disc > 0.3
    assert step < 0.1 * disc


def test_a_mechanism_signature_is_compared_with_every_parameter(updated):
    ctx, result = updated["ctx"], updated["result"]
    run = simulate(result["rig"], result["maneuver"], physics=[parse_physics("aero_drag:cd=5")],
                   duration=DURATION, initial_state=result["initial_state"])
    signature = _channels(run, ctx["channels"]) - result["sim"]
    corr = nuisance_correlation(updated["problem"], signature, result, most=4)
    assert len(corr) == 4 and all(-1.0 <= e["correlation"] <= 1.0 for e in corr)
    # A parameter's own sensitivity is perfectly correlated with itself.
    own = nuisance_correlation(updated["problem"], result["sensitivities"][0], result, most=1)[0]
    assert own["parameter"] == updated["params"][0].name and own["correlation"] == pytest.approx(1.0)


def test_a_moved_mass_centre_is_read_where_the_recording_reports_it(rig):
    """The recording's bucket position is the nominal mass centre's marker-fixed point, and so is the model's.

    A rig whose bucket mass centre sits 5 mm from the rig file's: its
    exact markers, reconstructed with the rig file (as a lab would), give a
    bucket position that is not the simulated mass centre (it swings with
    the pitch); ``channels_on`` reads the simulation at the reported point.
    """
    from dragline.compare._hypotheses import channels_on
    from dragline.reconstruct import trajectory_from_markers
    from dragline.simulate import marker_positions

    params = [p for p in rig.tolerances if p.name in ("bodies.bucket.cg_x", "bodies.bucket.cg_z")]
    moved_rig, maneuver = apply_parameters(rig, dig_maneuver(), params, np.array([0.005, -0.005]))
    run = simulate(moved_rig, maneuver, duration=3.0, rate_hz=200.0)
    names, positions = marker_positions(run)
    table, _ = trajectory_from_markers(names, positions, 200.0, rig, smoothing="none")
    channels = ["bucket.x", "bucket.z", "spreader_bar.x"]
    ok = np.isfinite(table[channels].to_numpy()).all(axis=1)
    time = np.asarray(table["time"])[ok]
    reported = channels_on(run, {"time": time, "channels": channels,
                                 "reported_cg": {n: b.cg_body for n, b in rig.bodies.items()}})
    own_centre = channels_on(run, {"time": time, "channels": channels})
    recorded = table[channels].to_numpy()[ok]
    np.testing.assert_allclose(reported, recorded, atol=1e-8)
    assert np.abs(own_centre[:, 0] - recorded[:, 0]).max() > 2e-3  # the mass centre itself is elsewhere
    np.testing.assert_array_equal(own_centre[:, 2], reported[:, 2])  # other bodies untouched
