"""Every importer checks the units after converting them: a tracked motion that disagrees with the wheels' by
a unit's factor (1000 for metres read as millimetres, 9.55 for radians read as rpm, ...) is refused in one line
naming the likely mistake, in both directions (``omni_gym.discrepancy.data.units.check_import_units``).

The runs are written here from the no-slip kinematics of the Williams robot: the body twist integrated to
poses, the wheel matrix times the twist integrated to wheel angles, so the correct units give a ratio of 1.
"""

from __future__ import annotations

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.physics.model import load_model

MODEL = "williams2002"
COLUMNS = "t=t,x=x,y=y,theta=th,enc1=a,enc2=b,enc3=c"
SPEEDS = "t=t,x=x,y=y,theta=th,w1=a,w2=b,w3=c"


def kinematic_run(duration: float = 6.0, rate: float = 50.0):
    """(t (K,), wheel angles (K, 3) [rad], wheel speeds (K, 3) [rad/s], pose (K, 3)) of a robot driving an
    S-curve at 0.3 m/s while turning 0.8 rad/s one way, then the other, without slip."""
    W = load_model(MODEL).robot.wheel_matrix()
    t = np.arange(0.0, duration, 1.0 / rate)
    twist = np.column_stack([0.3 + 0 * t, 0.1 * np.sin(t), 0.8 * np.sign(np.sin(0.5 * t) + 1e-9)])
    dt = np.diff(t)
    pose = np.zeros((len(t), 3))
    for k in range(len(t) - 1):
        c, s = np.cos(pose[k, 2]), np.sin(pose[k, 2])
        vx, vy, w = twist[k]
        pose[k + 1] = pose[k] + dt[k] * np.array([c * vx - s * vy, s * vx + c * vy, w])
    speeds = twist @ W.T
    angles = np.vstack([np.zeros((1, 3)), np.cumsum(speeds[:-1] * dt[:, None], axis=0)])
    return t, angles, speeds, pose


def write_csv(path, t, wheels, pose, length=1.0, wheel=1.0) -> None:
    rows = ["t,a,b,c,x,y,th"] + [",".join(repr(float(v)) for v in (t[k], *(wheel * wheels[k]), *(length * pose[k, :2]),
                                                                   pose[k, 2])) for k in range(len(t))]
    path.write_text("\n".join(rows) + "\n")


def _refused(capsys, args, out) -> str:
    rc = main(args)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and err.startswith("omni-gym: error: "), err
    assert not out.exists()
    return err


def test_correct_units_import(tmp_path):
    t, angles, _, pose = kinematic_run()
    write_csv(tmp_path / "log.csv", t, angles, pose, length=1000.0)
    assert main(["import", "csv", str(tmp_path / "log.csv"), "--model", MODEL, "--columns", COLUMNS, "--units", "mm",
                 "--out", str(tmp_path / "ds")]) == 0


def test_csv_metres_read_as_millimetres(tmp_path, capsys):
    t, angles, _, pose = kinematic_run()
    write_csv(tmp_path / "log.csv", t, angles, pose)  # metres
    out = tmp_path / "ds"
    err = _refused(capsys, ["import", "csv", str(tmp_path / "log.csv"), "--model", MODEL, "--columns", COLUMNS,
                            "--units", "mm", "--out", str(out)], out)
    assert "log.csv" in err and "x, y in metres read as millimetres" in err and "check --units" in err


def test_csv_speeds_in_rpm_read_as_rad_per_s(tmp_path, capsys):
    """Inside the travel-ratio bound (0.105) but translation and rotation both off by 2π/60: a unit."""
    t, _, speeds, pose = kinematic_run()
    write_csv(tmp_path / "log.csv", t, speeds, pose, wheel=60.0 / (2.0 * np.pi))  # rpm
    out = tmp_path / "ds"
    err = _refused(capsys, ["import", "csv", str(tmp_path / "log.csv"), "--model", MODEL, "--columns", SPEEDS,
                            "--out", str(out)], out)
    assert "wheel speeds in rpm read as rad/s" in err
    assert main(["import", "csv", str(tmp_path / "log.csv"), "--model", MODEL, "--columns", SPEEDS, "--units",
                 "wheel=rpm", "--out", str(out)]) == 0


def test_rosbag2_joint_angles_read_as_rpm(tmp_path, capsys):
    pytest.importorskip("rosbags")
    from omni_gym.discrepancy.synthetic.bags import write_bag

    t, angles, _, pose = kinematic_run()
    joints = ["left", "right", "back"]
    write_bag(tmp_path / "bag", [(t, angles, pose)], joints, [1.0, 1.0, 1.0])
    out = tmp_path / "ds"
    args = ["import", "rosbag2", str(tmp_path / "bag"), "--model", MODEL, "--joints", ",".join(joints),
            "--pose-topic", "/tracker/pose", "--out", str(out)]
    err = _refused(capsys, [*args, "--units", "wheel=rpm"], out)
    # 9.34, not 9.55: over 1 s baselines the tracked chord of a turning robot is shorter than its wheels' travel
    assert "likely wheel angles or speeds in rad (rad/s) read as rpm; check --units" in err and " 9.3" in err
    err = _refused(capsys, [*args, "--units", "mm"], out)
    assert "x, y in metres read as millimetres" in err
    assert main(args) == 0
