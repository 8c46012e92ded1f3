"""Whether a candidate's held-out lead is real (dragline.compare.diagnose._lead) on losses built by hand."""

import math

import numpy as np
import pytest
from scipy import stats

from dragline.compare.diagnose._lead import LEAD_BATCH_S, lead_test


def test_the_statistic_is_the_lead_over_its_newey_west_spread_worked_by_hand():
    # Four batches whose differences sum to 1, 2, 3, 6: centred -2, -1, 0, 3. Bandwidth
    # floor(4 (4/100)^(2/9)) = 1 lag: variance 14/4 + 2 (1 - 1/2) (2/4) = 4.0; t = 12 / sqrt(4 x 4) = 3.
    time = np.arange(4) * LEAD_BATCH_S
    test = lead_test(time, np.zeros(4), np.array([1.0, 2.0, 3.0, 6.0]))
    assert test["batches"] == 4 and test["bandwidth"] == 1
    assert test["lead"] == pytest.approx(12.0)
    assert test["t"] == pytest.approx(3.0)
    assert test["critical"] == pytest.approx(stats.t.ppf(0.99, 3))  # 4.54: four batches cannot decide it
    assert not test["consistent"]


def test_a_small_lead_the_whole_record_holds_is_consistent():
    rng = np.random.default_rng(1)
    time = np.arange(0.0, 14.0, 0.005)
    rival = rng.chisquare(1, time.size) + 0.3  # a rival worse by 30 % of the noise's chi2 at every sample
    lead = rng.chisquare(1, time.size)
    test = lead_test(time, lead, rival)
    assert test["batches"] == 14
    assert test["consistent"] and test["t"] > test["critical"]


def test_a_large_lead_that_one_stretch_gives_is_not():
    # The same noise, the rival worse only in one second, by as much as the whole record's lead above.
    rng = np.random.default_rng(1)
    time = np.arange(0.0, 14.0, 0.005)
    rival = rng.chisquare(1, time.size)
    lead = rng.chisquare(1, time.size)
    rival[(time >= 6.0) & (time < 7.0)] += 0.3 * 14
    test = lead_test(time, lead, rival)
    assert test["lead"] > 0.9 * 0.3 * time.size
    assert not test["consistent"]


def test_identical_losses_lead_nowhere():
    time = np.arange(0.0, 5.0, 0.01)
    loss = np.ones(time.size)
    test = lead_test(time, loss, loss)
    assert test["lead"] == 0.0 and not test["consistent"]
    assert math.isfinite(test["critical"])
