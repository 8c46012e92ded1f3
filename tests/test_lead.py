"""Whether a candidate's held-out lead is real (dragline.compare.diagnose._lead), on residuals built by hand.

The spread the test estimates from one record is checked against the
spread of the lead over many independent records of the same residual
process: the quantity the test claims to know.
"""

import numpy as np
import pytest
from scipy import stats

from dragline.compare.diagnose._problem import Problem
from dragline.compare.diagnose._lead import lead_tests
from dragline.compare.diagnose._model_error import MODEL_ERROR_FACTOR

DT = 0.005
TIME = np.arange(0.0, 20.0, DT)


def _problem(channels=2):
    # Unit noise level, no free-decay weighting: the weighted residual is the residual itself.
    return Problem(TIME, np.zeros((TIME.size, channels)), np.ones(channels), TIME[-1] + 1.0)


def _ar1(rng, phi, scale, channels=2):
    """AR(1) noise of unit marginal variance times ``scale`` (n,) per sample."""
    e = rng.normal(size=(TIME.size, channels)) * np.sqrt(1.0 - phi**2)
    x = np.empty_like(e)
    x[0] = rng.normal(size=channels)
    for k in range(1, TIME.size):
        x[k] = phi * x[k - 1] + e[k]
    return x * scale[:, None]


def _signature(where=None):
    s = np.stack([np.sin(2 * np.pi * 0.6 * TIME), np.cos(2 * np.pi * 0.9 * TIME)], axis=1)
    if where is not None:
        s = s * where[:, None]
    return s


def _spread_over_records(delta, phi, scale, n_records=300):
    """The lead's standard deviation over independent records: its random part is 2 delta . z."""
    rng = np.random.default_rng(7)
    return float(np.std([float((2.0 * delta * _ar1(rng, phi, scale)).sum()) for _ in range(n_records)]))


@pytest.mark.parametrize("phi", [0.0, 0.9])
def test_the_spread_from_one_record_is_the_spread_over_records(phi):
    rng = np.random.default_rng(3)
    scale = np.ones(TIME.size)
    delta = 0.05 * _signature()
    z = _ar1(rng, phi, scale)
    test = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"])["lead"]["rival"]
    truth = _spread_over_records(delta, phi, scale)
    assert test["sd"] == pytest.approx(truth, rel=0.15)
    assert test["lead"] == pytest.approx(float(((z + delta) ** 2 - z**2).sum()))
    assert test["t"] == pytest.approx(test["lead"] / test["sd"])
    assert test["critical"] == pytest.approx(stats.norm.ppf(0.99))


def test_a_stretch_of_large_error_is_read_against_its_own_spread():
    # The residual ten times larger in one stretch, where the rival's difference lives: the lead's spread
    # is that stretch's (a stationary model would put it at about a third of that).
    rng = np.random.default_rng(4)
    stretch = ((TIME >= 8.0) & (TIME < 11.0)).astype(float)
    scale = 1.0 + 9.0 * stretch
    delta = 0.05 * _signature(stretch)
    z = _ar1(rng, 0.5, scale)
    test = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"])["lead"]["rival"]
    truth = _spread_over_records(delta, 0.5, scale)
    assert test["sd"] == pytest.approx(truth, rel=0.2)
    stationary = 2.0 * np.sqrt(float((delta**2).sum()) * float(np.mean(z**2)))
    assert stationary < 0.5 * truth


def test_a_real_lead_is_consistent_and_an_equal_one_rarely():
    rng = np.random.default_rng(5)
    scale = np.ones(TIME.size)
    # The rival misses a signature the lead has: a lead of |delta|^2 = 2000 against a spread of 2 |delta|.
    delta = np.sqrt(2000.0 / float((_signature() ** 2).sum())) * _signature()
    z = _ar1(rng, 0.5, scale)
    test = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"])["lead"]["rival"]
    assert test["consistent"] and test["t"] > 5.0
    # Two candidates each missing a different signature of the same weight: equally close, the test at its
    # level (0.99) calls a lead in about 1 of 100 records.
    a = 0.05 * _signature()
    b = 0.05 * np.roll(_signature()[:, ::-1], 137, axis=0)
    b *= np.sqrt(float((a**2).sum()) / float((b**2).sum()))
    called = 0
    for k in range(40):
        z = _ar1(np.random.default_rng(100 + k), 0.5, scale)
        tests = lead_tests(_problem(), {"x": z + a, "y": z + b}, ["x", "y"], seed=k)
        called += tests["x"]["y"]["consistent"]
    assert called <= 3


