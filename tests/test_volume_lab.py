"""The synthetic lab for any machine: cameras placed about the volume its markers sweep.

Truth is geometric (every marker and the L-frame seen by enough cameras,
every camera above the floor looking at the volume) and end to end: a
pendulum filmed by its own lab, calibrated from its own takes,
reconstructed and diagnosed names the drag hidden in it.
"""

import json

import numpy as np
import pytest
from dragline.capture import camera_centre, project_points
from dragline.lab import lab_for_rig, volume_lab
from dragline.pipelines.cli import main
from dragline.simulate import load_rig, marker_positions, simulate


def _seen_by(points, cameras):
    """How many cameras see each point on their sensor, in front of them."""
    counts = np.zeros(len(points), int)
    for camera in cameras:
        in_front = (points @ camera.R.T + camera.tvec)[:, 2] > 0
        px = project_points(points, camera)
        w, h = camera.image_size
        on = in_front & (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
        counts += on
    return counts


def test_the_dragline_keeps_its_lab_and_another_machine_gets_one_about_its_markers():
    dig = simulate(duration=10.0, rate_hz=20.0)
    lab = lab_for_rig(dig.model.rig, marker_positions(dig)[1])
    assert lab.kind == "built-in"
    from dragline.lab import WAND_LENGTH, default_lab_cameras

    assert lab.wand_length == WAND_LENGTH and [c.to_dict() for c in lab.cameras] == [c.to_dict() for c in
                                                                                    default_lab_cameras()]
    swing = simulate(load_rig("pendulum"), duration=2.0, rate_hz=20.0)
    markers = marker_positions(swing)[1]
    lab = lab_for_rig(swing.model.rig, markers)
    assert lab.kind == "volume"
    inside = (markers >= lab.wand_volume[:, 0]) & (markers <= lab.wand_volume[:, 1])
    assert inside.all()


@pytest.mark.parametrize("scale", [0.2, 1.0, 20.0])
def test_a_volume_lab_sees_its_whole_box_and_l_frame_at_any_scale(scale):
    box = np.array([[-0.4, 0.5], [-0.1, 0.1], [-1.9, -0.8]]) * scale
    lab = volume_lab(box, seed=3)
    corners = np.array([[x, y, z] for x in lab.wand_volume[0] for y in lab.wand_volume[1] for z in lab.wand_volume[2]])
    assert (_seen_by(corners, lab.cameras) == len(lab.cameras)).all()  # the whole capture volume, every camera
    assert (_seen_by(lab.lframe, lab.cameras) >= 4).all()
    for camera in lab.cameras:
        assert camera_centre(camera)[2] < 0  # above the floor
    assert np.all(lab.wand_volume[:, 1] - lab.wand_volume[:, 0] >= 2 * lab.wand_length)


def test_a_pendulum_filmed_by_its_own_lab_is_diagnosed_end_to_end(tmp_path, capsys):
    session, truth, out = tmp_path / "session", tmp_path / "truth", tmp_path / "d.json"
    assert main(["synth", "--rig", "pendulum", "--duration", "16", "--rate", "100", "--discretization", "low",
                 "--physics", "aero_drag:cd=3", "--out", str(session), "--truth-out", str(truth)]) == 0
    assert "100.0 % of marker-frames seen by two cameras or more" in capsys.readouterr().err
    assert main(["diagnose", str(session), "--rig", "pendulum", "--discretization", "low", "--json", str(out),
                 "--candidates", "aero_drag,rope_bending_damping", "--quiet"]) == 0
    doc = json.loads(out.read_text())
    assert doc["verdict"] == "aero_drag", doc["reason"]
    cd = next(h for h in doc["hypotheses"] if h["name"] == "aero_drag")["parameters"]["cd"]
    assert cd == pytest.approx(3.0, rel=0.25)
    assert doc["source"]["calibration"] == "calibrated from the session's L-frame and wand takes"
