"""``omni-gym train --timesteps N`` says when PPO rounds N up to whole rollouts, and ``meta.json`` records the
steps that ran (``timesteps``) beside the ones asked for (``requested_timesteps``)."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("stable_baselines3")

from omni_gym.cli import main  # noqa: E402
from tests.test_train import ENV, SHORT, _small_yaml  # noqa: E402


def test_timesteps_rounded_up_to_whole_rollouts_are_announced_and_recorded(tmp_path, capsys):
    hp = tmp_path / "hp.yml"
    _small_yaml("ppo", hp)  # n_steps 256 × n_envs 2: rollouts of 512 steps
    out = tmp_path / "model"
    assert main(["train", "--algo", "ppo", "--env", ENV, "--timesteps", "600", "--seed", "1", "--out", str(out),
                 "--hyperparams", str(hp), "--env-kwargs", json.dumps(SHORT), "--eval-freq", "0",
                 "--no-progress"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if "rounds up" in line]
    assert notes == ["note: --timesteps 600 rounds up to 1024, whole rollouts of 512 steps (n_steps 256 x n_envs 2); "
                     "meta.json records the steps run as timesteps"], err
    meta = json.loads((out / "meta.json").read_text())
    assert meta["requested_timesteps"] == 600 and meta["timesteps"] == 1024