def test_a_lead_the_finer_discretization_reverses_is_no_lead():
    # The lead's residual misses less than the rival's at this level; at the next finer one the roles turn (a law
    # whose discretized form happens to fit better here). The truth lies about MODEL_ERROR_FACTOR times as far
    # as the finer level: the test reads the lead between this level and there, and a lead the finer level
    # reverses is no lead.
    rng = np.random.default_rng(5)
    z = _ar1(rng, 0.5, np.ones(TIME.size))
    delta = np.sqrt(2000.0 / float((_signature() ** 2).sum())) * _signature()
    levels = {"lead": (z, z + 1.5 * delta), "rival": (z + delta, z)}  # (this level, the finer one)
    finer_chi2 = {name: tuple(float((r**2).sum()) for r in pair) for name, pair in levels.items()}
    plain = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"])["lead"]["rival"]
    tests = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"], finer_chi2=finer_chi2)
    test = tests["lead"]["rival"]
    shift = (finer_chi2["rival"][1] - finer_chi2["lead"][1]) - (finer_chi2["rival"][0] - finer_chi2["lead"][0])
    assert shift < -test["lead"]  # the finer level reverses the lead
    assert test["discretization_shift"] == pytest.approx(shift)
    assert test["sd_noise"] == pytest.approx(plain["sd"])
    assert test["converged_lead"] == pytest.approx(test["lead"] + MODEL_ERROR_FACTOR * shift / 2)
    assert test["converged_lead"] < 0
    assert test["sd"] == pytest.approx(np.hypot(plain["sd"], MODEL_ERROR_FACTOR * shift / 2))
    assert plain["consistent"] and not test["consistent"]
    # A shift known for one candidate only says nothing about the lead.
    alone = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"],
                       finer_chi2={"lead": finer_chi2["lead"]})["lead"]["rival"]
    assert alone["discretization_shift"] is None and alone["sd"] == pytest.approx(plain["sd"])


def test_a_lead_that_grows_at_the_finer_level_is_read_where_the_converged_model_puts_it():
    # A lead whose discretization error falls as h^p: at the finer level it grows by a quarter of itself (as
    # the right law's did in lead-test misses of the dragline's site benchmark). Its converged value,
    # lead + shift 2^p / (2^p - 1), lies in the interval the test reads for every order p >= 1, and a lead
    # read against a spread of the shift about this level alone (the rule before) is doubted for growing.
    rng = np.random.default_rng(8)
    z = _ar1(rng, 0.5, np.ones(TIME.size))
    delta = np.sqrt(2000.0 / float((_signature() ** 2).sum())) * _signature()
    lead = float(((z + delta) ** 2 - z**2).sum())
    growth = 0.25 * lead
    finer_chi2 = {"lead": (1000.0, 1000.0), "rival": (1000.0 + lead, 1000.0 + lead + growth)}
    plain = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"])["lead"]["rival"]
    test = lead_tests(_problem(), {"lead": z, "rival": z + delta}, ["lead", "rival"],
                      finer_chi2=finer_chi2)["lead"]["rival"]
    assert test["discretization_shift"] == pytest.approx(growth)
    half = MODEL_ERROR_FACTOR * growth / 2
    for p in (1, 2, 4):
        converged = lead + growth * 2**p / (2**p - 1)
        assert test["converged_lead"] - half - 1e-9 <= converged <= test["converged_lead"] + half + 1e-9
    assert test["consistent"] and test["t"] == pytest.approx(test["converged_lead"] / test["sd"])
    assert test["sd"] == pytest.approx(np.hypot(plain["sd"], half))
    symmetric = lead / np.hypot(plain["sd"], MODEL_ERROR_FACTOR * growth)
    assert symmetric < test["critical"]


def test_identical_residuals_lead_nowhere():
    z = np.random.default_rng(6).normal(size=(TIME.size, 2))
    test = lead_tests(_problem(), {"a": z, "b": z.copy()}, ["a", "b"])["a"]["b"]
    assert test["lead"] == 0.0 and test["sd"] == 0.0 and not test["consistent"]


def test_the_cosine_is_between_what_each_candidate_takes_off_the_base_residual():
    # Two candidates taking the same shape off the base at different sizes are alike (cosine 1) whatever their
    # lead; one taking the other channel's shape is not (cosine 0); the noise left in both does not enter.
    noise = np.random.default_rng(8).normal(size=(TIME.size, 2))
    shape = _signature()
    other = shape[:, ::-1] * np.array([1.0, -1.0])  # the channels swapped: orthogonal over whole periods
    base = noise + shape
    tests = lead_tests(_problem(), {"a": noise, "b": noise + 0.3 * shape, "c": noise + shape - other},
                       ["a", "b", "c"], base=base)
    assert tests["a"]["b"]["cosine"] == pytest.approx(1.0, abs=1e-12)
    expected = float(np.sum(shape * other) / (np.linalg.norm(shape) * np.linalg.norm(other)))
    assert abs(expected) < 1e-3 and tests["a"]["c"]["cosine"] == pytest.approx(expected, abs=1e-12)
    assert "cosine" not in lead_tests(_problem(), {"a": noise, "b": base}, ["a", "b"])["a"]["b"]


def test_the_held_out_residual_sums_to_the_held_out_score():
    rng = np.random.default_rng(8)
    measured = rng.normal(size=(TIME.size, 2)) + _signature()
    measured[100:140, 1] = np.nan  # an unmeasured stretch
    problem = Problem(TIME, measured, np.array([0.5, 2.0]), 8.0)
    sim_a, sim_b = 0.9 * _signature(), 1.1 * _signature()
    r = problem.held_out_residual(sim_a, sim_b)
    assert np.all(r[100:140, 1] == 0.0)
    assert float((problem.W * r * r).sum()) == pytest.approx(
        problem.evaluate(sim_a)["AB"] + problem.evaluate(sim_b)["BA"], rel=1e-12)
