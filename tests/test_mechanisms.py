"""Optional mechanisms: each only removes energy, and leaves the rest pose alone."""

import numpy as np
import pytest

from dragline.simulate import Maneuver, assemble, parse_physics, simulate, solve_statics

SPECS = [
    "rope_bending_damping:c=0.005",
    "chain_link_friction:mu=0.3",
    "pulley_friction:mu=0.1",
    "pulley_inertia:inertia=0.001",
    "aero_drag:cd=5",
]


@pytest.fixture(scope="module")
def pushed(rig):
    """End pose of the dig, everything pushed at 0.2 m/s along +x, reels still."""
    man = Maneuver([0.0], {"hoist": [10.1], "drag": [1.4]})
    model = assemble(rig, man, dissipation=False)
    eq = solve_statics(model)
    y0 = eq.state.copy()
    for b in range(model.n_bodies):
        y0[12 * b + 3] = 0.2
    y0[model.o_vel : model.o_force].reshape(-1, 3)[:, 0] = 0.2
    return man, y0, eq.state


@pytest.mark.parametrize("spec", SPECS)
def test_mechanism_only_removes_energy(rig, pushed, spec):
    man, y0, _ = pushed
    physics = [parse_physics(spec)]
    res = simulate(rig, man, physics=physics, dissipation=False, initial_state=y0, duration=0.05, rate_hz=1000)
    E = res.energy()
    conservative = simulate(rig, man, dissipation=False, initial_state=y0, duration=0.05, rate_hz=1000).energy()
    assert np.max(np.diff(E)) < 1e-4  # J: never a real gain (integration error near the step limit aside)
    if spec.startswith("pulley_inertia"):
        # Inertia stores energy, it does not dissipate it (RK4's own slight
        # dissipation once made this case pass a "dissipates" check; Verlet
        # conserves energy to 2e-6 J here).
        assert np.max(np.abs(E - E[0])) < 1e-4
        return
    assert E[-1] < E[0] - 1e-6  # it dissipates
    assert E[-1] < conservative[-1]


@pytest.mark.parametrize("spec", SPECS)
def test_mechanism_leaves_the_rest_pose_alone(rig, pushed, spec):
    man, _, rest = pushed
    res = simulate(rig, man, physics=[parse_physics(spec)], dissipation=False, initial_state=rest, duration=0.02, rate_hz=1000)
    assert np.abs(res.states[-1, :3] - rest[:3]).max() < 1e-9


def test_every_mechanism_kind_has_the_one_interface_and_only_switches_on_its_own_coefficients(rig):
    # One module each, one registry (simulate/_mechanisms): the parameter the
    # diagnosis fits is a numeric parameter with a unit and a plausible range
    # around its default, and applying the kind only sets coefficients that
    # are zero in the nominal model (the force assembly never changes).
    from dragline.simulate import MECHANISMS, make_mechanism
    from dragline.simulate._mechanisms import MechanismType

    modules = {type(kind).__module__ for kind in MECHANISMS.values()}
    assert len(modules) == len(MECHANISMS)
    nominal = assemble(rig, Maneuver([0.0], {"hoist": [8.6], "drag": [4.2]})).arrays
    for name, kind in MECHANISMS.items():
        assert isinstance(kind, MechanismType) and kind.name == name
        numeric = {k for k, v in kind.defaults.items() if not isinstance(v, str)}
        assert kind.main in numeric and set(kind.units) == numeric, name
        lo, hi = kind.range
        assert 0 < lo < hi, name
        with_it = assemble(rig, Maneuver([0.0], {"hoist": [8.6], "drag": [4.2]}), physics=[make_mechanism(name)]).arrays
        changed = [k for k in nominal if not np.array_equal(nominal[k], with_it[k])]
        assert changed, name
        for k in changed:
            if k in ("air_density", "has_joints", "has_ring_friction"):
                continue  # a constant of the drag law and the kernel's switches
            assert not np.any(nominal[k]), (name, k)
