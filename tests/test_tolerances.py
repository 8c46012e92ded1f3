"""The rig file's tolerances: parsed, applied without touching the nominal rig, felt by the physics."""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from dragline.simulate import (
    apply_parameters,
    default_maneuver,
    dig_maneuver,
    draw_parameters,
    load_rig,
    rig_from_dict,
    simulate,
)


def _doc():
    return tomllib.loads(resources.files("dragline.simulate").joinpath("data/rig.toml").read_text())


def test_built_in_rig_states_a_tolerance_for_what_a_lab_knows_only_approximately(rig):
    names = {p.name for p in rig.tolerances}
    for body in ("bucket", "spreader_bar", "hoist_cluster", "drag_cluster"):
        assert f"bodies.{body}.mass" in names
    for group in ("wire_rope", "dump_rope", "chain"):
        assert f"ropes.{group}.static_stiffness" in names and f"ropes.{group}.viscous_damping" in names
    assert {"winches.hoist.zero", "winches.drag.zero", "fixed_points.boom_pulley.x"} <= names
    chain = next(p for p in rig.tolerances if p.name == "ropes.chain.viscous_damping")
    assert len(chain.targets) == 6 and chain.scale == "log"
    assert chain.tolerance == pytest.approx(math.log(2.0))  # factor 2: one sd of ln p
    mass = next(p for p in rig.tolerances if p.name == "bodies.bucket.mass")
    assert mass.tolerance == pytest.approx(math.log(1.02)) and mass.nominal == rig.bodies["bucket"].mass


@pytest.mark.parametrize("key, value, message", [
    ("bodies.bucket.volume", {"relative": 0.1}, "unknown parameter"),
    ("bodies.boom.mass", {"relative": 0.1}, "unknown parameter"),
    ("ropes.wire_rope.static_stiffness", {"relative": -0.1}, "positive finite"),
    ("ropes.wire_rope.static_stiffness", {"relative": float("inf")}, "positive finite"),
    ("ropes.chain.viscous_damping", {"factor": 0.5}, "above 1"),
    ("winches.hoist.zero", {"relative": 0.1}, "positive nominal"),
    ("fixed_points.boom_pulley.x", {"absolute": True}, "positive finite"),
    ("fixed_points.boom_pulley.x", {"absolute": 0.01, "relative": 0.1}, "expected one of"),
])
def test_a_bad_tolerance_is_refused_naming_its_key(key, value, message):
    doc = _doc()
    doc["tolerances"] = {key: value}
    with pytest.raises(ValueError, match=message) as err:
        rig_from_dict(doc, "my_rig.toml")
    assert "my_rig.toml" in str(err.value) and key in str(err.value)


def test_a_group_of_ropes_that_differ_is_refused():
    doc = _doc()
    doc["tolerance_groups"]["mixed"] = ["hoist_rope", "dump_rope"]
    doc["tolerances"] = {"ropes.mixed.static_stiffness": {"relative": 0.1}}
    with pytest.raises(ValueError, match="differ in static_stiffness"):
        rig_from_dict(doc)


def test_apply_moves_what_it_names_and_leaves_the_inputs_alone(rig):
    maneuver = dig_maneuver()
    params = rig.tolerances
    coords = np.array([p.tolerance for p in params])
    moved, moved_maneuver = apply_parameters(rig, maneuver, params, coords)
    assert rig.bodies["bucket"].mass == load_rig().bodies["bucket"].mass  # the nominal rig is untouched
    assert moved.bodies["bucket"].mass == pytest.approx(rig.bodies["bucket"].mass * 1.02)
    # The inertia keeps its shape: it scales with the mass.
    np.testing.assert_allclose(moved.bodies["bucket"].inertia, 1.02 * rig.bodies["bucket"].inertia, rtol=1e-12)
    for rope in ("left_drag_chain", "right_upper_hoist_chain"):
        assert moved.ropes[rope].viscous_damping == pytest.approx(2 * rig.ropes[rope].viscous_damping)
    assert moved.ropes["hoist_rope"].static_stiffness == pytest.approx(1.15 * rig.ropes["hoist_rope"].static_stiffness)
    np.testing.assert_allclose(moved.fixed_points["boom_pulley"] - rig.fixed_points["boom_pulley"], [0.005, 0, 0.005])
    np.testing.assert_allclose(moved_maneuver.lengths["hoist"] - maneuver.lengths["hoist"], 0.01)
    np.testing.assert_allclose(moved_maneuver.lengths["drag"] - maneuver.lengths["drag"], 0.01)
    np.testing.assert_array_equal(maneuver.lengths["hoist"], dig_maneuver().lengths["hoist"])


