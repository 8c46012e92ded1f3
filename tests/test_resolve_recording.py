"""One resolver tells every command what a recording path is (capture.resolve_recording)."""

import pytest

from dragline.capture import resolve_recording

from conftest import REPO

SAMPLE = REPO / "samples" / "dig_sample"


def test_a_session_directory_and_its_mcap(tmp_path):
    r = resolve_recording(SAMPLE)
    assert (r.kind, r.file, r.directory, r.folder) == ("session", str(SAMPLE / "capture.mcap"), str(SAMPLE), str(SAMPLE))
    r = resolve_recording(SAMPLE / "capture.mcap")
    assert (r.kind, r.directory, r.folder) == ("session", None, str(SAMPLE))


def test_marker_files_and_trajectory_tables(tmp_path):
    (tmp_path / "markers.csv").write_text("Trajectories\n100\n")
    assert resolve_recording(tmp_path).kind == "markers"  # a folder with markers.csv only
    table = tmp_path / "measured.csv"
    table.write_text("time,bucket.x,bucket.z\n0,1,2\n")
    assert resolve_recording(table, tables=True).kind == "table"
    assert resolve_recording(table).kind == "markers"  # where tables are not recordings, the marker reader judges
    assert resolve_recording(tmp_path / "markers.csv", tables=True).kind == "markers"
    for ext in (".c3d", ".trc", ".C3D"):
        (tmp_path / f"m{ext}").write_bytes(b"")
        assert resolve_recording(tmp_path / f"m{ext}").kind == "markers"


def test_what_is_not_a_recording_is_named(tmp_path):
    with pytest.raises(ValueError, match=r"empty: session directory holds neither capture.mcap nor markers.csv"):
        (tmp_path / "empty").mkdir()
        resolve_recording(tmp_path / "empty")
    with pytest.raises(ValueError, match=r"nowhere.mcap: no such file or directory"):
        resolve_recording(tmp_path / "nowhere.mcap")
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match=r"notes.txt: expected a session directory, a .mcap session file, a "
                                         r"trajectory table or a marker file"):
        resolve_recording(tmp_path / "notes.txt", tables=True)
