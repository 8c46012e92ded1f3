"""The cameras.json schema: a hand-edited calibration refused at the door.

Each edit below once ended in a traceback (KeyError for a camera without
``K``, a reshape error for a short ``tvec``) or was accepted and made
nonsense (a negative focal length or a rotation vector of inf: every
reconstructed cell NaN). Every one must exit 2 with one line naming the
file, the camera and the field; an unedited file reads back as written.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from conftest import REPO
from dragline.capture._cameras import load_cameras, save_cameras
from dragline.capture._cameras_schema import cameras_markdown
from dragline.lab import default_lab_cameras
from dragline.pipelines.cli import main


@pytest.fixture(scope="module")
def cameras():
    return default_lab_cameras(0)


def _written(tmp_path, cameras, edit):
    path = tmp_path / "cameras.json"
    save_cameras(path, cameras)
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))  # json.dumps writes inf and nan as Infinity and NaN, as a hand edit might
    return path


def _camera(key, value, k=1):
    def edit(doc):
        doc["cameras"][k][key] = value
    return edit


def _drop(key, k=1):
    def edit(doc):
        del doc["cameras"][k][key]
    return edit


def _focal(value):
    def edit(doc):
        doc["cameras"][1]["K"][0][0] = value
    return edit


@pytest.mark.parametrize("edit, words", [
    (_drop("K"), ["'cam2'", "K", "missing"]),
    (_focal(-1500.0), ["'cam2'", "focal"]),
    (_focal("1500"), ["'cam2'", "K.0.0", "a number"]),
    (_camera("rvec", [float("inf"), 0.0, 0.0]), ["'cam2'", "rvec.0", "finite"]),
    (_camera("tvec", [0.0, 1.0]), ["'cam2'", "tvec", "3 items"]),
    (_camera("tvec", [0.0, 0.0, 1e9]), ["'cam2'", "tvec"]),
    (_camera("dist", [0.0] * 4), ["'cam2'", "dist", "5 items"]),
    (_camera("image_size", [1280, 0]), ["'cam2'", "image_size"]),
    (_camera("name", "cam1"), ["unique"]),
    (lambda doc: doc.update(cameras=doc["cameras"][:1]), ["cameras", "2 items"]),
    (lambda doc: doc.update(format="dragline.cameras/9"), ["not a dragline cameras file"]),
])
def test_a_bad_cameras_file_exits_2_naming_file_camera_and_field(tmp_path, capsys, cameras, edit, words):
    bad = _written(tmp_path, cameras, edit)
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0], err
    for word in words:
        assert word in err[0], err
    with pytest.raises(ValueError):
        load_cameras(bad)


def test_an_unedited_file_reads_back_as_written(tmp_path, cameras):
    back = load_cameras(_written(tmp_path, cameras, lambda doc: None))
    assert [c.name for c in back] == [c.name for c in cameras]
    for a, b in zip(back, cameras):
        for field in ("K", "dist", "rvec", "tvec"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_the_docs_list_the_cameras_schema_as_generated():
    doc = (REPO / "docs" / "schemas.md").read_text()
    block = re.search(r"<!-- generated: cameras schema -->\n(.*?)<!-- end generated -->", doc, re.S).group(1)
    assert block == cameras_markdown()
    assert "| `cameras[].K` |" in block and "| `cameras[].tvec` |" in block
