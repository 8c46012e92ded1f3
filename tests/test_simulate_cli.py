"""``dragline simulate`` and the simulator's handling of bad input."""

import numpy as np
import pandas as pd
import pytest

from dragline.pipelines.cli import main
from dragline.simulate import (
    Maneuver,
    SimulationError,
    dig_maneuver,
    parse_physics,
    read_maneuver_csv,
    simulate,
    trajectory_columns,
)


def test_simulate_writes_the_trajectory_table(tmp_path, capsys):
    out = tmp_path / "traj.csv"
    assert main(["simulate", "--duration", "1", "--rate", "100", "--out", str(out)]) == 0
    table = pd.read_csv(out)
    assert list(table.columns[: len(trajectory_columns())]) == trajectory_columns()
    assert len(table) == 101 and table["time"].iloc[-1] == pytest.approx(1.0)
    assert np.isfinite(table[trajectory_columns()].to_numpy()).all()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["traj.csv"]  # no temporary left


def test_user_maneuver_csv_is_used(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("time,hoist_length,drag_length\n0,8.6,4.2\n1,8.6,4.2\n")
    out = tmp_path / "t.csv"
    assert main(["simulate", "--maneuver", str(path), "--duration", "0.5", "--out", str(out)]) == 0
    assert pd.read_csv(out)["bucket.vx"].abs().max() < 1e-6  # reels still: stays at rest


@pytest.mark.parametrize(
    "rows, message",
    [
        ("time,hoist_length,drag_length\n", "empty"),
        ("time,hoist_length,drag_length\n0,8.6,4.2\n2,8.7,4.1\n1,8.8,4.0\n", "not strictly increasing"),
        ("time,hoist_length,drag_length\n0,8.6,-4.2\n", "column drag_length, row 2 = -4.2: expected a value > 0"),
        ("time,hoist\n0,8.6\n", "unknown column 'hoist'"),
        ("time,hoist_length,drag_length\n0,8.6,abc\n", "column drag_length, row 2 = 'abc': expected a number"),
        ("time,hoist_length,drag_length\n0,8.6,4.2\n1,,4.2\n", "column hoist_length, row 3 = nan: expected a finite"),
        ("time,hoist_length,drag_length,hoist_lenght\n0,8.6,4.2,8.6\n", "unknown column 'hoist_lenght'"),
        ("time,hoist_length,drag_length\n0,8.6,4.2\n1e300,8.6,4.2\n", "column time, row 3"),
    ],
)
def test_bad_maneuver_tables_exit_2_with_one_line(tmp_path, capsys, rows, message):
    path = tmp_path / "m.csv"
    path.write_text(rows)
    with pytest.raises(ValueError, match=message):
        read_maneuver_csv(path)
    out = tmp_path / "t.csv"
    assert main(["simulate", "--maneuver", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not out.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--discretization", "huge"], "unknown discretization"),
        (["--discretization", "hoist_rope=0"], "integer from 1 to 500"),
        (["--discretization", "hoist_rope=1000000000"], "integer from 1 to 500"),  # grew to 24 GB
        (["--discretization", "tail_rope=4"], "unknown rope"),
        (["--physics", "warp_drive"], "unknown mechanism"),
        (["--physics", "aero_drag:cd=-1"], "non-negative"),
        (["--physics", "aero_drag:speed=3"], "unknown parameter"),
        (["--maneuver", "/nonexistent/m.csv"], "does not exist"),
        (["--rig", "/nonexistent/rig.toml"], "cannot read rig"),
        (["--duration=-1"], "argument --duration: expected a positive finite number, got '-1'"),
        # Work sized from the input is refused with the figure it would need
        # (these ran for hours or until the kernel killed them).
        (["--dt", "1e-12"], "--dt 1e-12: a 10 s simulation at a 1e-12 s step needs 1e+13 steps"),
        (["--dt", "nan"], "argument --dt: expected a positive finite number, got 'nan'"),
        (["--rate", "1e9"], "argument --rate: expected at most 100000, got '1e9'"),  # no clock ticks so fast
        (["--rate", "1e5", "--duration", "1e6"], "--duration 1e+06 at --rate 100000: 100000000000 records"),
        (["--duration", "inf"], "argument --duration: expected a positive finite number, got 'inf'"),
    ],
)
def test_bad_options_exit_2_with_one_line(tmp_path, capsys, args, message):
    out = tmp_path / "t.csv"
    assert main(["simulate", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("rows, message", [
    # The drag rope reeled to 1e-9 m: the statics stepped in femtoseconds (a hang), then the rope yanked
    # its cluster past 100 m/s (exit 1).
    ("0,8.6,4.2\n2.5,9.5,3.45\n3.5,9.5,1e-9\n6.5,10.1,1e-9\n", "drag_rope down to 1e-09 m"),
    # The hoist reel jumps 1 m in 1e-12 s (exit 1 before): no clock ticks so fast; in 1e-5 s, no reel runs so fast.
    ("0,8.6,4.2\n1,8.6,4.2\n1.000000000001,9.6,4.2\n3,9.6,4.2\n", "time steps 1e-12 s at row 4"),
    ("0,8.6,4.2\n1,8.6,4.2\n1.00001,9.6,4.2\n3,9.6,4.2\n", "1e+05 m/s"),
])
def test_a_reel_table_the_ropes_cannot_follow_exits_2_naming_the_file(tmp_path, capsys, rows, message):
    path = tmp_path / "m.csv"
    path.write_text("time,hoist_length,drag_length\n" + rows)
    out = tmp_path / "t.csv"
    assert main(["simulate", "--maneuver", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and message in err[0], err
    assert not out.exists()


def test_usage_errors_exit_2_with_one_line(capsys):
    assert main(["simulate"]) == 2
    assert main(["no-such-command"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("dragline: error:") for line in lines)


def test_help_lists_the_subcommands(capsys):
    assert main([]) == 0
    text = capsys.readouterr().out
    for command in ("simulate", "synth", "calibrate", "reconstruct", "inspect"):
        assert command in text


def test_blow_up_names_time_and_place_and_writes_nothing(rig, tmp_path, capsys):
    with pytest.raises(SimulationError, match=r"blew up at t = [0-9.]+ s: .* in (body|rope segment|ring)"):
        simulate(rig, duration=1.0, dt=2e-3)  # far beyond RK4's stability limit
    out = tmp_path / "t.csv"
    # The step was the user's (--dt): bad input, exit 2, the option named.
    assert main(["simulate", "--dt", "0.002", "--duration", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dragline: error: --dt 0.002:") and "blew up" in err[0], err
    assert not out.exists() and not list(tmp_path.iterdir())


def test_known_mechanisms_change_the_motion(rig):
    still = Maneuver([0.0], {"hoist": [10.1], "drag": [1.4]})
    base = simulate(rig, dig_maneuver(), duration=8.0, rate_hz=50).table
    drag = simulate(rig, dig_maneuver(), physics=[parse_physics("aero_drag:cd=1.2")], duration=8.0, rate_hz=50).table
    assert np.abs(drag["bucket.x"] - base["bucket.x"]).max() > 1e-4
    # a mechanism acting only on motion leaves the rest pose alone
    a = simulate(rig, still, duration=0.5, rate_hz=50).table
    b = simulate(rig, still, physics=[parse_physics("aero_drag:cd=1.2")], duration=0.5, rate_hz=50).table
    np.testing.assert_allclose(a["bucket.z"], b["bucket.z"], atol=1e-9)


def test_rope_lengths_the_rig_cannot_hang_at_exit_2(tmp_path, capsys):
    # 1 m of hoist rope cannot even reach from the reel to the boom pulley
    path = tmp_path / "m.csv"
    path.write_text("time,hoist_length,drag_length\n0,1.0,4.2\n1,1.0,4.2\n")
    out = tmp_path / "t.csv"
    assert main(["simulate", "--maneuver", str(path), "--duration", "0.5", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no static equilibrium" in err[0], err
    assert not out.exists()
