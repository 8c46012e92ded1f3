"""The comparison report PDF: determinism, pages, and what the pages say (dragline.compare._report).

The PDF is read back with pypdf (text of each page). Tables are built here
from closed-form signals, so the numbers the report must print are known.
The built-in run's own report is read back in ``test_pipeline_run.py``.
"""

import math

import numpy as np
import pytest

from dragline.compare import compare_tables, write_report
from dragline.compare._paper import FIG21_CAPTION, FIGURES

from conftest import REPORT_PAGES_WITHOUT_STUDY, pages_text, synthetic_table

pypdf = pytest.importorskip("pypdf")

T = np.round(np.arange(0.0, 10.0 + 1e-9, 0.02), 10)


@pytest.fixture(scope="module")
def case():
    measured = synthetic_table(T, reel_columns=False)
    simulated = synthetic_table(T)
    bump = np.exp(-0.5 * ((T - 6.2) / 0.1) ** 2)
    measured["bucket.vx"] = 0.99 * bump
    simulated["bucket.vx"] = 1.2 * bump
    measured["bucket.q"] = np.nan  # a channel the measurement lacks
    study_table = simulated.copy()
    study_table["bucket.pitch"] = study_table["bucket.pitch"] + 0.01
    study = {
        "low": {"table": study_table, "n_state": 133, "error": None},
        "high": {"table": None, "n_state": None, "error": "simulation blew up at t = 6.4450 s: a speed above 100 m/s"},
    }
    metrics = compare_tables(measured, simulated, study=study)
    return measured, simulated, metrics, study


@pytest.fixture(scope="module")
def report(case, tmp_path_factory):
    path = tmp_path_factory.mktemp("report") / "report.pdf"
    measured, simulated, metrics, study = case
    write_report(path, measured, simulated, metrics, study=study, sources={"measured": "m.csv", "simulated": "s.csv"})
    return path


def test_identical_inputs_give_a_byte_identical_pdf(case, report, tmp_path):
    measured, simulated, metrics, study = case
    again = tmp_path / "again.pdf"
    write_report(again, measured, simulated, metrics, study=study, sources={"measured": "m.csv", "simulated": "s.csv"})
    first, second = report.read_bytes(), again.read_bytes()
    assert first[:5] == b"%PDF-" and first == second
    assert b"CreationDate" not in first and b"ModDate" not in first
    assert list(tmp_path.iterdir()) == [again]  # no temporary file left behind


def test_page_count_and_figure_captions(report):
    text = pages_text(report)
    assert len(text) == REPORT_PAGES_WITHOUT_STUDY + 1
    everything = "\n".join(text)
    for label, _, caption, _ in FIGURES:
        assert f"Fig. {label}." in everything, label
        assert caption.split(" of ")[0] in everything.replace("\n", " "), label
    assert "Fig. 21." in text[-1] and FIG21_CAPTION[:40] in text[-1]
    assert "Pitch angle (deg)" in everything and "Pitch rate (deg/s)" in everything


def test_summary_page_numbers(case, report):
    measured, simulated, metrics, _ = case
    summary = pages_text(report)[1]
    assert "Measured: m.csv" in summary and "Simulated: s.csv" in summary
    # Paper's peak table beside ours: bump peaks 0.990 at 6.20 s and 1.200 at 6.20 s.
    assert "+0.990 @ 6.20 s" in summary and "+1.200 @ 6.20 s" in summary
    assert "+1.010 @ 5.95 s" in summary and "-2.400 @ 6.77 s" in summary and "-3.200 @ 6.77 s" in summary
    n = metrics["summary"]
    assert f"{n['n_pass']} of {n['n_channels']} channels within tolerance" in summary
    assert "Time offset (measured clock - simulation clock): estimated +0.0000 s" in summary
    # bucket.vx: residual 0.21 bump -> RMS by hand.
    rms = 0.21 * math.sqrt(np.mean(np.exp(-((T - 6.2) / 0.1) ** 2)))
    assert f"{rms:.3g} m/s" in summary
    assert "RMS <= 20 mm" in summary and "RMS <= 3 deg" in summary
    assert "Spreader bar x, mean predicted - measured: +0.0 mm" in summary
    assert "about 51 mm" in summary


