"""Tables of tracked poses (a tracker's CSV export) read through a declared mapping.

Truth is a simulation written out as a foreign lab would record it: y up,
millimetres, milliseconds, quaternions w first, columns in its own names;
read back through the mapping it must be the simulation again.
"""

import numpy as np
import pytest
from dragline.capture import frame_rotation, read_tracked_table
from dragline.pipelines.cli import main
from dragline.reconstruct import tracked_trajectory
from dragline.simulate import body_to_inertial, load_rig, simulate
from scipy.spatial.transform import Rotation

MAPPING = """
[table]
time = "Time (ms)"
time_unit = "ms"
units = "mm"
up = "+y"
quaternion = "wxyz"

[bodies.ball]
position = ["Ball X", "Ball Y", "Ball Z"]
quaternion = ["Ball QW", "Ball QX", "Ball QY", "Ball QZ"]
"""


@pytest.fixture(scope="module")
def swing():
    return simulate(load_rig("pendulum"), duration=4.0, rate_hz=100.0, discretization="low")


def _foreign(table, up="+y"):
    """The ball's pose as a y-up, millimetre, millisecond tracker with w-first quaternions records it."""
    import pandas as pd

    R = frame_rotation(up)
    T = body_to_inertial(*(table[f"ball.{a}"].to_numpy() for a in ("roll", "pitch", "yaw")))
    position = table[["ball.x", "ball.y", "ball.z"]].to_numpy() @ R  # R^T p, row-wise
    q = Rotation.from_matrix(R.T @ T @ R).as_quat()  # x, y, z, w
    return pd.DataFrame({"Frame": np.arange(len(table)), "Time (ms)": table["time"].to_numpy() * 1000.0,
                         "Ball QW": q[:, 3], "Ball QX": q[:, 0], "Ball QY": q[:, 1], "Ball QZ": q[:, 2],
                         "Ball X": position[:, 0] * 1000.0, "Ball Y": position[:, 1] * 1000.0,
                         "Ball Z": position[:, 2] * 1000.0})


@pytest.mark.parametrize("up", ["+x", "-x", "+y", "-y", "+z", "-z"])
def test_every_up_axis_is_a_proper_rotation_putting_up_at_minus_k(up):
    R = frame_rotation(up)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0)
    axis = np.zeros(3)
    axis["xyz".index(up[1])] = 1.0 if up[0] == "+" else -1.0
    np.testing.assert_allclose(R @ axis, [0.0, 0.0, -1.0], atol=1e-15)


def test_a_foreign_trackers_table_reads_back_as_the_simulation(tmp_path, swing):
    csv, mapping = tmp_path / "take.csv", tmp_path / "take.toml"
    _foreign(swing.table).to_csv(csv, index=False, float_format="%.12g")
    mapping.write_text(MAPPING)
    poses = read_tracked_table(csv, mapping)
    assert poses.report["rows_dropped"] == 0 and poses.report["gaps"] == 0
    assert poses.report["rate_hz"] == pytest.approx(100.0)
    table, maneuver = tracked_trajectory(poses, load_rig("pendulum"))
    assert maneuver is None
    np.testing.assert_allclose(table["time"], swing.table["time"] - swing.table["time"].iloc[0], atol=1e-9)
    for channel, tol in (("ball.x", 1e-9), ("ball.y", 1e-9), ("ball.z", 1e-9), ("ball.pitch", 1e-9),
                         ("ball.roll", 1e-9), ("ball.vx", 2e-3), ("ball.q", 2e-2)):
        np.testing.assert_allclose(table[channel], swing.table[channel], atol=tol, err_msg=channel)


