"""RLlib integration: Ray's env registry, PPO on each path-following id on a local Ray cluster
(``ray_cluster`` in conftest.py: 127.0.0.1, 2 CPUs, stopped after the module), the output directory, and
evaluation of the checkpoint through ``omni-gym evaluate``.

The trainings are tiny (4 robots, 128-step iterations, 2 s episodes): they check the plumbing, not learning.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from omni_gym.cli import main

ROOT = Path(__file__).resolve().parents[1]
PATH_IDS = ("OmniPathFollow-Phunopas-v0", "OmniPathFollow-Williams-v1")
BATCH = 128  # env steps per PPO iteration (train_batch_size_per_learner)
SHORT = json.dumps({"episode_seconds": 2.0})
TINY = """{id}:
  env_kwargs: {{obs_mode: state}}
  env_wrapper:
    - agents.rewards.TrackingReward: {{reward: squared}}
  n_envs: 4
  training: {{train_batch_size_per_learner: {batch}, minibatch_size: 64, num_epochs: 1}}
  model: {{fcnet_hiddens: [16, 16]}}
"""


def _tiny_file(tmp: Path, env_id: str) -> Path:
    f = tmp / f"tiny-{env_id}.yml"
    f.write_text(TINY.format(id=env_id, batch=BATCH))
    return f


def _train_argv(env_id: str, hp: Path, out: Path, address: str) -> list[str]:
    return ["train", "--backend", "rllib", "--env", env_id, "--hyperparams", str(hp), "--timesteps", str(2 * BATCH),
            "--seed", "3", "--out", str(out), "--eval-freq", str(BATCH), "--eval-episodes", "1", "--env-kwargs",
            SHORT, "--address", address, "--num-env-runners", "1", "--no-progress"]


@pytest.fixture(scope="module", params=PATH_IDS)
def trained(request, ray_cluster, tmp_path_factory):
    """(env id, output directory) of 2 PPO iterations. Phunopas trains in this process (on the fixture's
    connection); Williams in a separate ``omni-gym`` process that connects with ``--address``."""
    env_id = request.param
    tmp = tmp_path_factory.mktemp("rllib")
    out = tmp / "model"
    argv = _train_argv(env_id, _tiny_file(tmp, env_id), out, ray_cluster)
    if env_id == PATH_IDS[0]:
        assert main(argv) == 0
    else:
        env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg"}
        done = subprocess.run([sys.executable, "-m", "omni_gym.cli", *argv], capture_output=True, text=True,
                              cwd=tmp, env=env, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        # One JSON progress line per validation on stdout, also when piped (as the SB3 path prints them).
        rows = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
        assert [r["timesteps"] for r in rows] == [0, BATCH, 2 * BATCH]
    return env_id, out


def _evaluate(policy: Path, env_id: str, capsys, seed: int = 5000) -> dict:
    capsys.readouterr()
    assert main(["evaluate", "--policy", str(policy), "--env", env_id, "--episodes", "1", "--seed", str(seed),
                 "--env-kwargs", SHORT, "--json", "--trust-pickle"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.slow  # a live Ray cluster: 10-25 s of start-up per worker on 2 cores (the rllib extra; CI runs test-slow)
def test_ppo_trains_restores_and_samples_the_native_vector_env(trained, capsys):
    """One test per id over the module's training: under pytest-xdist each worker that draws a test using
    ``trained`` would train again (about 20 s per id), so its checks share one test."""
    _check_sb3_layout(trained)
    _check_restored_checkpoint(trained, capsys)
    _check_env_runner_stack(trained)


def _check_sb3_layout(trained) -> None:
    """2 PPO iterations write the SB3 path's layout: checkpoints, meta.json, curve."""
    env_id, out = trained
    assert (out / "checkpoint" / "rllib_checkpoint.json").is_file()
    assert (out / "final_checkpoint" / "rllib_checkpoint.json").is_file()
    meta = json.loads((out / "meta.json").read_text())
    assert meta["backend"] == "rllib" and meta["algo"] == "ppo" and meta["env_id"] == env_id
    assert meta["seed"] == 3 and meta["model"] == "checkpoint" and meta["obs_mode"] == "state"
    assert meta["iterations"] == 2 and meta["timesteps"] == 2 * BATCH  # 128-step batches: exactly 2 iterations
    assert meta["command"].startswith("omni-gym train --backend rllib --algo ppo --env " + env_id)
    assert meta["git_commit"] is None or len(meta["git_commit"]) == 40
    assert meta["reward"] == "squared" and meta["num_env_runners"] == 1
    # The SB3 path's keys are all there (docs/formats.md): one schema for both backends.
    for key in ("train_env_kwargs", "validation_env_kwargs", "validation_seeds", "best", "wall_time_s",
                "requested_timesteps", "stopped_early", "hyperparams", "hyperparams_file", "wrapper", "n_envs"):
        assert key in meta, key
    curve = np.genfromtxt(out / "curve.csv", delimiter=",", names=True)
    assert list(curve["timesteps"]) == [0, BATCH, 2 * BATCH]
    assert np.all(np.isfinite(curve["val_tracking_rmse"])) and (out / "curve.png").stat().st_size > 0
    assert meta["best"]["timesteps"] in (BATCH, 2 * BATCH)


