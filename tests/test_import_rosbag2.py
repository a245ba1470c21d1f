"""``omni-gym import rosbag2``: bags written with ``rosbags``' writer (SQLite3 and MCAP storage) from
simulated runs import back to those runs, by header stamps (not arrival times), with joint names, signs,
frames, units and time windows; bad input gets one line naming the bag and the topic."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

pytest.importorskip("rosbags")

from omni_gym.cli import main  # noqa: E402
from omni_gym.discrepancy.data.dataset import load_dataset  # noqa: E402
from omni_gym.discrepancy.synthetic.bags import write_bag  # noqa: E402
from omni_gym.discrepancy.synthetic.synth import synthesize  # noqa: E402
from omni_gym.physics.model import load_model  # noqa: E402

MODEL = "williams2002"
JOINTS = ["wheel_left_joint", "wheel_right_joint", "wheel_back_joint"]
SIGNS = [1.0, -1.0, 1.0]  # the right wheel's joint axis points the other way
JOINT_FLAG = "wheel_left_joint,-wheel_right_joint,wheel_back_joint"


@pytest.fixture(scope="module")
def sim():
    """Two simulated 3 s runs of the Williams robot (no tracker noise: the import must give them back)."""
    model = load_model(MODEL)
    runs, _ = synthesize(model, "wheel_radius", runs=2, noise=0.0, seed=5, duration=3.0)
    return model, runs


def _import(bag, out, *extra) -> int:
    return main(["import", "rosbag2", *map(str, bag if isinstance(bag, list) else [bag]), "--model", MODEL,
                 "--joints", JOINT_FLAG, "--out", str(out), *extra])


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_one_bag_per_run(sim, tmp_path, storage, capsys):
    _, runs = sim
    bags = []
    for run in runs:
        bag = tmp_path / f"{run.name}"
        write_bag(bag, [(run.t, run.enc, run.pose)], JOINTS, SIGNS, storage=storage, seed=len(bags))
        bags.append(bag)
    out = tmp_path / "ds"
    assert _import(bags, out, "--pose-topic", "/tracker/pose", "--frames", "world:base_link") == 0
    printed = capsys.readouterr().out
    assert "imported 2 run(s)" in printed and "header stamps" in printed
    ds = load_dataset(out)
    assert [r.name for r in ds.runs] == [r.name for r in runs]
    assert "wheel_left_joint" in ds.description and "world" in ds.description
    for got, want in zip(ds.runs, runs, strict=True):
        # Stamps are integer nanoseconds: times agree to 1 ns; angles are written as float64.
        np.testing.assert_allclose(got.t, want.t, rtol=0, atol=2e-9)
        np.testing.assert_allclose(got.enc, want.enc, rtol=0, atol=1e-9)
        # The yaw goes through a quaternion and back: about 1e-15 rad.
        np.testing.assert_allclose(got.pose[:, :2], want.pose[:, :2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.unwrap(got.pose[:, 2]), want.pose[:, 2], rtol=0, atol=1e-9)


def test_windows_tf_velocities_mm(sim, tmp_path):
    """Both runs in one MCAP bag 1 s apart, wheels as JointState velocities, the pose on /tf in mm at half
    the wheel rate; two windows cut them back out."""
    _, runs = sim
    segs = [(r.t, r.cmd, r.pose) for r in runs]
    bag = tmp_path / "session"
    write_bag(bag, segs, JOINTS, SIGNS, storage="mcap", field="velocity", pose_kind="tf", length_scale=1000.0,
              pose_every=2, gap_s=1.0)
    t1 = float(runs[0].t[-1])
    out = tmp_path / "ds"
    rc = _import(bag, out, "--wheel-field", "velocity", "--pose-topic", "/tf", "--frames", "world:base_link",
                 "--units", "mm", "--window", f"first=0:{t1}", "--window", f"second={t1 + 1.0}:")
    assert rc == 0
    ds = load_dataset(out)
    assert [r.name for r in ds.runs] == ["first", "second"]
    for got, want in zip(ds.runs, runs, strict=True):
        np.testing.assert_allclose(got.t, want.t, rtol=0, atol=2e-9)
        # Held command: the mean of two speed samples; the simulated command is piecewise constant, so the
        # two agree except on the rows where the command switches.
        same = np.all(want.cmd[:-1] == want.cmd[1:], axis=1)[:-1]
        np.testing.assert_allclose(got.cmd[:-1][:-1][same], want.cmd[:-1][:-1][same], atol=1e-12)
        # Every second pose is interpolated between poses 2 rows (40 ms) apart: the robot's path bends
        # little in 40 ms (at most 2 mm from the chord at these speeds).
        seen = np.isfinite(got.pose[:, 0])
        assert seen.all()
        assert np.max(np.abs(got.pose[:, :2] - want.pose[:, :2])) < 2e-3
        np.testing.assert_allclose(got.pose[::2, :2], want.pose[::2, :2], atol=1e-9)


def test_odometry_topic(sim, tmp_path):
    _, runs = sim
    bag = tmp_path / "odom"
    write_bag(bag, [(runs[0].t, runs[0].enc, runs[0].pose)], JOINTS, SIGNS, pose_kind="odom", pose_topic="/mocap")
    assert _import(bag, tmp_path / "ds", "--pose-topic", "/mocap") == 0
    np.testing.assert_allclose(load_dataset(tmp_path / "ds").runs[0].pose[:, :2], runs[0].pose[:, :2], atol=1e-12)


def _bad(tmp_path, capsys, bag, *extra, joints=JOINT_FLAG) -> str:
    rc = main(["import", "rosbag2", str(bag), "--model", MODEL, "--joints", joints, "--out",
               str(tmp_path / "bad"), *extra])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1, err
    assert not (tmp_path / "bad").exists()
    return err


def test_bad_input(sim, tmp_path, capsys):
    _, runs = sim
    run = runs[0]
    bag = tmp_path / "b"
    write_bag(bag, [(run.t, run.enc, run.pose)], JOINTS, SIGNS)
    err = _bad(tmp_path, capsys, bag, "--pose-topic", "/vicon/robot")
    assert "no topic /vicon/robot" in err and "/tracker/pose (PoseStamped)" in err
    err = _bad(tmp_path, capsys, bag, "--pose-topic", "/tracker/pose", joints="wheel_left_joint,-wheel_rt,back")
    assert "no message has joint 'wheel_rt'" in err and "wheel_right_joint" in err
    err = _bad(tmp_path, capsys, bag, "--pose-topic", "/joint_states")
    assert "topic /joint_states is sensor_msgs/msg/JointState" in err
    err = _bad(tmp_path, capsys, bag, "--pose-topic", "/tracker/pose", "--frames", "map:base_link")
    assert "poses are in frame world, not map" in err
    # A wheel that never moves: a wrong joint
    still = run.enc.copy()
    still[:, 1] = 0.0
    write_bag(tmp_path / "still", [(run.t, still, run.pose)], JOINTS, SIGNS)
    err = _bad(tmp_path, capsys, tmp_path / "still", "--pose-topic", "/tracker/pose")
    assert "wheel 2 (-wheel_right_joint) never moves" in err
    # Stamps that go back in time
    t = run.t.copy()
    t[10], t[11] = t[11], t[10]
    write_bag(tmp_path / "back", [(t, run.enc, run.pose)], JOINTS, SIGNS, arrival_t=run.t)
    err = _bad(tmp_path, capsys, tmp_path / "back", "--pose-topic", "/tracker/pose")
    assert "/joint_states: message 12: times must be strictly increasing" in err
    # The tracker publishes millimetres, imported as metres
    write_bag(tmp_path / "mm", [(run.t, run.enc, run.pose)], JOINTS, SIGNS, length_scale=1000.0)
    err = _bad(tmp_path, capsys, tmp_path / "mm", "--pose-topic", "/tracker/pose")
    assert "/tracker/pose" in err and "positions look like millimetres" in err
    # A tf topic without --frames, and a format-only option of another format
    write_bag(tmp_path / "tf", [(run.t, run.enc, run.pose)], JOINTS, SIGNS, pose_kind="tf")
    assert "give --frames PARENT:CHILD" in _bad(tmp_path, capsys, tmp_path / "tf", "--pose-topic", "/tf")
    assert "no transform odom:base_link" in _bad(tmp_path, capsys, tmp_path / "tf", "--pose-topic", "/tf",
                                                 "--frames", "odom:base_link")
    assert "--columns applies to 'import csv'" in _bad(tmp_path, capsys, bag, "--pose-topic", "/tracker/pose",
                                                       "--columns", "t=a")
    assert "the model has 3 wheels" in _bad(tmp_path, capsys, bag, "--pose-topic", "/tracker/pose",
                                            joints="a,b")
    (tmp_path / "empty").mkdir()
    assert "not a rosbag2 folder" in _bad(tmp_path, capsys, tmp_path / "empty", "--pose-topic", "/tracker/pose")
    (tmp_path / "empty" / "metadata.yaml").write_text("rosbag2_bagfile_information: {version: 99}\n")
    assert "cannot read the bag" in _bad(tmp_path, capsys, tmp_path / "empty", "--pose-topic", "/tracker/pose")


def test_without_rosbags_one_line(sim, tmp_path, capsys, monkeypatch):
    _, runs = sim
    bag = tmp_path / "b"
    write_bag(bag, [(runs[0].t, runs[0].enc, runs[0].pose)], JOINTS, SIGNS)
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)  # as if the extra were not installed
    assert "pip install -e '.[ros]'" in _bad(tmp_path, capsys, bag, "--pose-topic", "/tracker/pose")


@pytest.mark.parametrize("command_type", ["joint_state", "array"])
def test_wheel_command_topic(sim, tmp_path, command_type):
    """Commands from their own topic: the rows are the commands (held), enc the joint angles at those times."""
    _, runs = sim
    run = runs[0]
    bag = tmp_path / "cmd"
    write_bag(bag, [(run.t, run.enc, run.pose)], JOINTS, SIGNS, commands=[run.cmd], command_type=command_type)
    out = tmp_path / "ds"
    assert _import(bag, out, "--pose-topic", "/tracker/pose", "--command-topic", "/wheel_commands") == 0
    got = load_dataset(out).runs[0]
    assert "/wheel_commands" in load_dataset(out).description
    if command_type == "joint_state":  # header stamps: the rows are the simulated rows exactly
        np.testing.assert_allclose(got.t, run.t, rtol=0, atol=2e-9)
        np.testing.assert_array_equal(got.cmd[:-1], run.cmd[:-1])
        np.testing.assert_allclose(got.enc, run.enc, rtol=0, atol=1e-9)
        np.testing.assert_allclose(got.pose[:, :2], run.pose[:, :2], rtol=0, atol=1e-12)
    else:  # arrival times: 1-9 ms after the stamps (bag_writer), so only the command values are exact
        np.testing.assert_array_equal(got.cmd[:-1], run.cmd[: len(got.cmd) - 1])
        assert np.all(np.abs(np.diff(got.t) - np.diff(run.t[: len(got.t)])) < 0.01)


def test_mapping_file(sim, tmp_path, capsys):
    """The options in a JSON file (a robot imported often); an option on the command line wins."""
    _, runs = sim
    bag = tmp_path / "b"
    write_bag(bag, [(runs[0].t, runs[0].enc, runs[0].pose)], JOINTS, SIGNS)
    mapping = tmp_path / "robot.json"
    mapping.write_text(json.dumps({"model": MODEL, "joints": JOINT_FLAG, "pose_topic": "/nowhere",
                                   "frames": "world:base_link"}))
    out = tmp_path / "ds"
    assert main(["import", "rosbag2", str(bag), "--mapping", str(mapping), "--pose-topic", "/tracker/pose",
                 "--out", str(out)]) == 0
    np.testing.assert_allclose(load_dataset(out).runs[0].enc, runs[0].enc, atol=1e-9)
    mapping.write_text(json.dumps({"model": MODEL, "joint": JOINT_FLAG}))
    assert main(["import", "rosbag2", str(bag), "--mapping", str(mapping), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "robot.json" in err and "'joint'" in err
