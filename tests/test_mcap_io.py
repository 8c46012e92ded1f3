"""MCAP session and results files: exact round trips, truncation recovery, Foxglove layout.

Independent truth: the arrays written, the mcap package's own reader and
summary index (chunk offsets and times), and Hamilton quaternion algebra
implemented here.
"""

import json
import os

import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from dragline.compare._foxglove import quaternion_from_matrix, write_results
from dragline.capture._mcap_io import CaptureSession, read_session, summarize_mcap, write_session
from dragline.simulate import body_to_inertial

TAKE_TOPICS = {"lframe": "/calibration/lframe", "wand": "/calibration/wand",
               "trial": "/trial/centroids"}


def _with_nans(rng, arr):
    """Blank whole points and single coordinates, as occlusion and a half-seen blob would."""
    arr = arr.copy()
    arr[rng.random(arr.shape[:-1]) < 0.25] = np.nan
    arr[..., 1][rng.random(arr.shape[:-1]) < 0.03] = np.nan
    return arr


def make_session(seed=0, cams=3, frames=40, markers=5, wand_frames=30, lframe_frames=4,
                 calibration=True):
    rng = np.random.default_rng(seed)
    trial = _with_nans(rng, rng.uniform(0, 1280, (cams, frames, markers, 2)))
    # Values whose decimal form is long or extreme must survive too.
    trial[0, 0, 0] = [1 / 3, 2.0 ** -1074]
    trial[0, 0, 1] = [1e300, -0.0]
    kw = {}
    if calibration:
        kw = dict(wand=_with_nans(rng, rng.uniform(0, 1280, (cams, wand_frames, 2, 2))),
                  wand_rate_hz=100.0, wand_length=0.5 + rng.uniform(0, 1e-3),
                  lframe=_with_nans(rng, rng.uniform(0, 1280, (cams, lframe_frames, 4, 2))),
                  lframe_points=rng.normal(size=(4, 3)))
    t = np.linspace(0, 3, 7)
    return CaptureSession(
        rate_hz=200.0, camera_names=[f"cam{i}" for i in range(cams)], image_size=(1280, 960),
        nominal_focal_px=1111.5, marker_names=[f"bucket.m{i}" for i in range(markers)],
        trial=trial, maneuver={"time": t, "hoist_length": 2 + 0.1 * t,
                               "drag_length": np.r_[np.nan, 3 - 0.1 * t[1:]]},
        metadata={"operator": "synth", "seed": seed, "noise_px": [0.3, None]}, **kw)


