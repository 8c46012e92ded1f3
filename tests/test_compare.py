"""Alignment, time offset, reel stop, per-channel verdicts and free decay (dragline.compare).

Most tests build trajectory tables here from closed-form signals whose
errors, peaks, offsets and decay rates are known by construction; a few run
the simulator (the nominal dig maneuver) for the real-data paths.
"""

import json
import math
import tomllib

import numpy as np
import pandas as pd
import pytest

from dragline.compare import (
    align_tables,
    compare_tables,
    discretization_study,
    estimate_time_offset,
    reels_stop_time,
)
from conftest import PAPER_PARAMETERS
from dragline.compare._compare import TOLERANCES, channel_kind, iso_grade
from dragline.compare._paper import DIG_PEAKS
from dragline.simulate import dig_maneuver, trajectory_columns

CHANNELS = trajectory_columns()[1:]
REEL_STOP = dig_maneuver().end_time  # the dig maneuver's: its reels stop with its table (6.44 s)


def first_sample_from(times, t):
    """The first of ``times`` at or after ``t``: where a sampled table first shows the reels stopped."""
    times = np.asarray(times, float)
    return float(times[np.searchsorted(times, t - 1e-9)])


def rope_lengths(t):
    """Dig-maneuver reel lengths plus a decaying swing after the stop (m)."""
    hoist, drag = (dig_maneuver().lengths_at(t)[w] for w in ("hoist", "drag"))
    tau = np.clip(t - REEL_STOP, 0.0, None)
    swing = 0.03 * np.sin(2 * np.pi * 0.6 * tau) * np.exp(-0.3 * tau)
    return hoist + 0.3 + swing, drag + 0.04 - 0.5 * swing


def synthetic_table(t, reel_columns=True):
    """A full trajectory table of smooth, distinct, non-periodic signals."""
    cols = {"time": t}
    rng = np.random.default_rng(7)  # fixed: only picks amplitudes and phases
    scale = {"position": 0.4, "angle": 0.5, "velocity": 0.5, "rate": 1.0}
    for ch in CHANNELS:
        kind = channel_kind(ch)
        if kind == "rope_length":
            continue
        a, f, phi = scale[kind] * rng.uniform(0.5, 1.0), rng.uniform(0.2, 0.9), rng.uniform(0, 6.28)
        cols[ch] = a * np.sin(2 * np.pi * f * t + phi) + 0.05 * a * t
    cols["hoist_rope.length"], cols["drag_rope.length"] = rope_lengths(t)
    if reel_columns:
        cols["hoist_rope.reel_length"], cols["drag_rope.reel_length"] = (dig_maneuver().lengths_at(t)[w] for w in ("hoist", "drag"))
    return pd.DataFrame(cols)


def shifted(table, offset):
    """The same motion recorded on a clock that reads ``offset`` s more."""
    out = table.copy()
    out["time"] = out["time"] + offset
    return out


T = np.round(np.arange(0.0, 10.0 + 1e-9, 0.02), 10)


@pytest.fixture(scope="module")
def pair():
    sim = synthetic_table(T)
    return sim.drop(columns=["hoist_rope.reel_length", "drag_rope.reel_length"]), sim


# -- time offset and alignment ---------------------------------------------


def test_identical_tables_have_zero_offset_and_zero_errors(pair):
    measured, simulated = pair
    out = compare_tables(measured, simulated)
    assert out["time_offset"]["offset"] == 0.0
    assert out["time_offset"]["applied"] == 0.0
    for ch in CHANNELS:
        e = out["channels"][ch]
        assert e["status"] == "ok" and e["rms_error"] == 0.0 and e["verdict"] == "pass", ch
    assert out["summary"] == {"n_channels": 50, "n_pass": 50, "n_fail": 0, "n_missing": 0}
    json.dumps(out, allow_nan=False)  # strict JSON


@pytest.mark.parametrize("offset", [0.3731, -1.117])
def test_offset_recovered_from_rope_lengths(offset):
    # The measurement's clock reads `offset` more for the same event; it is
    # sampled at its own instants (not on the simulation's grid).
    t_meas = np.round(np.arange(-2.0, 12.0, 0.02), 10) + offset
    measured = shifted(synthetic_table(t_meas - offset, reel_columns=False), offset)
    simulated = synthetic_table(T)
    est = estimate_time_offset(measured, simulated)
    assert est["estimated"] and not est["at_search_edge"]
    assert est["offset"] == pytest.approx(offset, abs=1e-3)
    assert est["cost"] < 1e-4 < est["cost_at_zero"]