def test_draws_follow_the_tolerances_and_stop_at_the_limit(rig):
    rng = np.random.default_rng(3)
    draws = np.array([draw_parameters(rig.tolerances, rng) for _ in range(2000)])
    tol = np.array([p.tolerance for p in rig.tolerances])
    z = draws / tol
    assert np.abs(z).max() <= 2.0 + 1e-12
    # A standard normal clipped at c = 2 has variance 1 - 2Q(c) - 2 c phi(c) + 2 c^2 Q(c) = 0.9206.
    q, phi = 0.5 * math.erfc(2 / math.sqrt(2)), math.exp(-2) / math.sqrt(2 * math.pi)
    np.testing.assert_allclose(z.std(0), math.sqrt(1 - 2 * q - 4 * phi + 8 * q), atol=0.04)


@pytest.fixture(scope="module")
def static_pair(rig):
    """The rig at rest, nominal and with the hoist reel's zero 10 mm out and the wire rope 10 % softer."""
    maneuver = dig_maneuver()
    params = [p for p in rig.tolerances if p.name in ("winches.hoist.zero", "ropes.wire_rope.static_stiffness")]
    coords = [0.01 if p.kind == "reel_zero" else math.log(0.9) for p in params]
    a = simulate(rig, maneuver, duration=0.05)
    b = simulate(*apply_parameters(rig, maneuver, params, coords), duration=0.05)
    return a.table.iloc[0], b.table.iloc[0]


def test_the_reel_zero_lengthens_the_rope_the_reel_pays_out(static_pair):
    nominal, moved = static_pair
    assert moved["hoist_rope.reel_length"] - nominal["hoist_rope.reel_length"] == pytest.approx(0.01, abs=1e-12)


def test_a_softer_rope_stretches_more_under_the_same_load(static_pair):
    """Static stretch is T L / K: 10 % less stiffness, 1/0.9 the stretch (the tension barely changes)."""
    nominal, moved = static_pair
    stretch = nominal["hoist_rope.length"] - nominal["hoist_rope.reel_length"]
    stretch_soft = moved["hoist_rope.length"] - moved["hoist_rope.reel_length"]
    assert stretch > 0.05
    assert stretch_soft / stretch == pytest.approx(1 / 0.9, rel=0.03)


def test_a_release_moves_with_the_drawn_pivot_and_mass_centre():
    # The lab holds the ball where the wire is taut: drawn 3 mm lower pivot and a mass centre 2 mm off
    # the ball's centre, the held mass centre moves by both, so the eye keeps its distance to the pivot.
    import numpy as np
    from dragline.simulate import apply_parameters, body_to_inertial, default_maneuver, load_rig, simulate

    rig = load_rig("pendulum")
    moved = {"fixed_points.pivot.z": 0.003, "bodies.ball.cg_z": 0.002}
    coords = [moved.get(p.name, 0.0) for p in rig.tolerances]
    drawn, maneuver = apply_parameters(rig, default_maneuver(rig), rig.tolerances, coords)
    pose = rig.release["ball"]
    turn = body_to_inertial(*pose["angles"])
    expected = np.asarray(pose["position"]) + [0.0, 0.0, 0.003] + turn @ [0.0, 0.0, 0.002]
    np.testing.assert_allclose(drawn.release["ball"]["position"], expected, atol=1e-12)
    assert simulate(drawn, maneuver, duration=0.05).equilibrium_residual < 1e-6  # a taut start exists


def _box_with(tolerances):

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "real" / "hmer101.toml"
    doc = tomllib.loads(path.read_text())
    doc["maneuver"], doc["tolerances"] = str(path.parent / doc["maneuver"]), tolerances
    return rig_from_dict(doc, source="box")


