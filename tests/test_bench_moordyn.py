"""The MoorDyn peer benchmark: the two codes model the same line (benchmarks/_moordyn_peer.py)."""

import numpy as np
import pytest

from dragline.simulate import assemble, solve_statics
from dragline.benchmarks._moordyn_peer import (
    AMPLITUDE,
    FAIRLEAD,
    FREQUENCY,
    G,
    LINE,
    MoorDynLine,
    _ours,
    line_maneuver,
    line_rig,
    time_to_error,
    to_moordyn,
)

PARTICLES = 12
STEP = 2.5e-4  # within RK4's stability bound for this line (about 2.56e-4 s), divides 1 ms


def test_time_to_error_inverts_a_power_law():
    walls = np.array([0.5, 1.0, 2.0, 4.0])
    errors = 3.0 * walls**-4  # a fourth-order method: error = C wall^-4
    t, bound = time_to_error(walls, errors, 3.0 * 1.5**-4)
    assert t == pytest.approx(1.5, rel=1e-12) and not bound


def test_time_to_error_flags_a_stability_bound_and_an_unreached_level():
    assert time_to_error([1.0, 2.0], [1e-3, 1e-4], 0.1) == (1.0, True)
    t, bound = time_to_error([1.0, 2.0], [np.inf, 5.0], 0.1)
    assert np.isnan(t) and not bound
    # a blown-up cheaper run does not take part in the interpolation
    assert time_to_error([1.0, 2.0, 4.0], [np.inf, 10.0, 0.01], 10.0) == (2.0, False)


def test_frames_and_smooth_drive():
    p = np.array([[0.3, -0.2, -1.0]])
    assert np.allclose(to_moordyn(to_moordyn(p)), p)
    assert to_moordyn(p + [0, 0, 0.5])[0, 2] == pytest.approx(to_moordyn(p)[0, 2] - 0.5)  # our K is down, MoorDyn's z up
    man = line_maneuver(4.0, table_dt=0.001, ramp=2.0)
    x = man.points["fairlead"][:, 0]
    v = np.diff(x) / 0.001
    assert x[0] == FAIRLEAD[0] and abs(v[0]) < 1e-6  # starts from rest
    t = man.time[2500:]
    assert np.allclose(x[2500:], FAIRLEAD[0] + AMPLITUDE * np.sin(2 * np.pi * FREQUENCY * t), atol=1e-12)


@pytest.fixture(scope="module")
def moordyn_line():
    pytest.importorskip("moordyn")
    # one set of instances for the module, closed at its end (MoorDyn misbehaves after a Close)
    with MoorDynLine(PARTICLES, ic_time=300.0) as md:
        md.equilibrium()
        yield md


def test_moordyn_line_has_our_mass_weight_and_stiffness(moordyn_line):
    md = moordyn_line
    s, line = md.start(STEP)
    md.md.Step(s, list(to_moordyn(FAIRLEAD)), [0.0, 0.0, 0.0], 0.0, STEP)  # masses are filled in by a step
    particle_mass = LINE["weight_per_length"] / G * LINE["length"] / PARTICLES
    assert md.md.GetLineN(line) == PARTICLES + 1
    assert md.md.GetLineConstantEA(line) == LINE["static_stiffness"] + LINE["viscous_stiffness"]
    assert md.md.GetLineUnstretchedLength(line) == LINE["length"]
    for i in range(1, PARTICLES + 1):
        assert np.allclose(md.md.GetLineNodeM(line, i), particle_mass * np.eye(3), rtol=1e-12, atol=0)
        assert np.allclose(md.md.GetLineNodeWeight(line, i), [0.0, 0.0, -particle_mass * G], rtol=1e-12, atol=0)


def test_node_positions_agree_after_one_second(moordyn_line):
    """Same ODE, same RK4, same step: only the starting difference may show.

    Each code starts from its own static solution; the dynamics may carry that
    difference around but add no more than 10 um of their own.
    """
    rig = line_rig(PARTICLES)
    man = line_maneuver(1.0, table_dt=0.001, ramp=0.5)
    model = assemble(rig, man, "baseline", dissipation=False)
    eq = solve_statics(model, 0.0)
    ours, _, _ = _ours(rig, man, eq.state, STEP, 1.0)
    theirs, _, _ = moordyn_line.run(STEP, man, "RK4", 1.0)
    start = np.abs(moordyn_line.equilibrium() - ours[0]).max()
    assert start < 1e-4  # both statics agree to 0.1 mm
    assert np.ptp(ours[:, -1, 0]) > 0.15  # the fairlead really moved
    tol = 2 * start + 1e-5
    assert np.abs(theirs[-1] - ours[-1]).max() < tol
    assert np.abs(theirs - ours).max() < tol


def test_without_moordyn_installed_the_comparison_is_skipped_with_what_to_install(monkeypatch):
    # MoorDyn is an optional extra: its absence skips the comparison, named, not the whole benchmark.
    import sys

    from dragline.benchmarks._simulator import moordyn_report, summary_lines

    monkeypatch.setitem(sys.modules, "moordyn", None)  # ``import moordyn`` now raises ImportError
    report = {"compile": {"compile_s": 1.0, "cold_first_call_s": 2.0}, "moordyn": moordyn_report()}
    assert "pip install -e '.[bench]'" in report["moordyn"]["skipped"]
    assert any(line.startswith("MoorDyn comparison skipped") for line in summary_lines(report))