def test_dropped_rows_shuffled_rows_and_a_gap_are_resampled_and_said(tmp_path, swing):
    foreign = _foreign(swing.table)
    foreign = foreign.drop(index=list(range(200, 206)))  # a dropout of six frames
    foreign.loc[10, "Time (ms)"] = np.nan  # a row with no time
    foreign = foreign.sample(frac=1.0, random_state=3)  # written out of order
    csv, mapping = tmp_path / "take.csv", tmp_path / "take.toml"
    foreign.to_csv(csv, index=False, float_format="%.12g")
    mapping.write_text(MAPPING)
    poses = read_tracked_table(csv, mapping)
    assert poses.report["rows_dropped"] == 1 and poses.report["gaps"] == 1
    table, _ = tracked_trajectory(poses, load_rig("pendulum"))
    assert table["time"].size == len(swing.table)
    inside = (table["time"] > 1.995) & (table["time"] < 2.055)  # rows 200-205: 2.00-2.05 s
    assert table.loc[inside, "ball.x"].isna().all() and table.loc[~inside, "ball.x"].notna().all()
    kept = ~inside.to_numpy()
    np.testing.assert_allclose(table["ball.x"][kept], swing.table["ball.x"][kept], atol=2e-4)  # row 10: interpolated


def _roll_pitch_yaw(M):
    """Roll, pitch, yaw (rad) of rotation matrices M (n, 3, 3) = Rz(yaw) Ry(pitch) Rx(roll), by hand."""
    return (np.arctan2(M[:, 2, 1], M[:, 2, 2]), -np.arcsin(np.clip(M[:, 2, 0], -1.0, 1.0)),
            np.arctan2(M[:, 1, 0], M[:, 0, 0]))


@pytest.mark.parametrize("sequence, order", [("xyz", (0, 1, 2)), ("ZYX", (2, 1, 0))])
def test_a_body_tracked_by_angles_reads_back_as_the_simulation(tmp_path, swing, sequence, order):
    """A tracker that writes roll, pitch and yaw in degrees: about its fixed axes x, then y, then z (ROS's
    convention) or, the same rotation, yaw, pitch, roll about the body's turned axes (ZYX)."""
    foreign = _foreign(swing.table)
    R = frame_rotation("+y")
    T = body_to_inertial(*(swing.table[f"ball.{a}"].to_numpy() for a in ("roll", "pitch", "yaw")))
    angles = np.degrees(np.column_stack(_roll_pitch_yaw(R.T @ T @ R)))
    names = ["Ball A1", "Ball A2", "Ball A3"]
    for name, k in zip(names, order):
        foreign[name] = angles[:, k]
    csv, mapping = tmp_path / "take.csv", tmp_path / "take.toml"
    foreign.drop(columns=["Ball QW", "Ball QX", "Ball QY", "Ball QZ"]).to_csv(csv, index=False, float_format="%.12g")
    mapping.write_text(MAPPING.replace('quaternion = ["Ball QW", "Ball QX", "Ball QY", "Ball QZ"]',
                                       f"euler = {names}".replace("'", '"'))
                       .replace('quaternion = "wxyz"', f'euler = "{sequence}"\nangle_unit = "deg"'))
    table, _ = tracked_trajectory(read_tracked_table(csv, mapping), load_rig("pendulum"))
    for channel in ("ball.roll", "ball.pitch", "ball.yaw"):
        np.testing.assert_allclose(table[channel], swing.table[channel], atol=1e-9, err_msg=channel)


@pytest.mark.parametrize("edit, words", [
    (('"Ball QW", "Ball QX"', '"Ball QW", "Ball Q"'), ["no column 'Ball Q'", "Time (ms)"]),
    (('up = "+y"', 'up = "north"'), ["table.up", "'north'"]),
    (('time = "Time (ms)"', 'rate_hz = 100.0\ntime = "Time (ms)"'), ["clock once"]),
    (('up = "+y"', 'up = "+y"\nshared_frame = true'), ["shared_frame", "tracks no point"]),
    (('"Ball QZ"]', '"Ball QZ"]\neuler = ["Ball X", "Ball Y", "Ball Z"]'), ["attitude once"]),
    (('up = "+y"', 'up = "+y"\neuler = "xyx"'), ["table.euler", "'xyx'"]),
])
def test_a_mapping_that_names_what_the_table_lacks_is_refused_in_one_line(tmp_path, swing, edit, words):
    csv, mapping = tmp_path / "take.csv", tmp_path / "take.toml"
    _foreign(swing.table).to_csv(csv, index=False)
    mapping.write_text(MAPPING.replace(*edit))
    with pytest.raises(ValueError) as info:
        read_tracked_table(csv, mapping)
    message = str(info.value)
    assert "\n" not in message and (str(csv) in message or str(mapping) in message)
    for word in words:
        assert word in message, message


