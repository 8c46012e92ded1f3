"""A rope reeved through several rings: a four-fall hook block against its statics and its energy.

The block hangs from one rope that runs from a drum over a head sheave, down
through the block's first sheave, up over a second head sheave, down through
the block's second sheave and up to a dead end, the points 50 mm apart in
that order: every fall leans 50 mm over its depth, so the block hangs level
under the middle sheave and, frictionless, the rope's tension is one number
along its whole path, T = m g / (4 cos(alpha)).
The same block is ``tests/data/hook_block.toml``, the rig file the docs'
reeving example describes.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from conftest import refused_edit
from dragline.pipelines.cli import main
from dragline.simulate import (Maneuver, assemble, load_rig, make_mechanism, rig_from_dict, simulate, solve_statics,
                               stable_time_step)
from dragline.simulate._simulate import element_tensions, mechanical_energy

DATA = Path(__file__).parent / "data"
STILL = Maneuver([0.0])
HEAD_Z = -3.0
MASS = 5.0
K = 2.0e5  # N per unit strain
LENGTH = 0.5 + 4 * 1.0  # drum to the first head sheave, then four falls of about 1 m
HALF_GAP = 0.05  # m, each fall's sideways lean at the block's rest


def _hook_block(**rope):
    return {
        "g": 9.81,
        "fixed_points": {"drum": [-0.6, 0.0, HEAD_Z], "head_a": [-0.1, 0.0, HEAD_Z],
                         "head_b": [0.0, 0.0, HEAD_Z], "dead_end": [0.1, 0.0, HEAD_Z]},
        "bodies": {"block": {"mass": MASS, "cg_body": [0, 0, 0], "inertia_diag": [0.02, 0.02, 0.02],
                             "points": {"sheave_1": [-0.05, 0.0, -0.05], "sheave_2": [0.05, 0.0, -0.05]},
                             "position": [0.0, 0.0, HEAD_Z + 1.0]}},
        "ropes": {"hoist_rope": {
            "start": "fixed.drum", "end": "fixed.dead_end",
            "rings": ["fixed.head_a", "block.sheave_1", "fixed.head_b", "block.sheave_2"],
            "length": LENGTH, "particles": 8, "weight_per_length": 0.01, "static_stiffness": K,
            "viscous_stiffness": 1.0, "viscous_damping": 1.0, **rope}},
    }


def _analytic_rest():
    """Each fall's depth (m) and the rope's tension (N) at rest, from the rope's length and stretch."""
    weight = MASS * 9.81

    def excess(depth):
        fall = np.hypot(HALF_GAP, depth)
        tension = weight * fall / (4 * depth)
        return 0.5 + 4 * fall - LENGTH * (1 + tension / (K + 1.0))

    depth = brentq(excess, 0.5, 1.5, xtol=1e-12)
    return depth, weight * np.hypot(HALF_GAP, depth) / (4 * depth)


def test_a_four_fall_block_hangs_where_its_rope_length_puts_it_with_one_tension_along_the_rope():
    rig = rig_from_dict(_hook_block())
    model = assemble(rig, STILL, dissipation=False)
    assert model.n_rings == 4
    rest = solve_statics(model)
    depth, tension = _analytic_rest()
    # the rope weighs 0.05 N against the block's 49 N: the analytic weightless rope within 0.1 %
    assert rest.state[:3] == pytest.approx([0.0, 0.0, HEAD_Z + depth + 0.05], abs=1e-3 * depth)
    assert np.degrees(rest.state[6:9]) == pytest.approx([0.0, 0.0, 0.0], abs=0.05)
    tensions = element_tensions(model, np.array([0.0]), rest.state[None], "hoist_rope")[0]
    assert tensions == pytest.approx(tension, rel=2e-3)
    # every ring's slide at rest, each span holding its share of the rope
    slides = rest.state[model.o_ring:].reshape(-1, 2)
    assert slides[:, 1] == pytest.approx(0.0, abs=1e-9)
    assert np.diff(np.r_[0.0, slides[:, 0], LENGTH]) == pytest.approx(
        np.r_[0.5, [np.hypot(HALF_GAP, depth)] * 4] / (1 + tension / (K + 1.0)), rel=1e-3)


