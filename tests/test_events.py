"""A marker file's labelled events, and the trial cut between two of them (``--between``).

Nexus writes events in a CSV's Events section and in a C3D's EVENT group
(minutes and seconds per event); both count time from the capture's start,
frame 1 at 0 s. The cut keeps the frames from the start event's to the end
event's, and the reconstruction of the cut must equal that of a file that
only ever held those frames.
"""

import dataclasses

import numpy as np
import pandas as pd
import pytest

from dragline.capture import between_events, event_frame, read_marker_file, write_c3d, write_vicon_csv
from dragline.pipelines.cli import main
from dragline.reconstruct import reconstruct_marker_file, vicon_name
from dragline.simulate import marker_positions, simulate

RATE = 200.0
# (context, name, time s): a second "Dump" after the first shows the cut ends at the first one after the start.
EVENTS = [("General", "Dig Start", 0.1), ("General", "Dump", 0.6), ("Left", "Dump", 0.05), ("General", "Dump", 0.8)]


def _events_section():
    rows = [f"Rig,{context},{name},{time:g}," for context, name, time in EVENTS]
    return "Events\n" + f"{RATE:g}\n" + "Subject,Context,Name,Time (s),Description\n" + "\n".join(rows) + "\n\n"


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """One second of the rig's true markers as a Nexus CSV with an Events section, and as a C3D with events."""
    import ezc3d

    root = tmp_path_factory.mktemp("events")
    result = simulate(duration=1.0, rate_hz=RATE)
    names, pos = marker_positions(result)
    labels = [vicon_name(n) for n in names]
    plain = root / "plain.csv"
    write_vicon_csv(plain, labels, pos, RATE)
    csv = root / "with_events.csv"
    csv.write_text(_events_section() + plain.read_text())
    write_c3d(root / "plain.c3d", labels, pos, RATE)
    c3d = ezc3d.c3d(str(root / "plain.c3d"))
    c3d.add_parameter("EVENT", "USED", len(EVENTS))
    c3d.add_parameter("EVENT", "CONTEXTS", [e[0] for e in EVENTS])
    c3d.add_parameter("EVENT", "LABELS", [e[1] for e in EVENTS])
    # TIMES holds minutes, then seconds (a test below writes 1 min 2.5 s)
    c3d.add_parameter("EVENT", "TIMES", np.array([[0.0] * len(EVENTS), [e[2] for e in EVENTS]]))
    c3d.write(str(root / "with_events.c3d"))
    return root, labels, pos


def test_events_are_read_from_a_nexus_csv_and_a_c3d(recording):
    root, _, _ = recording
    for name in ("with_events.csv", "with_events.c3d"):
        markers = read_marker_file(root / name)
        got = [(e["context"], e["name"], e["time_s"]) for e in markers.events]
        assert got == [(c, n, pytest.approx(t)) for c, n, t in EVENTS], name
    assert read_marker_file(root / "plain.csv").events == []


def test_a_c3d_event_time_is_minutes_and_seconds(tmp_path, recording):
    import ezc3d

    root, _, _ = recording
    c3d = ezc3d.c3d(str(root / "plain.c3d"))
    c3d.add_parameter("EVENT", "LABELS", ["Late"])
    c3d.add_parameter("EVENT", "TIMES", np.array([[1.0], [2.5]]))
    c3d.write(str(tmp_path / "late.c3d"))
    (event,) = read_marker_file(tmp_path / "late.c3d").events
    assert event["name"] == "Late" and event["time_s"] == pytest.approx(62.5) and event["context"] == ""


def test_the_cut_keeps_the_frames_from_start_to_the_first_end_after_it(recording):
    root, _, pos = recording
    markers = read_marker_file(root / "with_events.csv")
    before = markers.positions.copy()
    cut = between_events(markers, "Dig Start", "Dump")
    # frame 1 is 0 s: 0.1 s is frame 21 (row 20), 0.6 s frame 121 (row 120); the Left:Dump at 0.05 s is
    # before the start and the later Dump is not the first after it.
    assert (event_frame(markers, 0.1), event_frame(markers, 0.6)) == (20, 120)
    assert cut.frames == 101 and cut.first_frame == 21
    np.testing.assert_allclose(cut.positions, pos[20:121], atol=1e-8)  # the CSV holds 5 decimals of mm
    assert cut.info["cut"] == {"start": "Dig Start", "end": "Dump", "start_s": 0.1, "end_s": 0.6,
                               "frames": [21, 121]}
    np.testing.assert_array_equal(markers.positions, before)  # the input is not modified
    assert markers.first_frame == 1 and "cut" not in markers.info
    # CONTEXT:NAME picks one context's event
    assert between_events(markers, "General:Dig Start", "General:Dump").frames == 101


