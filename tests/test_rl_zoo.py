"""The hyperparameter files are valid RL Zoo files: the real ``rl_zoo3.train`` trains with them, and
``omni-gym evaluate`` reads the Zoo's output folder.

Needs ``rl_zoo3`` (the ``dev`` extra); skipped without it.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from agents.evaluate import evaluate
from agents.sb3_policy import ModelOptions
from omni_gym.cli import main

pytest.importorskip("rl_zoo3")
torch.set_num_threads(1)

ROOT = Path(__file__).resolve().parents[1]
ENV = "OmniPathFollow-Phunopas-v0"
MECANUM = "OmniPathFollow-Mecanum-v0"  # four mecanum wheels: the same ppo.yml agent (an alias of ENV's entry)
SHORT = {"episode_seconds": 1.0}


@pytest.fixture(scope="module", params=[ENV, MECANUM])
def zoo_run(request, tmp_path_factory):
    """``python -m rl_zoo3.train`` with the committed ppo.yml for one small PPO update (128 steps), per id;
    returns (id, the Zoo's run folder).

    ``learning_rate:0`` keeps the weights at their initialisation, so the test can see that the Zoo ran
    our ResidualInit callback; the rollout, the update and the saving run as in a real training.
    """
    env_id = request.param
    logs = tmp_path_factory.mktemp("zoo")
    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", env_id, "--gym-packages", "omni_gym",
           "-conf", str(ROOT / "agents/hyperparams/ppo.yml"), "-n", "128", "--seed", "0", "-f", str(logs),
           "--eval-freq", "-1", "--device", "cpu", "--verbose", "0", "--num-threads", "1",
           "-params", "n_envs:1", "n_steps:128", "batch_size:64", "n_epochs:1", "learning_rate:0.0"]
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg"}
    proc = subprocess.run(cmd, cwd=logs, capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return env_id, logs / "ppo" / f"{env_id}_1"


def test_rl_zoo_trains_with_our_hyperparameter_file(zoo_run):
    from stable_baselines3 import PPO

    env_id, zoo_run = zoo_run
    for f in (f"{env_id}.zip", f"{env_id}/config.yml", f"{env_id}/args.yml", f"{env_id}/vecnormalize.pkl"):
        assert (zoo_run / f).is_file(), f
    model = PPO.load(zoo_run / f"{env_id}.zip", device="cpu")
    # EKFFeatures observation: 30 + 3·n features for the 4-wheeled robots (phunopas2018, optiodom_omni4).
    assert model.observation_space.shape == (42,)
    # ResidualInit ran: the action layer's orthogonal rows (norm 0.01, SB3's gain for action_net) were
    # scaled by 0.01; with learning_rate 0 they keep norm 1e-4 (float32 rounding: 1e-3 relative).
    norms = torch.linalg.norm(model.policy.action_net.weight, dim=1)
    assert torch.allclose(norms, torch.full_like(norms, 1e-4), rtol=1e-3)


def test_evaluate_reads_the_rl_zoo_folder(zoo_run, capsys):
    """The folder needs no options (algorithm, wrapper, obs mode and statistics come from its files) and
    gives the same episodes as the bare zip with all of them spelled out."""
    env_id, zoo_run = zoo_run
    assert main(["evaluate", "--policy", str(zoo_run), "--env", env_id, "--episodes", "2", "--seed", "60",
                 "--env-kwargs", json.dumps(SHORT), "--json", "--trust-pickle"]) == 0
    folder = json.loads(capsys.readouterr().out)
    opts = ModelOptions("ppo", "residual-ekf-pid", 0.3, str(zoo_run / env_id / "vecnormalize.pkl"), trust_pickle=True)
    bare = evaluate(str(zoo_run / f"{env_id}.zip"), env_id, 2, 60, {**SHORT, "obs_mode": "sensors"}, progress=False,
                    model_options=opts)
    assert folder["per_episode"] == bare["per_episode"]
    # An option that contradicts the folder's files is refused in one line.
    assert main(["evaluate", "--policy", str(zoo_run), "--env", env_id, "--episodes", "1", "--seed", "0",
                 "--wrapper", "none"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--wrapper 'none' contradicts" in err[0] and "config.yml" in err[0], err
