"""``docs/your_robot.md``, every command of it, on ROS 2 bags written here: simulated runs of a known robot
with a hidden effect and a tracker offset (the independent reference integrator,
:mod:`omni_gym.discrepancy.synthetic.reference_data`) recorded as ``sensor_msgs/JointState`` and
``geometry_msgs/PoseStamped`` messages with ``rosbags``' writer. The parameters ``gap`` recovers are checked
against the truth used to write the bags, to the tolerances of the dataset-format recovery tests."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import runpy
import shlex
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")
pytest.importorskip("onnxruntime")
pytest.importorskip("stable_baselines3")

from omni_gym.cli import main  # noqa: E402
from omni_gym.discrepancy.synthetic.bags import write_bag  # noqa: E402
from omni_gym.discrepancy.synthetic.recovery import TOLERANCES, param_error  # noqa: E402
from omni_gym.discrepancy.synthetic.reference_data import reference_runs  # noqa: E402
from omni_gym.physics.model import load_model  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "your_robot.md"
JOINTS = ["wheel_1_joint", "wheel_2_joint", "wheel_3_joint"]
SIGNS = [1.0, -1.0, 1.0]  # the second joint's axis points the other way (the doc's --joints flips it)
# The walkthrough's robot: the doc's nominal model (williams2002, initial friction) and what it does not know.
HIDDEN = {"tracker_offset": {"offset": [-0.015, 0.02], "yaw": -0.02}}
# Training is the walkthrough's only long step: a few thousand steps here prove the commands work.
SHORT_TRAINING = {"--timesteps": "64", "--n-envs": "2"}


def commands() -> list[str]:
    """The shell commands of the walkthrough's ``sh`` blocks, continuation lines joined, comments dropped."""
    text = DOC.read_text()
    out = []
    for block in re.findall(r"```sh\n(.*?)```", text, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                out.append(line)
    return out


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)


def write_bags(folder: Path, nominal) -> None:
    runs = reference_runs(nominal, HIDDEN, 4, 3.0, seed=5)
    for r in runs:
        # The joint positions of a robot whose wheels turn as commanded (ideal actuation, exact encoders).
        angles = np.vstack([np.zeros(r.cmd.shape[1]), np.cumsum(r.cmd[:-1] * np.diff(r.t)[:, None], axis=0)])
        write_bag(folder / "bags" / r.name, [(r.t, angles, r.pose)], JOINTS, SIGNS, storage="mcap",
                  pose_topic="/mocap/robot/pose")


EXPECTED_EXIT = re.compile(r"\s+# exits (\d+)\b.*$")  # a line the walkthrough says fails, and how


def run_command(line: str) -> str:
    """Run one walkthrough line in this process (``omni-gym …``, ``python …``, with ``> FILE``); its stdout. A line
    ending in ``# exits N: why`` must exit with status N (the walkthrough shows a refusal)."""
    expected = 0
    if m := EXPECTED_EXIT.search(line):
        expected, line = int(m.group(1)), line[:m.start()]
    redirect = None
    if " > " in line:
        line, redirect = (s.strip() for s in line.split(" > ", 1))
    argv = shlex.split(line)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        if argv[0] == "omni-gym":
            args = argv[1:]
            if args[0] == "train":
                for opt, value in SHORT_TRAINING.items():
                    if opt in args:
                        args[args.index(opt) + 1] = value
                    else:
                        args += [opt, value]
            assert main(args) == expected, line
        elif argv[0] == "python":
            old = sys.argv
            sys.argv = argv[1:]
            try:
                with pytest.raises(SystemExit) as exit_info:
                    runpy.run_path(str(ROOT / argv[1]), run_name="__main__")
                assert exit_info.value.code == 0, line
            finally:
                sys.argv = old
        else:
            raise AssertionError(f"unknown command in the walkthrough: {line}")
    if redirect:
        Path(redirect).write_text(buf.getvalue())
    return buf.getvalue()


@pytest.mark.slow
def test_walkthrough(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    lines = commands()
    assert lines[0].startswith("omni-gym model show") and "> nominal.json" in lines[0]
    run_command(lines[0])
    nominal = load_model("nominal.json")
    write_bags(tmp_path, nominal)
    printed, wall = {}, {}
    for line in lines[1:]:
        t0 = time.perf_counter()
        printed[line] = run_command(line)
        wall[" ".join(line.split()[:2])] = round(time.perf_counter() - t0, 1)
    print("wall seconds per walkthrough step:", json.dumps(wall))  # pytest -s shows it (docs/your_robot.md)
    for code in python_blocks():
        exec(compile(code, str(DOC), "exec"), {})  # noqa: S102  (the doc's own example)
    # What gap recovered against the truth written into the bags
    result = json.loads((tmp_path / "report" / "result.json").read_text())
    named = {s["effect"]: s.get("params") for s in result["steps"]}
    for effect, truth in HIDDEN.items():
        assert effect in named, result["effects"]
        err = param_error(effect, truth, named[effect], nominal)
        assert all(err[k] <= TOLERANCES[effect][k] for k in err), (effect, err, named[effect])
    assert (tmp_path / "exported" / "policy.onnx").is_file()
    assert any("tracking RMSE" in out for out in printed.values())
    assert os.path.isfile("my-robot-agent/meta.json")
