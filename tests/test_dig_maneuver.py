"""The dig maneuver: the seed paper's text (section 4) read with its free choices (docs/model.md)."""

import json

import numpy as np
import pytest

from conftest import REPO
from dragline.simulate import dig_maneuver


def _speeds(man):
    return np.diff(man.lengths["hoist"]) / np.diff(man.time), np.diff(man.lengths["drag"]) / np.diff(man.time)


def test_the_literal_reading_is_the_texts_phases():
    """2.5 s, 1 s, 2 s, 1 s at the speeds the text gives; the phase-3 hoist and phase-4 drag from the end lengths."""
    man = dig_maneuver(2.5, 0.48, 0.0)
    np.testing.assert_allclose(man.time, [0.0, 2.5, 3.5, 5.5, 6.5], atol=1e-12)
    hoist, drag = _speeds(man)
    np.testing.assert_allclose(hoist, [0.36, 0.0, 0.30, 0.0], atol=1e-12)
    np.testing.assert_allclose(drag, [-0.30, -0.61, -0.48, -0.48], atol=1e-12)
    assert man.end_time == 6.5


@pytest.mark.parametrize("ramp_s", [0.0, 0.0567, 0.3])
@pytest.mark.parametrize("phase1_s, phase3_drag", [(2.5, 0.48), (2.3, 0.36), (2.6, 0.3)])
def test_every_reading_keeps_the_papers_lengths_and_stated_speeds(ramp_s, phase1_s, phase3_drag):
    man = dig_maneuver(phase1_s, phase3_drag, ramp_s)
    assert (man.lengths["hoist"][0], man.lengths["drag"][0]) == (pytest.approx(8.6, abs=1e-9), pytest.approx(4.2, abs=1e-9))
    assert (man.lengths["hoist"][-1], man.lengths["drag"][-1]) == (pytest.approx(10.1, abs=1e-9), pytest.approx(1.4, abs=1e-9))
    assert man.end_time == pytest.approx(phase1_s + 4.0 + ramp_s)
    hoist, drag = _speeds(man)
    drag4 = 4.2 - 1.4 - 0.30 * phase1_s - 0.61 - 2 * phase3_drag
    hoist3 = (10.1 - 8.6 - 0.36 * phase1_s) / 2
    # no reel faster than asked (to the rounding of differencing the 5 ms table)
    assert -drag.min() == pytest.approx(max(0.61, phase3_drag, drag4), abs=1e-8)
    assert hoist.max() == pytest.approx(max(0.36, hoist3), abs=1e-8) and hoist.min() >= -1e-8
    # Past each ramp the lengths are the stepped reading's, half a ramp late (a moving average of a line);
    # within a ramp the speed passes between the phases' speeds instead of stepping.
    stepped = dig_maneuver(phase1_s, phase3_drag, 0.0)
    edges = phase1_s + np.array([0.0, 1.0, 3.0])
    after = edges + ramp_s + 0.05
    for ramped_len, stepped_len in zip(man.lengths_at(after).values(), stepped.lengths_at(after - ramp_s / 2).values()):
        np.testing.assert_allclose(ramped_len, stepped_len, rtol=0, atol=1e-9)
    if ramp_s > 0:
        t = phase1_s + np.array([0.25, 0.75]) * ramp_s  # in the ramp from phase 1's drag speed to phase 2's
        speed = np.diff(man.lengths_at(t)["drag"]) / np.diff(t)
        assert -0.61 + 0.05 < speed[0] < -0.30 - 0.05


def test_a_reading_past_the_reels_speed_limit_is_refused():
    with pytest.raises(ValueError, match="phase-4 drag speed of -0.*outside 0-1.3 m/s"):
        dig_maneuver(2.5, 0.8, 0.0)  # the end length would need the drag paid out again
    with pytest.raises(ValueError, match="phase-4 drag speed of 1.4"):
        dig_maneuver(2.3, 0.05, 0.0)


def test_the_default_reading_is_the_identified_one():
    """The built-in dig is the reading tools/identify_paper_rig.py fitted (its record in samples/paper_rig)."""
    record = json.loads((REPO / "samples" / "paper_rig" / "identification.json").read_text())["identified"]
    values = record["parameters"]
    fitted = dig_maneuver(values["maneuver.phase1_s"], values["maneuver.phase3_drag_m_s"], values["maneuver.ramp_s"])
    built_in = dig_maneuver()
    np.testing.assert_array_equal(built_in.time, fitted.time)
    np.testing.assert_array_equal(built_in.lengths["drag"], fitted.lengths["drag"])