def test_diagnose_reads_a_tracked_table_through_its_mapping(tmp_path, capsys):
    """A foreign lab's free decay of the pendulum with air drag, diagnosed from its own export."""
    import json

    from dragline.simulate import parse_physics

    run = simulate(load_rig("pendulum"), physics=[parse_physics("aero_drag:cd=3.0")], duration=16.0,
                   rate_hz=100.0, discretization="low")
    foreign = _foreign(run.table)
    rng = np.random.default_rng(9)
    for c in ("Ball X", "Ball Y", "Ball Z"):
        foreign[c] += rng.normal(0.0, 0.5, len(foreign))  # 0.5 mm
    csv, mapping, out = tmp_path / "take.csv", tmp_path / "take.toml", tmp_path / "d.json"
    foreign.to_csv(csv, index=False, float_format="%.12g")
    mapping.write_text(MAPPING)
    assert main(["diagnose", str(csv), "--mapping", str(mapping), "--rig", "pendulum", "--discretization", "low",
                 "--json", str(out), "--quiet"]) == 0
    doc = json.loads(out.read_text())
    assert doc["verdict"] == "aero_drag", doc["reason"]
    assert doc["source"]["kind"] == "tracked table" and doc["source"]["tracked"]["rate_hz"] == pytest.approx(100.0)


def test_the_docs_list_the_mapping_schema_as_generated():
    import re

    from conftest import REPO
    from dragline.capture._tracked import tracked_mapping_markdown

    doc = (REPO / "docs" / "schemas.md").read_text()
    block = re.search(r"<!-- generated: tracked mapping schema -->\n(.*?)<!-- end generated -->", doc, re.S).group(1)
    assert block == tracked_mapping_markdown()