def test_a_reeved_block_swinging_through_its_four_rings_keeps_its_energy_and_converges_with_the_step():
    rig = rig_from_dict(_hook_block())
    model = assemble(rig, STILL, dissipation=False)
    rest = solve_statics(model)
    e_rest = mechanical_energy(model, np.array([0.0]), rest.state[None])[0]
    y0 = rest.state.copy()
    y0[3] = 0.3  # m/s sideways: the falls lean and the rope slides through every ring
    drift = []
    for factor in (1.0, 0.5):
        res = simulate(rig, STILL, duration=3.0, rate_hz=200, dissipation=False, initial_state=y0,
                       dt=stable_time_step(model) * factor)
        energy = res.energy()
        motion = energy[0] - e_rest
        assert motion > 0.2  # J
        drift.append(np.max(np.abs(energy - energy[0])) / motion)
        # the rope slides through every block and head sheave (the first head sheave follows the
        # drum's straight fixed span, whose rope only stretches)
        slides = res.states[:, model.o_ring + 2 :: 2]
        assert np.ptp(slides, axis=0).min() > 1e-3  # m
    assert drift[0] < 1e-3, drift
    assert drift[1] < drift[0] / 2, drift


@pytest.mark.parametrize("machine", ["hook block", "dragline"])
def test_the_steps_stiffness_bound_reads_each_element_at_the_rest_length_the_rope_model_gives_it(machine):
    # The tracked step's bound (taken at every record) reads the element rest lengths from a table per
    # segment side; the same bound from each element's rest length as the trajectory reader computes it
    # (element_rest_lengths, written apart), mid-swing, the rope slid through every ring: the block's spans
    # differ (the drum's straight 0.5 m, falls of about 1 m), so an element read on a wrong side changes it.
    from dragline.simulate import _kernel
    from dragline.simulate._simulate import element_rest_lengths
    from dragline.simulate._tracked import gershgorin_lambda, state_gershgorin_lambda

    if machine == "hook block":
        rig = rig_from_dict(_hook_block())
        y0 = solve_statics(assemble(rig, STILL)).state.copy()
        y0[3] = 0.3  # m/s sideways, as the energy test swings it
        res = simulate(rig, STILL, duration=0.5, rate_hz=100, initial_state=y0)
    else:
        rig = load_rig()
        res = simulate(rig, None, duration=1.0, rate_hz=100)
    model, time, y = res.model, res.time[-1:], res.states[-1]
    rest = np.empty(model.arrays["el_seg"].shape[0])
    for segment in model.seg_names:
        rest[model.seg_elements[segment]] = element_rest_lengths(model, time, res.states[-1:], segment)[0]
    m = model.kernel_tuple()
    expected = gershgorin_lambda(rest, model.segment_lengths(time)[:, 0].copy(), m)
    assert state_gershgorin_lambda(float(time[0]), y, m, _kernel.make_work(m)) == pytest.approx(expected, rel=1e-12)
    if machine == "hook block":
        spans = [rest[model.arrays["el_side"] == side] for side in range(1, 6)]
        assert np.ptp([s[0] for s in spans]) > 0.05  # m: the spans' elements differ


def test_one_ring_written_either_way_builds_the_same_model():
    one = _hook_block(rings=["fixed.head_a"], end="block.sheave_1")
    old = _hook_block(end="block.sheave_1")
    del old["ropes"]["hoist_rope"]["rings"]
    old["ropes"]["hoist_rope"].update(ring="fixed.head_a", ring_name="head_a")
    a, b = (assemble(rig_from_dict(doc), STILL) for doc in (one, old))
    assert a.arrays.keys() == b.arrays.keys()
    for key in a.arrays:
        assert np.array_equal(a.arrays[key], b.arrays[key]), key
    assert a.ring_sites == b.ring_sites == ("head_a",)


def test_a_pulley_mechanism_acts_at_the_site_it_names_or_at_every_ring_of_the_rope_it_names():
    rig = rig_from_dict(_hook_block(ring_names=["head_a", "block_left", "head_b", "block_right"]))
    friction = assemble(rig, STILL, physics=[make_mechanism("pulley_friction", mu=0.1, pulley="head_b")])
    assert friction.ring_sites == ("head_a", "block_left", "head_b", "block_right")
    assert friction.arrays["ring_mu"] == pytest.approx([0.0, 0.0, 0.1, 0.0])
    everywhere = assemble(rig, STILL, physics=[make_mechanism("pulley_friction", mu=0.1, pulley="hoist_rope")])
    assert everywhere.arrays["ring_mu"] == pytest.approx([0.1] * 4)
    with pytest.raises(ValueError, match="block_left"):
        assemble(rig, STILL, physics=[make_mechanism("pulley_friction", mu=0.1, pulley="nowhere")])


