"""Training SB3 agents: the wrappers, the hyperparameter files and a smoke run of each algorithm end to end.

Seeds: the tests use seeds below 10 000 (benchmarks report from 10 000).
"""

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from stable_baselines3 import PPO

from agents.algorithms import ALGOS
from agents.evaluate import evaluate
from agents.policies import make_policy
from agents.rollout import make_env, run_episode
from agents.train import HYPERPARAM_DIR, load_hyperparams, train, train_into
from agents.wrappers import EKFFeatures, SensorNoiseRandomizer, wrap_env
from agents.zoo_config import LEGACY_KEYS, residual_init, wrapper_spec
from omni_gym.cli import main
from omni_gym.sensor_bank import STD_GYRO

ENV = "OmniPathFollow-Phunopas-v0"
ROOT = Path(__file__).resolve().parents[1]
SHORT = {"episode_seconds": 1.0}

torch.set_num_threads(1)


# --- wrappers -------------------------------------------------------------------------------------


def test_zero_residual_is_exactly_ekf_pid():
    """Action 0 of the residual wrapper sends the ekf-pid action: same episode, bit for bit."""
    env = make_env(ENV, {"episode_seconds": 3.0})
    base = run_episode(env, make_policy("ekf-pid", env), 7)
    wrapped = wrap_env(make_env(ENV, {"episode_seconds": 3.0}), "residual-ekf-pid")
    obs, _ = wrapped.reset(seed=7)
    assert obs.shape == wrapped.observation_space.shape and wrapped.observation_space.contains(obs)
    sq, steps = 0.0, 0
    while True:
        obs, _, terminated, truncated, info = wrapped.step(np.zeros(3, dtype=np.float32))
        sq += info["tracking_error"] ** 2
        steps += 1
        if terminated or truncated:
            break
    assert steps == base.steps
    assert math.sqrt(sq / steps) == base.tracking_rmse  # identical arithmetic on identical numbers


def test_residual_is_bounded_and_added_to_the_pid_action():
    env = wrap_env(make_env(ENV, SHORT), "residual-ekf-pid", residual_scale=0.3)
    env.reset(seed=3)
    for a in (np.ones(3), -np.ones(3), np.array([5.0, -5.0, 0.5])):  # out-of-range actions are clipped to ±1
        base = env.base_action.copy()
        env.step(a.astype(np.float32))
        sent = env.unwrapped.core.prev_action[0]  # the clipped action the environment received
        expected = np.clip(base + 0.3 * np.clip(a, -1, 1), -1, 1)
        assert np.allclose(sent, expected, atol=1e-6)  # float32 round trip of the action (~1e-7)


def test_ekf_features_gives_the_whole_action_to_the_agent():
    env = wrap_env(make_env(ENV, SHORT), "ekf-features")
    env.reset(seed=3)
    env.step(np.array([0.5, -0.25, 0.1], dtype=np.float32))
    assert np.allclose(env.unwrapped.core.prev_action[0], [0.5, -0.25, 0.1], atol=1e-6)


def test_ekf_features_estimate_is_the_filter_pose():
    env = wrap_env(make_env(ENV, SHORT), "residual-ekf-pid")
    _, info = env.reset(seed=4)
    for _ in range(50):
        _, _, _, _, info = env.step(np.zeros(3, dtype=np.float32))
    assert np.array_equal(env.estimate, env.base.ekf.pose)
    # The filter tracks the true pose to centimetres on a 0.5 s stretch (camera fixes: 5 mm std).
    assert np.linalg.norm(env.estimate[:2] - np.asarray(info["pose"])[:2]) < 0.03


def test_sensor_noise_randomizer_draws_per_seed_and_scales_the_sensors():
    env = SensorNoiseRandomizer(make_env(ENV, SHORT), (0.5, 1.5))
    scales = []
    for seed in (1, 2, 1):
        env.reset(seed=seed)
        scales.append(env.scale)
        gyro_std = env.unwrapped.core.sensors.std[0, STD_GYRO]  # the std robot 0's sensors draw with
        assert gyro_std == pytest.approx(0.005 * env.scale, rel=1e-12)  # SensorConfig default 0.005 rad/s
    assert scales[0] == scales[2] != scales[1]
    assert all(0.5 <= s <= 1.5 for s in scales)