# The official ROS 2 definitions (common_interfaces, rcl_interfaces), in the
# concatenated form a recorder stores in a bag's schema records.
_SEP = "=" * 80
_POSE_DEPS = f"""{_SEP}
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
{_SEP}
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
_QUATERNION = f"""{_SEP}
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
"""
POSE_STAMPED = f"""std_msgs/Header header
geometry_msgs/Pose pose
{_POSE_DEPS}{_SEP}
MSG: geometry_msgs/Pose
Point position
Quaternion orientation
{_SEP}
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
{_QUATERNION}"""
TRANSFORM_STAMPED = f"""std_msgs/Header header
string child_frame_id
Transform transform
{_POSE_DEPS}{_SEP}
MSG: geometry_msgs/Transform
Vector3 translation
Quaternion rotation
{_SEP}
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
{_QUATERNION}"""


def _write_bag(path, table, start_ns=1_777_983_827_312_483_916, drop=()):
    """The ball's pose as a z-up (ROS, ENU) mocap bridge publishes it: PoseStamped on one topic, the
    pivot as TransformStamped on another, header stamps on the recording's clock."""
    from mcap_ros2.writer import Writer

    R = frame_rotation("+z")
    T = body_to_inertial(*(table[f"ball.{a}"].to_numpy() for a in ("roll", "pitch", "yaw")))
    position = table[["ball.x", "ball.y", "ball.z"]].to_numpy() @ R
    q = Rotation.from_matrix(R.T @ T @ R).as_quat()
    pivot = np.array([0.0, 0.0, -2.0]) @ R
    with open(path, "wb") as stream:
        writer = Writer(stream)
        pose_schema = writer.register_msgdef("geometry_msgs/msg/PoseStamped", POSE_STAMPED)
        tf_schema = writer.register_msgdef("geometry_msgs/msg/TransformStamped", TRANSFORM_STAMPED)
        for k, t in enumerate(table["time"].to_numpy()):
            ns = start_ns + int(round(t * 1e9))
            stamp = {"sec": ns // 10**9, "nanosec": ns % 10**9}
            if k not in drop:
                writer.write_message("/vrpn_mocap/ball/pose", pose_schema, {
                    "header": {"stamp": stamp, "frame_id": "world"},
                    "pose": {"position": dict(zip("xyz", position[k])), "orientation": dict(zip("xyzw", q[k]))}},
                    log_time=ns + 3_000_000, publish_time=ns)
            writer.write_message("/vrpn_mocap/pivot/transform", tf_schema, {
                "header": {"stamp": stamp, "frame_id": "world"}, "child_frame_id": "pivot",
                "transform": {"translation": dict(zip("xyz", pivot)), "rotation": {"x": 0.0, "y": 0.0, "z": 0.0,
                                                                                   "w": 1.0}}},
                log_time=ns + 3_000_000, publish_time=ns)
        writer.finish()


BAG_MAPPING = """
[table]
up = "+z"

[bodies.ball]
topic = "/vrpn_mocap/ball/pose"

[points.pivot]
topic = "/vrpn_mocap/pivot/transform"
"""


def test_a_ros2_bag_of_pose_topics_reads_back_as_the_simulation(tmp_path, swing):
    from dragline.capture import read_tracked_bag

    bag, mapping = tmp_path / "take.mcap", tmp_path / "take.toml"
    _write_bag(bag, swing.table, drop=range(150, 156))
    mapping.write_text(BAG_MAPPING)
    poses = read_tracked_bag(bag, mapping)
    assert poses.report["gaps"] == 1 and poses.report["rate_hz"] == pytest.approx(100.0)
    table, maneuver = tracked_trajectory(poses, load_rig("pendulum"))
    # the pivot's track, smoothed and sampled finer for the model (``smoothed_track``), is where it stood
    assert maneuver.time[0] == table["time"].iloc[0] and maneuver.time[-1] == pytest.approx(table["time"].iloc[-1])
    np.testing.assert_allclose(maneuver.points["pivot"], np.broadcast_to([0.0, 0.0, -2.0], (maneuver.time.size, 3)),
                               atol=1e-12)
    kept = table["ball.x"].notna().to_numpy()
    assert (~kept).sum() == 6
    for channel in ("ball.x", "ball.y", "ball.z", "ball.pitch"):
        np.testing.assert_allclose(table[channel][kept], swing.table[channel][kept], atol=1e-9, err_msg=channel)


def test_a_bag_without_the_mapped_topic_is_refused_naming_it(tmp_path, swing):
    from dragline.capture import read_tracked_bag

    bag, mapping = tmp_path / "take.mcap", tmp_path / "take.toml"
    _write_bag(bag, swing.table)
    mapping.write_text(BAG_MAPPING.replace("/vrpn_mocap/ball/pose", "/vrpn_mocap/load/pose"))
    with pytest.raises(ValueError, match=f"^{mapping}: bag .* has no message on the topic it names for body 'ball', "
                                         "'/vrpn_mocap/load/pose'"):
        read_tracked_bag(bag, mapping)
    bag.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)
    with pytest.raises(ValueError, match="cut short"):
        read_tracked_bag(bag, mapping)
    bag.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40 + b"\x89MCAP0\r\n")
    with pytest.raises(ValueError, match="cannot be read as ROS 2 poses"):
        read_tracked_bag(bag, mapping)


def test_a_bag_cut_anywhere_is_refused_in_one_line(tmp_path, swing):
    # The reader seeks to the footer: a cut bag's last bytes once read as a record of terabytes (a MemoryError
    # on one of 10,000 fuzzed inputs, the bag cut 302 bytes before its end).
    from dragline.capture import read_tracked_bag

    whole, mapping = tmp_path / "take.mcap", tmp_path / "take.toml"
    _write_bag(whole, swing.table)
    mapping.write_text(BAG_MAPPING)
    data = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    for end in (*range(0, len(data), 97), len(data) - 302, len(data) - 8, len(data) - 1):
        cut.write_bytes(data[:end])
        with pytest.raises(ValueError) as err:
            read_tracked_bag(cut, mapping)
        assert str(cut) in str(err.value) and "\n" not in str(err.value)
