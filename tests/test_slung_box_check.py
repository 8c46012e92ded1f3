"""The independent slung-box model (tools/slung_box_check.py) against the inclined trifilar pendulum's period."""

import importlib.util
import math

import numpy as np
from scipy.interpolate import CubicSpline

from conftest import REPO

_spec = importlib.util.spec_from_file_location("slung_box_check", REPO / "tools" / "slung_box_check.py")
sb = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sb)


def test_a_small_turn_swings_at_the_inclined_trifilar_period():
    # Three inextensible cords of length L from points at radius R, height H to the lid points at radius r:
    # turning the box by phi raises it by R r phi^2 / (2 h0), h0 = sqrt(L^2 - (R - r)^2), so its potential is
    # m g R r phi^2 / (2 h0) and omega^2 = m g R r / (I h0). The cords' stretch (0.7 mm of 2.2 m) and the lid's
    # 0.03 m above the mass centre (no tilt in a pure turn of a symmetric rig) shift it by far less than 0.2 %.
    radius, height, length = 1.0, 2.8, 2.4
    angles = np.radians([0.0, 120.0, -120.0])
    tops = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(3, height)], axis=1)
    tracks = CubicSpline([0.0, 10.0], np.stack([tops, tops]), axis=0)
    r = np.hypot(*sb.LID_POINTS[0, :2])
    h0 = math.sqrt(length ** 2 - (radius - r) ** 2)
    tension = sb.MASS * sb.GRAVITY * length / (3 * h0)
    stretched = length * (1 + tension / sb.STIFFNESS_EA)
    rest_z = height - math.sqrt(stretched ** 2 - (radius - r) ** 2) - sb.LID_POINTS[0, 2]
    start = {"position": np.array([0.0, 0.0, rest_z]), "rotvec": np.array([0.0, 0.0, 0.02]),
             "velocity": np.zeros(3), "rates": np.zeros(3)}
    time_s = np.arange(0.0, 6.0, 0.002)
    origin, attitude = sb.simulate_window(time_s, tracks, start, {"lengths": np.full(3, length)})
    yaw = attitude.as_rotvec()[:, 2]
    down = np.flatnonzero((yaw[:-1] > 0) & (yaw[1:] <= 0))
    crossings = time_s[down] + 0.002 * yaw[down] / (yaw[down] - yaw[down + 1])
    period = np.mean(np.diff(crossings))
    expected = 2 * math.pi * math.sqrt(sb.INERTIA[2] * h0 / (sb.MASS * sb.GRAVITY * radius * r))
    assert len(crossings) >= 4
    assert abs(period / expected - 1) < 0.002
    assert np.abs(origin[:, :2]).max() < 1e-4          # a pure turn: the box does not sway
    assert abs(yaw.max() - 0.02) < 1e-3                 # and, undamped, keeps its amplitude