@pytest.mark.parametrize("bad, match", [
    ({"obs_mode": "state"}, "obs_mode='sensors'"),
])
def test_wrappers_reject_other_modes(bad, match):
    import gymnasium as gym

    import omni_gym  # noqa: F401

    env = gym.make(ENV, **bad)
    with pytest.raises(ValueError, match=match):
        EKFFeatures(env)
    with pytest.raises(ValueError, match="unknown wrapper 'x'"):
        wrap_env(make_env(ENV, SHORT), "x")
    with pytest.raises(ValueError, match="residual_scale"):
        EKFFeatures(make_env(ENV, SHORT), residual_scale=2.0)


# --- hyperparameter files -------------------------------------------------------------------------


@pytest.mark.parametrize("algo", ALGOS)
def test_committed_hyperparams_have_the_zoo_keys(algo):
    hp = load_hyperparams(algo, ENV)
    for key in ("n_timesteps", "policy", "n_envs", "env_wrapper"):
        assert key in hp
    # The RL Zoo's syntax: importable wrapper classes with their keywords, no keys of our own.
    assert hp["env_wrapper"][-1] == {"agents.wrappers.EKFFeatures": {"residual_scale": 0.3, "reward": "squared"}}
    assert not set(LEGACY_KEYS) & set(hp)
    spec = wrapper_spec(hp, "test")
    assert spec.name == "residual-ekf-pid" and spec.sensor_noise_range == [0.5, 1.5]
    # Domain randomisation is on for every committed configuration.
    assert {"randomize_friction", "randomize_mass", "randomize_lift_rate"} <= set(hp["env_kwargs"])


@pytest.mark.parametrize("algo", ["ppo", "sac"])
@pytest.mark.parametrize("env_id", [ENV, "OmniPathFollow-Williams-v1"])
def test_every_learned_agent_trains_on_the_squared_tracking_error(env_id, algo):
    """The privileged, EKF-feature and residual agents differ in what they observe, not in the reward,
    with either algorithm; the residual agents of both start at ekf-pid (ResidualInit)."""
    for agent, name in (("privileged", "none"), ("features", "ekf-features"), ("residual", "residual-ekf-pid")):
        hp = load_hyperparams(algo, env_id, HYPERPARAM_DIR / f"{algo}_{agent}.yml")
        spec = wrapper_spec(hp, agent)
        assert (spec.name, spec.reward) == (name, "squared"), (algo, agent)
        assert hp["env_kwargs"]["obs_mode"] == ("state" if agent == "privileged" else "sensors")
        inits = [c for c in hp.get("callback", []) if "agents.callbacks.ResidualInit" in c]
        assert bool(inits) == (agent == "residual"), (algo, agent)


def _shrink(hp: dict) -> dict:
    """One environment, one small PPO update: enough to compare two trainings weight by weight."""
    return {**hp, "n_envs": 1, "n_steps": 64, "batch_size": 32, "n_epochs": 1}


def test_zoo_layout_trains_the_same_agent_as_the_earlier_layout(tmp_path):
    """The committed model's meta.json records the ppo.yml entry it was trained with, in the earlier layout
    (env_wrapper: residual-ekf-pid, residual_scale, reward, sensor_noise_range, residual_init). The RL Zoo
    layout of today's ppo.yml must give the same training: bit-identical weights after an update."""
    legacy = json.loads((ROOT / "agents/models/ppo-residual/meta.json").read_text())["hyperparams"]
    assert legacy["env_wrapper"] == "residual-ekf-pid" and "residual_init" in legacy
    weights, metas = [], []
    for name, hp in (("legacy", legacy), ("zoo", load_hyperparams("ppo", ENV))):
        f = tmp_path / f"{name}.yml"
        f.write_text(yaml.safe_dump({ENV: _shrink(hp)}))
        meta = train("ppo", ENV, 64, 3, tmp_path / name, SHORT, f, eval_freq=0, progress=False)
        metas.append(meta)
        model = PPO.load(tmp_path / name / "model.zip", device="cpu")
        weights.append({k: v.clone() for k, v in model.policy.state_dict().items()})
    for key in ("wrapper", "residual_scale", "sensor_noise_range", "reward", "obs_mode"):
        assert metas[0][key] == metas[1][key], key
    assert weights[0].keys() == weights[1].keys()
    for key in weights[0]:
        assert torch.equal(weights[0][key], weights[1][key]), key
    # The residual initialisation took place: PPO's action layer (orthogonal rows of norm 0.01) scaled by
    # 0.01 gives rows of norm 1e-4; two Adam steps of lr 1e-4 move each of the 64 weights of a row by at
    # most 2e-4, the row by at most 1.6e-3. Unscaled rows would have norm 0.01 ± 1.6e-3.
    assert torch.linalg.norm(weights[1]["action_net.weight"], dim=1).max() < 4e-3