def test_the_first_page_gives_the_verdict_every_channel_and_the_worst_one(case, report, tmp_path):
    measured, simulated, metrics, study = case
    glance = pages_text(report)[0]
    n = metrics["summary"]
    assert f"{n['n_pass']} of {n['n_channels']} channels within tolerance, {n['n_fail']} outside" in glance
    # the worst channel against its tolerance is bucket.vx: its 0.21 bump's RMS over 10 % of the measured peak
    ok = {c: e for c, e in metrics["channels"].items() if e["status"] == "ok"}
    worst = max(ok, key=lambda c: ok[c]["rms_error"] / ok[c]["rms_tolerance"])
    assert worst == "bucket.vx"
    assert "Worst: bucket.vx" in glance and "The worst channel, bucket.vx" in glance
    assert "Every channel against its tolerance" in glance
    # with the machine drawn: its bodies named on the page
    from dragline.compare import machine_picture
    from dragline.simulate import load_rig

    drawn = tmp_path / "drawn.pdf"
    write_report(drawn, measured, simulated, metrics, machine=machine_picture(load_rig()))
    first = pages_text(drawn)[0]
    assert all(body in first for body in ("bucket", "spreader_bar", "hoist_cluster", "drag_cluster"))


def test_the_machine_picture_knows_its_rings_and_marks_a_site():
    # The rings are drawn where the rig file puts them: the boom's at the boom pulley's fixed point; a site
    # name marks a ring, a rope, a damping group's ropes or a body, and nothing else.
    from dragline.compare import machine_picture, marked_sites
    from dragline.simulate import load_rig

    rig = load_rig()
    picture = machine_picture(rig)
    rings = dict(picture.rings)
    assert set(rings) == {"boom", "hoist_cluster"}
    np.testing.assert_allclose(rings["boom"], [-5.314, 0.0, -4.1285], atol=1e-12)
    ropes = [name for name, _, _ in picture.ropes]
    bodies = [name for name, _, _ in picture.bodies]
    assert marked_sites(picture, ["boom"]) == ([[s for s, _ in picture.rings].index("boom")], [], [])
    _, marked, _ = marked_sites(picture, ["wire_rope"])
    assert sorted(ropes[k] for k in marked) == ["drag_rope", "hoist_rope"]
    assert marked_sites(picture, ["bucket", "dump_rope"]) == ([], [ropes.index("dump_rope")], [bodies.index("bucket")])
    assert marked_sites(picture, ["derrick"]) == ([], [], [])
    # drawn: a red ring around the boom's sheave, seen from the side (x, height)
    from matplotlib.figure import Figure

    from dragline.compare import draw_machine

    ax = Figure().add_subplot()
    draw_machine(ax, picture, sites=["boom"])
    circles = [ln for ln in ax.lines if ln.get_marker() == "o"]
    assert len(circles) == 1 and circles[0].get_markeredgecolor() == "tab:red"
    np.testing.assert_allclose(np.ravel(circles[0].get_xydata()), [-5.314, 4.1285], atol=1e-12)


def test_missing_channel_is_marked_not_silently_empty(report):
    text = pages_text(report)
    assert "bucket.q" in text[1] and "MISSING: no finite samples in the measured table" in text[1]
    fig15 = next(t for t in text if "Fig. 15." in t)
    assert "Measured: MISSING (no finite samples in the measured table)" in fig15
    assert "no residual: one side is missing" in fig15
    assert "missing" in text[1].split("pitch rate q")[1].split("\n")[0]


def test_failed_discretization_level_is_reported(report):
    fig21 = pages_text(report)[-1]
    assert "FAILED: simulation blew up at t = 6.4450 s" in fig21
    assert "low" in fig21 and "133" in fig21


def test_report_without_study_has_no_fig21(case, tmp_path):
    measured, simulated, metrics, _ = case
    path = tmp_path / "plain.pdf"
    write_report(path, measured, simulated, metrics)
    text = pages_text(path)
    assert len(text) == REPORT_PAGES_WITHOUT_STUDY
    assert not any("Fig. 21." in t for t in text)
