"""Property tests (Hypothesis) over every file reader, at the level of bytes.

Each reader starts from a real file of its kind (a VICON Nexus export, an
Optotrak C3D, a Pose2Sim TRC, a session's MCAP, a maneuver and a trajectory
CSV, a cameras.json, the rig TOML and a run config) and gets it back with
bytes overwritten, inserted, deleted or the file cut short, as a bad disk,
a partial copy or a hand edit would leave it. Property, whatever is drawn:
the reader returns, or raises ValueError with one line (never another
exception, never a crash of the process).

``DRAGLINE_BYTES_EXAMPLES`` raises the number of draws for a long run by hand.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import REPO

REAL = Path(__file__).parent / "data" / "real_exports"
EXAMPLES = settings(max_examples=int(os.environ.get("DRAGLINE_BYTES_EXAMPLES", 40)), deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _small_session(folder):
    from dragline.capture import CaptureSession, write_session

    rng = np.random.default_rng(0)
    trial = rng.uniform(0, 1280, (3, 60, 4, 2))
    trial[rng.random((3, 60, 4)) < 0.2] = np.nan
    session = CaptureSession(rate_hz=100.0, camera_names=["c1", "c2", "c3"], image_size=(1280, 960),
                             nominal_focal_px=1000.0, marker_names=[f"bucket.m{k}" for k in range(4)],
                             trial=trial, maneuver={"time": np.array([0.0, 1.0]),
                                                    "hoist_length": np.array([8.6, 9.0]),
                                                    "drag_length": np.array([4.2, 4.0])})
    return write_session(folder / "capture.mcap", session, chunk_size=2048)


def _readers(folder):
    """name -> (original bytes, reader of a path)."""
    from dragline.capture import read_session, read_vicon_csv
    from dragline.capture._c3d import read_c3d
    from dragline.capture._cameras import load_cameras, save_cameras
    from dragline.lab import default_lab_cameras
    from dragline.capture._trc import read_trc
    from dragline.compare import read_trajectory_table
    from dragline.pipelines._run import read_config
    from dragline.simulate import load_rig, read_maneuver_csv
    from importlib import resources

    save_cameras(folder / "cameras.json", default_lab_cameras(0)[:2])
    trajectories = (REPO / "samples" / "dig_sample_truth" / "trajectories.csv").read_bytes()
    (folder / "config.toml").write_text('[simulate]\ndiscretization = "low"\n[reconstruct]\nmax_gap = 5\n')
    return {
        "vicon_csv": ((REAL / "vicon_nexus_devices_and_trajectories_with_gaps.csv").read_bytes(), read_vicon_csv),
        "c3d": ((REAL / "optotrak_markers.c3d").read_bytes(), read_c3d),
        "trc": ((REAL / "pose2sim_static_trial.trc").read_bytes(), read_trc),
        "mcap": (Path(_small_session(folder)).read_bytes(), read_session),
        "maneuver_csv": ((REPO / "samples" / "dig_sample" / "maneuver.csv").read_bytes(), read_maneuver_csv),
        "trajectory_csv": (b"\n".join(trajectories.split(b"\n")[:40]), read_trajectory_table),
        "cameras_json": ((folder / "cameras.json").read_bytes(), load_cameras),
        "rig_toml": (resources.files("dragline.simulate").joinpath("data/rig.toml").read_bytes(), load_rig),
        "config_toml": ((folder / "config.toml").read_bytes(), read_config),
    }


@pytest.fixture(scope="module")
def readers(tmp_path_factory):
    return _readers(tmp_path_factory.mktemp("originals"))


EDITS = st.lists(st.tuples(st.sampled_from(["overwrite", "insert", "delete", "cut"]),
                           st.floats(0.0, 1.0), st.binary(min_size=1, max_size=8)), min_size=1, max_size=4)


def _edited(data, edits):
    data = bytearray(data)
    for op, where, chunk in edits:
        at = int(where * len(data))
        if op == "overwrite":
            data[at: at + len(chunk)] = chunk
        elif op == "insert":
            data[at:at] = chunk
        elif op == "delete":
            del data[at: at + len(chunk)]
        else:
            del data[at:]
    return bytes(data)


@pytest.mark.parametrize("kind", ["vicon_csv", "c3d", "trc", "mcap", "maneuver_csv", "trajectory_csv",
                                  "cameras_json", "rig_toml", "config_toml"])
@EXAMPLES
@given(edits=EDITS)
def test_a_damaged_file_is_read_or_refused_in_one_line(readers, tmp_path, kind, edits):
    original, read = readers[kind]
    path = tmp_path / f"input.{kind.rsplit('_', 1)[-1] if '_' in kind else kind}"
    path.write_bytes(_edited(original, edits))
    try:
        read(path)
    except ValueError as exc:
        assert "\n" not in str(exc).strip(), str(exc)


@pytest.mark.parametrize("kind", ["vicon_csv", "c3d", "trc", "mcap", "maneuver_csv", "trajectory_csv",
                                  "cameras_json", "rig_toml", "config_toml"])
def test_the_original_files_are_read(readers, tmp_path, kind):
    original, read = readers[kind]
    path = tmp_path / f"input.{kind.rsplit('_', 1)[-1] if '_' in kind else kind}"
    path.write_bytes(original)
    assert read(path) is not None
