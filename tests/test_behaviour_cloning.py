"""Behaviour-cloning warm start of the privileged agent on the true-state feedback law.

Seeds below 10 000 (benchmarks report from 10 000).
"""

import json
import math

import numpy as np
import pytest
import torch
import yaml

from agents.feedback_law import TrueStateFeedback, law_actions
from agents.train import train
from agents.vector_rollout import make_vector_env
from agents.zoo_config import bc_init_spec
from omni_gym.envs.observations import StateObsDecoder

ENV = "OmniPathFollow-Williams-v1"

torch.set_num_threads(1)


def _state_obs(n=4, steps=40, seed=3):
    """State observations of n robots after some random driving (errors, velocities and look-ahead non-zero)."""
    venv = make_vector_env(ENV, n, {"episode_seconds": 2.0}, obs_mode="state")
    obs, _ = venv.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, *_ = venv.step(rng.uniform(-0.5, 0.5, (n, 3)).astype(np.float32))
    return venv, obs


def test_vectorised_law_matches_the_decoded_formula():
    """law_actions on an (N, D) batch equals feed-forward + k·error computed from each row's decoded fields."""
    venv, obs = _state_obs()
    decode = StateObsDecoder.for_env(venv)
    sc = decode.scales
    twist = np.array([sc.max_speed, sc.max_speed, sc.max_yaw_rate])
    for k in (1.0, 2.0, 4.0):
        expect = []
        for row in obs:
            r = decode(row)
            expect.append(np.clip((r.reference_velocity + k * np.array([*r.tracking_error_body, r.heading_error]))
                                  / twist, -1, 1))
        assert np.allclose(law_actions(decode, obs.astype(float), k), expect, atol=1e-12)  # same arithmetic
    raw = law_actions(decode, obs.astype(float), 2.0, clip=False)
    assert np.array_equal(np.clip(raw, -1, 1), TrueStateFeedback(venv).act(obs))
    with pytest.raises(ValueError, match="shape"):
        law_actions(decode, obs[:, :-1].astype(float))
    venv.close()


def _bc_yaml(tmp_path, algo="ppo", obs_mode="state", extra=""):
    body = {ENV: {"env_kwargs": {"obs_mode": obs_mode, "episode_seconds": 2.0},
                  "env_wrapper": [{"agents.rewards.TrackingReward": {"reward": "pose"}}],
                  "callback": [{"agents.callbacks.BehaviourCloningInit": {"rollout_steps": 40, "noise": 0.05,
                                                                          "epochs": 2, "log_std": -3.0}}],
                  "policy": "MlpPolicy", "n_envs": 4,
                  "normalize": "{'norm_obs': False, 'norm_reward': True}"}}
    if algo == "ppo":
        body[ENV].update(n_steps=32, batch_size=64, n_epochs=1,
                         policy_kwargs="dict(log_std_init=-3.0, net_arch=dict(pi=[], vf=[16]))")
    else:
        body[ENV].update(learning_starts=0, batch_size=32, buffer_size=1000,
                         policy_kwargs="dict(net_arch=dict(pi=[16], qf=[16]))")
    path = tmp_path / f"{algo}_bc.yml"
    path.write_text(yaml.safe_dump(body) + extra)
    return path


def test_affine_ppo_actor_clones_the_law_exactly(tmp_path):
    """The law is affine in the state observation, so the least-squares clone reproduces its actions on
    observations it was not fitted on, to float32 rounding (the policy runs in float32)."""
    from stable_baselines3 import PPO

    meta = train("ppo", ENV, 64, 0, tmp_path / "m", hyperparams=_bc_yaml(tmp_path), eval_freq=0)
    assert meta["bc_init"]["label"] == "BC-initialised from the feedback law"
    assert meta["bc_init"]["samples"] == 40 * 4
    saved = json.loads((tmp_path / "m" / "meta.json").read_text())
    assert saved["bc_init"]["mse_last_epoch"] < 1e-10
    # The fine-tuned model moved little in 64 steps; the clone itself is checked on fresh observations.
    venv, obs = _state_obs(n=6, steps=25, seed=11)
    model = PPO.load(tmp_path / "m" / "final_model.zip", device="cpu")
    assert math.isclose(float(model.policy.log_std.detach().mean()), -3.0, abs_tol=0.05)
    decode = StateObsDecoder.for_env(venv)
    act, _ = model.predict(obs, deterministic=True)
    # 64 PPO steps at lr 3e-4 move each weight by at most ~1e-2 (Adam's step); the law's actions are O(0.1-1).
    assert np.abs(act - law_actions(decode, obs.astype(float))).max() < 0.05
    venv.close()