@pytest.mark.parametrize("entry, match", [
    ({"env_wrapper": ["agents.wrappers.Nope"]}, r"env_wrapper: 'agents.wrappers.Nope'"),
    ({"env_wrapper": [{"agents.wrappers.EKFFeatures": {"scale": 0.3}}]}, r"unknown keyword 'scale'"),
    ({"env_wrapper": ["agents.wrappers.EKFFeatures", {"agents.wrappers.SensorNoiseRandomizer": {}}]},
     "in this order"),
    ({"env_wrapper": ["agents.wrappers.EKFFeatures"], "residual_scale": 0.3}, r"key 'residual_scale' belongs"),
    ({"env_wrapper": "residual_ekf_pid"}, "env_wrapper 'residual_ekf_pid'"),
    ({"env_wrapper": [["a"]]}, "each entry must be a class path"),
    ({"env_wrapper": [{"agents.rewards.TrackingReward": {"mode": "squared"}}]}, r"unknown keyword 'mode'"),
    ({"env_wrapper": ["agents.wrappers.EKFFeatures", "agents.rewards.TrackingReward"]}, "alone"),
])
def test_wrapper_entries_are_checked_with_file_and_key(entry, match):
    with pytest.raises(ValueError, match=match):
        wrapper_spec(entry, "hp.yml")
    assert "hp.yml" in str(pytest.raises(ValueError, wrapper_spec, entry, "hp.yml").value)


def test_callback_entries_are_checked():
    assert residual_init({"callback": [{"agents.callbacks.ResidualInit": {"factor": 0.5, "log_std": -2}}]},
                         "w") == (0.5, -2.0, 0)
    assert residual_init({"callback": [{"agents.callbacks.ResidualInit": {"factor": 0.0, "actor_warmup": 500}}]},
                         "w") == (0.0, None, 500)
    assert residual_init({"residual_init": 0.01}, "w") == (0.01, None, 0)  # the earlier layout
    with pytest.raises(ValueError, match="actor_warmup must be an integer >= 0"):
        residual_init({"callback": [{"agents.callbacks.ResidualInit": {"actor_warmup": -1}}]}, "w")
    with pytest.raises(ValueError, match="callback: 'x.Y': this trainer knows only"):
        residual_init({"callback": ["x.Y"]}, "w")


def test_hyperparams_errors_name_file_and_key(tmp_path):
    f = tmp_path / "hp.yml"
    f.write_text("Other-v0: {n_timesteps: 10}\n")
    with pytest.raises(ValueError, match=r"hp.yml: no entry for 'OmniPathFollow-Phunopas-v0'"):
        load_hyperparams("ppo", ENV, f)
    f.write_text("a: [1, 2\n")
    with pytest.raises(ValueError, match="hp.yml: not valid YAML"):
        load_hyperparams("ppo", ENV, f)
    f.write_text(f"{ENV}: {{n_timesteps: 10, policy_kwargs: \"dict(x=__import__('os'))\"}}\n")
    with pytest.raises(ValueError, match="policy_kwargs"):
        train("ppo", ENV, 10, 0, tmp_path / "out", SHORT, f, n_envs=1, eval_freq=0, progress=False)


