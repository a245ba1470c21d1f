"""The ``kinematics`` keyword: twist actions (and the controllers that read ``env.unwrapped.wheel_kinematics``)
through the robot's nominal wheel matrix or the model's effective one (omni_gym.physics.kinematics)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.physics.kinematics import effective_kinematics
from omni_gym.physics.model import load_model

CUSTOM = "OmniPathFollow-Custom-v0"
SCALE = 1.08  # every wheel rolls on a radius 8 % larger than the nominal one


def large_wheel_model():
    """williams2002 (3 omni wheels: W is square, a commanded twist has exactly one set of wheel speeds) on the
    grip floor, every effective rolling radius 8 % above nominal."""
    return load_model("williams2002", surface="grip", friction="initial").with_effect(
        "wheel_radius", {"scale": [SCALE] * 3})


def steady_body_velocity(kinematics: str, twist: np.ndarray) -> np.ndarray:
    """Body-frame velocity (vx, vy [m/s], ω [rad/s]) after holding the twist action for 0.3 s."""
    env = gym.make(CUSTOM, model=large_wheel_model(), kinematics=kinematics, sensor_noise=0.0)
    cfg = env.unwrapped.cfg
    action = (twist / np.array([cfg.max_speed, cfg.max_speed, cfg.max_yaw_rate])).astype(np.float32)
    env.reset(seed=0)
    for _ in range(30):
        _, _, terminated, truncated, info = env.step(action)
        assert not (terminated or truncated)
    theta = info["pose"][2]
    c, s = np.cos(theta), np.sin(theta)
    vx, vy, om = info["velocity"]  # geometric centre, world frame
    return np.array([c * vx + s * vy, -s * vx + c * vy, om])


def test_model_kinematics_drive_the_commanded_twist_nominal_overshoots_by_the_radius_scale():
    """On the grip floor a body moving at the twist the wheel speeds imply needs no friction force, so the
    steady state is that twist (the transient decays at ~3000 /s, docs/model.md: gone within the 0.3 s held;
    0.1 % allows for it and for the regularised friction's creep). Through the nominal matrix every wheel turns
    at v/r on a radius 1.08 r: the body moves 8 % faster than commanded."""
    twist = np.array([0.2, -0.1, 0.0])  # m/s, m/s, rad/s
    model = steady_body_velocity("model", twist)
    nominal = steady_body_velocity("nominal", twist)
    np.testing.assert_allclose(model[:2], twist[:2], rtol=1e-3)
    np.testing.assert_allclose(nominal[:2], SCALE * twist[:2], rtol=1e-3)
    assert abs(model[2]) < 1e-3 and abs(nominal[2]) < 1e-3  # no yaw: all wheels scaled alike


def rollout(env_id: str, seed: int, steps: int, **kwargs) -> list[np.ndarray]:
    env = gym.make(env_id, obs_mode="sensors", **kwargs)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        out += [obs, np.array([reward]), info["pose"]]
        if terminated or truncated:
            break
    return out


@pytest.mark.parametrize(("env_id", "robot", "friction"), [
    ("OmniPathFollow-Phunopas-v0", "phunopas2018", "roller_gap"),
    ("OmniPathFollow-Mecanum-v0", "optiodom_omni4", "initial")])
def test_without_kinematic_effects_both_choices_give_the_same_episode_bit_for_bit(env_id, robot, friction):
    plain = load_model(robot, surface="carpet", friction=friction)  # a model file without kinematic effects
    nominal = rollout(env_id, 3, 60, model=plain, kinematics="nominal")
    model = rollout(env_id, 3, 60, model=plain, kinematics="model")
    assert len(nominal) == len(model)
    for a, b in zip(nominal, model, strict=True):
        np.testing.assert_array_equal(a, b)


def test_vector_env_with_model_kinematics_matches_single_envs():
    n = 3
    kwargs = {"model": large_wheel_model(), "kinematics": "model", "obs_mode": "sensors", "episode_seconds": 0.3}
    venv = gym.make_vec(CUSTOM, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(CUSTOM, **kwargs) for _ in range(n)]
    np.testing.assert_array_equal(venv.unwrapped.wheel_matrix, effective_kinematics(large_wheel_model()).matrix)
    vobs, _ = venv.reset(seed=5)
    assert np.array_equal(vobs, np.stack([env.reset(seed=5 + i)[0] for i, env in enumerate(singles)]))
    rng = np.random.default_rng(1)
    for k in range(25):  # within the 30-step episode
        actions = rng.uniform(-1, 1, size=(n, 3)).astype(np.float32)
        vobs, vrew, *_ = venv.step(actions)
        for i, env in enumerate(singles):
            obs, rew, *_ = env.step(actions[i])
            assert np.array_equal(vobs[i], obs) and vrew[i] == rew, f"step {k}, robot {i}"


def test_scripted_policies_read_the_environments_kinematics():
    """ekf-pid (single and batched) builds its feed-forward and its filter's encoder model from
    env.unwrapped.wheel_kinematics: the model's effective matrix with kinematics="model"."""
    from agents.batched.policies import make_vector_policy
    from agents.policies import make_policy

    W_eff = effective_kinematics(large_wheel_model()).matrix
    kwargs = {"model": large_wheel_model(), "obs_mode": "sensors"}
    for kinematics, expected in (("model", W_eff), ("nominal", large_wheel_model().robot.wheel_matrix())):
        env = gym.make(CUSTOM, kinematics=kinematics, **kwargs)
        policy = make_policy("ekf-pid", env)
        np.testing.assert_array_equal(policy.W, expected)
        np.testing.assert_array_equal(policy.ekf.W, expected)
        venv = gym.make_vec(CUSTOM, num_envs=2, vectorization_mode="vector_entry_point", kinematics=kinematics,
                            **kwargs)
        vpolicy = make_vector_policy("ekf-pid", venv)
        np.testing.assert_array_equal(vpolicy.W, expected)
        np.testing.assert_array_equal(vpolicy.ekf.W, expected)
    assert not np.allclose(W_eff, large_wheel_model().robot.wheel_matrix())


@pytest.mark.parametrize("value", ["effective", 3, None])
def test_bad_kinematics_refused_in_one_line_naming_it(value):
    for make in (lambda: gym.make(CUSTOM, model=large_wheel_model(), kinematics=value),
                 lambda: gym.make_vec(CUSTOM, num_envs=2, vectorization_mode="vector_entry_point",
                                      model=large_wheel_model(), kinematics=value)):
        with pytest.raises(ValueError) as exc:
            make()
        message = str(exc.value)
        assert message.startswith("invalid kinematics=") and "'nominal', 'model'" in message
        assert "\n" not in message
