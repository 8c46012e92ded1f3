"""The rig's scale of mass and force, which no motion recording weighs (compare/diagnose/_mass_scale.py).

The probe's threshold is checked on the real slung-load rig, simulated: every mass and force coefficient
moved together is a pure rescaling, to the arithmetic's rounding; one of them left out is not."""

from pathlib import Path

import numpy as np
import pytest
from dragline.compare.diagnose._mass_scale import (
    PROBE,
    SCALE_NULL,
    gauge_covariance,
    is_pure_rescaling,
    scale_direction,
)
from dragline.simulate import apply_parameters, default_maneuver, load_rig, simulate

RIG = Path(__file__).resolve().parents[1] / "benchmarks" / "real" / "stormlord.toml"


def test_the_direction_is_every_free_mass_and_rope_force_and_weight_and_nothing_geometric():
    params = load_rig(RIG).tolerances
    names = [params[i].name for i in scale_direction(params)]
    assert sorted(names) == sorted(["bodies.load.mass", "ropes.rope.static_stiffness",
                                    "ropes.rope.viscous_stiffness", "ropes.rope.viscous_damping",
                                    "ropes.rope.weight_per_length", "bodies.load.drag_area"])


def test_the_held_parameters_prior_moves_every_part_of_the_direction_together():
    tol = np.array([0.02, 1.1, 1.1, 0.5])
    cov = np.diag([0.0, 0.3, 0.2, 0.1]) ** 2  # 0 held (its row empty), 3 not in the direction
    out = gauge_covariance(cov, [0, 1, 2], 0, tol)
    assert out[0, 0] == pytest.approx(0.02**2) and out[0, 1] == out[1, 2] == pytest.approx(0.02**2)
    assert out[1, 1] == pytest.approx(0.3**2 + 0.02**2) and out[3, 3] == cov[3, 3] and out[0, 3] == 0.0
    assert cov[0, 1] == 0.0  # the input is not modified


def _response(a, b):
    return float(np.linalg.norm(a.states[:, :3] - b.states[:, :3]))


def test_on_the_slung_load_rig_the_whole_direction_is_a_rescaling_and_a_part_left_out_is_not():
    rig = load_rig(RIG)
    maneuver = default_maneuver(rig)
    params = rig.tolerances
    direction = scale_direction(params)

    def run(which):
        x = np.zeros(len(params))
        x[list(which)] = PROBE
        moved_rig, moved = apply_parameters(rig, maneuver, params, x)
        return simulate(moved_rig, moved, duration=4.0, rate_hz=50.0)

    base = run([])
    parts = [_response(run([i]), base) for i in direction]
    assert min(parts) > 0.0
    whole = _response(run(direction), base)
    assert is_pure_rescaling(whole, parts)
    assert whole < 1e-3 * SCALE_NULL * sum(parts)  # rounding, far below the threshold
    weight = next(i for i in direction if params[i].field == "weight_per_length")
    broken = _response(run([i for i in direction if i != weight]), base)
    assert not is_pure_rescaling(broken, parts)
    assert broken > 1e3 * SCALE_NULL * sum(parts)  # a part left out, far above it