def test_capstan_friction_at_one_head_sheave_holds_a_tension_step_there_alone():
    # The dead end hauled up at 0.2 m/s (eased in over 1 s): the rope slips through the block's sheaves
    # and over head_b, and friction at head_b alone makes the fall after it (the hauled side) carry
    # e^(mu beta) times the one before. Damped ropes (relaxation 0.01 s) so that the start's jolt dies out.
    mu = 0.2
    rig = rig_from_dict(_hook_block(ring_names=["head_a", "block_left", "head_b", "block_right"],
                                    viscous_stiffness=1.0e5, viscous_damping=1.0e3))
    t = np.linspace(0.0, 4.0, 401)
    rise = 0.2 * np.where(t < 1.0, t**2 / 2, t - 0.5)  # m, constant 0.2 m/s after the first second
    haul = Maneuver(t, points={"dead_end": np.column_stack([np.full_like(t, 0.1), 0 * t, HEAD_Z - rise])})
    res = simulate(rig, haul, duration=4.0, rate_hz=100, physics=[make_mechanism("pulley_friction", mu=mu,
                                                                                   pulley="head_b")])
    model = res.model
    late = res.time > 2.5
    tension = element_tensions(model, res.time[late], res.states[late], "hoist_rope")
    side = model.arrays["el_side"][model.seg_elements["hoist_rope"]]
    before, after = tension[:, side == 3][:, -1], tension[:, side == 4][:, 0]
    nodes = model.node_positions(res.states[late], "hoist_rope", res.time[late])
    ring = [j for j, node in enumerate(model.seg_nodes["hoist_rope"]) if node[0] != 0][3]  # head_b, the 4th anchor
    ins, outs = nodes[:, ring - 1] - nodes[:, ring], nodes[:, ring + 1] - nodes[:, ring]
    wrap = np.pi - np.arccos(np.einsum("ij,ij->i", ins, outs) / np.linalg.norm(ins, axis=1) / np.linalg.norm(outs, axis=1))
    assert np.median(after / before) == pytest.approx(np.median(np.exp(mu * wrap)), rel=0.05)
    # the frictionless sheave the rope slides through before it passes the tension on
    first, second = tension[:, side == 2][:, -1], tension[:, side == 3][:, 0]
    assert np.median(second / first) == pytest.approx(1.0, abs=0.01)


def test_the_rig_file_is_the_block_of_these_tests_and_dragline_rig_lists_its_path_and_sites(tmp_path, capsys):
    from_file = load_rig(DATA / "hook_block.toml")
    from_dict = rig_from_dict(_hook_block(ring_names=["head_a", "block_left", "head_b", "block_right"]))
    assert from_file.ropes["hoist_rope"] == from_dict.ropes["hoist_rope"]
    out = tmp_path / "rig.json"
    assert main(["rig", str(DATA / "hook_block.toml"), "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["ropes"]["hoist_rope"]["path"] == ["fixed.drum", "fixed.head_a", "block.sheave_1", "fixed.head_b",
                                                 "block.sheave_2", "fixed.dead_end"]
    assert list(doc["rings"]) == ["head_a", "block_left", "head_b", "block_right"]
    assert doc["rings"]["block_left"] == {"at": "block.sheave_1", "rope": "hoist_rope"}
    depth, _ = _analytic_rest()
    assert doc["statics"]["bodies"]["block"][2] == pytest.approx(HEAD_Z + depth + 0.05, abs=2e-3)


@pytest.mark.parametrize("edit, words", [
    (('end = "fixed.dead_end"', 'end = "fixed.dead_end"\nring = "fixed.head_b"'), ["ropes.hoist_rope", "not both"]),
    (('"head_b", "block_right"]', '"head_b"]'), ["ropes.hoist_rope", "3 names for 4 rings"]),
    (('"fixed.head_b", "block.sheave_2"]', '"fixed.head_a", "block.sheave_2"]'), ["hoist_rope", "same ring twice"]),
    (('"block.sheave_2"]', '"block.sheave_9"]'), ["hoist_rope", "no point 'sheave_9'"]),
])
def test_a_reeving_that_cannot_be_is_refused_with_one_line_naming_the_file(tmp_path, edit, words):
    message = refused_edit(tmp_path, DATA / "hook_block.toml", edit, load_rig)
    for word in words:
        assert word in message, message