def test_an_inertia_tolerance_turns_the_box_on_its_cables_as_one_over_its_root():
    # the box's turn on its three cables, the rest held: omega^2 = K / I_zz, the cables' K untouched
    from dragline.simulate import assemble, body_frequencies, default_maneuver, solve_statics

    rig = _box_with({"bodies.box.inertia_z": {"relative": 0.1}, "bodies.box.mass": {"relative": 0.01}})
    inertia = rig.tolerances[0]
    assert (inertia.kind, inertia.nominal) == ("inertia", pytest.approx(0.0210))

    def turn(coords):
        moved, maneuver = apply_parameters(rig, default_maneuver(rig), rig.tolerances, coords)
        model = assemble(moved, maneuver, "baseline")
        return moved, body_frequencies(model, solve_statics(model, 0.0).state)[1][0, 5]

    _, base = turn([0.0, 0.0])
    moved, heavier = turn([math.log(1.21), 0.0])
    assert heavier == pytest.approx(base / 1.1, rel=1e-6)
    assert moved.bodies["box"].inertia[2, 2] == pytest.approx(0.0210 * 1.21)
    assert moved.bodies["box"].inertia[0, 0] == rig.bodies["box"].inertia[0, 0]
    # with the mass moved too the moment is both factors' product, in either order
    both, _ = apply_parameters(rig, default_maneuver(rig), rig.tolerances, [math.log(1.21), math.log(1.02)])
    assert both.bodies["box"].inertia[2, 2] == pytest.approx(0.0210 * 1.21 * 1.02)
    assert both.bodies["box"].inertia[0, 0] == pytest.approx(rig.bodies["box"].inertia[0, 0] * 1.02)


def test_an_attachment_tolerance_moves_where_the_rope_holds_the_body():
    # the pendulum's eye 10 mm higher on the ball: the ball's centre hangs 10 mm lower, the wire as long
    folder = resources.files("dragline.simulate").joinpath("data")
    doc = tomllib.loads(folder.joinpath("pendulum.toml").read_text())
    doc.pop("release")
    doc["maneuver"] = str(folder.joinpath(doc["maneuver"]))
    doc["tolerances"] = {"bodies.ball.points.eye.z": {"absolute": 0.005}}
    free = rig_from_dict(doc, source="pendulum")
    (eye,) = free.tolerances
    assert (eye.kind, eye.unit, eye.nominal) == ("point", "m", -0.04)
    from dragline.simulate import default_maneuver

    moved, maneuver = apply_parameters(free, default_maneuver(free), free.tolerances, [-0.01])
    np.testing.assert_allclose(moved.bodies["ball"].points["eye"], [0.0, 0.0, -0.05])
    assert free.bodies["ball"].points["eye"][2] == -0.04  # the input is not modified
    low = simulate(moved, maneuver, duration=0.01).states[0][2]
    high = simulate(free, default_maneuver(free), duration=0.01).states[0][2]
    assert low - high == pytest.approx(0.01, abs=1e-6)


@pytest.mark.parametrize("key", ["bodies.box.inertia_w", "bodies.box.points.nowhere.x", "bodies.box.points.a1.w"])
def test_an_inertia_or_attachment_key_that_names_nothing_is_refused(key):
    with pytest.raises(ValueError, match="unknown parameter"):
        _box_with({key: {"absolute": 0.01}})


def test_a_tracks_offset_is_each_trials_own_and_moves_that_trials_point():
    from dragline.compare.diagnose._trials import apply_to_trials, each_trials_own
    from dragline.simulate import default_maneuver

    rig = _box_with({"tracks.drone1.z": {"absolute": 0.05}, "bodies.box.mass": {"relative": 0.01}})
    track, mass = rig.tolerances
    assert (track.kind, track.of_a_trial, mass.of_a_trial) == ("track", True, False)
    maneuver = default_maneuver(rig)
    params = each_trials_own(rig.tolerances, ["a", "b"])
    assert [p.name for p in params] == ["tracks.a.drone1.z", "tracks.b.drone1.z", "bodies.box.mass"]
    ctx = {"rig": rig, "maneuver": (maneuver, maneuver), "trials": ({"name": "a"}, {"name": "b"})}
    moved, (first, second) = apply_to_trials(ctx, params, [0.02, 0.0, math.log(1.01)])
    np.testing.assert_allclose(first.points["drone1"], maneuver.points["drone1"] + [0.0, 0.0, 0.02])
    np.testing.assert_array_equal(second.points["drone1"], maneuver.points["drone1"])
    np.testing.assert_array_equal(first.points["drone2"], maneuver.points["drone2"])
    assert moved.bodies["box"].mass == pytest.approx(1.6868 * 1.01)  # the shared one moves the one rig
    # a point no maneuver moves: its place in the rig
    still, _ = apply_parameters(rig, maneuver.__class__([0.0]), [track], [0.02])
    assert still.fixed_points["drone1"][2] == pytest.approx(rig.fixed_points["drone1"][2] + 0.02)