def _check_restored_checkpoint(trained, capsys) -> None:
    """The restored checkpoint evaluates as its validation did, and deterministically."""
    env_id, out = trained
    meta = json.loads((out / "meta.json").read_text())
    first = _evaluate(out, env_id, capsys)
    again = _evaluate(out, env_id, capsys)
    assert first["per_episode"] == again["per_episode"]  # same seed, deterministic mean action: identical
    for metric in ("tracking_rmse", "final_position_error", "final_heading_error"):
        assert math.isfinite(first[metric]["mean"])
    # The checkpoint holds the weights validated in training (seed 5000, same env): the same episode. The
    # tolerance covers float32 weights round-tripped through the checkpoint (exact in practice).
    assert first["tracking_rmse"]["mean"] == pytest.approx(meta["best"]["val_tracking_rmse"], rel=1e-9)
    bare = _evaluate(out / "checkpoint", env_id, capsys)  # a bare RLlib checkpoint folder
    assert bare["per_episode"] == first["per_episode"]


def _check_env_runner_stack(trained) -> None:
    """Each env runner steps the native vector env (not a SyncVectorEnv of single envs)."""
    _, out = trained
    meta = json.loads((out / "meta.json").read_text())
    [stack] = meta["env_runner_envs"]  # one env runner actor: its env, outermost wrapper first
    assert stack.endswith("DistinctSeeds(VectorTrackingReward(OmniPathVectorEnv)))"), stack
    assert "SyncVectorEnv" not in stack


def test_registry_creators_build_the_native_vector_env_and_distinct_seeds():
    import gymnasium as gym
    from ray.tune.registry import ENV_CREATOR, _global_registry

    from agents.rllib.env import DistinctSeeds, TrainingEnvCreator
    from omni_gym.envs import CUSTOM_ID, ENV_IDS
    from omni_gym.envs.vector import OmniPathVectorEnv
    from omni_gym.rllib import EnvCreator, register_envs

    assert register_envs() == [*ENV_IDS, CUSTOM_ID]
    assert "OmniPathFollow-Mecanum-v0" in ENV_IDS
    for env_id in ("OmniPathFollow-Williams-v1", "OmniPathFollow-Mecanum-v0"):  # 3 omni, 4 mecanum wheels
        assert _global_registry.contains(ENV_CREATOR, env_id)  # what RLlib looks up for .environment(env_id)
        creator = _global_registry.get(ENV_CREATOR, env_id)
        venv = creator({"num_envs": 3, "obs_mode": "state", "episode_seconds": 1.0})
        single = EnvCreator(env_id)({"obs_mode": "state", "episode_seconds": 1.0})
        try:
            assert isinstance(venv.unwrapped, OmniPathVectorEnv) and venv.num_envs == 3
            assert isinstance(single, gym.Env) and single.observation_space == venv.single_observation_space
            assert venv.unwrapped.robot.name == gym.spec(env_id).kwargs["robot"]
        finally:
            venv.close()
            single.close()
    # Env runner k resets with base + k; robot i of runner k must start from base + k*num_envs + i: the
    # second runner's first robot (seed 10 + 4) is a single env reset with seed 14.
    train = TrainingEnvCreator()({"env_id": PATH_IDS[0], "reward": "squared", "seed": 10, "num_envs": 4,
                                  "obs_mode": "state", "episode_seconds": 1.0})
    ref = gym.make(PATH_IDS[0], obs_mode="state", action_mode="twist", episode_seconds=1.0)
    try:
        assert isinstance(train, DistinctSeeds)
        obs, _ = train.reset(seed=11)
        np.testing.assert_array_equal(obs[0], ref.reset(seed=14)[0])
    finally:
        train.close()
        ref.close()


