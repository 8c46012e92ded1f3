"""Free-decay analysis on signals with known modes (dragline.compare._decay).

Envelope tests use decays generated here by integrating the three equations
of motion; their known parameters are the truth.
"""

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dragline.compare import dominant_mode, envelope_shape, free_decay, matrix_pencil

DT = 0.005


def damped(t, f_hz, zeta, amplitude=1.0, phase=0.3, offset=0.0):
    """``offset + A exp(-zeta w_n t) cos(w_d t + phase)``, f_hz the damped frequency."""
    wd = 2 * np.pi * f_hz
    wn = wd / math.sqrt(1.0 - zeta**2)
    return offset + amplitude * np.exp(-zeta * wn * t) * np.cos(wd * t + phase)


# -- matrix pencil ---------------------------------------------------------


@pytest.mark.parametrize("f_hz, zeta", [(0.7, 0.01), (1.5, 0.1), (3.0, 0.3)])
def test_matrix_pencil_noise_free_is_exact(f_hz, zeta):
    t = np.arange(0.0, 6.0, DT)
    modes = matrix_pencil(damped(t, f_hz, zeta, 0.8, 1.1, offset=0.2), DT)
    osc = [m for m in modes if m["frequency_hz"] > 0.1]
    const = [m for m in modes if m["frequency_hz"] == 0.0]
    assert len(osc) == 1 and len(const) == 1
    m = osc[0]
    assert m["frequency_hz"] == pytest.approx(f_hz, rel=1e-6)
    assert m["damping_ratio"] == pytest.approx(zeta, rel=1e-5)
    assert m["natural_frequency_hz"] == pytest.approx(f_hz / math.sqrt(1 - zeta**2), rel=1e-6)
    assert m["amplitude"] == pytest.approx(0.8, rel=1e-6)
    assert m["phase"] == pytest.approx(1.1, abs=1e-6)
    assert const[0]["amplitude"] == pytest.approx(0.2, rel=1e-6)
    assert const[0]["decay_rate"] == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize(
    "noise, zeta_tol",
    [(0.01, 0.05), (0.05, 0.20)],
)
def test_matrix_pencil_noisy_single_mode(noise, zeta_tol):
    # Noise std relative to the initial amplitude; five seeds per case.
    t = np.arange(0.0, 6.0, DT)
    for f_hz in (0.7, 1.5):
        for zeta in (0.01, 0.03, 0.1):
            for seed in range(5):
                rng = np.random.default_rng(seed)
                x = damped(t, f_hz, zeta, offset=0.2) + rng.normal(0.0, noise, t.size)
                freq, z, amp = dominant_mode(x, DT)
                case = (f_hz, zeta, seed)
                # Order selection keeps the noise out: one oscillation plus
                # the settling value, nothing else.
                assert len(matrix_pencil(x, DT)) == 2, case
                assert freq == pytest.approx(f_hz, rel=0.01), case
                assert z == pytest.approx(zeta, rel=zeta_tol), case
                assert amp == pytest.approx(1.0, rel=0.05), case


@pytest.mark.parametrize("noise, zeta_tol", [(0.0, 1e-5), (0.01, 0.05), (0.05, 0.20)])
def test_matrix_pencil_two_modes(noise, zeta_tol):
    t = np.arange(0.0, 8.0, DT)
    truth = [(0.8, 0.02, 1.0), (2.3, 0.05, 0.5)]
    for seed in range(3):
        x = sum(damped(t, f, z, a, phase=0.4 * i) for i, (f, z, a) in enumerate(truth))
        x = x + np.random.default_rng(seed).normal(0.0, noise, t.size)
        modes = [m for m in matrix_pencil(x, DT) if m["frequency_hz"] > 0.1][:2]
        modes.sort(key=lambda m: m["frequency_hz"])
        for m, (f, z, a) in zip(modes, truth):
            assert m["frequency_hz"] == pytest.approx(f, rel=0.01)
            assert m["damping_ratio"] == pytest.approx(z, rel=zeta_tol)
            assert m["amplitude"] == pytest.approx(a, rel=max(2 * noise, 1e-5))


def test_dominant_mode_picks_largest_oscillation():
    t = np.arange(0.0, 8.0, DT)
    x = damped(t, 0.8, 0.02, 0.3) + damped(t, 2.3, 0.05, 1.0)
    freq, zeta, amp = dominant_mode(x, DT)
    assert freq == pytest.approx(2.3, rel=1e-6)
    assert zeta == pytest.approx(0.05, rel=1e-5)
    assert amp == pytest.approx(1.0, rel=1e-6)