def test_with_the_anchors_track_prescribed_only_the_loads_mass_against_the_ropes_forces_moves_anything():
    # Dimensional analysis: the load's mass, the rope's weight and every rope force constant times k give every
    # particle the same acceleration (gravity's included) under a prescribed anchor, so a recording cannot see the
    # mass once the rope's material is free (the Stormlord file's tolerances); holding one of them breaks it.
    from dragline.simulate import Maneuver

    rig = load_rig(Path(__file__).resolve().parents[1] / "benchmarks" / "real" / "stormlord.toml")
    t = np.linspace(0.0, 4.0, 401)
    ramp = np.clip(t - 0.5, 0.0, 2.0) / 2.0
    move = 0.5 * (ramp - np.sin(2.0 * np.pi * ramp) / (2.0 * np.pi))  # 0.5 m over 2 s, no jump in acceleration
    drone = rig.fixed_points["drone"] + np.column_stack([move, 0.4 * move, -0.2 * move])
    maneuver = Maneuver(t, {}, {"drone": drone})
    forces = {"bodies.load.mass", "ropes.rope.static_stiffness", "ropes.rope.viscous_stiffness",
              "ropes.rope.viscous_damping", "ropes.rope.weight_per_length", "bodies.load.drag_area"}
    assert forces <= {p.name for p in rig.tolerances}

    def load_track(scaled):
        coords = [math.log(1.5) if p.name in scaled else 0.0 for p in rig.tolerances]
        moved, moved_maneuver = apply_parameters(rig, maneuver, rig.tolerances, coords)
        table = simulate(moved, moved_maneuver, duration=4.0, rate_hz=100.0, dt=1e-4).table
        return np.column_stack([table[f"load.{a}"] for a in "xyz"])

    nominal = load_track(set())
    assert np.ptp(nominal[:, 0]) > 0.3  # the load follows the drone: a motion, not a rest
    np.testing.assert_allclose(load_track(forces), nominal, rtol=0, atol=1e-9)
    held_weight = load_track(forces - {"ropes.rope.weight_per_length"})
    assert np.abs(held_weight - nominal).max() > 1e-4
    held_drag = load_track(forces - {"bodies.load.drag_area"})  # the load's air drag is a force too
    assert np.abs(held_drag - nominal).max() > 1e-4


def test_a_bodys_drag_area_is_the_air_drag_the_candidate_would_add_and_its_tolerance_moves_it():
    """The slung load's box given cd A in its rig file swings as the drag-free file under aero_drag at the cd
    whose mean face area makes that cd A (one drag law); the candidate then adds to the file's drag,
    and the drag area's tolerance moves it as the file's value would."""
    import dataclasses

    from dragline.simulate import parse_physics

    rig = load_rig("slung_load")
    sx, sy, sz = rig.bodies["load"].size
    area = (sx * sy + sy * sz + sx * sz) / 3.0
    dragged = dataclasses.replace(rig, bodies={"load": dataclasses.replace(rig.bodies["load"], drag_area=2.0 * area)})

    def track(r, physics=()):
        return simulate(r, physics=list(physics), duration=6.0, rate_hz=50.0).table[["load.x", "load.y"]].to_numpy()

    by_file = track(dragged)
    # the same law: apart only by the rounding of cd A's two products
    np.testing.assert_allclose(by_file, track(rig, [parse_physics("aero_drag:cd=2.0,body=load")]), rtol=0, atol=1e-12)
    assert np.abs(by_file - track(rig)).max() > 1e-3  # the drag is felt
    np.testing.assert_allclose(track(dragged, [parse_physics("aero_drag:cd=1.0,body=load")]),
                               track(rig, [parse_physics("aero_drag:cd=3.0,body=load")]), rtol=0, atol=1e-12)
    doc = tomllib.loads(resources.files("dragline.simulate").joinpath("data/slung_load.toml").read_text())
    doc["bodies"]["load"]["drag_area"] = 2.0 * area
    doc["tolerances"] = {"bodies.load.drag_area": {"factor": 2.0}}
    del doc["maneuver"]
    filed = rig_from_dict(doc)
    (p,) = filed.tolerances
    assert (p.kind, p.nominal, p.unit) == ("drag_area", 2.0 * area, "m^2")
    moved, _ = apply_parameters(filed, default_maneuver(rig), [p], [math.log(1.5)])
    assert moved.bodies["load"].drag_area == pytest.approx(3.0 * area, rel=1e-12)
    assert filed.bodies["load"].drag_area == 2.0 * area