def test_offset_survives_noise_and_rope_bias():
    offset = 0.4567
    rng = np.random.default_rng(1)
    measured = shifted(synthetic_table(T, reel_columns=False), offset)
    for ch, bias in (("hoist_rope.length", 0.05), ("drag_rope.length", -0.03)):
        measured[ch] = measured[ch] + bias + rng.normal(0.0, 0.003, len(T))
    est = estimate_time_offset(measured, synthetic_table(T))
    assert est["offset"] == pytest.approx(offset, abs=5e-3)
    assert est["ropes"]["hoist_rope.length"]["bias"] == pytest.approx(0.05, abs=2e-3)
    assert est["ropes"]["drag_rope.length"]["bias"] == pytest.approx(-0.03, abs=2e-3)


def test_offset_not_estimable_without_rope_lengths(pair):
    measured, simulated = pair
    est = estimate_time_offset(measured.drop(columns=["hoist_rope.length", "drag_rope.length"]), simulated)
    assert not est["estimated"] and est["offset"] == 0.0 and "rope-length" in est["reason"]


def test_shifted_measurement_compares_as_identical_after_alignment():
    offset = 0.25  # a whole number of samples: aligned values are exact
    measured = shifted(synthetic_table(T, reel_columns=False), offset)
    out = compare_tables(measured, synthetic_table(T))
    assert out["time_offset"]["applied"] == pytest.approx(offset, abs=1e-3)
    assert out["channels"]["bucket.x"]["rms_error"] < 1e-3
    assert out["time_base"]["start"] == pytest.approx(0.0, abs=1e-3)
    assert out["time_base"]["end"] == pytest.approx(10.0, abs=0.021)  # both cover 10 s of motion
    # Forcing no offset is honoured and the error shows.
    forced = compare_tables(measured, synthetic_table(T), time_offset=0.0)
    assert forced["time_offset"]["applied"] == 0.0 and forced["time_offset"]["source"] == "given"
    assert forced["time_offset"]["offset"] == pytest.approx(offset, abs=1e-3)  # still reported
    assert forced["channels"]["bucket.x"]["rms_error"] > 10 * out["channels"]["bucket.x"]["rms_error"]


def test_align_uses_the_coarser_rate_and_interpolates_linearly():
    t_m = np.arange(0.0, 5.0 + 1e-9, 0.01)
    t_s = np.arange(1.0, 7.0 + 1e-9, 0.005)
    measured = pd.DataFrame({"time": t_m, "bucket.x": 2.0 * t_m + 1.0})
    simulated = pd.DataFrame({"time": t_s, "bucket.x": -t_s})
    time, m, s = align_tables(measured, simulated, time_offset=0.5)
    # Measured clock shifted by -0.5 s: it covers -0.5 .. 4.5 s; overlap 1.0 .. 4.5 s at 0.01 s.
    assert time[0] == pytest.approx(1.0) and time[-1] == pytest.approx(4.5)
    assert np.allclose(np.diff(time), 0.01)
    assert np.allclose(m["bucket.x"], 2.0 * (time + 0.5) + 1.0)
    assert np.allclose(s["bucket.x"], -time)


def test_align_does_not_fill_gaps():
    t = np.arange(0.0, 1.0 + 1e-9, 0.1)
    y = t.copy()
    y[4] = np.nan
    table = pd.DataFrame({"time": t, "bucket.x": y})
    fine = pd.DataFrame({"time": np.arange(0.0, 1.0 + 1e-9, 0.05), "bucket.x": 0.0})
    time, m, _ = align_tables(table, fine)  # coarser step wins: 0.1 s
    assert np.isnan(m["bucket.x"][4]) and np.isfinite(m["bucket.x"][3]) and np.isfinite(m["bucket.x"][5])


# -- bad input ---------------------------------------------------------------


def test_no_common_channels_is_an_error(pair):
    measured, simulated = pair
    only_time = pd.DataFrame({"time": T, "something_else": 1.0})
    with pytest.raises(ValueError, match="no trajectory channel in common"):
        compare_tables(only_time, simulated)