def test_dominant_mode_without_oscillation_is_nan():
    t = np.arange(0.0, 5.0, DT)
    assert all(math.isnan(v) for v in dominant_mode(1.0 + np.exp(-t), DT))


def test_given_model_order_and_block_averaging():
    # 10 s at 1 kHz is block-averaged before the SVD; the poles must survive.
    dt = 0.001
    t = np.arange(0.0, 10.0, dt)
    x = damped(t, 1.2, 0.04, offset=-1.2) + np.random.default_rng(7).normal(0.0, 0.01, t.size)
    modes = matrix_pencil(x, dt, n_modes=1)
    assert len(modes) == 2  # one oscillation plus the settling value
    osc = max(modes, key=lambda m: m["frequency_hz"])
    assert osc["frequency_hz"] == pytest.approx(1.2, rel=1e-3)
    assert osc["damping_ratio"] == pytest.approx(0.04, rel=0.05)
    settle = min(modes, key=lambda m: m["frequency_hz"])
    assert settle["amplitude"] == pytest.approx(1.2, rel=1e-3)
    assert settle["phase"] == pytest.approx(np.pi)  # a negative constant


def test_matrix_pencil_rejects_bad_input():
    with pytest.raises(ValueError):
        matrix_pencil(np.array([1.0, np.nan] * 10), DT)
    with pytest.raises(ValueError):
        matrix_pencil(np.zeros(20), -1.0)
    with pytest.raises(ValueError):
        matrix_pencil(np.zeros((20, 2)), DT)


# -- generated free decays -------------------------------------------------

F_HZ = 1.0
W = 2 * np.pi * F_HZ
ENV_DT = 0.01
ENV_T = np.arange(0.0, 15.0, ENV_DT)
X0 = 0.25  # released from rest at X0 (m)
ZETA = 0.02  # viscous
MU, G = 0.01, 9.81  # Coulomb: x'' + w^2 x + mu g sign(x') = 0
C_DRAG = 1.0  # quadratic: x'' + c |x'| x' + w^2 x = 0 (1/m)


def _integrate(rhs, t):
    sol = solve_ivp(rhs, (t[0], t[-1]), [X0, 0.0], t_eval=t, method="DOP853", rtol=1e-10, atol=1e-13)
    assert sol.success
    return sol.y[0]


def _coulomb(t):
    """Integrate the Coulomb oscillator half-cycle by half-cycle.

    Within a half-cycle sign(x') is constant, so the right-hand side is
    smooth; an event at x' = 0 ends it. At a turning point the mass sticks
    for good when the spring force cannot beat static friction,
    w^2 |x| <= mu g.
    """
    x = np.full(t.size, np.nan)
    t0, state = t[0], np.array([X0, 0.0])
    while t0 < t[-1]:
        if W**2 * abs(state[0]) <= MU * G:
            x[t >= t0] = state[0]
            break
        direction = -np.sign(state[0])  # the sign of x' over this half-cycle

        def rhs(_, u, d=direction):
            return [u[1], -(W**2) * u[0] - MU * G * d]

        def turn(_, u):
            return u[1]

        turn.terminal = True
        turn.direction = -direction  # x' returns through zero
        inside = t[(t >= t0)]
        sol = solve_ivp(
            rhs, (t0, t[-1]), state, events=turn, dense_output=True, method="DOP853",
            rtol=1e-11, atol=1e-13, first_step=1e-4,
        )
        t1 = sol.t_events[0][0] if sol.t_events[0].size else t[-1]
        seg = inside[inside <= t1]
        x[(t >= t0) & (t <= t1)] = sol.sol(seg)[0]
        t0, state = t1, np.array([sol.sol(t1)[0], 0.0])
    return x


@pytest.fixture(scope="module")
def decays():
    viscous = _integrate(lambda _, u: [u[1], -2 * ZETA * W * u[1] - W**2 * u[0]], ENV_T)
    quadratic = _integrate(lambda _, u: [u[1], -C_DRAG * abs(u[1]) * u[1] - W**2 * u[0]], ENV_T)
    return {"exponential": viscous, "linear": _coulomb(ENV_T), "hyperbolic": quadratic}


