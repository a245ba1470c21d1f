"""``examples/deploy_onnx.py``: the exported network driving the simulated robot without torch or
Stable-Baselines3 tracks as the trained policy does inside ``evaluate``'s environment."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("onnxruntime")
pytest.importorskip("stable_baselines3")

from agents.export import export  # noqa: E402
from agents.loaders import find_loader  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deploy_onnx.py"
SECONDS = 3.0
SEED = 10000
MODELS = {"residual": ROOT / "agents" / "models" / "ppo-residual-williams",
          "privileged": ROOT / "agents" / "models" / "sac-privileged-williams"}


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    base = tmp_path_factory.mktemp("exports")
    for name, model in MODELS.items():
        export(str(model), base / name)
    return base


def policy_actions(model: Path, inputs: np.ndarray) -> np.ndarray:
    """The trained policy's actions (in memory, as evaluate loads it) on the network inputs of the loop."""
    meta = json.loads((model / "meta.json").read_text())
    env, policy = find_loader(str(model)).load(str(model), meta["env_id"], {"episode_seconds": SECONDS}, None)
    env.close()
    return np.asarray(policy.act(inputs.astype(np.float32)), dtype=np.float32).reshape(len(inputs), -1)


def test_deploy_loop_without_torch(exported):
    code = (
        "import json, runpy, sys\n"
        f"ns = runpy.run_path({str(EXAMPLE)!r})\n"
        f"out = {{name: ns['run'](sys.argv[1] + '/' + name, {SECONDS}, {SEED}, record=True)\n"
        f"       for name in {list(MODELS)!r}}}\n"
        "out['modules'] = sorted(m for m in ('torch', 'stable_baselines3') if m in sys.modules)\n"
        "print(json.dumps(out))\n")
    proc = subprocess.run([sys.executable, "-c", code, str(exported)], capture_output=True, text=True, cwd=ROOT,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["modules"] == []
    for name, model in MODELS.items():
        res = out[name]
        assert res["steps"] == round(SECONDS / 0.01)
        # Every action the loop took is the trained policy's on the same input (the EKF features built by
        # EKFFeatureFilter, or the state observation) within the export's 1e-5. (Whole trajectories are not
        # compared: on carpet a 1e-7 difference can grow through wheel slip over 300 periods.)
        inputs, outputs = np.asarray(res["inputs"]), np.asarray(res["outputs"])
        assert len(inputs) == res["steps"]
        assert np.max(np.abs(outputs - policy_actions(model, inputs))) <= 1e-5, name
        assert 0 < res["tracking_rmse"] < 0.1 and 0 < res["max_wheel_speed"] < 1e3


def test_command_line(exported):
    proc = subprocess.run([sys.executable, str(EXAMPLE), str(exported / "residual"), "--seconds", "1"],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "100 control periods, tracking RMSE" in proc.stdout


def test_command_line_drives_a_plant(exported, tmp_path):
    # The same exported agent driving the second generator with a hidden 2 cm centre-of-mass offset: the loop
    # runs unchanged (the plant protocol) and the robot it drives is not the simulator (another RMSE).
    from omni_gym.physics.friction import SURFACES
    from omni_gym.physics.model import SimModel
    from omni_gym.physics.robot import robot_preset

    truth = SimModel(robot=robot_preset("williams2002"), surface=SURFACES["carpet"], friction="roller_gap",
                     effects={"com_offset": {"com": [0.02, 0.0]}})
    path = tmp_path / "truth.json"
    path.write_text(json.dumps(truth.to_json()))
    outs = []
    for extra in ([], ["--plant-model", str(path)]):
        proc = subprocess.run([sys.executable, str(EXAMPLE), str(exported / "residual"), "--seconds", "1", *extra],
                              capture_output=True, text=True, cwd=ROOT, timeout=600)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert "100 control periods, tracking RMSE" in proc.stdout
        outs.append(proc.stdout)
    assert outs[0] != outs[1]