@pytest.mark.parametrize("entry, expected", [
    ({"n_steps": -1}, "n_steps must be an integer in [1, 1000000] steps, got -1"),
    ({"n_steps": 10**15}, "n_steps must be an integer in [1, 1000000] steps"),  # numpy: "maximum dimension"
    ({"gamma": "abc"}, "gamma: must be a number, got 'abc'"),
    ({"gamma": 1.5}, "gamma must be a number in [0, 1]"),
    ({"batch_size": 0}, "batch_size must be an integer"),
    ({"learning_rate": "lin_x"}, "learning_rate: must be a number, got 'x'"),
    ({"learning_rate": -1e-3}, "learning_rate must be a number in (0, 1]"),
    ({"ent_coef": "automatic"}, "ent_coef: must be a number"),
    ({"n_envs": True}, "n_envs: must be a number, got True"),
])
def test_bad_hyperparameters_are_refused_with_file_and_key(entry, expected, tmp_path, capsys):
    """Before they reach Stable-Baselines3 (which answered with an AssertionError, "could not convert string to
    float" or "Maximum allowed dimension exceeded"): one line naming the file and the key, exit 2, no output."""
    f = tmp_path / "hp.yml"
    f.write_text(yaml.safe_dump({ENV: {"policy": "MlpPolicy", "n_envs": 1, **entry}}))
    out = tmp_path / "m"
    assert main(["train", "--algo", "ppo", "--env", ENV, "--timesteps", "64", "--out", str(out), "--hyperparams",
                 str(f), "--eval-freq", "0", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"omni-gym: error: {f}: ") and expected in err[0], err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["hp.yml"]


def test_hyperparameter_numbers_written_as_yaml_strings_are_read():
    """PyYAML reads ``1e-3`` (no dot) as a string; SB3 and the RL Zoo take it as the number it spells."""
    from agents.options import check_hyperparams

    hp = check_hyperparams({"learning_rate": "1e-3", "n_steps": 256.0, "ent_coef": "auto_0.1", "policy": "x"}, "f",
                           "sac")
    assert hp == {"learning_rate": 1e-3, "n_steps": 256, "ent_coef": "auto_0.1", "policy": "x"}
    assert isinstance(hp["n_steps"], int)
    with pytest.raises(ValueError, match="f: ent_coef: must be a number, got 'auto'"):
        check_hyperparams({"ent_coef": "auto"}, "f", "ppo")  # PPO has no automatic entropy coefficient
    for path in sorted(HYPERPARAM_DIR.glob("*.yml")):  # every shipped entry passes, each value as written
        algo = path.stem.partition("_")[0]
        for env_id, raw in yaml.safe_load(path.read_text()).items():
            checked = check_hyperparams(raw, path.name, algo)
            assert checked == raw, (path.name, env_id)


def test_hyperparameter_file_encodings(tmp_path, capsys):
    """UTF-16 with a byte order mark is valid YAML and is read; bytes that are no text give one line naming
    the file (UnicodeDecodeError without the file, before)."""
    entry = {ENV: {"n_timesteps": 10, "gamma": 0.9}}
    f = tmp_path / "hp.yml"
    f.write_bytes(yaml.safe_dump(entry).encode("utf-16"))  # Python writes the BOM
    assert load_hyperparams("ppo", ENV, f) == entry[ENV]
    f.write_bytes(b"\xff\xfe\x00\xd8 broken")  # a BOM, then an unpaired surrogate
    with pytest.raises(ValueError, match=r"hp.yml: not valid YAML"):
        load_hyperparams("ppo", ENV, f)
    f.write_bytes(b"gamma: \xe9t\xe9\n")  # Latin-1, not UTF-8
    assert main(["train", "--algo", "ppo", "--env", ENV, "--out", str(tmp_path / "m"), "--hyperparams", str(f),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"omni-gym: error: {f}: not valid YAML"), err


def test_a_shipped_hyperparameter_file_is_named_by_its_stem(tmp_path, monkeypatch):
    """``--hyperparams ppo_residual`` works from any folder (after pip install there is no agents/hyperparams
    beside the user); a file of that name in the current folder wins."""
    from agents.train import hyperparams_path, shipped_hyperparams

    monkeypatch.chdir(tmp_path)
    assert hyperparams_path("ppo", "ppo_residual") == HYPERPARAM_DIR / "ppo_residual.yml"
    assert hyperparams_path("ppo", "ppo_residual.yml") == HYPERPARAM_DIR / "ppo_residual.yml"
    assert load_hyperparams("ppo", "OmniPathFollow-Williams-v1", "ppo_residual") == yaml.safe_load(
        (HYPERPARAM_DIR / "ppo_residual.yml").read_text())["OmniPathFollow-Williams-v1"]
    assert {"ppo", "ppo_residual", "sac_privileged", "td3"} <= set(shipped_hyperparams())
    (tmp_path / "ppo_residual").write_text(f"{ENV}: {{gamma: 0.5}}\n")
    assert load_hyperparams("ppo", ENV, "ppo_residual") == {"gamma": 0.5}
    with pytest.raises(ValueError, match=r"--hyperparams ppo_resid: no such file, nor a shipped .*ppo_residual"):
        load_hyperparams("ppo", ENV, "ppo_resid")
    with pytest.raises(ValueError, match=r"no such file"):
        load_hyperparams("ppo", ENV, "sub/ppo_residual")  # a path is a path: no lookup among shipped files


def test_a_missing_entry_names_the_shipped_files_that_hold_the_id(tmp_path):
    """ppo.yml holds only the Phunopas id; the message points to the files with the Williams id."""
    holding = sorted(p.stem for p in HYPERPARAM_DIR.glob("*.yml")
                     if "OmniPathFollow-Williams-v1" in yaml.safe_load(p.read_text()))
    assert "ppo_residual" in holding and "ppo" not in holding  # the premise of this test
    with pytest.raises(ValueError) as info:
        load_hyperparams("ppo", "OmniPathFollow-Williams-v1")
    message = str(info.value)
    assert "ppo.yml: no entry for 'OmniPathFollow-Williams-v1'" in message
    assert f"shipped files with an entry for it: {', '.join(holding)}" in message
    with pytest.raises(ValueError, match="no shipped hyperparameter file has one"):
        load_hyperparams("ppo", "OmniGoToPose-v0")


# --- smoke runs -----------------------------------------------------------------------------------


def _small_yaml(algo: str, path) -> None:
    """The committed configuration with batch sizes and warm-up shrunk to fit a few thousand steps."""
    data = yaml.safe_load((HYPERPARAM_DIR / f"{algo}.yml").read_text())
    hp = data[ENV]
    hp["n_envs"] = 2
    if algo == "ppo":
        hp.update(n_steps=256, batch_size=128, n_epochs=2)
    else:
        hp.update(learning_starts=200, batch_size=64, buffer_size=5000)
    path.write_text(yaml.safe_dump(data))


@pytest.mark.parametrize("algo", ALGOS)
def test_train_smoke_and_evaluate_end_to_end(algo, tmp_path, capsys):
    """Train a few thousand steps through the CLI, then evaluate the directory through the CLI."""
    hp = tmp_path / "hp.yml"
    _small_yaml(algo, hp)
    out = tmp_path / "model"
    assert main(["train", "--algo", algo, "--env", ENV, "--timesteps", "2000", "--seed", "1", "--out", str(out),
                 "--hyperparams", str(hp), "--env-kwargs", json.dumps(SHORT), "--eval-freq", "1000",
                 "--eval-episodes", "1", "--no-progress"]) == 0
    capsys.readouterr()
    meta = json.loads((out / "meta.json").read_text())
    assert meta["algo"] == algo and meta["seed"] == 1 and meta["timesteps"] >= 2000
    assert meta["command"].startswith("omni-gym train") and "--seed 1" in meta["command"]
    assert meta["wrapper"] == "residual-ekf-pid" and meta["wall_time_s"] > 0
    assert (out / "model.zip").is_file() and (out / "vecnormalize.pkl").is_file()
    curve = np.genfromtxt(out / "curve.csv", delimiter=",", names=True)
    assert list(curve["timesteps"]) == [0, 1000, 2000]  # validation at the start and every 1000 steps
    assert (out / "curve.png").is_file()

    assert main(["evaluate", "--policy", str(out), "--env", ENV, "--episodes", "2", "--seed", "11",
                 "--env-kwargs", json.dumps(SHORT), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["episodes"] == 2 and result["policy"] == str(out)
    assert all(math.isfinite(v) for v in result["per_episode"]["tracking_rmse"])


def test_train_rejects_bad_input_in_one_line(tmp_path, capsys):
    for args, expected in (
        (["--env-kwargs", "{x"], "--env-kwargs: not valid JSON"),
        (["--env-kwargs", '{"surface": "ice"}'], "surface"),
        (["--timesteps", "0"], "--timesteps must be an integer in [1, 1000000000]"),
    ):
        assert main(["train", "--algo", "ppo", "--env", ENV, "--seed", "0", "--out", str(tmp_path / "m"),
                     "--no-progress", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("omni-gym: error: ") and expected in err[0], err


@pytest.mark.parametrize("option, value", [
    ("--max-minutes", "-1"), ("--max-minutes", "0"), ("--max-minutes", "nan"), ("--threads", "0"),
    ("--threads", "-2"), ("--seed", "-1"), ("--seed", str(2**31)), ("--timesteps", "-5"), ("--timesteps", "inf"),
    ("--timesteps", "100.5"), ("--eval-freq", "-1"), ("--eval-episodes", "0"), ("--checkpoint-freq", "-1"),
    ("--n-envs", "0"),
])
def test_train_options_out_of_bounds_are_refused_before_anything_is_touched(option, value, tmp_path, capsys):
    """E.g. --max-minutes -1 used to be accepted and overwrite the model directory."""
    out = tmp_path / "model"
    out.mkdir()
    (out / "meta.json").write_text("{}")  # an existing model directory: it must survive, byte for byte
    assert main(["train", "--algo", "ppo", "--env", ENV, "--out", str(out), "--no-progress", "--force",
                 option, value]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"omni-gym: error: {option} must be "), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model"] and os.listdir(out) == ["meta.json"]
    assert (out / "meta.json").read_text() == "{}"


def test_train_library_refuses_zero_threads(tmp_path):
    with pytest.raises(ValueError, match="threads must be an integer >= 1"):
        train_into("ppo", ENV, 10, 0, tmp_path / "m", SHORT, threads=0)


def test_evaluate_rejects_a_missing_model_or_meta(tmp_path):
    with pytest.raises(ValueError, match="model.zip: no such model file"):
        evaluate(str(tmp_path / "model.zip"), ENV, 1, 0)
    with pytest.raises(ValueError, match=r"neither our model directory \(meta.json\) nor an RL Zoo folder"):
        evaluate(str(tmp_path), ENV, 1, 0)
    (tmp_path / "meta.json").write_text("{not json")
    with pytest.raises(ValueError, match="meta.json: not valid JSON"):
        evaluate(str(tmp_path), ENV, 1, 0)
    (tmp_path / "meta.json").write_text(json.dumps({"algo": "dqn", "model": "m.zip", "wrapper": "none"}))
    with pytest.raises(ValueError, match="unknown algorithm 'dqn'"):
        evaluate(str(tmp_path), ENV, 1, 0)


@pytest.mark.parametrize("lost", [0.5, 0.001])
def test_squared_reward_is_the_squared_tracking_error_with_a_lost_penalty(lost):
    """reward="squared": −(e/0.1 m)² − 0.01·mean(a²) per step, minus 50 steps at the lost distance when lost."""
    kw = {**SHORT, "lost_distance": lost, "success_distance": lost / 2}  # success below lost
    env = wrap_env(make_env(ENV, kw), "residual-ekf-pid", reward="squared")
    env.reset(seed=6)
    a = np.array([1.0, -1.0, 0.0], dtype=np.float32)  # the full residual pushes the robot off the path
    for _ in range(env.unwrapped.cfg.episode_steps):
        _, r, terminated, truncated, info = env.step(a)
        expected = -((info["tracking_error"] / 0.1) ** 2) - 0.01 * np.mean(a.astype(float) ** 2)
        if terminated:
            expected -= 50 * (lost / 0.1) ** 2
        assert r == pytest.approx(expected, rel=1e-12, abs=1e-15)
        if terminated or truncated:
            break
    # 1 mm (the smallest lost_distance allowed) is left within the 1 s episode; 0.5 m is not.
    assert terminated == (lost < 0.01)


def test_tracking_reward_is_bounded_and_positive():
    env = wrap_env(make_env(ENV, SHORT), "residual-ekf-pid", reward="tracking")
    env.reset(seed=6)
    for _ in range(20):
        _, r, *_ = env.step(np.ones(3, dtype=np.float32))
        assert -0.02 <= r <= 1.0  # 0.5 + 0.5 at e = 0; the action term costs at most 0.02


def test_option_bounds_are_the_tables_in_docs_bounds_md():
    from agents.options import EVALUATE, HYPERPARAMS, TRAIN
    from omni_gym.bounds import markdown_table

    text = (ROOT / "docs" / "bounds.md").read_text()
    for name, table in (("train", TRAIN), ("evaluate", EVALUATE), ("hyperparameter", HYPERPARAMS)):
        assert markdown_table(table) in text, f"docs/bounds.md: the {name} options differ from agents/options.py"


def test_training_on_a_model_file_keeps_the_model_itself(tmp_path, capsys):
    """A calibrated model file enters training, and meta.json holds its content, not its path.

    The report a model.json came from may be replaced (``gap --force``) or the agent evaluated from
    another folder: the run must stay reproducible from meta.json alone.
    """
    import gymnasium as gym

    from omni_gym.physics.model import load_model

    model = load_model("phunopas2018", "carpet", "roller_gap").with_effect(
        "wheel_radius", {"scale": [1.02, 0.98, 1.0, 1.01]})
    path = tmp_path / "calibrated.json"
    path.write_text(json.dumps(model.to_json()))
    hp = tmp_path / "hp.yml"
    _small_yaml("ppo", hp)
    out = tmp_path / "model"
    kwargs = {**SHORT, "model": str(path)}
    assert main(["train", "--algo", "ppo", "--env", ENV, "--timesteps", "256", "--seed", "1", "--out", str(out),
                 "--hyperparams", str(hp), "--env-kwargs", json.dumps(kwargs), "--eval-freq", "0",
                 "--no-progress"]) == 0
    capsys.readouterr()
    meta = json.loads((out / "meta.json").read_text())
    saved = meta["train_env_kwargs"]["model"]
    assert saved == model.to_json()  # the effect travelled with the model
    path.unlink()
    env = gym.make(ENV, **meta["train_env_kwargs"])  # no file needed any more
    assert env.unwrapped.cfg.base_model().effects["wheel_radius"]["scale"] == [1.02, 0.98, 1.0, 1.01]
    env.close()


# --- training vector env --------------------------------------------------------------------------


def test_native_vec_env_trains_the_same_agent_as_dummy(tmp_path, capsys):
    """--vec-env native (the default) and dummy see the same transitions (same seeds, episodes that end by
    truncation within the rollout, VecNormalize on top): bit-identical weights. With an EKF wrapper and the
    noise randomiser, native trains on VectorEKFFeatures and the randomize_sensor_noise keyword, silently."""
    f = tmp_path / "hp.yml"
    f.write_text(yaml.safe_dump({ENV: {"policy": "MlpPolicy", "n_envs": 3, "n_steps": 64, "batch_size": 48,
                                       "n_epochs": 2, "normalize": True, "env_kwargs": {"obs_mode": "state"}}}))
    weights, metas = [], []
    for kind in ("native", "dummy"):
        meta = train("ppo", ENV, 384, 4, tmp_path / kind, {"episode_seconds": 0.5}, f, vec_env=kind, eval_freq=0,
                     progress=False)
        metas.append(meta)
        weights.append(PPO.load(tmp_path / kind / "final_model.zip", device="cpu").policy.state_dict())
    assert [m["vec_env"] for m in metas] == ["native", "dummy"]
    assert "notice" not in capsys.readouterr().err
    for key in weights[0]:
        assert torch.equal(weights[0][key], weights[1][key]), key

    hp = {**_shrink(load_hyperparams("ppo", ENV)), "n_steps": 16, "batch_size": 16}
    f.write_text(yaml.safe_dump({ENV: hp}))
    meta = train("ppo", ENV, 16, 0, tmp_path / "ekf", SHORT, f, eval_freq=0, progress=False)
    err = capsys.readouterr().err
    assert meta["vec_env"] == "native" and meta["wrapper"] == "residual-ekf-pid" and meta["timesteps"] >= 16
    assert err == ""


# --- progress on a terminal -----------------------------------------------------------------------


def _run_on_a_terminal(argv: list[str], timeout: float = 120.0) -> tuple[int, str, str]:
    """Run ``python -m omni_gym.cli ARGV`` with stderr on a pseudo-terminal (stdout piped); (rc, stdout, tty)."""
    import fcntl
    import pty
    import select
    import struct
    import subprocess
    import sys
    import termios
    import time

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 100 columns, as a terminal has
    env = {**os.environ, "PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg"}
    proc = subprocess.Popen([sys.executable, "-m", "omni_gym.cli", *argv], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=slave, cwd=ROOT, env=env)
    os.close(slave)
    chunks, deadline = [], time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.5)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # EIO: the child closed the terminal
                    break
                if not data:
                    break
                chunks.append(data)
            elif proc.poll() is not None:
                break
        out = proc.communicate(timeout=max(1.0, deadline - time.monotonic()))[0]
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    return proc.returncode, out.decode(), b"".join(chunks).decode(errors="replace")


def test_train_shows_progress_on_a_terminal(tmp_path):
    """With stderr a terminal the progress bar is on by default; validation at step 0 (no best yet) used to
    crash it. The bar and the validation rows go to the terminal, the summary to stdout."""
    f = tmp_path / "hp.yml"
    f.write_text(yaml.safe_dump({ENV: {"policy": "MlpPolicy", "n_envs": 1, "n_steps": 64, "batch_size": 32,
                                       "n_epochs": 1, "env_kwargs": {"obs_mode": "state"}}}))
    rc, out, tty = _run_on_a_terminal(
        ["train", "--algo", "ppo", "--env", ENV, "--timesteps", "128", "--out", str(tmp_path / "m"),
         "--hyperparams", str(f), "--env-kwargs", json.dumps({"episode_seconds": 0.3}), "--eval-freq", "64",
         "--eval-episodes", "1"])
    assert rc == 0, tty
    assert "train ppo" in tty and "val_rmse=" in tty and "best=" in tty  # the bar with its postfix
    rows = [json.loads(line) for line in tty.replace("\r", "\n").splitlines() if line.startswith("{")]
    assert [r["timesteps"] for r in rows] == [0, 64, 128]
    assert out.startswith("trained 128 steps")


def test_curve_plot_reads_as_it_should():
    """curve.png: the RMSE axis starts at 0 (a 1 % wiggle of 0.0505 m must not fill the panel), the reward
    panel names the training reward and its formula, and no label overlaps the title or another label."""
    import matplotlib.pyplot as plt

    from agents.train import CURVE_COLUMNS, curve_figure

    assert CURVE_COLUMNS[2] == "val_tracking_rmse" and CURVE_COLUMNS[5] == "train_ep_reward"
    data = np.array([[0, 0, 0.0505, 0.1, 1, np.nan], [1000, 5, 0.0502, 0.1, 1, -3600.0],
                     [2000, 9, 0.0507, 0.1, 1, -900.0]])
    meta = {"algo": "ppo", "wrapper": "residual-ekf-pid", "env_id": ENV, "seed": 0, "reward": "squared"}
    fig = curve_figure(data, meta)
    rmse_ax, reward_ax = fig.axes
    lo, hi = rmse_ax.get_ylim()
    assert lo == 0.0 and 0.0507 <= hi <= 0.06  # from zero to just above the data
    assert reward_ax.get_ylim()[1] == 0.0 and reward_ax.get_ylim()[0] < -3600  # returns ≤ 0: up to zero
    assert "'squared'" in reward_ax.get_title() and "(e/0.1 m)²" in reward_ax.get_title()
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [fig._suptitle.get_window_extent(renderer)] + [
        t.get_window_extent(renderer) for ax in fig.axes for t in (ax.yaxis.label, ax.title)]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert not a.overlaps(b), (a, b)
        assert a.x0 >= 0 and a.x1 <= fig.bbox.width and a.y1 <= fig.bbox.height  # nothing cut off
    plt.close(fig)


def test_batched_validation_equals_single_environment_validation():
    """Training validates with all episodes as robots of one vector env; the curve row equals the one from
    single environments (the batched EKF reproduces the scalar filter within 1e-8 m per step,
    tests/test_vector_rollout.py; over a 3 s episode the RMSE agrees far below the 1e-6 m asserted)."""
    from agents.sb3_policy import build, build_vector
    from agents.train import validation_row, validation_row_vector

    model = "agents/models/ppo-residual-williams"
    kw = {"episode_seconds": 3.0}
    env, single = build(model, None, kw)
    venv, batched = build_vector(model, 4, None, kw)
    a = validation_row(env, single, 4, 0, 0.0, None)
    b = validation_row_vector([venv], [batched], 0, 0.0, None)
    env.close()
    venv.close()
    assert a["val_tracking_rmse"] == pytest.approx(b["val_tracking_rmse"], abs=1e-6)
    assert a["val_final_error"] == pytest.approx(b["val_final_error"], abs=1e-6)
    assert a["val_success"] == b["val_success"]
    assert a["val_tracking_rmse"] > 1e-4  # the episodes ran (a controller tracks to ~mm, not exactly 0)


def test_validation_spreads_its_episodes_over_the_training_floors_and_lift_off(tmp_path):
    """Model selection reads the validation mean, so the episodes must cover what the agent trains on: a run
    on two floors with a randomised lift-off rate validates on four cells (each floor, lift-off rate 0 and
    0.5 /s), the requested episodes spread evenly, the same seeds (5000...) in every cell; the command
    line's default is 100 episodes (30 picked noise, docs/agents.md)."""
    from agents.train import build_arg_parser
    from agents.validation import VALIDATION_EPISODES

    kw = {**SHORT, "randomize_floor": ["grip:initial", "carpet:roller_gap"], "randomize_lift_rate": [0.0, 1.0],
          "randomize_mass": [0.9, 1.1]}
    meta = train("ppo", ENV, 64, 0, tmp_path / "m", kw, n_envs=2, eval_freq=64, eval_episodes=6, progress=False)
    cells = meta["validation_cells"]
    assert [(c["surface"], c.get("friction"), c["lift_rate"]) for c in cells] == [
        ("grip", "initial", 0.0), ("grip", "initial", 0.5), ("carpet", "roller_gap", 0.0),
        ("carpet", "roller_gap", 0.5)]
    assert all("randomize_mass" not in c and c["episode_seconds"] == 1.0 for c in cells)
    assert meta["validation_episodes"] == 8 and meta["validation_seeds"] == [5000, 5001]  # ceil(6 / 4) = 2 each
    assert build_arg_parser().parse_args(["--algo", "ppo", "--env", ENV, "--out", "x"]).eval_episodes is None
    assert VALIDATION_EPISODES >= 100
