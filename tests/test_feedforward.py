"""The privileged feed-forward action structure (agents.wrappers.FeedForwardTwist and its vector twin): the
environment receives clip(v_ref + scale·a, −1, 1), v_ref read from the state observation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import omni_gym  # noqa: F401  (registers the environments)
from agents.wrappers import FeedForwardTwist, VectorFeedForwardTwist, wrap_env, wrap_vector_env

ENV = "OmniPathFollow-Williams-v1"
KW = dict(obs_mode="state", action_mode="twist", max_episode_steps=60)


def test_zero_action_drives_the_reference_twist_and_a_correction_adds_scaled():
    """Against a plain environment driven by hand with the observation's reference_velocity (+ 0.5·a):
    the same observations bit for bit, so the wrapper adds nothing else."""
    ff = FeedForwardTwist(gym.make(ENV, **KW), scale=0.5)
    plain = gym.make(ENV, **KW)
    o1, _ = ff.reset(seed=5)
    o2, _ = plain.reset(seed=5)
    ref = plain.unwrapped.observation_layout["reference_velocity"]
    rng = np.random.default_rng(0)
    for t in range(60):
        a = (np.zeros(3) if t < 30 else rng.uniform(-1, 1, 3)).astype(np.float32)
        o1, *_ = ff.step(a)
        o2, *_ = plain.step(np.clip(o2[ref] + 0.5 * a.astype(float), -1, 1).astype(np.float32))
        np.testing.assert_array_equal(o1, o2, err_msg=f"step {t}")


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_vector_twin_matches_the_single_wrapper(mode):
    num = 3
    vec = VectorFeedForwardTwist(gym.make_vec(ENV, num_envs=num, vectorization_mode="vector_entry_point",
                                              autoreset_mode=mode, **KW), 0.5)
    singles = [FeedForwardTwist(gym.make(ENV, **KW), 0.5) for _ in range(num)]
    ov, _ = vec.reset(seed=[7, 8, 9])
    os_ = [s.reset(seed=7 + i)[0] for i, s in enumerate(singles)]
    rng = np.random.default_rng(1)
    for t in range(40):  # within one episode (60 steps): no autoreset of the singles needed
        a = rng.uniform(-1, 1, (num, 3)).astype(np.float32)
        ov, *_ = vec.step(a)
        os_ = [s.step(a[i])[0] for i, s in enumerate(singles)]
        np.testing.assert_allclose(ov, np.array(os_), atol=1e-6, err_msg=f"step {t}")  # float32 obs


def test_feedforward_is_built_by_name_and_refuses_sensor_observations():
    env = wrap_env(gym.make(ENV, **KW), "feedforward", 0.5, reward="pose")
    assert isinstance(env.env, FeedForwardTwist) and env.env.scale == 0.5
    venv = wrap_vector_env(gym.make_vec(ENV, num_envs=2, vectorization_mode="vector_entry_point", **KW),
                           "feedforward", 0.25, reward="env")
    assert isinstance(venv, VectorFeedForwardTwist) and venv.scale == 0.25
    with pytest.raises(ValueError, match="needs obs_mode='state'"):
        FeedForwardTwist(gym.make(ENV, obs_mode="sensors"))


def test_hyperparameter_entry_names_the_feedforward_agent():
    from agents.zoo_config import wrapper_spec

    spec = wrapper_spec({"env_wrapper": [{"agents.wrappers.FeedForwardTwist": {"scale": 0.4}},
                                         {"agents.rewards.TrackingReward": {"reward": "pose"}}]}, "hp.yml")
    assert (spec.name, spec.residual_scale, spec.reward) == ("feedforward", 0.4, "pose")
    with pytest.raises(ValueError, match="hp.yml: env_wrapper: 'agents.wrappers.FeedForwardTwist'"):
        wrapper_spec({"env_wrapper": ["agents.wrappers.EKFFeatures", "agents.wrappers.FeedForwardTwist"]}, "hp.yml")