def test_bc_clone_held_through_the_warm_up_is_the_law(tmp_path):
    """With the actor held for longer than the run (actor_warmup; the critic still trains), the saved actor is
    the least-squares clone: its actions equal the law's on unseen observations within float32 rounding of a
    21-input affine map (1e-5)."""
    from stable_baselines3 import PPO

    path = _bc_yaml(tmp_path)
    data = yaml.safe_load(path.read_text())
    data[ENV]["callback"][0]["agents.callbacks.BehaviourCloningInit"]["actor_warmup"] = 10_000
    path.write_text(yaml.safe_dump(data))
    train("ppo", ENV, 64, 0, tmp_path / "m", hyperparams=path, eval_freq=0)
    venv, obs = _state_obs(n=6, steps=25, seed=12)
    model = PPO.load(tmp_path / "m" / "final_model.zip", device="cpu")
    act, _ = model.predict(obs, deterministic=True)
    assert np.abs(act - law_actions(StateObsDecoder.for_env(venv), obs.astype(float))).max() < 1e-5
    venv.close()


def test_sac_bc_runs_and_holds_the_actor(tmp_path):
    """SAC: the actor is regressed on the law and held at its cloned weights during actor_warmup."""
    from stable_baselines3 import SAC

    path = _bc_yaml(tmp_path, "sac")
    data = yaml.safe_load(path.read_text())
    data[ENV]["callback"][0]["agents.callbacks.BehaviourCloningInit"]["actor_warmup"] = 10_000
    path.write_text(yaml.safe_dump(data))
    meta = train("sac", ENV, 32, 0, tmp_path / "m", hyperparams=path, eval_freq=0)
    assert meta["bc_init"]["mse_last_epoch"] < meta["bc_init"]["mse_first_epoch"]  # the regression learned
    model = SAC.load(tmp_path / "m" / "final_model.zip", device="cpu")
    assert float(model.actor.log_std.bias.detach().mean()) == pytest.approx(-3.0)  # held: no actor update reached it
    assert float(model.actor.log_std.weight.detach().abs().max()) == 0.0


def test_bc_needs_the_state_observation_and_known_keys(tmp_path):
    with pytest.raises(ValueError, match="obs_mode 'state'"):
        train("ppo", ENV, 64, 0, tmp_path / "a", hyperparams=_bc_yaml(tmp_path, obs_mode="sensors"), eval_freq=0)
    hp = {"callback": [{"agents.callbacks.BehaviourCloningInit": {"gain": 2.0, "epoch": 3}}]}
    with pytest.raises(ValueError, match="unknown keyword 'epoch'"):
        bc_init_spec(hp, "f.yml")
    hp = {"callback": [{"agents.callbacks.BehaviourCloningInit": {"rollout_steps": 0}}]}
    with pytest.raises(ValueError, match="rollout_steps"):
        bc_init_spec(hp, "f.yml")
    assert bc_init_spec({}, "f.yml") is None


def _features_yaml(tmp_path, warmup=10_000):
    body = {ENV: {"env_kwargs": {"obs_mode": "sensors", "episode_seconds": 2.0},
                  "env_wrapper": [{"agents.wrappers.EKFFeatures": {"residual_scale": 0.0, "reward": "pose"}}],
                  "callback": [{"agents.callbacks.BehaviourCloningInit": {
                      "teacher": "ekf-pid", "rollout_steps": 40, "noise": 0.05, "log_std": -3.0,
                      "actor_warmup": warmup}}],
                  "policy": "MlpPolicy", "n_envs": 4, "n_steps": 32, "batch_size": 64, "n_epochs": 1,
                  "normalize": "{'norm_obs': False, 'norm_reward': True}",
                  "policy_kwargs": "dict(log_std_init=-3.0, net_arch=dict(pi=[], vf=[16]))"}}
    path = tmp_path / "ppo_features_bc.yml"
    path.write_text(yaml.safe_dump(body))
    return path


def test_features_agent_cloned_from_ekf_pid_is_ekf_pid(tmp_path):
    """Teacher 'ekf-pid': ekf-pid's action is one of the EKF features (its twist before clipping), so the
    affine clone held through the warm-up drives exactly as ekf-pid: the same actions as the wrapper's own
    ekf-pid on a fresh episode, within float32 rounding of a (30 + 3n)-input affine map (1e-5)."""
    from stable_baselines3 import PPO

    from agents.train import make_train_env

    meta = train("ppo", ENV, 64, 0, tmp_path / "m", hyperparams=_features_yaml(tmp_path), eval_freq=0)
    assert meta["bc_init"]["label"] == "BC-initialised from ekf-pid"
    model = PPO.load(tmp_path / "m" / "final_model.zip", device="cpu")
    env = make_train_env(ENV, {"episode_seconds": 2.0}, "ekf-features", 0.0, None, "env")
    obs, _ = env.reset(seed=77)
    worst = 0.0
    for _ in range(150):
        act, _ = model.predict(obs, deterministic=True)
        worst = max(worst, float(np.abs(act - env.base_action).max()))
        obs, _, terminated, truncated, _ = env.step(act)
        if terminated or truncated:
            break
    assert worst < 1e-5
    env.close()