def test_no_time_overlap_is_an_error(pair):
    measured, simulated = pair
    with pytest.raises(ValueError, match="do not overlap"):
        compare_tables(shifted(measured, 100.0), simulated)


def test_nan_only_channel_is_missing_not_silent(pair):
    measured, simulated = pair
    measured = measured.copy()
    measured["bucket.q"] = np.nan
    simulated = simulated.drop(columns=["spreader_bar.pitch"])
    out = compare_tables(measured, simulated)
    assert out["channels"]["bucket.q"] == {
        "status": "missing", "reason": "no finite samples in the measured table", "verdict": "missing"}
    assert out["channels"]["spreader_bar.pitch"]["reason"] == "not in the simulated table"
    assert out["summary"]["n_missing"] == 2 and out["summary"]["n_pass"] == 48
    q_row = next(r for r in out["peaks"] if r["channel"] == "bucket.q")
    assert q_row["measured"] is None and q_row["simulated"] is not None


def test_all_channels_nan_is_an_error(pair):
    measured, simulated = pair
    blank = measured.copy()
    blank[[c for c in blank.columns if c != "time"]] = np.nan
    with pytest.raises(ValueError, match="no channel has finite samples"):
        compare_tables(blank, simulated)


def test_bad_time_column_is_an_error(pair):
    measured, simulated = pair
    backwards = measured.iloc[::-1].reset_index(drop=True)
    with pytest.raises(ValueError, match="not strictly increasing"):
        compare_tables(backwards, simulated)
    with pytest.raises(ValueError, match="no 'time' column"):
        compare_tables(measured.drop(columns=["time"]), simulated)


# -- metrics, verdicts and the peak table by hand ----------------------------


@pytest.mark.parametrize(
    "channel, error, verdict",
    [
        ("bucket.x", 0.019, "pass"),
        ("bucket.x", 0.021, "fail"),
        ("bucket.pitch", math.radians(2.9), "pass"),
        ("bucket.pitch", math.radians(3.1), "fail"),
        ("bucket.vz", 0.09, "pass"),
        ("bucket.vz", 0.11, "fail"),
        ("bucket.q", 0.49, "pass"),
        ("drag_rope.length", 0.021, "fail"),
    ],
)
def test_constant_error_gives_rms_peak_and_verdict(pair, channel, error, verdict):
    # ``verdict`` is the RMS criterion alone (error against the tolerance).
    measured, simulated = pair
    simulated = simulated.copy()
    simulated[channel] = simulated[channel] + error
    # Offset fixed at zero so that a rope-length bias cannot move the clocks.
    out = compare_tables(measured, simulated, time_offset=0.0)
    e = out["channels"][channel]
    assert e["rms_error"] == pytest.approx(error, rel=1e-9)
    assert e["peak_error"] == pytest.approx(error, rel=1e-9)
    assert e["rms_tolerance"] == TOLERANCES[channel_kind(channel)]["rms"]
    assert e["rms_ok"] == (verdict == "pass")
    # The ISO rating can fail a channel within its RMS tolerance, never pass one outside it.
    assert e["verdict"] == ("pass" if e["rms_ok"] and e["iso_ok"] else "fail")
    if verdict == "fail":
        assert e["verdict"] == "fail"


def test_scaled_channel_sprague_geers_and_theil(pair):
    measured, simulated = pair
    simulated = simulated.copy()
    simulated["bucket.z"] = 1.2 * simulated["bucket.z"]
    e = compare_tables(measured, simulated, time_offset=0.0)["channels"]["bucket.z"]
    # s = 1.2 m: magnitude error 0.2, no phase error, U = 0.2 / 2.2.
    assert e["sg_magnitude"] == pytest.approx(0.2, rel=1e-9)
    assert e["sg_phase"] == pytest.approx(0.0, abs=1e-6)
    assert e["theil_u"] == pytest.approx(0.2 / 2.2, rel=1e-9)
    m = np.asarray(measured["bucket.z"])
    assert e["rms_error"] == pytest.approx(0.2 * math.sqrt(np.mean(m * m)), rel=1e-9)


