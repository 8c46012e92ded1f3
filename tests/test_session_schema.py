"""The session info schema: a hand-edited ``capture.mcap`` refused at the door.

Each edit below once ended in a traceback (KeyError for a missing
``rate_hz``, TypeError for a string rate) or sized an array from nonsense
(``markers = 10**9`` asked for 35 TiB). Every one must exit 2 with one line
naming the file and the field, quickly.
"""

from __future__ import annotations

import json

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from conftest import REPO
from dragline.capture import read_session
from dragline.capture._mcap_io import INFO_TOPIC
from dragline.pipelines.cli import main

SAMPLE = REPO / "samples" / "dig_sample" / "capture.mcap"
TRIAL_FRAMES = read_session(SAMPLE)[0].trial.shape[1]


def rewrite_info(src, dst, edit, topic=INFO_TOPIC):
    """Copy a session file with its info message (or every message on ``topic``) passed through ``edit``."""
    with open(src, "rb") as fin, open(dst, "wb") as fout:
        writer = Writer(fout)
        writer.start()
        schemas, channels = {}, {}
        for schema, channel, message in make_reader(fin).iter_messages():
            if schema is not None and schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas.get(channel.schema_id, 0))
            data = message.data
            if channel.topic == topic:
                data = json.dumps(edit(json.loads(data))).encode()
            writer.add_message(channels[channel.id], message.log_time, data, message.publish_time)
        writer.finish()
    return dst


def _drop(key):
    def edit(info):
        del info[key]
        return info
    return edit


def _set(*path_and_value):
    *path, value = path_and_value

    def edit(info):
        node = info
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
        return info
    return edit


@pytest.mark.parametrize("edit, field", [
    (_drop("rate_hz"), "rate_hz"),
    (_set("rate_hz", "100"), "rate_hz"),
    (_set("rate_hz", -100.0), "rate_hz"),
    (_set("nominal_focal_px", -1500.0), "nominal_focal_px"),
    (_set("image_size", [1280]), "image_size"),
    (_set("camera_names", ["only_one"]), "camera_names"),
    (_set("takes", "trial", "markers", 10**9), "takes.trial.markers"),
    (_set("takes", "trial", "frames", 10**7), "GiB"),
    (_set("lframe_points", [[0, 0, 0]]), "lframe_points"),
    (_drop("takes"), "takes"),
])
def test_a_bad_session_info_exits_2_naming_file_and_field(tmp_path, capsys, edit, field):
    bad = rewrite_info(SAMPLE, tmp_path / "capture.mcap", edit)
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and field in err[0], err
    with pytest.raises(ValueError, match="session info"):
        read_session(bad)


def test_an_unedited_copy_reads_as_the_original(tmp_path):
    copy = rewrite_info(SAMPLE, tmp_path / "capture.mcap", lambda info: info)
    a, _ = read_session(SAMPLE)
    b, _ = read_session(copy)
    assert a.rate_hz == b.rate_hz and a.marker_names == b.marker_names and a.trial.shape == b.trial.shape


@pytest.mark.parametrize("key", ["wand_rate_hz", "maneuver", "metadata"])
def test_an_optional_field_left_out_takes_its_default(tmp_path, key):
    """The schema lets these go; the reader indexed them (a fuzzed session without wand_rate_hz: KeyError)."""
    copy = rewrite_info(SAMPLE, tmp_path / "capture.mcap", _drop(key))
    session, _ = read_session(copy)
    assert session.trial.shape == read_session(SAMPLE)[0].trial.shape
    assert main(["inspect", "--json", str(copy)]) == 0
    assert main(["calibrate", str(copy), "--out", str(tmp_path / "cameras.json")]) == 0


def test_a_frame_number_typo_exits_2_without_sizing_an_array_from_it(tmp_path, capsys):
    # The last trial frame numbered 3000000 instead of its own: reconstruct once grew to 24 GB.
    last = {}

    def retype(msg):
        last.setdefault("seen", 0)
        last["seen"] += 1
        return dict(msg, frame=3_000_000) if msg["frame"] == TRIAL_FRAMES - 1 else msg

    bad = rewrite_info(SAMPLE, tmp_path / "capture.mcap", retype, topic="/trial/centroids")
    assert last["seen"] == TRIAL_FRAMES
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "frame numbers run outside" in err[0], err