def test_ekf_pid_teacher_needs_the_features_wrapper(tmp_path):
    path = _bc_yaml(tmp_path)  # the state observation, no wrapper
    data = yaml.safe_load(path.read_text())
    data[ENV]["callback"][0]["agents.callbacks.BehaviourCloningInit"]["teacher"] = "ekf-pid"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match="teacher 'ekf-pid' reads the EKF features"):
        train("ppo", ENV, 64, 0, tmp_path / "a", hyperparams=path, eval_freq=0)
    with pytest.raises(ValueError, match="teacher 'pid': choose one of law, ekf-pid"):
        bc_init_spec({"callback": [{"agents.callbacks.BehaviourCloningInit": {"teacher": "pid"}}]}, "f.yml")


def test_residual_agent_held_at_zero_is_ekf_pid(tmp_path):
    """ResidualInit with factor 0 and a warm-up longer than the run: the residual is exactly 0, so the agent
    with its residual wrapper drives as ekf-pid (actions equal to float32 rounding)."""
    from stable_baselines3 import PPO

    from agents.train import make_train_env

    body = {ENV: {"env_kwargs": {"obs_mode": "sensors", "episode_seconds": 2.0},
                  "env_wrapper": [{"agents.wrappers.EKFFeatures": {"residual_scale": 0.3, "reward": "pose"}}],
                  "callback": [{"agents.callbacks.ResidualInit": {"factor": 0.0, "actor_warmup": 10_000}}],
                  "policy": "MlpPolicy", "n_envs": 4, "n_steps": 32, "batch_size": 64, "n_epochs": 1,
                  "normalize": "{'norm_obs': False, 'norm_reward': True}",
                  "policy_kwargs": "dict(log_std_init=-2.3, net_arch=dict(pi=[16], vf=[16]))"}}
    path = tmp_path / "res.yml"
    path.write_text(yaml.safe_dump(body))
    train("ppo", ENV, 64, 0, tmp_path / "m", hyperparams=path, eval_freq=0)
    model = PPO.load(tmp_path / "m" / "final_model.zip", device="cpu")
    env = make_train_env(ENV, {"episode_seconds": 2.0}, "residual-ekf-pid", 0.3, None, "env")
    obs, _ = env.reset(seed=78)
    for _ in range(50):
        act, _ = model.predict(obs, deterministic=True)
        assert np.abs(act).max() == 0.0  # held: the zeroed output layer never received an update
        obs, *_ = env.step(act)
    env.close()


def test_affine_skip_actor_clones_the_law_exactly_and_starts_its_mlp_at_zero(tmp_path):
    """agents.networks.AffineSkip: features [x, mlp(x)] under an affine actor. The least-squares clone puts the
    law on x and zero on mlp(x), so, held through the warm-up, the actor is the law on unseen observations
    (float32 rounding, 1e-5) and its nonlinear weights are exactly 0; the MLP exists (64 features)."""
    from stable_baselines3 import PPO

    path = _bc_yaml(tmp_path)
    data = yaml.safe_load(path.read_text())
    data[ENV]["callback"][0]["agents.callbacks.BehaviourCloningInit"]["actor_warmup"] = 10_000
    data[ENV]["policy_kwargs"] = ("dict(features_extractor_class=AffineSkip, features_extractor_kwargs=dict(hidden=64),"
                                  " share_features_extractor=False, log_std_init=-3.0, net_arch=dict(pi=[], vf=[16]))")
    path.write_text(yaml.safe_dump(data))
    meta = train("ppo", ENV, 64, 0, tmp_path / "m", hyperparams=path, eval_freq=0)
    assert meta["bc_init"]["mse_last_epoch"] < 1e-10
    model = PPO.load(tmp_path / "m" / "final_model.zip", device="cpu")
    w = model.policy.action_net.weight.detach().numpy()
    d = model.observation_space.shape[0]
    assert w.shape == (3, d + 64) and np.all(w[:, d:] == 0.0)
    venv, obs = _state_obs(n=6, steps=25, seed=13)
    act, _ = model.predict(obs, deterministic=True)
    assert np.abs(act - law_actions(StateObsDecoder.for_env(venv), obs.astype(float))).max() < 1e-5
    venv.close()