def test_spreader_bar_offset_beside_the_papers(pair):
    measured, simulated = pair
    simulated = simulated.copy()
    simulated["spreader_bar.x"] = simulated["spreader_bar.x"] + 0.051
    out = compare_tables(measured, simulated, time_offset=0.0)["spreader_bar_x_offset"]
    assert out["mean_difference"] == pytest.approx(0.051, rel=1e-9) and out["paper"] == 0.051


def test_iso_rating_counts_only_on_channels_that_move():
    t = T
    table = synthetic_table(t, reel_columns=False)
    table["bucket.y"] = 1e-4 * np.sin(t)  # barely moves: rating is noise against noise
    other = table.copy()
    other["bucket.y"] = -1e-4 * np.sin(t)
    out = compare_tables(table, other, time_offset=0.0)
    e = out["channels"]["bucket.y"]
    assert not e["iso_applies"] and e["iso_grade"] == "poor" and e["verdict"] == "pass"
    assert out["channels"]["bucket.x"]["iso_applies"]


def test_iso_grades():
    assert [iso_grade(r) for r in (0.95, 0.94, 0.81, 0.8, 0.59, 0.58, None)] == [
        "excellent", "good", "good", "fair", "fair", "poor", None]


def test_peak_table_against_hand_built_extremes(pair):
    measured, simulated = pair
    measured, simulated = measured.copy(), simulated.copy()
    bump = lambda t0, height: height * np.exp(-0.5 * ((T - t0) / 0.05) ** 2)  # noqa: E731
    measured["bucket.vx"] = 0.1 * np.sin(T) + bump(6.2, 0.99)
    simulated["bucket.vx"] = 0.1 * np.sin(T) + bump(5.96, 1.01)
    measured["bucket.q"] = bump(6.78, -2.4)
    simulated["bucket.q"] = bump(6.78, -3.2)
    rows = {r["channel"]: r for r in compare_tables(measured, simulated, time_offset=0.0)["peaks"]}
    assert rows["bucket.vx"]["measured"]["time"] == pytest.approx(6.2)
    assert rows["bucket.vx"]["measured"]["value"] == pytest.approx(0.99 + 0.1 * math.sin(6.2))
    assert rows["bucket.vx"]["simulated"]["time"] == pytest.approx(5.96)
    assert rows["bucket.q"]["measured"]["value"] == pytest.approx(-2.4, abs=1e-3)
    assert rows["bucket.q"]["simulated"]["value"] == pytest.approx(-3.2, abs=1e-3)
    for ch, paper in DIG_PEAKS.items():
        assert rows[ch]["paper_measured"] == {"value": paper["measured"][0], "time": paper["measured"][1]}


def test_paper_numbers_match_the_transcription():
    dig = tomllib.loads(PAPER_PARAMETERS.read_text())["dig_maneuver"]
    for ch, key in (("bucket.vx", "vx"), ("bucket.vz", "vz"), ("bucket.q", "pitch_rate")):
        for side, paper_side in (("measured", "measured"), ("predicted", "predicted")):
            entry = dig[f"peak_{key}_{paper_side}"]
            assert DIG_PEAKS[ch][side] == (entry["value"], entry["time"])


def test_pitch_rate_note_measures_euler_minus_body_rate(pair):
    measured, simulated = pair
    measured, simulated = measured.copy(), simulated.copy()
    for table in (measured, simulated):
        table["bucket.p"] = 0.0
        table["bucket.yaw"] = 0.0
    measured["bucket.roll"] = 0.0
    simulated["bucket.roll"] = 0.2
    note = compare_tables(measured, simulated, time_offset=0.0)["pitch_rate"]
    q = np.asarray(simulated["bucket.q"])
    assert note["max_difference"]["measured"] == 0.0
    assert note["max_difference"]["simulated"] == pytest.approx(np.max(np.abs(q)) * (1 / math.cos(0.2) - 1), rel=1e-3)


# -- reel stop and free decay ------------------------------------------------


def test_reels_stop_from_reel_columns_and_from_rates(pair):
    measured, simulated = pair
    assert reels_stop_time(measured, simulated) == (pytest.approx(first_sample_from(T, REEL_STOP)),
                                                    "reel_length columns of the simulated table")
    stop, method = reels_stop_time(measured, measured)
    assert method == "rope-length rates of the measured table"
    assert stop == pytest.approx(REEL_STOP, abs=0.1)  # the accuracy ``reels_stop_time`` states for rates
    # A measured clock 1 s ahead: the stop is still reported on the simulation clock.
    stop_ahead, _ = reels_stop_time(shifted(measured, 1.0), measured, time_offset=1.0)
    assert stop_ahead == pytest.approx(stop, abs=0.02)


