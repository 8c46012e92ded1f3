"""The diagnosis's floors at the machine's own scale: the dragline's exactly, any other's by Froude similarity."""

import math

import numpy as np
import pytest

from dragline.compare.diagnose._locate import NOISE_FLOOR, STRUCTURE_FLOOR, noise_level, structure_threshold
from dragline.compare.diagnose._scale import REFERENCE, REFERENCE_SWING_HZ, machine_scale
from dragline.simulate import Maneuver, load_rig, rig_from_dict

G = 9.81


def _pendulum(length, g=G):
    """A heavy bob on a stiff light string: a simple pendulum of ``length`` (m) to 0.1 % (the string weighs
    under 0.5 % of the bob and stretches 0.1 %)."""
    return rig_from_dict({
        "g": g,
        "fixed_points": {"pivot": [0.0, 0.0, -length - 1.0]},
        "bodies": {"bob": {"mass": 100.0, "cg_body": [0, 0, 0], "inertia_diag": [1e-6] * 3,
                           "points": {"eye": [0, 0, 0]}, "position": [0.0, 0.0, -1.0]}},
        "ropes": {"string": {"start": "fixed.pivot", "end": "bob.eye", "length": length, "particles": 2,
                             "weight_per_length": 0.1, "static_stiffness": 1e6, "viscous_stiffness": 1.0,
                             "viscous_damping": 1.0}},
    })


def test_the_dragline_keeps_every_constant_as_it_was_set():
    scale = machine_scale(load_rig())
    # The eigenvalue to its last digits depends on the LAPACK build (numpy 2.4.6's OpenBLAS 0.3.31 gives
    # 0.35231780235805377, 8e-11 from the constant): the ratios' three-digit rounding is what keeps the floors.
    assert scale.swing_hz == pytest.approx(REFERENCE_SWING_HZ, rel=1e-9)
    assert scale.length == 1.0 and scale.time == 1.0
    assert scale.floor(STRUCTURE_FLOOR, "position") == STRUCTURE_FLOOR["position"]
    assert scale.lowpass_width(0.1, 1 / 200) == 21  # 0.1 s at 200 Hz, as before


@pytest.mark.parametrize("length, g", [(0.5, G), (50.0, G), (3.0, 3.71)])
def test_a_pendulum_gets_lengths_by_its_length_and_times_by_its_period(length, g):
    reference_length = G / (2 * math.pi * REFERENCE_SWING_HZ) ** 2  # the dragline's slowest swing as a pendulum
    scale = machine_scale(_pendulum(length, g), Maneuver([0.0]))
    assert scale.swing_hz == pytest.approx(math.sqrt(g / length) / (2 * math.pi), rel=2e-3)
    assert scale.length == pytest.approx(length / reference_length, rel=5e-3)
    assert scale.time == pytest.approx(math.sqrt(length / g) / math.sqrt(reference_length / G), rel=5e-3)
    # lengths scale, angles do not
    assert scale.floor(STRUCTURE_FLOOR, "position") == pytest.approx(STRUCTURE_FLOOR["position"] * scale.length)
    assert scale.floor(STRUCTURE_FLOOR, "rope_length") == pytest.approx(STRUCTURE_FLOOR["rope_length"] * scale.length)
    assert scale.floor(STRUCTURE_FLOOR, "angle") == STRUCTURE_FLOOR["angle"]
    # the low-pass spans the same share of the machine's own swing
    rate = 100.0
    width = scale.lowpass_width(0.1, 1 / rate)
    assert width == max(3, int(round(0.1 * scale.time * rate)) | 1)


def test_a_crane_50_m_tall_judges_structure_against_its_own_floor_and_noise():
    crane = machine_scale(_pendulum(50.0), Maneuver([0.0]))
    assert crane.length == pytest.approx(25.0, rel=0.01)
    # below the dragline's noise floor but above nothing: a noiseless table's sigma is the floor
    flat = np.zeros(400)
    assert noise_level(flat, "position", crane) == pytest.approx(NOISE_FLOOR["position"] * crane.length)
    assert noise_level(flat, "position") == NOISE_FLOOR["position"]
    # a 10 mm low-passed mismatch is structure on the dragline, not on the crane
    assert 0.010 > structure_threshold("bucket.x", 1e-6, 21)
    assert 0.010 < structure_threshold("boom_tip.x", 1e-6, 21, crane)
    assert structure_threshold("hook.pitch", 1e-6, 21, crane) == structure_threshold("hook.pitch", 1e-6, 21, REFERENCE)


def test_a_rig_without_a_body_to_swing_keeps_the_draglines_scale():
    # a taut line's slowest mode is elastic (hundreds of Hz here), not a swing under gravity
    line = rig_from_dict({
        "fixed_points": {"a": [0.0, 0.0, 0.0], "b": [1.0, 0.0, 0.0]},
        "ropes": {"line": {"start": "fixed.a", "end": "fixed.b", "length": 0.99, "particles": 3,
                           "weight_per_length": 0.01, "static_stiffness": 1e5, "viscous_stiffness": 1.0,
                           "viscous_damping": 1.0}},
    })
    assert machine_scale(line, Maneuver([0.0])) == REFERENCE


def test_dragline_rig_states_the_machines_scale(tmp_path, capsys):
    import json

    from dragline.pipelines.cli import main

    out = tmp_path / "rig.json"
    assert main(["rig", "pendulum", "--json", str(out)]) == 0
    scale = json.loads(out.read_text())["scale"]
    own = machine_scale(load_rig("pendulum"))
    assert scale["length"] == own.length and scale["time"] == own.time
    assert scale["reach_m"] == pytest.approx(1.0 + 0.08)  # the 1 m wire and the 80 mm ball
    assert f"floors are the dragline's x {own.length:g} in length" in capsys.readouterr().out
