"""Model updating and the model's own error budget (dragline.compare.diagnose._updating).

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

from dragline.compare.diagnose._confounding import nuisance_correlation, parameter_span_share
from dragline.compare.diagnose._differences import FD_FRACTION
from dragline.compare.diagnose._hypotheses import channels_on
from dragline.compare.diagnose._locate import DYNAMIC_CHANNELS
from dragline.compare.diagnose._model_error import model_error
from dragline.compare.diagnose._problem import MAX_SHIFT, Problem
from dragline.compare.diagnose._report import _calibration_lines
from dragline.compare.diagnose._updating import update_model
from dragline.simulate import apply_parameters, dig_maneuver, parse_physics, simulate

KEPT = ("winches.hoist.zero", "fixed_points.boom_pulley.z", "bodies.bucket.cg_x", "ropes.chain.viscous_damping")
TRUTH_IN_TOLERANCES = {"winches.hoist.zero": 1.5, "fixed_points.boom_pulley.z": -1.0, "bodies.bucket.cg_x": 1.0,
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
    recorded = channels_on(truth, {"time": nominal.time, "channels": channels, "reported_rig": small})
    measured = recorded + rng.normal(size=(len(truth.time), len(channels))) * sigma
    problem = Problem(nominal.time, measured, sigma, t_stop=dig_maneuver().end_time)
    ctx = {"rig": small, "maneuver": maneuver, "discretization": "baseline", "duration": DURATION,
           "rate_hz": 200.0, "initial_state": nominal.states[0], "time": nominal.time, "channels": channels,
           "nominal_dt": float(nominal.dt), "parameters": params, "reported_rig": small}
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
        # Within three stated standard deviations (noise alone), or 0.15 of a tolerance: the model's own
        # discretization error against the medium truth biases the fit too (0.102 of a tolerance on the
        # boom pulley's height here, where noise alone allows 0.054).
        assert err < max(3 * entry["coordinate_sd"], 0.15 * p.tolerance), (p.name, entry["coordinate"], x)


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
    # The floor is the noise plus what no parameter removes: the model's discretization error against the
    # medium truth (measured by ``model_error`` on this maneuver, in noise units per channel).
    disc = np.mean([c["rms_noise"] ** 2 for c in updated["error_block"]["discretization"]["channels"].values()])
    assert best < 1.3 * (1.0 + disc) * problem.n_weighted
    # At the noise floor a step has nothing left to gain: the gain rule ended it, not the cap.
    assert it[-1]["stopped_by"] == "gain" and it[-1]["predicted_gain"] < it[-1]["least_gain"]
    assert updated["result"]["block"]["converged"] is True
    # Static offsets were explained by the parameters, none left as a finding.
    assert updated["result"]["block"]["unexplained_offsets"] == []


def test_the_sensitivities_updating_returns_are_differences_at_the_point_it_returns(updated):
    # What the candidates are fitted against (the regressors) and the covariance must be finite
    # differences at the updated rig itself, not at an earlier point of the fit.
    result, ctx, params = updated["result"], updated["ctx"], updated["params"]
    tol = np.array([p.tolerance for p in params])
    assert result["block"]["iterations"][-1]["jacobians"] >= 2  # it did take steps
    for i in result["active"]:
        x = result["coords"].copy()
        x[i] += FD_FRACTION * tol[i]
        # on the step schedule the updated rig's run took (``_updating``: every fit steps on one schedule)
        moved = simulate(*apply_parameters(ctx["rig"], ctx["maneuver"], params, x), "baseline",
                         duration=DURATION, rate_hz=ctx["rate_hz"], statics_guess=result["initial_state"],
                         schedule=result["schedules"][0])
        fresh = (channels_on(moved, ctx) - result["sim"]) / (FD_FRACTION * tol[i])
        # (The statics start from another guess: equal to about 1e-7 of the largest.)
        np.testing.assert_allclose(result["sensitivities"][i], fresh, rtol=0, atol=1e-5 * np.abs(fresh).max())


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


def test_updating_taken_up_again_from_a_better_rig_reaches_the_full_fit(updated, monkeypatch):
    """Updating capped after its first step stops short; taken up again from a rig nearer the truth (as a
    joint refit reaches one), it goes on to what uncapped updating reached; from a rig that fits worse than
    where it stopped it is not taken up."""
    from dragline.compare.diagnose import _updating
    from dragline.compare.diagnose._updating import resume_update

    problem, ctx, params, truth = updated["problem"], updated["ctx"], updated["params"], updated["truth"]
    full = updated["result"]
    monkeypatch.setattr(_updating, "MAX_JACOBIANS", 2)
    short = update_model(problem, ctx, updated["nominal_sim"], updated["directions"], workers=2)
    monkeypatch.undo()

    def chi2(update):
        return update["block"]["iterations"][-1]["chi2"]

    def joint_at(coords):
        rig, maneuver = apply_parameters(ctx["rig"], ctx["maneuver"], params, coords)
        return {"coords": coords, "rig": rig, "maneuver": maneuver, "initial_state": short["initial_state"]}

    assert chi2(short) > 1.5 * chi2(full)  # the cap did stop it short
    # ... and says so: more to gain than its stop asks, so not converged.
    last = short["block"]["iterations"][-1]
    assert last["stopped_by"] == "cap" and last["predicted_gain"] > last["least_gain"]
    assert short["block"]["converged"] is False
    said = [line for line in _calibration_lines({"calibration": short["block"]}) if "not converged" in line]
    assert len(said) == 1 and "cap of 2 Jacobians" in said[0]
    assert not any("not converged" in line for line in _calibration_lines({"calibration": full["block"]}))
    directions = updated["directions"]
    resumed = resume_update(problem, ctx, updated["nominal_sim"], short, joint_at(0.5 * (short["coords"] + truth)),
                            directions, workers=2)
    again = resumed["update"]
    assert resumed["objective_joint_rig"] < resumed["objective_updated"]
    assert chi2(again) < 1.05 * chi2(full)
    assert resumed["model_error"]["rig"] == "joint rig without its mechanism"
    assert len(resumed["error_directions"]) == 2
    tol = np.array([p.tolerance for p in params])
    moved = [i for i, p in enumerate(params) if p.name != "ropes.chain.viscous_damping"]
    assert np.all(np.abs(again["coords"] - truth)[moved] < 0.15 * tol[moved])
    # Its simulations count on from the capped run's: one at the joint rig, its sensitivities, the steps.
    assert again["n_simulations"] > short["n_simulations"] + 1 + len(short["active"])
    farther = 2.0 * short["coords"] - truth
    declined = resume_update(problem, ctx, updated["nominal_sim"], short, joint_at(farther), directions, workers=2)
    assert declined["update"] is None and declined["objective_joint_rig"] > declined["objective_updated"]


def test_the_share_a_parameter_change_reproduces_is_one_for_a_mix_of_sensitivities(updated):
    problem, result = updated["problem"], updated["result"]
    sens = result["sensitivities"]
    # Any mix of the parameters' sensitivities is a parameter change: share 1,
    # although no single parameter's cosine need be near 1.
    mix = 0.7 * sens[0] - 1.3 * sens[-1]
    assert parameter_span_share(problem, mix, result) == pytest.approx(1.0, abs=1e-9)
    # Noise the parameters cannot make: a small share; half of each: in between.
    noise = np.random.default_rng(0).normal(size=mix.shape) * np.abs(mix).max()
    low = parameter_span_share(problem, noise, result)
    assert low < 0.1
    assert low < parameter_span_share(problem, mix + 0.5 * noise, result) < 1.0
    assert parameter_span_share(problem, np.zeros_like(mix), result) == 0.0


def _read_as_recorded(rig, coords_by_name, channels, duration=3.0):
    """A rig moved within its tolerances, its exact markers reconstructed with the rig file, and its simulation."""
    from dragline.reconstruct import trajectory_from_markers
    from dragline.simulate import marker_positions

    params = [p for p in rig.tolerances if p.name in coords_by_name]
    moved_rig, maneuver = apply_parameters(rig, dig_maneuver(), params,
                                           np.array([coords_by_name[p.name] for p in params]))
    run = simulate(moved_rig, maneuver, duration=duration, rate_hz=200.0)
    names, positions = marker_positions(run)
    table, _ = trajectory_from_markers(names, positions, 200.0, rig, smoothing="none")
    ok = np.isfinite(table[channels].to_numpy()).all(axis=1)
    return run, np.asarray(table["time"])[ok], table[channels].to_numpy()[ok]


def test_a_moved_mass_centre_is_read_where_the_recording_reports_it(rig):
    """The recording's bucket position is the rig file's mass centre's marker-fixed point, and so is the model's.

    A rig whose bucket mass centre sits 5 mm from the rig file's: its
    exact markers, reconstructed with the rig file (as a lab would), give a
    bucket position that is not the simulated mass centre (it swings with
    the pitch); ``channels_on`` reads the simulation at the reported point.
    """
    channels = ["bucket.x", "bucket.z", "spreader_bar.x"]
    run, time, recorded = _read_as_recorded(rig, {"bodies.bucket.cg_x": 0.005, "bodies.bucket.cg_z": -0.005},
                                            channels)
    reported = channels_on(run, {"time": time, "channels": channels, "reported_rig": rig})
    own_centre = channels_on(run, {"time": time, "channels": channels})
    np.testing.assert_allclose(reported, recorded, atol=1e-8)
    assert np.abs(own_centre[:, 0] - recorded[:, 0]).max() > 2e-3  # the mass centre itself is elsewhere
    np.testing.assert_array_equal(own_centre[:, 2], reported[:, 2])  # other bodies untouched


def test_a_moved_boom_pulley_is_read_from_where_the_recording_measures_the_rope(rig):
    """The hoist rope is measured from the rig file's boom pulley; the model is read from there too.

    The cubic fit of the rope's markers has its own small error, the same
    whether the pulley moved or not, so the comparison is of the change:
    reading the moved rig from the file's pulley reproduces what the
    reconstruction measured to a fraction of a millimetre, while the moved
    rig's own rope length is 25 mm off.
    """
    channels = ["hoist_rope.length", "drag_rope.length"]
    _, t0, recorded0 = _read_as_recorded(rig, {}, channels)
    run0 = simulate(rig, dig_maneuver(), duration=3.0, rate_hz=200.0)
    fit_error = recorded0 - channels_on(run0, {"time": t0, "channels": channels})
    run, time, recorded = _read_as_recorded(rig, {"fixed_points.boom_pulley.x": 0.01,
                                                  "fixed_points.boom_pulley.z": 0.01}, channels)
    assert np.array_equal(time, t0)
    reported = channels_on(run, {"time": time, "channels": channels, "reported_rig": rig})
    own = channels_on(run, {"time": time, "channels": channels})
    unread = (recorded - own - fit_error)[:, 0]
    left = (recorded - reported - fit_error)[:, 0]
    # A 10 mm move of the pulley: 25 mm on the rope, read away to under a
    # millimetre (the cubic through the file's pulley bends a little
    # differently), nearly constant (a channel offset takes it), its
    # variation well under the 0.4 mm the reconstruction's noise leaves.
    assert np.abs(unread).min() > 0.02
    assert np.abs(left).max() < 0.03 * np.abs(unread).min()
    assert left.std() < 2e-4
    np.testing.assert_array_equal(reported[:, 1], own[:, 1])  # the drag rope starts at its reel, not moved


def test_a_mismatch_the_finer_model_also_shows_is_marked_as_the_models_own_error():
    """Within MODEL_ERROR_FACTOR of the finer model's difference in its channel and window: the model's error."""
    from dragline.compare.diagnose._locate import locate_mismatch
    from dragline.compare.diagnose._model_error import MODEL_ERROR_FACTOR, mark_model_error

    time = np.arange(0.0, 4.0, 0.005)
    swing = np.sin(2 * np.pi * 0.8 * time)
    direction = np.column_stack([0.002 * swing, 0.002 * swing])  # the finer model moves both channels 2 mm
    residual = np.column_stack([0.5 * MODEL_ERROR_FACTOR * 0.002 * swing,  # half the allowance: its own error
                                2.0 * MODEL_ERROR_FACTOR * 0.002 * swing])  # twice it: more than its error
    channels = ["bucket.x", "bucket.z"]
    entries = locate_mismatch(time, residual, channels, [1e-4, 1e-4], [("all", 0.0, 4.0)])
    assert all(e["significant"] for e in entries)
    marked = {e["channel"]: e for e in mark_model_error(entries, time, [direction], channels)}
    assert marked["bucket.x"]["within_model_error"] and not marked["bucket.z"]["within_model_error"]
    # RMS of a 2 mm sine (the 0.1 s low-pass passes 0.8 Hz at 0.99; 3.2 cycles leave a small mean).
    assert marked["bucket.x"]["model_error_rms"] == pytest.approx(0.002 / np.sqrt(2), rel=0.03)
    # No model error estimated: nothing is excused.
    assert not any(e["within_model_error"] for e in mark_model_error(entries, time, [], channels))


def test_the_clock_shift_is_bounded_about_the_updated_models_own():
    # A recording 18 ms late against its model (the updating's clock, fitted with a soft prior, may sit
    # past MAX_SHIFT): bounded about zero the shift stops at MAX_SHIFT and the misfit stays far above
    # the noise; bounded about the updated clock it is found, and the misfit is the noise's.
    t = np.arange(0.0, 10.0, 0.005)
    sim = np.column_stack([np.sin(2 * np.pi * 0.6 * t), 0.5 * np.cos(2 * np.pi * 0.9 * t)])
    late = 0.018
    sigma = np.array([5e-3, 5e-3])  # above the linear shift model's own error (about 2.5e-3 at 18 ms)
    rng = np.random.default_rng(3)
    measured = np.column_stack([np.sin(2 * np.pi * 0.6 * (t - late)), 0.5 * np.cos(2 * np.pi * 0.9 * (t - late))])
    measured = measured + rng.normal(size=measured.shape) * sigma
    rate = np.gradient(sim, t, axis=0)
    sim_late = sim - late * rate  # the nuisance model is linear in the shift: the lateness is delta = -late
    plain = Problem(t, measured, sigma, t_stop=6.5)
    centred = Problem(t, measured, sigma, t_stop=6.5, shift_center=-0.015)
    assert plain.evaluate(sim)["nuisance"][1] == pytest.approx(-MAX_SHIFT)
    assert centred.evaluate(sim)["nuisance"][1] == pytest.approx(-late, abs=1e-3)
    assert plain.evaluate(sim)["full"] > 5 * plain.n_weighted
    assert centred.evaluate(sim)["full"] < 1.5 * centred.n_weighted
    # The regressors' problem keeps the centre.
    assert centred.with_regressors([sim_late - sim]).shift_center == -0.015


def test_the_predicted_gain_is_the_residuals_part_in_the_jacobians_span():
    from dragline.compare.diagnose._objective import predicted_gain

    rng = np.random.default_rng(3)
    J = rng.normal(size=(50, 3))
    a = np.array([0.5, -2.0, 1.0])
    e = rng.normal(size=50)
    e -= J @ np.linalg.lstsq(J, e, rcond=None)[0]  # orthogonal to J's columns: no step can remove it
    r = J @ a + e
    # A full Gauss-Newton step removes J a and leaves e: |r|^2 - |e|^2 = |J a|^2.
    assert predicted_gain(J, r) == pytest.approx(float((J @ a) @ (J @ a)), rel=1e-10)


@pytest.mark.parametrize("first_cd", [0.65, 0.3])
def test_the_joint_refit_fits_the_mechanism_with_the_parameters_not_after_them(first_cd):
    # A gantry crane whose air drag (cd 0.9) the updating could only mimic: the truth's masses, mass centre
    # and sling damping moved within tolerance, simulated finer. Started from cd 0.65 (a first fit on the
    # rig updated without drag), fitting the value after the parameters left them compensating the low
    # value (cd 0.84, the objective 2 % above the truth's: the masses at their bounds); fitted together,
    # the value and the objective are the truth's. From cd 0.3 too (the rig took up two thirds of the drag):
    # the first fit is no bound on the value (a span of exp(0.4) about it stopped at 0.45).
    from dragline.compare.diagnose._hypotheses import _init
    from dragline.compare.diagnose._objective import _objective_at, _offset_prior
    from dragline.compare.diagnose._rig_runs import _rig_job
    from dragline.compare.diagnose._updating import joint_refit, rig_alone_channels
    from dragline.simulate import default_maneuver, load_rig, make_mechanism

    crane = load_rig("gantry_crane")
    moved = {"bodies.hook.mass": -1.67, "bodies.payload.mass": 0.05, "bodies.payload.cg_z": 2.0,
             "ropes.slings.viscous_damping": -1.56}
    crane = dataclasses.replace(crane, tolerances=tuple(p for p in crane.tolerances if p.name in moved))
    params, maneuver = crane.tolerances, default_maneuver(crane)
    tol = np.array([p.tolerance for p in params])
    truth_coords = np.array([moved[p.name] for p in params]) * tol
    drag = make_mechanism("aero_drag", cd=0.9)
    truth = simulate(*apply_parameters(crane, maneuver, params, truth_coords), "medium", [drag], duration=10.0)
    nominal = simulate(crane, maneuver, duration=10.0)
    channels = [f"{b}.{a}" for b in crane.bodies for a in ("x", "z", "pitch")]
    sigma = np.array([NOISE["angle"] if "pitch" in c else NOISE["position"] for c in channels])
    recorded = channels_on(truth, {"time": nominal.time, "channels": channels, "reported_rig": crane})
    measured = recorded + np.random.default_rng(5).normal(size=recorded.shape) * sigma
    problem = Problem(nominal.time, measured, sigma, t_stop=4.0)
    ctx = {"rig": crane, "maneuver": maneuver, "discretization": "baseline", "duration": 10.0, "rate_hz": 200.0,
           "initial_state": nominal.states[0], "time": nominal.time, "channels": channels,
           "nominal_dt": float(nominal.dt), "parameters": params, "reported_rig": crane}
    nominal_sim = _channels(nominal, channels)
    directions, _ = model_error(problem, ctx, nominal_sim, workers=2)
    update = update_model(problem, ctx, nominal_sim, directions, workers=2)
    joint = joint_refit(problem, ctx, update, make_mechanism("aero_drag", cd=first_cd), directions, workers=2,
                        value_range=(0.05, 50.0))
    _init(dict(ctx, base_physics=[drag]))
    at_truth = _objective_at(problem, _rig_job(truth_coords)[0], truth_coords, tol, _offset_prior(ctx),
                             directions)[0]
    assert joint["mechanism"].parameters["cd"] == pytest.approx(0.9, rel=0.04)
    assert joint["history"][-1]["objective"] <= 1.005 * at_truth
    # The joint rig with the drag taken out: the crane simulated at the joint's parameters, nothing added, from
    # the same statics guess (the payload's turn about its rope is a neutral direction of the statics), read
    # as the recording is (the rig file's mass centres).
    alone = rig_alone_channels(ctx, joint)
    plain = channels_on(simulate(*apply_parameters(crane, maneuver, params, joint["coords"]), duration=10.0,
                                 statics_guess=joint["initial_state"]), ctx)
    assert np.abs(alone - plain).max() < 1e-6
    assert np.abs(alone - joint["sim"]).max() > 1e3 * np.abs(alone - plain).max()


def test_a_parameter_the_trials_disagree_on_is_said_with_each_trials_value_only_where_chance_would_not_do_it():
    # three trials' own estimates as the three-drone flights gave them (2026-12-03); the 95 % point of chi2 on 2
    # degrees of freedom is -2 ln 0.05 = 5.99: Q 49.6 and 6.0 are beyond it, 5.9 is not
    def entry(name, identifiable):
        return {"parameter": name, "nominal": 1.0, "estimate": 1.0, "uncertainty": 0.1, "unit": "m",
                "shift_in_tolerances": 0.0, "identifiable": identifiable}

    def spread(values, q):
        return {"trial_estimates": values, "trial_uncertainties": [0.1] * 3, "between_trials_sd": 0.5,
                "cochran_q": q, "degrees_of_freedom": 2}

    cal = {"parameters": [entry("ropes.c1.length", False), entry("bodies.box.cg_x", False),
                          entry("bodies.box.inertia_z", True)],
           "between_trials": {"trials": ["a", "b", "c"],
                              "parameters": {"ropes.c1.length": spread([1.412, 2.965, 2.586], 49.6),
                                             "bodies.box.cg_x": spread([0.061, 0.022, 0.020], 5.9),
                                             "bodies.box.inertia_z": spread([0.045, 0.068, 0.017], 122.7)}}}
    said = [line for line in _calibration_lines({"calibration": cal}) if "the trials disagree" in line]
    assert len(said) == 1
    assert "ropes.c1.length" in said[0] and "1.412, 2.965, 2.586 m" in said[0] and "49.6 on 2" in said[0]
    cal["between_trials"]["parameters"]["bodies.box.cg_x"]["cochran_q"] = 6.0
    lines = _calibration_lines({"calibration": cal})
    assert sum("the trials disagree on bodies.box.cg_x" in line for line in lines) == 1
    # an estimate held at the updating's bound is said to be (the unbounded step had put the first at 1.412)
    cal["between_trials"]["parameters"]["ropes.c1.length"].update(trial_estimates=[2.121, 2.721, 2.586],
                                                                  trial_at_bound=[True, True, False])
    said = [line for line in _calibration_lines({"calibration": cal}) if "disagree on ropes.c1.length" in line]
    assert "2.121 (at its bound), 2.721 (at its bound), 2.586 m" in said[0]