def test_reels_stop_of_the_simulated_dig_maneuver_from_rates(dig_baseline):
    table = dig_baseline.table
    assert reels_stop_time(table, table)[0] == pytest.approx(first_sample_from(table["time"], REEL_STOP))
    bare = table.drop(columns=["hoist_rope.reel_length", "drag_rope.reel_length"])
    stop, method = reels_stop_time(bare, bare)
    assert "rates" in method and stop == pytest.approx(REEL_STOP, abs=0.15)


def _swing(t, zeta, f_hz=0.7, amplitude=0.05, start=REEL_STOP):
    tau = np.clip(t - start, 0.0, None)
    wn = 2 * np.pi * f_hz / math.sqrt(1 - zeta**2)
    return amplitude * np.exp(-zeta * wn * tau) * np.cos(2 * np.pi * f_hz * tau)


def test_free_decay_says_how_much_faster_the_measurement_settles():
    t = np.round(np.arange(0.0, 16.0 + 1e-9, 0.01), 10)
    measured = synthetic_table(t, reel_columns=False)
    simulated = synthetic_table(t)
    measured["bucket.pitch"] = -0.3 + _swing(t, 0.08)
    simulated["bucket.pitch"] = -0.3 + _swing(t, 0.03)
    out = compare_tables(measured, simulated, time_offset=0.0)
    entry = out["free_decay"]["bucket.pitch"]
    assert entry["measured"]["damping_ratio"] == pytest.approx(0.08, rel=0.02)
    assert entry["simulated"]["damping_ratio"] == pytest.approx(0.03, rel=0.02)
    assert entry["measured"]["frequency_hz"] == pytest.approx(0.7, rel=0.01)
    diff = entry["difference"]
    assert diff["same_dominant_mode"]
    assert diff["damping_ratio_ratio"] == pytest.approx(0.08 / 0.03, rel=0.03)
    assert diff["frequency_shift"] == pytest.approx(0.0, abs=0.01)
    assert entry["measured"]["shape"] == "exponential"
    assert out["reels_stop"]["time"] == pytest.approx(first_sample_from(t, REEL_STOP))
    assert out["free_decay_summary"]["n_compared"] == len(out["free_decay"])


def test_free_decay_start_can_be_given(pair):
    measured, simulated = pair
    out = compare_tables(measured, simulated, free_decay_start=8.0)
    assert out["reels_stop"] == {"time": 8.0, "method": "given"}
    assert out["free_decay"]["bucket.x"]["measured"]["t_start"] == pytest.approx(8.0)


def test_nominal_against_itself_with_a_slower_start(dig_baseline):
    # A real simulated table against itself recorded 0.8 s early (the camera
    # started first): found, removed, nothing else differs.
    table = dig_baseline.table
    measured = shifted(table.drop(columns=["hoist_rope.reel_length", "drag_rope.reel_length"]), 0.8)
    out = compare_tables(measured, table)
    assert out["time_offset"]["applied"] == pytest.approx(0.8, abs=1e-3)
    assert out["summary"]["n_pass"] == 50
    assert out["channels"]["bucket.pitch"]["rms_error"] < 1e-3


def test_discretization_study_runs_the_model_per_level():
    study = discretization_study(levels=("low",), duration=0.5)
    run = study["low"]
    assert run["error"] is None and run["n_state"] > 0
    assert run["table"]["time"].iloc[-1] == pytest.approx(0.5)
    assert np.isfinite(run["table"]["bucket.pitch"]).all()


def test_discretization_study_levels_run_in_parallel_give_the_same_tables():
    serial = discretization_study(levels=("low", "baseline"), duration=0.3)
    parallel = discretization_study(levels=("low", "baseline"), duration=0.3, workers=2)
    assert list(parallel) == ["low", "baseline"]  # the caller's order, though the finest runs first
    assert serial["low"]["n_state"] < serial["baseline"]["n_state"]
    for level in ("low", "baseline"):
        assert parallel[level]["n_state"] == serial[level]["n_state"]
        pd.testing.assert_frame_equal(parallel[level]["table"], serial[level]["table"])