def test_coulomb_generator_loses_four_deltas_per_cycle(decays):
    # Independent check of the generator: each half-cycle the amplitude
    # about zero drops by 2 mu g / w^2 (energy argument).
    x = decays["linear"]
    first_min = np.min(x[ENV_T < 0.5 / F_HZ + 0.05])
    assert first_min == pytest.approx(-(X0 - 2 * MU * G / W**2), rel=1e-4)


@pytest.mark.parametrize("shape", ["exponential", "linear", "hyperbolic"])
@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_envelope_shape_classifies_generated_decays(decays, shape, noise):
    for seed in range(3 if noise else 1):
        rng = np.random.default_rng(seed)
        x = 0.3 + decays[shape] + rng.normal(0.0, noise * X0, ENV_T.size)
        r = envelope_shape(x, ENV_T)
        assert r["shape"] == shape, (seed, r["models"])
        assert r["confidence"] > 0.99, (seed, r["confidence"])
        assert r["n_extrema"] >= 20
        assert r["settling_value"] == pytest.approx(0.3, abs=0.1 * noise * X0 + 1e-4)
        assert r["frequency_hz"] == pytest.approx(F_HZ, rel=0.01)
        json.dumps(r, allow_nan=False)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_envelope_parameters_match_the_physics(decays, noise):
    rng = np.random.default_rng(11)
    fit = {
        shape: envelope_shape(x + rng.normal(0.0, noise * X0, ENV_T.size), ENV_T)["models"][shape]
        for shape, x in decays.items()
    }
    # Viscous: peaks decay exactly as exp(-zeta w_n t).
    assert fit["exponential"]["decay_rate"] == pytest.approx(ZETA * W, rel=0.01 + noise)
    # Coulomb: 4 mu g / w^2 lost per cycle, exactly.
    assert fit["linear"]["decrement_per_cycle"] == pytest.approx(4 * MU * G / W**2, rel=0.01 + noise)
    # Quadratic drag: first-order averaging, dA/dt = -(4 c w / 3 pi) A^2.
    kappa = 4 * C_DRAG * W / (3 * np.pi)
    assert fit["hyperbolic"]["quadratic_coefficient"] == pytest.approx(kappa, rel=0.03 + noise)


def test_envelope_without_decay_is_not_confident():
    # An undamped oscillation fits all three laws equally (zero rate).
    r = envelope_shape(np.cos(W * ENV_T), ENV_T)
    assert r["confidence"] < 0.5


def test_envelope_of_noise_or_constant_is_undetermined():
    r = envelope_shape(np.random.default_rng(3).normal(size=ENV_T.size), ENV_T)
    assert r["shape"] == "undetermined" and r["confidence"] is None
    assert envelope_shape(np.ones(ENV_T.size), ENV_T)["shape"] == "undetermined"


# -- free_decay ------------------------------------------------------------


@pytest.mark.parametrize("shape", ["exponential", "hyperbolic"])
def test_free_decay_after_the_reels_stop(decays, shape):
    # Ramp (reels running) until 6.5 s, then the generated free swing about
    # 0.65; a NaN gap before t_start must not matter.
    t = np.arange(0.0, 6.5 + ENV_T[-1], ENV_DT)
    before = t < 6.5 - 1e-9
    x = np.where(before, 0.1 * t, np.nan)
    x[~before] = 0.65 + decays[shape][: np.count_nonzero(~before)]
    x[50:60] = np.nan
    noisy = x + np.random.default_rng(5).normal(0.0, 0.005 * X0, t.size)
    r = free_decay(t, noisy, 6.5)
    json.dumps(r, allow_nan=False)
    assert r["t_start"] == pytest.approx(6.5)
    assert r["n_samples"] == np.count_nonzero(~before)
    assert r["shape"] == shape and r["confidence"] > 0.99
    assert r["settling_value"] == pytest.approx(0.65, abs=1e-3)
    if shape == "exponential":
        assert r["frequency_hz"] == pytest.approx(F_HZ * math.sqrt(1 - ZETA**2), rel=0.01)
        assert r["damping_ratio"] == pytest.approx(ZETA, rel=0.05)
        assert r["decay_rate"] == pytest.approx(ZETA * W, rel=0.02)
    else:
        assert r["frequency_hz"] == pytest.approx(F_HZ, rel=0.01)


def test_free_decay_rejects_window_without_data():
    t = np.arange(0.0, 5.0, DT)
    with pytest.raises(ValueError):
        free_decay(t, np.sin(t), 6.5)