def test_an_event_the_file_does_not_hold_is_named_with_the_ones_it_does(recording):
    root, _, _ = recording
    markers = read_marker_file(root / "with_events.csv")
    with pytest.raises(ValueError, match=r"no event 'Foot Strike' in the file \(events: General:Dig Start, "
                                         r"General:Dump, Left:Dump\)"):
        between_events(markers, "Foot Strike", "Dump")
    with pytest.raises(ValueError, match="no event 'Dig Start' after the start event"):
        between_events(markers, "Dig Start", "Dig Start")
    late = {"subject": "", "context": "", "name": "Late", "time_s": 5.0, "description": ""}
    beyond = dataclasses.replace(markers, events=[*markers.events, late])
    with pytest.raises(ValueError, match=r"event 'Late' at 5 s is frame 1001, outside the file's frames 1-201"):
        between_events(beyond, "Dig Start", "Late")


def test_reconstruct_between_equals_a_file_that_held_only_those_frames(recording, tmp_path, capsys):
    root, labels, pos = recording
    out = tmp_path / "cut.csv"
    assert main(["reconstruct", str(root / "with_events.csv"), "--between", "Dig Start", "Dump",
                 "--out", str(out)]) == 0
    assert "kept frames 21-121, from event 'Dig Start' at 0.1 s to 'Dump' at 0.6 s" in capsys.readouterr().err
    write_vicon_csv(tmp_path / "only.csv", labels, pos[20:121], RATE)
    alone, _ = reconstruct_marker_file(tmp_path / "only.csv")
    table = pd.read_csv(out)
    assert len(table) == 101 and table["time"].iloc[0] == 0.0
    np.testing.assert_allclose(table.to_numpy(float), alone.to_numpy(float), atol=1e-9, equal_nan=True)
    # the C3D's events cut it the same way
    table_c3d, summary = reconstruct_marker_file(root / "with_events.c3d", between=("Dig Start", "Dump"))
    assert len(table_c3d) == 101 and summary["cut"]["frames"] == [21, 121]


def test_between_on_an_input_without_events_is_a_one_line_refusal(recording, tmp_path, capsys):
    root, _, _ = recording
    table = tmp_path / "measured.csv"
    assert main(["reconstruct", str(root / "plain.csv"), "--out", str(table), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(table), "--between", "A", "B", "--json", str(tmp_path / "d.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--between cuts a marker file" in err[0]
    assert main(["reconstruct", str(root / "plain.csv"), "--between", "A", "B", "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no event 'A' in the file (events: none)" in err[0]
    assert not (tmp_path / "d.json").exists() and not (tmp_path / "x.csv").exists()


def test_inspect_lists_the_events_as_between_takes_them(recording, capsys):
    root, _, _ = recording
    for name in ("with_events.csv", "with_events.c3d"):
        assert main(["inspect", str(root / name)]) == 0
        out = capsys.readouterr().out
        # the CSV names each event's subject; this C3D was written without EVENT:SUBJECTS
        expected = "event 0.1 s: General:Dig Start" + (" (subject Rig)" if name.endswith(".csv") else "\n")
        assert expected in out, out


def test_run_between_cuts_the_marker_file_it_reconstructs(recording, tmp_path, capsys):
    root, _, _ = recording
    out = tmp_path / "run"
    assert main(["run", str(root / "with_events.csv"), "--between", "Dig Start", "Dump", "--no-study",
                 "--no-diagnose", "--quiet", "--out", str(out)]) == 0
    measured = pd.read_csv(out / "measured.csv")
    cut, _ = reconstruct_marker_file(root / "with_events.csv", between=("Dig Start", "Dump"))
    assert len(measured) == 101
    np.testing.assert_allclose(measured.to_numpy(float), cut.to_numpy(float), atol=1e-9, equal_nan=True)
    capsys.readouterr()
    # the built-in session holds no events: refused before anything is made
    assert main(["run", "--between", "A", "B", "--out", str(tmp_path / "builtin")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the built-in session is not one" in err[0]
    assert not (tmp_path / "builtin").exists()