@pytest.mark.parametrize("extra, match", [
    (["--backend", "rllib", "--algo", "sac"], "--backend rllib trains ppo only"),
    (["--backend", "rllib", "--algo", "ppo", "--vec-env", "dummy"], "native vector env only"),
    (["--backend", "rllib", "--tensorboard", "tb"], "--tensorboard applies to --backend sb3"),
    (["--algo", "ppo", "--address", "127.0.0.1:1"], "--address applies to --backend rllib"),
    (["--algo", "ppo", "--num-env-runners", "2"], "--num-env-runners applies to --backend rllib"),
    (["--backend", "sb3"], "--algo is required with --backend sb3"),
    (["--backend", "rllib", "--num-env-runners", "-1"], "--num-env-runners"),
])
def test_train_options_of_the_other_backend_are_one_line_errors(extra, match, tmp_path, capsys):
    out = tmp_path / "m"
    assert main(["train", "--env", PATH_IDS[0], "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("omni-gym: error: ") and match in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_rllib_config_errors_name_the_file(tmp_path, capsys):
    bad = tmp_path / "bad.yml"
    bad.write_text(f"{PATH_IDS[0]}:\n  env_wrapper:\n    - agents.wrappers.EKFFeatures: {{residual_scale: 0.3}}\n")
    assert main(["train", "--backend", "rllib", "--env", PATH_IDS[0], "--hyperparams", str(bad), "--out",
                 str(tmp_path / "m")]) == 2
    assert "bad.yml: env_wrapper" in capsys.readouterr().err
    bad.write_text(f"{PATH_IDS[0]}:\n  n_steps: 256\n")
    assert main(["train", "--backend", "rllib", "--env", PATH_IDS[0], "--hyperparams", str(bad), "--out",
                 str(tmp_path / "m")]) == 2
    assert "unknown key 'n_steps'" in capsys.readouterr().err


def test_committed_rllib_config_has_an_entry_per_path_following_id():
    from agents.rllib.config import load

    for env_id in PATH_IDS:
        hp = load(env_id)
        assert hp.env_kwargs["obs_mode"] == "state" and hp.spec.reward == "squared" and hp.n_timesteps > 0


@pytest.mark.parametrize("layout", ["marker only", "meta without checkpoint", "damaged module"])
def test_missing_or_corrupt_checkpoint_is_a_one_line_error(layout, tmp_path, capsys):
    d = tmp_path / "ckpt"
    d.mkdir()
    if layout == "marker only":
        (d / "rllib_checkpoint.json").write_text("{}")
    elif layout == "meta without checkpoint":
        (d / "meta.json").write_text(json.dumps({"backend": "rllib", "algo": "ppo", "model": "checkpoint",
                                                 "wrapper": "none"}))
    else:
        (d / "rllib_checkpoint.json").write_text("{}")
        module = d.joinpath("learner_group", "learner", "rl_module", "default_policy")
        module.mkdir(parents=True)
        (module / "module_state.pkl").write_bytes(b"not a pickle")
    assert main(["evaluate", "--policy", str(d), "--env", PATH_IDS[0], "--episodes", "1", "--seed", "0",
                 "--trust-pickle"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("omni-gym: error: ") and len(err.strip().splitlines()) == 1


@pytest.mark.slow  # a live Ray cluster: 10-25 s of start-up per worker on 2 cores (the rllib extra; CI runs test-slow)
def test_too_many_env_runners_for_the_cluster_is_refused(ray_cluster, tmp_path, capsys):
    out = tmp_path / "m"
    argv = _train_argv(PATH_IDS[0], _tiny_file(tmp_path, PATH_IDS[0]), out, ray_cluster)
    argv[argv.index("--num-env-runners") + 1] = "3"  # the cluster has 2 CPUs
    assert main(argv) == 2
    assert "the Ray cluster has 2 CPUs" in capsys.readouterr().err and not out.exists()


def test_without_ray_the_error_names_the_extra(monkeypatch):
    import importlib.util

    from omni_gym import rllib

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name.startswith("ray") else real(name))
    with pytest.raises(ModuleNotFoundError, match=r"-e '\.\[rllib\]'"):
        rllib.register_envs()
