"""The rig file schema: a hand-edited rig TOML refused at the door.

Each edit below once ended in a traceback (``start = 5``: AttributeError),
was accepted and made nonsense (``length = inf``, a negative or NaN mass, a
discretization row with a zero: 308 states instead of 350) or hung the
integrator (a dump rope of 1e-9 m). Each is one text edit of the built-in
rig file; every one must exit 2 with one line naming the file and the key.
"""

from __future__ import annotations

import re
from importlib import resources

import pytest

from conftest import REPO
from dragline.simulate import load_rig
from dragline.simulate._rig_schema import rig_markdown
from dragline.pipelines.cli import main

BUILT_IN = resources.files("dragline.simulate").joinpath("data/rig.toml").read_text()


@pytest.mark.parametrize("old, new, words", [
    ('start = "fixed.drag_reel"', "start = 5", ["ropes.drag_rope.start", "a string"]),
    ("length = 1.088", "length = inf", ["ropes.dump_rope.length", "finite"]),
    ("length = 1.088", "length = 1e-9", ["ropes.dump_rope.length", ">= 0.001"]),
    ("mass = 5.4975", "mass = -5.4975", ["bodies.bucket.mass", ">= 1e-06"]),
    ("mass = 5.4975", "mass = nan", ["bodies.bucket.mass", "finite"]),
    ("mass = 5.4975", 'mass = "5.4975"', ["bodies.bucket.mass", "a number"]),
    ("baseline = [6, 5, 12, 4, 2, 3]", "baseline = [0, 5, 12, 4, 2, 3]", ["discretization.baseline.0", ">= 1"]),
    ("baseline = [6, 5, 12, 4, 2, 3]", "baseline = [6, 5, 12, 4, 2]", ["discretization.baseline", "5 counts"]),
    ("viscous_damping = 53.0", "viscous_dampign = 53.0", ["ropes.dump_rope"]),
    ('rope = "drag_rope"', 'rope = "drag_ropes"', ["winches.drag.rope", "no such rope"]),
    ('rope = "drag_rope"', 'rope = "hoist_rope"', ["winches.drag.rope", "already paid out by winch 'hoist'"]),
    ('kind = "chain"', 'kind = "wire"', ["ropes.left_drag_chain.kind", "'chain'"]),  # a kind no mechanism knows
    ("g = 9.81", "g = -9.81", ["g = -9.81", "> 0"]),
    ("g = 9.81", "g = 0", ["g = 0", "> 0"]),  # weights per length became masses dividing by g: a traceback
    ("boom_pulley = [-5.314, 0.0, -4.1285]", "boom_pulley = [-5.314, 0.0]", ["fixed_points.boom_pulley"]),
])
def test_a_bad_rig_file_exits_2_naming_file_and_key(tmp_path, capsys, old, new, words):
    assert old in BUILT_IN
    bad = tmp_path / "rig.toml"
    bad.write_text(BUILT_IN.replace(old, new, 1))
    out = tmp_path / "t.csv"
    assert main(["simulate", "--rig", str(bad), "--duration", "0.1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0], err
    for word in words:
        assert word in err[0], err
    assert not out.exists()
    with pytest.raises(ValueError):
        load_rig(bad)


def test_an_unedited_copy_loads_as_the_built_in_rig(tmp_path):
    copy = tmp_path / "rig.toml"
    copy.write_text(BUILT_IN)
    a, b = load_rig(), load_rig(copy)
    assert a.ropes == b.ropes and a.discretization == b.discretization
    assert [p.name for p in a.tolerances] == [p.name for p in b.tolerances]


def test_the_docs_list_the_rig_schema_as_generated():
    doc = (REPO / "docs" / "schemas.md").read_text()
    block = re.search(r"<!-- generated: rig schema -->\n(.*?)<!-- end generated -->", doc, re.S).group(1)
    assert block == rig_markdown()
    assert "| `ropes.NAME.length` |" in block and "| `bodies.NAME.mass` |" in block


def test_the_docs_list_the_maneuver_schema_as_generated():
    from dragline.simulate._maneuver_schema import maneuver_markdown

    doc = (REPO / "docs" / "schemas.md").read_text()
    block = re.search(r"<!-- generated: maneuver schema -->\n(.*?)<!-- end generated -->", doc, re.S).group(1)
    assert block == maneuver_markdown()
    assert "| `lengths` |" in block and "<winch>_length" in block


def test_the_docs_list_the_trajectory_schema_as_generated():
    from dragline.simulate._table_schema import trajectory_markdown

    doc = (REPO / "docs" / "schemas.md").read_text()
    block = re.search(r"<!-- generated: trajectory schema -->\n(.*?)<!-- end generated -->", doc, re.S).group(1)
    assert block == trajectory_markdown()


def test_a_rig_document_whose_report_preset_is_none_loads_as_without_one():
    # a rig given as a dictionary (not TOML, which has no null): the schema allows None, the reader once failed
    import tomllib

    from dragline.simulate import rig_from_dict

    doc = tomllib.loads(BUILT_IN)
    doc.setdefault("report", {})["preset"] = None
    assert "preset" not in rig_from_dict(doc, "rig.toml").report
