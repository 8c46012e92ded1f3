"""Machines other than the dragline: the rig file describes them, the simulator reads them.

Truth is analytic: the small-oscillation modes of a pendulum (a ball on a
string, hung from its top: a two-degree-of-freedom system) and of a double
pendulum (point masses on two strings), from their Lagrangians; the
simulated period is read off zero crossings of a release in one mode.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import refused_edit
from dragline.pipelines.cli import main
from dragline.simulate import Maneuver, assemble, load_rig, make_mechanism, rig_from_dict, simulate
from scipy.linalg import eigh

DATA = Path(__file__).parent / "data"
G = 9.81


def _period(t, x):
    """Mean period (s) between downward zero crossings of x(t), interpolated."""
    i = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    assert crossings.size >= 4, "fewer than four swings"
    return float(np.mean(np.diff(crossings)))


def _modes(mass, stiffness):
    """Angular frequencies (rad/s, ascending) and mode shapes (columns) of M q'' + K q = 0."""
    w2, shapes = eigh(stiffness, mass)
    return np.sqrt(w2), shapes


def test_the_pendulum_swings_at_its_analytic_period():
    """The built-in pendulum: string of length l (stretched by the ball's weight) to the ball's top,
    the ball's centre a further a on, inertia I about it, the string's weight lumped at its particles
    as the model lumps it. Released in the slow mode at 2 degrees; the period is the mode's, times
    the pendulum's finite-amplitude factor 1 + theta^2 / 16."""
    rig = load_rig("pendulum")
    ball, wire = rig.bodies["ball"], rig.ropes["wire"]
    M, a, inertia = ball.mass, -ball.points["eye"][2], ball.inertia[1, 1]
    n = rig.particle_counts("baseline")["wire"]
    l = wire.length * (1.0 + M * G / wire.static_stiffness)
    string_mass = wire.weight_per_length / G * wire.length
    s = np.arange(1, n + 1) / (n + 1)  # the particles' places along the string
    mass = np.array([[M * l * l + string_mass / n * np.sum(s**2) * l * l, M * l * a], [M * l * a, M * a * a + inertia]])
    stiffness = np.diag([M * G * l + string_mass / n * G * l * np.sum(s), M * G * a])
    w, shapes = _modes(mass, stiffness)
    phi = math.radians(2.0)
    psi = phi * shapes[1, 0] / shapes[0, 0]
    pivot = rig.fixed_points["pivot"]
    centre = pivot + [l * math.sin(phi) + a * math.sin(psi), 0.0, l * math.cos(phi) + a * math.cos(psi)]
    run = simulate(rig, release={"ball": {"position": centre, "angles": [0.0, psi, 0.0]}}, duration=10.0,
                   rate_hz=1000.0)
    t, x = run.table["time"].to_numpy(), run.table["ball.x"].to_numpy()
    expected = 2 * math.pi / w[0] * (1 + phi**2 / 16)
    assert _period(t, x) == pytest.approx(expected, rel=2e-5)  # measured 7e-7
    # Held, then let go: the first record is the release pose at rest.
    first = run.table.iloc[0]
    np.testing.assert_allclose([first["ball.x"], first["ball.z"], first["ball.pitch"]], [centre[0], centre[2], psi],
                               atol=1e-12)
    assert first["ball.vx"] == first["ball.vz"] == first["ball.q"] == 0.0


def test_the_pendulums_own_trial_is_a_release_from_its_file():
    rig = load_rig("pendulum")
    run = simulate(rig, duration=0.5, rate_hz=100.0)
    np.testing.assert_allclose(run.table[["ball.x", "ball.y", "ball.z"]].iloc[0], rig.release["ball"]["position"],
                               atol=1e-12)
    assert run.table["ball.x"].iloc[-1] < 0.5 * rig.release["ball"]["position"][0]  # swung toward the bottom
    assert list(run.table.columns[:13]) == ["time"] + [f"ball.{q}" for q in
                                                      ("x", "y", "z", "roll", "pitch", "yaw", "vx", "vy", "vz",
                                                       "p", "q", "r")]
    assert not any(c.endswith(".length") for c in run.table.columns)  # no winch, no rope-length channel


@pytest.mark.parametrize("mode", [0, 1])
def test_a_double_pendulum_written_from_the_docs_swings_in_its_two_modes(mode):
    """Point masses m1, m2 on strings l1, l2 (each stretched by the weight below it): the textbook
    double pendulum, with each string's weight lumped at its particles as the model lumps it.
    Released at 1 degree in each mode shape in turn."""
    rig = load_rig(DATA / "double_pendulum.toml")
    m1, m2 = rig.bodies["upper"].mass, rig.bodies["lower"].mass
    up, low = rig.ropes["upper_string"], rig.ropes["lower_string"]
    n1, n2 = (rig.particle_counts("baseline")[r] for r in ("upper_string", "lower_string"))
    p1, p2 = up.weight_per_length / G * up.length / n1, low.weight_per_length / G * low.length / n2
    s1, s2 = np.arange(1, n1 + 1) / (n1 + 1), np.arange(1, n2 + 1) / (n2 + 1)
    l1 = up.length * (1 + (m1 + m2 + p2 * n2) * G / up.static_stiffness)
    l2 = low.length * (1 + m2 * G / low.static_stiffness)
    below = m2 + p2 * n2  # what the upper string's end carries besides the upper mass
    mass = np.array([[(m1 + below) * l1**2 + p1 * np.sum(s1**2) * l1**2, (m2 + p2 * np.sum(s2)) * l1 * l2],
                     [(m2 + p2 * np.sum(s2)) * l1 * l2, (m2 + p2 * np.sum(s2**2)) * l2**2]])
    stiffness = np.diag([(m1 + below) * G * l1 + p1 * np.sum(s1) * G * l1, (m2 + p2 * np.sum(s2)) * G * l2])
    w, shapes = _modes(mass, stiffness)
    shape = shapes[:, mode] / np.max(np.abs(shapes[:, mode]))
    phi1, phi2 = np.radians(1.0) * shape
    pivot = rig.fixed_points["pivot"]
    upper = pivot + [l1 * math.sin(phi1), 0.0, l1 * math.cos(phi1)]
    lower = upper + [l2 * math.sin(phi2), 0.0, l2 * math.cos(phi2)]
    run = simulate(rig, release={"upper": {"position": upper}, "lower": {"position": lower}},
                   duration=4.5 * 2 * math.pi / w[mode], rate_hz=2000.0)
    t = run.table["time"].to_numpy()
    x = run.table["lower.x"].to_numpy() - pivot[0]
    # measured 1.1e-5 (slow) and 1.1e-4 (fast mode, whose 1 degree swings the strings' particles harder)
    assert _period(t, x) == pytest.approx(2 * math.pi / w[mode], rel=5e-4)


def _two_rope_rig(kinds):
    """A load hung from two anonymous ropes, one of them through a sheave: names that say nothing."""
    return rig_from_dict({
        "bodies": {"load": {"mass": 1.0, "cg_body": [0, 0, 0], "inertia_diag": [0.01, 0.01, 0.01],
                            "position": [0.0, 0.0, -1.0], "points": {"p": [0.0, 0.0, 0.0]}}},
        "fixed_points": {"a": [-0.5, 0.0, -2.0], "b": [0.5, 0.0, -2.0], "c": [0.0, 0.0, -2.5]},
        "ropes": {
            "cable_1": {"kind": kinds[0], "start": "fixed.a", "end": "load.p", "length": 1.2, "particles": 2,
                        "weight_per_length": 0.1, "static_stiffness": 1e4, "viscous_stiffness": 1e3,
                        "viscous_damping": 10.0},
            "line_x": {"kind": kinds[1], "start": "fixed.b", "ring": "fixed.c", "ring_name": "sheave_7",
                       "end": "load.p", "length": 1.8, "particles": 3, "weight_per_length": 0.1,
                       "static_stiffness": 1e4, "viscous_stiffness": 1e3, "viscous_damping": 10.0},
        },
    })


def test_every_mechanism_finds_its_sites_by_kind_and_ring_name_never_by_rope_name():
    rig = _two_rope_rig(("chain", "cable"))
    still = Maneuver([0.0])
    physics = [make_mechanism("chain_link_friction", mu=0.2), make_mechanism("rope_bending_damping", c=0.01),
               make_mechanism("pulley_friction", mu=0.05, pulley="sheave_7"),
               make_mechanism("pulley_inertia", inertia=1e-4, pulley="line_x")]
    a = assemble(rig, still, physics=physics).arrays
    np.testing.assert_array_equal(a["seg_link_mu"], [0.2, 0.0])  # the chain, whatever its name
    np.testing.assert_array_equal(a["seg_bend_c"], [0.0, 0.01])  # a cable bends as a rope does
    np.testing.assert_array_equal(a["ring_mu"], [0.05])
    assert a["ring_added_mass"][0] > 0
    swapped = assemble(_two_rope_rig(("rope", "chain")), still, physics=physics[:2]).arrays
    np.testing.assert_array_equal(swapped["seg_link_mu"], [0.0, 0.2])
    np.testing.assert_array_equal(swapped["seg_bend_c"], [0.01, 0.0])
    with pytest.raises(ValueError, match="sheave_7"):  # the error lists the rig's ring names
        assemble(rig, still, physics=[make_mechanism("pulley_friction", mu=0.05, pulley="boom")])


def test_a_kind_no_mechanism_knows_is_refused_naming_it(tmp_path, capsys):
    text = (DATA / "double_pendulum.toml").read_text().replace('kind = "cable"', 'kind = "hemp"', 1)
    bad = tmp_path / "rig.toml"
    bad.write_text(text)
    assert main(["simulate", "--rig", str(bad), "--out", str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "ropes.upper_string.kind = 'hemp'" in err[0], err


@pytest.mark.parametrize("edit, words", [
    (("[ropes.lower_string]\nkind", "[ropes.lower_string]\nend_note = 1\nkind"), ["lower_string"]),
    (('end = "lower.top"', 'end = "upper.bottom"'), ["body 'lower' is held by no rope"]),
    (('end = "lower.top"', 'end = "lower.tip"'), ["body 'lower' has no point 'tip'"]),
    (('start = "fixed.pivot"', 'start = "fixed.pivot2"'), ["unknown fixed point 'pivot2'"]),
])
def test_a_rig_that_names_nothing_or_holds_nothing_is_refused_with_one_line(tmp_path, capsys, edit, words):
    message = refused_edit(tmp_path, DATA / "double_pendulum.toml", edit, load_rig)
    for word in words:
        assert word in message, message


def test_a_maneuver_column_that_names_no_winch_is_refused(tmp_path, capsys):
    man = tmp_path / "m.csv"
    man.write_text("time,trolley_length\n0,1.0\n1,1.1\n")
    out = tmp_path / "t.csv"
    assert main(["simulate", "--rig", "pendulum", "--maneuver", str(man), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "trolley_length" in err[0] and "names no winch" in err[0], err
    assert not out.exists()


def test_a_rig_file_written_before_winches_reads_as_the_built_in_rig(tmp_path):
    """``reel = "hoist"`` on the rope (and no kinds, every rope then a rope) is still read: the same
    winches, the same trajectories."""
    from importlib import resources

    text = resources.files("dragline.simulate").joinpath("data/rig.toml").read_text()
    legacy = text.replace('[ropes.hoist_rope]\n', '[ropes.hoist_rope]\nreel = "hoist"\n')
    legacy = legacy.replace('[ropes.drag_rope]\n', '[ropes.drag_rope]\nreel = "drag"\n')
    start = legacy.index("[winches.hoist]")
    legacy = legacy[:start] + legacy[legacy.index("# Where the statics start"):]
    assert "[winches" not in legacy
    old = tmp_path / "rig.toml"
    old.write_text(legacy)
    rig = load_rig(old)
    assert rig.winches == {"drag": "drag_rope", "hoist": "hoist_rope"}  # in the order the ropes name them
    built_in = simulate(duration=0.5, rate_hz=50.0, discretization="low").table
    read = simulate(rig, duration=0.5, rate_hz=50.0, discretization="low").table
    for column in built_in.columns:
        np.testing.assert_array_equal(read[column], built_in[column], err_msg=column)


def test_a_load_under_a_moving_point_follows_the_forced_pendulum_solution():
    """A load hung at its mass centre on a light line from a point the maneuver moves as A sin(w t):
    from rest, u'' = -w0^2 (u - A sin w t) gives u = A w0^2 / (w0^2 - w^2) (sin w t - (w / w0) sin w0 t),
    w0^2 = g / L (L stretched by the load's weight). Three swings at w = w0 / 2."""
    mass, length, ea = 0.46, 1.0, 2e4
    rig = rig_from_dict({
        "g": G,
        "bodies": {"load": {"mass": mass, "cg_body": [0, 0, 0], "inertia_diag": [6e-4, 6e-4, 7e-4],
                            "position": [0.0, 0.0, -1.0], "points": {"eye": [0.0, 0.0, 0.0]}}},
        "fixed_points": {"anchor": [0.0, 0.0, -2.0]},
        "ropes": {"line": {"start": "fixed.anchor", "end": "load.eye", "length": length, "particles": 4,
                           "weight_per_length": 0.001, "static_stiffness": ea, "viscous_stiffness": 1e3,
                           "viscous_damping": 10.0}},
    })
    w0 = math.sqrt(G / (length * (1 + mass * G / ea)))
    w, amplitude = 0.5 * w0, 0.02
    duration = 3 * 2 * math.pi / w0
    t = np.arange(0.0, duration + 1e-3, 1e-3)
    track = np.column_stack([amplitude * np.sin(w * t), np.zeros_like(t), np.full_like(t, -2.0)])
    run = simulate(rig, Maneuver(t, points={"anchor": track}), duration=duration, rate_hz=200.0)
    ts, u = run.table["time"].to_numpy(), run.table["load.x"].to_numpy()
    expected = amplitude * w0**2 / (w0**2 - w**2) * (np.sin(w * ts) - (w / w0) * np.sin(w0 * ts))
    assert np.max(np.abs(u - expected)) < 1e-3 * np.max(np.abs(expected))  # measured 1.0e-4


def test_the_gantry_cranes_two_falls_carry_everything_below_the_trolley():
    """At rest the hoist rope's two falls hold, at the trolley, the hook, the payload, both slings and
    every particle of the rope (the lumped model hangs the rope's whole weight on its particles): the
    vertical parts of the tensions in their top elements sum to that weight, half on each fall as the
    block hangs under the middle, the rope sliding freely through the block's sheave."""
    rig = load_rig("gantry_crane")
    run = simulate(rig, duration=0.01, rate_hz=100.0)
    hoist, slings = rig.ropes["hoist_rope"], (rig.ropes["left_sling"], rig.ropes["right_sling"])
    weight = G * sum(b.mass for b in rig.bodies.values()) + sum(s.weight_per_length * s.length for s in slings)
    weight += hoist.weight_per_length * run.table["hoist_rope.reel_length"].iloc[0]  # every particle hangs below
    nodes = run.model.node_positions(run.states[:1], "hoist_rope", run.time[:1])[0]
    first, last = nodes[1] - nodes[0], nodes[-2] - nodes[-1]  # down the falls from the drum and the dead end
    up = [run.table[f"hoist_rope.tension_{end}"].iloc[0] * d[2] / np.linalg.norm(d)
          for end, d in (("start", first), ("end", last))]
    assert sum(up) == pytest.approx(weight, rel=1e-6)
    assert up[0] == pytest.approx(up[1], rel=1e-3)


def test_the_hook_blocks_four_falls_carry_everything_below_the_trolley_a_quarter_each():
    """At rest the rope leaves the drum, the dead end and both sides of the head sheave (the trolley's three
    points) in four falls: the vertical parts of the tensions where it leaves them sum to the weight of the
    block, the payload, the slings and the rope, and each fall carries a quarter of it within the share of the
    rope's own weight (the rope slides freely through all three sheaves)."""
    from dragline.simulate._simulate import element_tensions

    rig = load_rig("hook_block_crane")
    run = simulate(rig, duration=0.01, rate_hz=100.0)
    hoist, slings = rig.ropes["hoist_rope"], (rig.ropes["left_sling"], rig.ropes["right_sling"])
    rope_weight = hoist.weight_per_length * run.table["hoist_rope.reel_length"].iloc[0]
    weight = G * sum(b.mass for b in rig.bodies.values()) + sum(s.weight_per_length * s.length for s in slings)
    weight += rope_weight
    model = run.model
    nodes = model.node_positions(run.states[:1], "hoist_rope", run.time[:1])[0]
    tension = element_tensions(model, run.time[:1], run.states[:1], "hoist_rope")[0]
    head = model.ring_nodes("hoist_rope")[1]  # the rings in order: block, head, block
    ends = [(0, 1, 0), (len(nodes) - 1, len(nodes) - 2, len(tension) - 1), (head, head - 1, head - 1),
            (head, head + 1, head)]  # (trolley node, the next node down the fall, the element between)
    up = [tension[e] * (nodes[b] - nodes[a])[2] / np.linalg.norm(nodes[b] - nodes[a]) for a, b, e in ends]
    assert sum(up) == pytest.approx(weight, rel=1e-6)
    assert np.allclose(up, weight / 4, atol=rope_weight / 4)


@pytest.mark.parametrize("name", ["pendulum", "slung_load", "gantry_crane", "hook_block_crane"])
def test_every_built_in_machine_runs_its_own_maneuver_with_its_own_channels(name, tmp_path):
    rig = load_rig(name)
    out = tmp_path / "t.csv"
    assert main(["simulate", "--rig", name, "--duration", "1", "--out", str(out), "--quiet"]) == 0
    import pandas as pd

    table = pd.read_csv(out)
    for body in rig.bodies:
        assert {f"{body}.x", f"{body}.pitch", f"{body}.q"} <= set(table.columns)
    for rope in rig.winches.values():
        assert f"{rope}.length" in table.columns
    assert np.isfinite(table.to_numpy()).all()


# ---------------------------------------------------------------- the diagnosis on another machine

PENDULUM_NOISE = {"position": 5e-4, "angle": 5e-3}  # m, rad: a lab's reconstruction


def _recorded(run, body, seed):
    """``body``'s channels of a simulation as a lab records them: white noise of ``PENDULUM_NOISE``."""
    rng = np.random.default_rng(seed)
    table = run.table[["time"] + [c for c in run.table.columns if c.startswith(f"{body}.")]].copy()
    for c in table.columns[1:]:
        kind = "angle" if c.rsplit(".", 1)[1] in ("roll", "pitch", "yaw", "p", "q", "r") else "position"
        table[c] = table[c] + rng.normal(0.0, PENDULUM_NOISE[kind], len(table))
    return table


def _pendulum_recording(physics, seed):
    """The pendulum's own trial (a release) simulated with ``physics``, white noise on its motion."""
    from dragline.simulate import parse_physics

    rig = load_rig("pendulum")
    run = simulate(rig, physics=[parse_physics(p) for p in physics], duration=16.0, rate_hz=100.0,
                   discretization="low")
    return rig, _recorded(run, "ball", seed)


@pytest.fixture(scope="module")
def pendulum_aero_diagnosis():
    from dragline.compare.diagnose import diagnose

    rig, table = _pendulum_recording(["aero_drag:cd=3.0"], seed=5)
    return diagnose(table, rig=rig, discretization="low",
                    candidates=["aero_drag", "rope_bending_damping", "pulley_friction", "chain_link_friction"])


def test_the_diagnosis_reads_a_pendulum_from_its_rig_and_names_the_hidden_drag(pendulum_aero_diagnosis):
    doc = pendulum_aero_diagnosis.doc
    assert doc["verdict"] == "aero_drag", doc["reason"]
    named = next(h for h in doc["hypotheses"] if h["name"] == "aero_drag")
    assert named["parameters"]["cd"] == pytest.approx(3.0, rel=0.25)
    # Its channels are the ball's that swing (a planar release: no y, roll or yaw), its clock the release.
    assert set(doc["channels"]) == {"ball.x", "ball.z", "ball.pitch"}
    assert doc["alignment"]["time_offset"] == 0.0 and doc["alignment"]["reels_stop"] == 0.0
    assert [w["window"] for w in doc["windows"]] == ["free decay"]
    # What the machine cannot hold is skipped, saying why.
    skipped = {s["name"]: s["reason"] for s in doc["skipped"]}
    assert "no ring" in skipped["pulley_friction"] and "kind chain" in skipped["chain_link_friction"]


def test_the_diagnosis_of_a_pendulum_with_nothing_hidden_is_none():
    from dragline.compare.diagnose import diagnose

    rig, table = _pendulum_recording([], seed=6)
    doc = diagnose(table, rig=rig, discretization="low", candidates=["aero_drag", "rope_bending_damping"]).doc
    assert doc["verdict"] == "none", doc["reason"]


def test_the_linearized_modes_of_the_pendulum_are_its_analytic_ones():
    """The conservative model (springs Ks + Kv) linearized at rest: the swing (twice, in two planes)
    and the ball's rocking about its eye are the two-degree-of-freedom pendulum's modes."""
    from dragline.simulate import linear_modes, solve_statics

    rig = load_rig("pendulum")
    ball, wire = rig.bodies["ball"], rig.ropes["wire"]
    M, a, inertia = ball.mass, -ball.points["eye"][2], ball.inertia[1, 1]
    n = rig.particle_counts("baseline")["wire"]
    l = wire.length * (1.0 + M * G / (wire.static_stiffness + wire.viscous_stiffness))
    p = wire.weight_per_length / G * wire.length / n
    s = np.arange(1, n + 1) / (n + 1)
    mass = np.array([[M * l * l + p * np.sum(s**2) * l * l, M * l * a], [M * l * a, M * a * a + inertia]])
    stiffness = np.diag([M * G * l + p * G * l * np.sum(s), M * G * a])
    w, _ = _modes(mass, stiffness)
    model = assemble(rig, Maneuver([0.0]), "baseline", dissipation=False)
    modes = linear_modes(model, solve_statics(model).state, count=5)
    f = modes.frequency_hz
    assert f[0] < 1e-3  # the ball's spin about the wire: nothing resists it
    np.testing.assert_allclose(f[1:3], w[0] / (2 * np.pi), rtol=1e-5)
    np.testing.assert_allclose(f[3:5], w[1] / (2 * np.pi), rtol=1e-3)  # the string's bending enters here


def test_dragline_rig_describes_a_machine_and_refuses_a_broken_file(tmp_path, capsys):
    import json

    out, figure = tmp_path / "rig.json", tmp_path / "rig.png"
    assert main(["rig", str(DATA / "double_pendulum.toml"), "--json", str(out), "--figure", str(figure)]) == 0
    doc = json.loads(out.read_text())
    assert set(doc["bodies"]) == {"upper", "lower"} and doc["winches"] == {}
    assert doc["ropes"]["lower_string"]["path"] == ["upper.bottom", "lower.top"]
    assert doc["statics"]["bodies"]["lower"][2] == pytest.approx(-2.0 + 0.8 + 0.6, abs=2e-3)  # hanging straight
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = capsys.readouterr().out
    assert "upper_string (cable): fixed.pivot -> upper.top" in text and "lowest modes (Hz)" in text
    bad = tmp_path / "bad.toml"
    bad.write_text((DATA / "double_pendulum.toml").read_text().replace("mass = 0.5", "mass = -0.5"))
    assert main(["rig", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "bodies.lower.mass" in err[0]


@pytest.mark.parametrize("physics, verdict", [(["aero_drag:cd=3.0"], "aero_drag"), ([], "none")])
def test_the_diagnosis_of_a_load_under_a_moving_point(physics, verdict):
    """The slung load's own trial: the hook moves for 3 s, then hovers. The hook's track is the model's
    input (the maneuver), the free decay starts when it stops; measured 2.996 for 3.0."""
    from dragline.compare.diagnose import diagnose
    from dragline.simulate import parse_physics

    rig = load_rig("slung_load")
    run = simulate(rig, physics=[parse_physics(p) for p in physics], duration=12.0, rate_hz=100.0,
                   discretization="low")
    table = _recorded(run, "load", 21)
    doc = diagnose(table, rig=rig, discretization="low", candidates=["aero_drag", "rope_bending_damping"]).doc
    assert doc["verdict"] == verdict, doc["reason"]
    assert doc["alignment"]["reels_stop"] == pytest.approx(3.0)  # the hook's last move
    if verdict == "aero_drag":
        named = next(h for h in doc["hypotheses"] if h["name"] == "aero_drag")
        assert named["parameters"]["cd"] == pytest.approx(3.0, rel=0.25)


@pytest.mark.parametrize("physics, verdict", [(["aero_drag:cd=3.0"], "aero_drag"), ([], "none")])
def test_a_load_under_a_point_moving_to_the_end_is_diagnosed_from_its_forced_response(physics, verdict):
    """A flight: the hook moves as 0.15 m sin(2 pi t / 5 s) for the whole recording, so there is no
    free decay; the diagnosis judges the forced response on its held-out blocks."""
    from dragline.compare.diagnose import diagnose
    from dragline.simulate import parse_physics

    rig = load_rig("slung_load")
    t = np.round(np.arange(0.0, 12.0 + 1e-9, 0.02), 6)
    track = np.column_stack([0.15 * np.sin(2 * np.pi * t / 5.0), np.zeros_like(t), np.full_like(t, -4.0)])
    flight = Maneuver(t, points={"anchor": track})
    run = simulate(rig, flight, physics=[parse_physics(p) for p in physics], duration=12.0, rate_hz=100.0,
                   discretization="low")
    table = _recorded(run, "load", 31)
    doc = diagnose(table, flight, rig=rig, discretization="low", candidates=["aero_drag", "rope_bending_damping"]).doc
    assert doc["verdict"] == verdict, doc["reason"]
    assert "free decay" not in [w["window"] for w in doc["windows"]]
    if verdict == "aero_drag":
        named = next(h for h in doc["hypotheses"] if h["name"] == "aero_drag")
        assert named["parameters"]["cd"] == pytest.approx(3.0, rel=0.25)