def assert_same_session(a, b):
    for name in ("rate_hz", "nominal_focal_px", "wand_rate_hz", "wand_length"):
        assert getattr(a, name) == getattr(b, name), name
    assert list(a.camera_names) == b.camera_names and list(a.marker_names) == b.marker_names
    assert tuple(a.image_size) == b.image_size
    for name in ("trial", "wand", "lframe", "lframe_points"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert y.dtype == np.float64 and y.shape == x.shape, name
            # bit-exact, NaN where NaN (also keeps -0.0 and subnormals apart)
            assert np.array_equal(np.isnan(x), np.isnan(y)), name
            assert np.array_equal(np.nan_to_num(x).view(np.int64),
                                  np.nan_to_num(y).view(np.int64)), name
    assert a.maneuver.keys() == b.maneuver.keys()
    for k in a.maneuver:
        np.testing.assert_array_equal(a.maneuver[k], b.maneuver[k])
    assert a.metadata == b.metadata
    assert a.recorded_ns == b.recorded_ns


# ----------------------------------------------------------------- session round trips

def test_session_round_trip_is_exact(tmp_path):
    session = make_session()
    before = make_session()
    written = write_session(tmp_path, session)
    assert_same_session(before, session)  # the input is left as it was
    assert written == str(tmp_path / "capture.mcap")
    assert os.listdir(tmp_path) == ["capture.mcap"]  # no temporary file left behind
    back, report = read_session(tmp_path)
    assert_same_session(session, back)
    assert report["truncated"] is False and report["lost"] == "nothing"
    assert report["frames"] == {"lframe": 4, "wand": 30, "trial": 40}
    assert report["missing_takes"] == []
    assert back.recorded_ns is None  # not dated: stays undated


def test_a_dated_session_keeps_its_recording_time_to_the_nanosecond(tmp_path):
    when = 1_764_000_000_123_456_789  # beyond float64's integer precision: must not pass through a float
    session = CaptureSession(**{**make_session(seed=2).__dict__, "recorded_ns": when})
    write_session(tmp_path, session)
    back, _ = read_session(tmp_path)
    assert back.recorded_ns == when
    assert summarize_mcap(tmp_path)["session"]["recorded_at"] == "2025-11-24T16:00:00.123457+00:00"


def test_session_messages_follow_the_documented_layout(tmp_path):
    session = make_session(seed=1)
    path = write_session(tmp_path / "s.mcap", session)
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert {s.name: s.encoding for s in summary.schemas.values()} == {
            "dragline.SessionInfo": "jsonschema", "dragline.Centroids2D": "jsonschema"}
        assert {c.message_encoding for c in summary.channels.values()} == {"json"}
        msgs = {}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            msgs.setdefault(channel.topic, []).append(message)
    (info,) = [json.loads(m.data) for m in msgs["/session/info"]]
    assert info["camera_names"] == session.camera_names
    assert info["wand_length"] == session.wand_length
    assert info["lframe_points"] == session.lframe_points.tolist()
    trial_msgs = msgs["/trial/centroids"]
    assert len(trial_msgs) == 40
    t0 = trial_msgs[0].log_time
    for i, m in enumerate(trial_msgs):
        doc = json.loads(m.data)
        assert doc["frame"] == i
        assert m.log_time - t0 == round(i * 1e9 / 200.0)
        expect = session.trial[:, i]
        for c, cam in enumerate(doc["points"]):
            for k, p in enumerate(cam):
                u, v = expect[c, k]
                if np.isnan(u) and np.isnan(v):
                    assert p is None
                else:
                    assert p == [None if np.isnan(u) else u, None if np.isnan(v) else v]
    # takes follow each other on one clock: L-frame, wand, trial
    assert (msgs["/calibration/lframe"][-1].log_time < msgs["/calibration/wand"][0].log_time
            < msgs["/calibration/wand"][-1].log_time < t0)


def test_missing_calibration_takes_come_back_none(tmp_path):
    session = make_session(seed=2, calibration=False)
    write_session(tmp_path, session)
    back, report = read_session(tmp_path / "capture.mcap")
    assert back.wand is None and back.lframe is None and back.lframe_points is None
    assert_same_session(session, back)
    assert report["truncated"] is False
    assert report["missing_takes"] == ["lframe", "wand"]
    assert any("wand: not recorded" in n for n in report["notes"])


# ----------------------------------------------------------------- truncation

def _complete_chunk_cutoff(full_path, cut):
    """Latest message time among chunks lying wholly before byte ``cut``, by mcap's own index."""
    with open(full_path, "rb") as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    done = [c for c in chunks if c.chunk_start_offset + c.chunk_length <= cut]
    return max((c.message_end_time for c in done), default=None), chunks


def _log_times(full_path, topic):
    with open(full_path, "rb") as fh:
        return [m.log_time for _, _, m in make_reader(fh).iter_messages(topics=[topic])]


def test_truncated_file_recovers_every_complete_chunk(tmp_path):
    session = make_session(seed=3, cams=3, frames=300, markers=6, wand_frames=120)
    full = write_session(tmp_path / "full.mcap", session, chunk_size=4096)
    data = open(full, "rb").read()
    _, chunks = _complete_chunk_cutoff(full, len(data))
    assert len(chunks) > 10
    mid = chunks[len(chunks) // 2]
    cuts = [chunks[1].chunk_start_offset + 7,                 # inside the 2nd chunk
            chunks[2].chunk_start_offset,                     # on a record boundary
            chunks[len(chunks) // 3].chunk_start_offset + 100,
            mid.chunk_start_offset + mid.chunk_length // 2,
            chunks[-1].chunk_start_offset + chunks[-1].chunk_length - 1,
            len(data) - 30,                                   # inside the footer
            len(data) - 3]                                    # inside the closing magic
    times = {take: _log_times(full, topic) for take, topic in TAKE_TOPICS.items()}
    previous = -1
    for cut in cuts:
        cut_path = tmp_path / f"cut{cut}.mcap"
        cut_path.write_bytes(data[:cut])
        back, report = read_session(cut_path)
        last, _ = _complete_chunk_cutoff(full, cut)
        assert report["truncated"] is True, cut
        for take in TAKE_TOPICS:
            n = sum(t <= last for t in times[take])
            written = getattr(session, take)
            got = getattr(back, take)
            if take != "trial" and n == 0:
                assert got is None and take in report["missing_takes"]
                continue
            assert got.shape[1] == n, (cut, take)
            np.testing.assert_array_equal(got, written[:, :n])  # the prefix, exactly
            if n < written.shape[1]:
                assert f"{take} frames {n}-{written.shape[1] - 1}" in report["lost"]
        assert back.trial.shape[1] >= previous
        previous = back.trial.shape[1]
        assert_same_session(
            CaptureSession(**{**session.__dict__, "trial": back.trial, "wand": back.wand,
                              "lframe": back.lframe}), back)
    assert previous == 300  # the cut in the summary section loses no frame
    assert "no messages" in report["lost"]


def _frames_in(full, topic, chunk):
    """Frame numbers of ``topic`` logged inside ``chunk`` (by mcap's own reader and index)."""
    with open(full, "rb") as fh:
        return sorted(json.loads(m.data)["frame"] for _, _, m in make_reader(fh).iter_messages(topics=[topic])
                      if chunk.message_start_time <= m.log_time <= chunk.message_end_time)


def _corrupt(full, tmp_path, edits):
    data = bytearray(open(full, "rb").read())
    for at, value in edits:
        data[at] = value if value is not None else data[at] ^ 0xFF
    path = tmp_path / "bad.mcap"
    path.write_bytes(bytes(data))
    return path


def _assert_lost_exactly(session, back, lost_frames):
    """Every trial frame back as written, except ``lost_frames``, which are all NaN."""
    assert back.trial.shape == session.trial.shape
    keep = np.setdiff1d(np.arange(session.trial.shape[1]), lost_frames)
    np.testing.assert_array_equal(back.trial[:, keep], session.trial[:, keep])
    assert np.isnan(back.trial[:, lost_frames]).all()


@pytest.mark.parametrize("where", ["data", "crc", "length", "opcode"])
def test_a_corrupt_chunk_loses_that_chunk_alone(tmp_path, where):
    session = make_session(seed=8, frames=300)
    full = write_session(tmp_path / "full.mcap", session, chunk_size=4096)
    _, chunks = _complete_chunk_cutoff(full, 0)
    bad = chunks[len(chunks) // 2]
    start, end = bad.chunk_start_offset, bad.chunk_start_offset + bad.chunk_length
    edit = {"data": (end - 5, None),           # inside the compressed data: zstd or CRC fails
            "crc": (start + 9 + 24, None),     # the stored CRC of the uncompressed records
            "length": (start + 8, 0x7F),       # the record length: framing broken, read resyncs
            "opcode": (start, 0x2A)}[where]    # an opcode MCAP does not define
    back, report = read_session(_corrupt(full, tmp_path, [edit]))
    lost = _frames_in(full, "/trial/centroids", bad)
    assert 0 < len(lost) < 300
    _assert_lost_exactly(session, back, lost)
    assert report["truncated"] is False and report["error"] is None
    [entry] = report["lost_chunks"]
    assert entry["from_byte"] == start
    assert entry["to_byte"] >= end
    if where in ("data", "crc"):  # the framing held: the message indexes after it say what was lost
        assert entry["to_byte"] == end
        assert entry["messages"] == {"/trial/centroids": len(lost)}
        assert (entry["first_log_time_ns"], entry["last_log_time_ns"]) == (bad.message_start_time,
                                                                          bad.message_end_time)
    else:  # the lost stretch is bounded by the good chunks on either side
        before = chunks[len(chunks) // 2 - 1]
        assert entry["first_log_time_ns"] == before.message_end_time
        assert entry["last_log_time_ns"] >= bad.message_end_time
    assert "corrupt stretch skipped" in report["lost"] and f"bytes {start}-" in report["lost"]
    summary = summarize_mcap(tmp_path / "bad.mcap")
    assert summary["lost_chunks"] == report["lost_chunks"]
    assert "trial: %d frames missing" % len(lost) in " ".join(summary["session"]["notes"])


def test_two_corrupt_chunks_and_a_cut(tmp_path):
    session = make_session(seed=9, frames=400)
    full = write_session(tmp_path / "full.mcap", session, chunk_size=4096)
    _, chunks = _complete_chunk_cutoff(full, 0)
    a, b, c = chunks[len(chunks) // 3], chunks[len(chunks) // 2], chunks[-3]
    path = _corrupt(full, tmp_path, [(a.chunk_start_offset + a.chunk_length - 9, None),
                                     (b.chunk_start_offset + 3, 0xEE)])
    path.write_bytes(path.read_bytes()[: c.chunk_start_offset + 50])
    back, report = read_session(path)
    n = _frames_in(full, "/trial/centroids", c)[0]  # the cut ends the take there
    lost = [f for f in _frames_in(full, "/trial/centroids", a) + _frames_in(full, "/trial/centroids", b)]
    assert back.trial.shape[1] == n
    keep = np.setdiff1d(np.arange(n), lost)
    np.testing.assert_array_equal(back.trial[:, keep], session.trial[:, keep])
    assert np.isnan(back.trial[:, lost]).all()
    assert report["truncated"] is True and len(report["lost_chunks"]) == 2
    assert f"trial frames {n}-399" in report["lost"]


def test_garbage_after_the_last_chunk_keeps_every_frame(tmp_path):
    session = make_session(seed=10, frames=120)
    full = write_session(tmp_path / "full.mcap", session, chunk_size=4096)
    data = open(full, "rb").read()
    _, chunks = _complete_chunk_cutoff(full, 0)
    end = chunks[-1].chunk_start_offset + chunks[-1].chunk_length
    path = tmp_path / "bad.mcap"
    path.write_bytes(data[:end] + bytes(range(32, 250)) * 4)  # 0x20: no MCAP opcode
    back, report = read_session(path)
    np.testing.assert_array_equal(back.trial, session.trial)
    assert report["truncated"] is True and "unreadable record after byte" in report["error"]


def test_cut_inside_first_chunk_has_no_session_info(tmp_path):
    full = write_session(tmp_path / "full.mcap", make_session(seed=4, frames=200),
                         chunk_size=4096)
    _, chunks = _complete_chunk_cutoff(full, 0)
    for cut in (8, 20, chunks[0].chunk_start_offset + chunks[0].chunk_length - 1):
        p = tmp_path / "cut.mcap"
        p.write_bytes(open(full, "rb").read()[:cut])
        with pytest.raises(ValueError, match="no session info"):
            read_session(p)


@pytest.mark.parametrize("content", [b"", b"\x89MCA", b"time,bucket.x\n0,1\n" * 50])
def test_not_mcap_is_a_one_line_value_error(tmp_path, content):
    p = tmp_path / "capture.mcap"
    p.write_bytes(content)
    with pytest.raises(ValueError, match="not an MCAP file") as err:
        read_session(p)
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="not an MCAP file"):
        summarize_mcap(p)


def test_missing_file_and_results_file_are_value_errors(tmp_path):
    with pytest.raises(ValueError, match="no such"):
        read_session(tmp_path / "nope.mcap")
    with pytest.raises(ValueError, match="no such"):
        read_session(tmp_path)  # a directory without capture.mcap
    results = write_results(tmp_path / "r.mcap", {"measured": _table(5)})
    with pytest.raises(ValueError, match="no session info"):
        read_session(results)


@pytest.mark.parametrize("change, message", [
    (dict(trial=np.zeros((2, 5, 5, 2))), "trial has shape"),
    (dict(wand=np.zeros((3, 5, 3, 2))), "wand has shape"),
    (dict(wand_length=None), "wand_length"),
    (dict(lframe_points=None), "lframe_points"),
    (dict(rate_hz=0.0), "rate_hz"),
    (dict(image_size=(1280,)), "image_size"),
    (dict(marker_names=["a", "a", "b", "c", "d"]), "marker_names"),
    (dict(metadata={"truth_dir": "/tmp/x"}), "reveal"),
    (dict(metadata={"note": "made with pulley_friction:mu=0.1"}), "mechanism"),
    (dict(recorded_ns=-1), "recorded_ns"),
    (dict(recorded_ns=1.7e18), "recorded_ns"),
])
def test_bad_sessions_are_refused_and_leave_no_file(tmp_path, change, message):
    target = tmp_path / "capture.mcap"
    target.write_bytes(b"previous")
    session = make_session(seed=5)
    bad = CaptureSession(**{**session.__dict__, **change})
    with pytest.raises(ValueError, match=message):
        write_session(target, bad)
    assert target.read_bytes() == b"previous"
    assert os.listdir(tmp_path) == ["capture.mcap"]


# ----------------------------------------------------------------- summary

def test_summary_of_a_session(tmp_path):
    session = make_session(seed=6)
    path = write_session(tmp_path, session, chunk_size=4096)
    s = summarize_mcap(tmp_path)
    json.dumps(s, allow_nan=False)
    counts = {c["topic"]: c["messages"] for c in s["channels"]}
    assert counts == {"/session/info": 1, "/calibration/lframe": 4, "/calibration/wand": 30,
                      "/trial/centroids": 40}
    trial = next(c for c in s["channels"] if c["topic"] == "/trial/centroids")
    assert trial["schema"] == "dragline.Centroids2D"
    assert trial["last_time_s"] - trial["first_time_s"] == pytest.approx(39 / 200.0)
    assert s["truncated"] is False
    info = s["session"]
    assert info["cameras"] == session.camera_names and info["markers"] == session.marker_names
    assert info["frames"] == {"lframe": 4, "wand": 30, "trial": 40}
    assert info["rate_hz"] == 200.0 and info["wand_rate_hz"] == 100.0
    for take in ("trial", "wand"):
        arr = getattr(session, take)
        for c, cam in enumerate(session.camera_names):
            assert info["unseen_fraction"][take][cam] == pytest.approx(
                np.isnan(arr[c]).any(axis=-1).mean())
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(open(path, "rb").read()[: os.path.getsize(path) * 2 // 3])
    s = summarize_mcap(cut)
    assert s["truncated"] is True and s["session"]["frames"]["trial"] < 40
    assert "trial frames" in s["lost"]


# ----------------------------------------------------------------- quaternions

def _qmul(a, b):
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], -1)


def _rotate(q, v):
    qv = np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], -1)
    conj = q * np.array([-1, -1, -1, 1])
    return _qmul(_qmul(q, qv), conj)[..., :3]


def test_quaternion_rotates_like_body_to_inertial():
    rng = np.random.default_rng(7)
    n = 400
    roll = rng.uniform(-1.5, 1.5, n)
    pitch = rng.uniform(-np.pi, np.pi, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    # pitch -52 deg (the paper's start) and half turns about each axis (every branch)
    roll[:4], pitch[:4], yaw[:4] = [0.1, np.pi, 0, 0], [np.radians(-52), 0, np.pi, 0], \
        [0.2, 0, 0, np.pi]
    T = body_to_inertial(roll, pitch, yaw)
    q = quaternion_from_matrix(T)
    assert q.shape == (n, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    assert (q[:, 3] >= 0).all()
    v = rng.normal(size=(n, 3))
    np.testing.assert_allclose(_rotate(q, v), np.einsum("nij,nj->ni", T, v), atol=1e-12)
    conj = q * np.array([-1, -1, -1, 1])
    np.testing.assert_allclose(_rotate(conj, v), np.einsum("nji,nj->ni", T, v), atol=1e-12)
    # half turn about J: the axis (0, 1, 0) up to sign
    np.testing.assert_allclose(np.abs(q[2]), [0, 1, 0, 0], atol=1e-12)


def test_quaternion_keeps_leading_shape_and_nan():
    T = body_to_inertial(np.zeros((2, 3)), 0.3, 0.0)
    T[1, 2, 0, 0] = np.nan
    q = quaternion_from_matrix(T)
    assert q.shape == (2, 3, 4)
    assert np.isnan(q[1, 2]).all() and np.isfinite(q[0]).all()
    np.testing.assert_allclose(q[0, 0], [0, np.sin(0.15), 0, np.cos(0.15)], atol=1e-15)


# ----------------------------------------------------------------- results for Foxglove

def _table(n, dt=0.01, t0=0.0, seed=0, drag_angles=True):
    rng = np.random.default_rng(seed)
    cols = {"time": t0 + dt * np.arange(n)}
    for body in ("bucket", "spreader_bar", "hoist_cluster", "drag_cluster"):
        for k in "xyz":
            cols[f"{body}.{k}"] = rng.normal(size=n)
        for k in ("roll", "pitch", "yaw"):
            cols[f"{body}.{k}"] = rng.uniform(-1, 1, n)
    if not drag_angles:
        for k in ("roll", "pitch", "yaw"):
            cols[f"drag_cluster.{k}"] = np.nan
    return pd.DataFrame(cols)


def _read_results(path):
    """Summary and (schema, channel, message, decoded protobuf) per message, in file order."""
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        out = list(reader.iter_decoded_messages(log_time_order=False))
    return summary, out


def _xyz(v):
    return [v.x, v.y, v.z]


def test_results_file_is_foxglove_shaped(tmp_path):
    measured = _table(12, dt=0.005, seed=1, drag_angles=False)
    measured.loc[3, "bucket.x"] = np.nan  # bucket lost for one frame
    simulated = _table(7, dt=0.01, t0=0.001, seed=2)
    rng = np.random.default_rng(3)
    markers = rng.normal(size=(12, 5, 3))
    markers[2, 1] = np.nan
    rope = rng.normal(size=(7, 9, 3))
    start = 1_764_000_000_123_456_789  # 2025-11-24, ns since the epoch
    path = write_results(tmp_path / "results.mcap", {"measured": measured, "simulated": simulated},
                         markers={"measured": markers}, ropes={"simulated/hoist_rope": rope}, start_ns=start)
    summary, msgs = _read_results(path)

    # Foxglove's own schemas, protobuf-encoded: the decoder builds each message type from the file's schema.
    assert {s.name for s in summary.schemas.values()} == {
        "foxglove.FrameTransforms", "foxglove.SceneUpdate", "foxglove.PointCloud"}
    assert {s.encoding for s in summary.schemas.values()} == {"protobuf"}
    assert {c.topic for c in summary.channels.values()} == {
        "/measured/transforms", "/measured/scene", "/measured/markers",
        "/simulated/transforms", "/simulated/scene"}
    assert {c.message_encoding for c in summary.channels.values()} == {"protobuf"}
    log_times = [m.log_time for _, _, m, _ in msgs]
    assert log_times == sorted(log_times)  # sources interleaved in time order

    tables = {"measured": measured, "simulated": simulated}
    seen = {"transforms": 0, "scene": 0, "markers": 0}
    for schema, channel, message, doc in msgs:
        source, kind = channel.topic.strip("/").split("/")
        table = tables[source]
        i = int(np.argmin(np.abs(table["time"].to_numpy() - (message.log_time - start) / 1e9)))
        t_ns = start + round(table["time"][i] * 1e9)
        assert message.log_time == t_ns
        stamp = (t_ns // 10**9, t_ns % 10**9)
        seen[kind] += 1
        assert doc.DESCRIPTOR.full_name == schema.name
        if kind == "transforms":
            children = set()
            up, *bodies = doc.transforms
            # the display frame: world half a turn about x, so that z is up
            assert (up.parent_frame_id, up.child_frame_id) == ("world_z_up", "world")
            assert (up.timestamp.seconds, up.timestamp.nanos) == stamp and _xyz(up.translation) == [0.0, 0.0, 0.0]
            down = np.array([0.0, 0.0, 1.0])  # world's K, pointing down
            q = np.array([getattr(up.rotation, k) for k in "xyzw"])
            np.testing.assert_allclose(_rotate(q, down[None])[0], [0.0, 0.0, -1.0], atol=1e-15)
            for tf in bodies:
                assert (tf.timestamp.seconds, tf.timestamp.nanos) == stamp and tf.parent_frame_id == "world"
                body = tf.child_frame_id.split("/")[1]
                children.add(tf.child_frame_id)
                assert _xyz(tf.translation) == [table[f"{body}.{k}"][i] for k in "xyz"]
                q = np.array([getattr(tf.rotation, k) for k in "xyzw"])
                T = body_to_inertial(*(table[f"{body}.{k}"][i] for k in ("roll", "pitch", "yaw")))
                np.testing.assert_allclose(_rotate(q, np.eye(3)), T.T, atol=1e-12)
            expected = {f"{source}/{b}" for b in ("bucket", "spreader_bar", "hoist_cluster",
                                                   "drag_cluster")}
            if source == "measured":
                expected.discard("measured/drag_cluster")  # no orientation: no frame
                if i == 3:
                    expected.discard("measured/bucket")
            assert children == expected
        elif kind == "scene":
            ents = {e.id: e for e in doc.entities}
            for e in ents.values():
                assert (e.timestamp.seconds, e.timestamp.nanos) == stamp and e.frame_id == "world"
            if source == "measured" and i == 3:
                assert "measured/bucket" not in ents
                (gone,) = doc.deletions
                assert (gone.timestamp.seconds, gone.timestamp.nanos) == stamp and gone.id == "measured/bucket"
                assert gone.type == 0  # MATCHING_ID
            else:
                (cube,) = ents[f"{source}/bucket"].cubes
                assert _xyz(cube.size) == [0.381, 0.203, 0.152]
                assert _xyz(cube.pose.position) == [table[f"bucket.{k}"][i] for k in "xyz"]
                assert 0.0 < cube.color.a <= 1.0
            if source == "measured":
                (sphere,) = ents["measured/drag_cluster"].spheres
                assert len(ents["measured/drag_cluster"].cubes) == 0
                assert _xyz(sphere.pose.position) == [table[f"drag_cluster.{k}"][i] for k in "xyz"]
            else:
                (line,) = ents["simulated/hoist_rope"].lines
                assert line.type == 0  # LINE_STRIP
                assert [_xyz(p) for p in line.points] == rope[i].tolist()
        else:
            assert (doc.timestamp.seconds, doc.timestamp.nanos) == stamp and doc.frame_id == "world"
            fields = {f.name: f for f in doc.fields}
            assert set(fields) == set("xyz") and all(f.type == 8 for f in fields.values())  # FLOAT64
            raw = doc.data
            n = len(raw) // doc.point_stride
            pts = np.array([[np.frombuffer(raw, "<f8", 1, j * doc.point_stride + fields[k].offset)[0]
                             for k in "xyz"] for j in range(n)]).reshape(n, 3)
            want = markers[i][np.isfinite(markers[i]).all(axis=1)]
            np.testing.assert_array_equal(pts, want)
    assert seen == {"transforms": 19, "scene": 19, "markers": 12}

    s = summarize_mcap(path)
    json.dumps(s, allow_nan=False)
    assert s["session"] is None and s["truncated"] is False
    by_topic = {c["topic"]: c for c in s["channels"]}
    assert by_topic["/simulated/scene"]["schema"] == "foxglove.SceneUpdate"
    assert by_topic["/measured/markers"]["messages"] == 12
    assert by_topic["/simulated/transforms"]["first_time_s"] == pytest.approx(start / 1e9 + 0.001, abs=1e-6)


def _results_metadata(path):
    with open(path, "rb") as fh:
        return {m.name: m.metadata for m in make_reader(fh).iter_metadata()}["dragline"]


def test_results_log_times_are_dated_from_the_recording_start_or_now(tmp_path):
    import time
    from datetime import datetime

    start = 1_764_000_000 * 10**9
    path = write_results(tmp_path / "dated.mcap", {"measured": _table(3)}, start_ns=start)
    meta = _results_metadata(path)
    assert datetime.fromisoformat(meta["log_time_origin"]).timestamp() == 1_764_000_000
    assert meta["log_time_origin_source"] == "the recording's start"
    assert "world_z_up" in meta["display_frame"]
    _, msgs = _read_results(path)
    assert min(m.log_time for _, _, m, _ in msgs) == start  # the table's first row is at time 0
    before = time.time_ns()
    path = write_results(tmp_path / "now.mcap", {"measured": _table(3)})
    after = time.time_ns()
    meta = _results_metadata(path)
    assert before <= datetime.fromisoformat(meta["log_time_origin"]).timestamp() * 1e9 <= after + 1e6
    assert "not known" in meta["log_time_origin_source"]
    _, msgs = _read_results(path)
    assert before <= min(m.log_time for _, _, m, _ in msgs) <= after
    with pytest.raises(ValueError, match="start_ns must be"):
        write_results(tmp_path / "bad.mcap", {"measured": _table(3)}, start_ns=-5)


@pytest.mark.parametrize("kwargs, message", [
    (dict(tables={}), "at least one"),
    (dict(tables={"bad name": _table(3)}), "source name"),
    (dict(tables={"measured": _table(3).drop(columns="time")}), "time"),
    (dict(tables={"measured": _table(3, dt=-0.1, t0=1.0)}), "non-decreasing"),
    (dict(tables={"measured": _table(3)}, markers={"measured": np.zeros((4, 2, 3))}), "shape"),
    (dict(tables={"measured": _table(3)}, markers={"simulated": np.zeros((3, 2, 3))}),
     "no table"),
    (dict(tables={"a": _table(3), "b": _table(3)}, ropes={"hoist": np.zeros((3, 4, 3))}),
     "<source>/<rope>"),
])
def test_bad_results_input_is_refused(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        write_results(tmp_path / "r.mcap", **kwargs)
    assert os.listdir(tmp_path) == []
