"""Property tests (Hypothesis) over the declared input schemas.

Each structured input starts from a real, valid document (the built-in rig
file, the sample session's info message, a cameras.json written by
``save_cameras``, a full run config) and has one of its fields replaced by a
drawn value. Properties, whatever is drawn:

- the reader either accepts the document or raises ValueError with one
  line that names the file (never another exception);
- a number replaced by a string, a boolean, a list or an object, or
  by NaN or infinity, is refused;
- an accepted document builds what the reader builds (a rig, cameras).

Free-form fields (a session's ``metadata``, a calibration's ``quality``,
the maneuver columns of a session, where null stands for NaN) are left out
of the numeric properties.
"""

from __future__ import annotations

import copy
import json
import math
import os
import tomllib
from importlib import resources

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from conftest import REPO
from dragline.capture._cameras import Camera, save_cameras
from dragline.capture._cameras_schema import check_cameras_doc
from dragline.lab import default_lab_cameras
from dragline.capture._mcap_io import INFO_TOPIC
from dragline.capture._session_schema import check_session_info
from dragline.pipelines._config_schema import validate_config
from dragline.simulate import dig_maneuver, rig_from_dict
from dragline.simulate._maneuver import maneuver_from_columns
from dragline.simulate._table_schema import check_trajectory_columns
from dragline.simulate._rig_schema import check_rig_doc

PATH = "lab/input.file"
FREE_FORM = ("metadata", "quality", "maneuver", "tolerances", "tolerance_groups")
# 150 draws per property and input kind in CI; DRAGLINE_PROPERTY_EXAMPLES raises it for a long local run.
EXAMPLES = settings(max_examples=int(os.environ.get("DRAGLINE_PROPERTY_EXAMPLES", 150)), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _rig_doc():
    return tomllib.loads(resources.files("dragline.simulate").joinpath("data/rig.toml").read_text())


def _session_info():
    with open(REPO / "samples" / "dig_sample" / "capture.mcap", "rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages(topics=[INFO_TOPIC]):
            return json.loads(message.data)


def _cameras_doc(tmp_path_factory):
    path = tmp_path_factory.mktemp("cams") / "cameras.json"
    save_cameras(path, default_lab_cameras(0))
    return json.loads(path.read_text())


def _config_doc():
    return {"run": {"seed": 3, "study": True, "diagnose": False},
            "simulate": {"discretization": "medium"},
            "reconstruct": {"method": "svd", "smoothing": "none", "max_gap": 5}}


def _maneuver_doc():
    m = dig_maneuver()
    return {"time": m.time.tolist(), "hoist_length": m.lengths["hoist"].tolist(), "drag_length": m.lengths["drag"].tolist(),
            "points": {"boom_pulley": [[-5.35, 0.0, -4.06]] * m.time.size}}


def _load_rig(doc):
    check_rig_doc(doc, PATH)
    return rig_from_dict(doc, PATH)


def _load_cameras(doc):
    check_cameras_doc(doc, PATH)
    return [Camera.from_dict(c) for c in doc["cameras"]]


READERS = {
    "rig": _load_rig,
    "session": lambda doc: check_session_info(doc, PATH),
    "cameras": _load_cameras,
    "config": lambda doc: validate_config(doc, PATH),
    "maneuver": lambda doc: maneuver_from_columns(doc, PATH),
    "trajectory": lambda doc: check_trajectory_columns(doc, PATH),
}


@pytest.fixture(scope="module")
def documents(tmp_path_factory):
    return {"rig": _rig_doc(), "session": _session_info(), "cameras": _cameras_doc(tmp_path_factory),
            "config": _config_doc(), "maneuver": _maneuver_doc(),
            "trajectory": {"time": [0.0, 0.01, 0.02, 0.03], "channels": {"bucket.x": [0.1, None, 0.12, 0.13],
                                                                      "bucket.pitch": [0.0, 0.01, 0.02, 0.01]}}}


def _leaves(node, path=()):
    """(path, value) of every scalar in a JSON-like document."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _leaves(v, path + (i,))
    else:
        yield path, node


def _replaced(doc, path, value):
    out = copy.deepcopy(doc)
    node = out
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return out


def _numeric_leaves(doc):
    return [p for p, v in _leaves(doc) if isinstance(v, (int, float)) and not isinstance(v, bool)
            and not any(str(k) in FREE_FORM for k in p)]


ANY_VALUE = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-10**20, max_value=10**20),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
    st.lists(st.floats(min_value=-10, max_value=10), max_size=4), st.dictionaries(st.text(max_size=3), st.integers(),
                                                                                  max_size=2))
NOT_A_NUMBER = st.one_of(st.booleans(), st.text(max_size=8), st.just([1.0]), st.just({"a": 1}),
                         st.sampled_from([math.nan, math.inf, -math.inf]))


def _outcome(kind, doc):
    """None when the reader accepts the document, else its one-line message; any other exception fails."""
    try:
        READERS[kind](doc)
    except ValueError as exc:
        message = str(exc)
        assert "\n" not in message and PATH in message, message
        return message
    return None


@pytest.mark.parametrize("kind", sorted(READERS))
def test_the_unedited_document_is_accepted(documents, kind):
    assert _outcome(kind, documents[kind]) is None


@pytest.mark.parametrize("kind", sorted(READERS))
@EXAMPLES
@given(data=st.data())
def test_any_value_anywhere_is_accepted_or_refused_in_one_line(documents, kind, data):
    doc = documents[kind]
    path, _ = data.draw(st.sampled_from(list(_leaves(doc))))
    _outcome(kind, _replaced(doc, path, data.draw(ANY_VALUE)))


@pytest.mark.parametrize("kind", sorted(READERS))
@EXAMPLES
@given(data=st.data())
def test_a_number_replaced_by_a_non_number_is_refused(documents, kind, data):
    doc = documents[kind]
    path = data.draw(st.sampled_from(_numeric_leaves(doc)))
    value = data.draw(NOT_A_NUMBER)
    assert _outcome(kind, _replaced(doc, path, value)) is not None, (path, value)


@pytest.mark.parametrize("kind", sorted(READERS))
@EXAMPLES
@given(data=st.data())
def test_a_key_removed_or_added_is_accepted_or_refused_in_one_line(documents, kind, data):
    doc = copy.deepcopy(documents[kind])
    dicts = [doc] + [v for _, v in _walk_dicts(doc)]
    node = data.draw(st.sampled_from(dicts))
    if node and data.draw(st.booleans()):
        del node[data.draw(st.sampled_from(sorted(node, key=str)))]
    else:
        node[data.draw(st.text(min_size=1, max_size=6))] = data.draw(ANY_VALUE)
    _outcome(kind, doc)


def _walk_dicts(node, path=()):
    if isinstance(node, dict):
        for k, v in node.items():
            if isinstance(v, dict):
                yield path + (k,), v
            yield from _walk_dicts(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _walk_dicts(v, path + (i,))
