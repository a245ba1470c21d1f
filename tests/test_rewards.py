"""The training rewards (agents/rewards.py): the formula against the docstring, the reward-only wrappers
on single and native vector environments.

The squared reward is recomputed here from the environment's reported tracking error and the action,
independently of :func:`agents.rewards.tracking_reward`; the only tolerance is float64 rounding.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import omni_gym  # noqa: F401  (registers the environments)
from agents.rewards import TrackingReward, VectorTrackingReward, tracking_reward
from agents.wrappers import wrap_env

ENV = "OmniPathFollow-Phunopas-v0"
# A short lost distance so that robots driven by random actions terminate at different steps.
KW = dict(obs_mode="state", action_mode="twist", lost_distance=0.06, max_episode_steps=100)


def _expected_squared(e: float, a: np.ndarray, terminated: bool, lost: float) -> float:
    a = np.clip(np.asarray(a, dtype=float), -1.0, 1.0)
    r = -((e / 0.1) ** 2) - 0.01 * float(np.mean(a * a))
    return r - 50 * (lost / 0.1) ** 2 if terminated else r


def test_privileged_env_gets_the_squared_reward_and_unchanged_observations():
    env = wrap_env(gym.make(ENV, **KW), "none", reward="squared")
    assert isinstance(env, TrackingReward)
    plain = gym.make(ENV, **KW)
    o1, _ = env.reset(seed=3)
    o2, _ = plain.reset(seed=3)
    rng = np.random.default_rng(0)
    terminated = False
    for _ in range(100):
        a = rng.uniform(-1.5, 1.5, 3).astype(np.float32)  # beyond the box: the reward uses the clipped action
        o1, r, terminated, truncated, info = env.step(a)
        o2, r_env, *_ = plain.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r != r_env
        assert r == pytest.approx(_expected_squared(info["tracking_error"], a, terminated, 0.06), rel=1e-12)
        if terminated or truncated:
            break
    assert terminated  # random twists leave a 6 cm corridor within 100 steps (10 s)


@pytest.mark.parametrize("reward", ["squared", "pose"])  # pose: the heading error of ended robots too
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_vector_tracking_reward_matches_single_wrappers(mode, reward):
    num = 3
    vec = VectorTrackingReward(gym.make_vec(ENV, num_envs=num, vectorization_mode="vector_entry_point",
                                            autoreset_mode=mode, **KW), reward)
    ref = SyncVectorEnv([lambda: TrackingReward(gym.make(ENV, **KW), reward) for _ in range(num)],
                        autoreset_mode=mode)
    o1, _ = vec.reset(seed=11)
    o2, _ = ref.reset(seed=11)
    np.testing.assert_allclose(o1, o2, atol=1e-6)  # float32 observations
    rng = np.random.default_rng(4)
    ends = set()
    for t in range(200):
        a = rng.uniform(-1, 1, (num, 3)).astype(np.float32)
        o1, r1, te1, tr1, _ = vec.step(a)
        o2, r2, te2, tr2, _ = ref.step(a)
        np.testing.assert_allclose(o1, o2, atol=1e-6, err_msg=f"step {t}")
        np.testing.assert_allclose(r1, r2, rtol=1e-12, atol=1e-12, err_msg=f"step {t}")
        assert np.array_equal(te1, te2) and np.array_equal(tr1, tr2)
        if (te1 | tr1).any():
            ends.add(t)
    assert len(ends) >= 3  # robots ended at different steps, so autoreset rows were compared


def test_reward_modes_and_bad_names():
    e, a = np.array([0.0, 0.1, 0.3]), np.zeros((3, 3))
    tracking = tracking_reward("tracking", np.zeros(3), e, a, np.zeros(3, bool), 0.5)
    assert tracking[0] == pytest.approx(1.0) and np.all(np.diff(tracking) < 0)  # 1 on the path, falling with e
    squared = tracking_reward("squared", np.zeros(3), e, a, np.array([False, False, True]), 0.5)
    np.testing.assert_allclose(squared, [0.0, -1.0, -9.0 - 50 * 25.0])
    np.testing.assert_array_equal(tracking_reward("env", [0.25, 0.5, 1.0], e, a, np.zeros(3, bool), 0.5),
                                  [0.25, 0.5, 1.0])
    # gaussian: 1 on the path; at 1 cm and 10 cm each term is e^-1 of its weight (the scales in the docstring)
    g = tracking_reward("gaussian", np.zeros(3), [0.0, 0.01, 0.1], a, np.zeros(3, bool), 0.5)
    np.testing.assert_allclose(g, [1.0, 0.5 * np.exp(-1) + 0.5 * np.exp(-0.01), 0.5 * np.exp(-100) + 0.5 * np.exp(-1)])
    # pose: the heading term adds 0.5 at zero heading error, 0.25·e^-1 + 0.25·e^-0.01 at 0.02 rad
    p = tracking_reward("pose", np.zeros(3), np.zeros(3), a, np.zeros(3, bool), 0.5, heading=[0.0, -0.02, 3.0])
    np.testing.assert_allclose(p, [1.5, 1.0 + 0.25 * np.exp(-1) + 0.25 * np.exp(-0.01), 1.0 + 0.25 * np.exp(-225)])
    with pytest.raises(ValueError, match="'pose' reward needs the heading error"):
        tracking_reward("pose", np.zeros(3), e, a, np.zeros(3, bool), 0.5)
    # pose_fine: 1.5 on the path; at 1 mm its narrowest position term is e^-1 of its weight (1/3), the 1 cm and
    # 10 cm terms nearly 1: so it still rewards going from 1 mm to 0 by ~0.2, where pose gains only ~0.005
    f = tracking_reward("pose_fine", np.zeros(2), [0.0, 0.001], a[:2], np.zeros(2, bool), 0.5, heading=[0.0, 0.0])
    np.testing.assert_allclose(f, [1.5, 0.5 + (np.exp(-1) + np.exp(-0.01) + np.exp(-1e-4)) / 3])
    p1 = tracking_reward("pose", np.zeros(2), [0.0, 0.001], a[:2], np.zeros(2, bool), 0.5, heading=[0.0, 0.0])
    assert f[0] - f[1] > 30 * (p1[0] - p1[1])
    with pytest.raises(ValueError, match="unknown reward 'quadratic'; choose one of env, tracking, squared"):
        TrackingReward(gym.make(ENV, **KW), "quadratic")
    with pytest.raises(ValueError, match="TrackingReward needs an omni-gym environment"):
        TrackingReward(gym.make("Pendulum-v1"), "squared")


def test_training_builds_the_same_privileged_reward_on_native_and_dummy_vec_envs():
    """`omni-gym train` wraps the privileged env in VectorTrackingReward (native, the default) or
    TrackingReward (dummy): per robot the same episodes, hence the same rewards up to float64 rounding."""
    from agents.train import make_training_vec_env
    from agents.zoo_config import WrapperSpec

    spec = WrapperSpec(reward="squared")
    kw = {"obs_mode": "state", "episode_seconds": 0.5, "lost_distance": 0.06, "randomize_friction": [0.7, 1.3]}
    native, _ = make_training_vec_env("native", ENV, kw, spec, 3, seed=5)
    dummy, _ = make_training_vec_env("dummy", ENV, kw, spec, 3, seed=5)
    np.testing.assert_allclose(native.reset(), dummy.reset(), atol=1e-6)
    rng = np.random.default_rng(2)
    dones = 0
    for _ in range(60):
        a = rng.uniform(-1, 1, (3, 3)).astype(np.float32)
        native.step_async(a)
        dummy.step_async(a)
        o1, r1, d1, _ = native.step_wait()
        o2, r2, d2, _ = dummy.step_wait()
        np.testing.assert_allclose(o1, o2, atol=1e-6)
        np.testing.assert_allclose(r1, r2, rtol=1e-12, atol=1e-12)
        assert np.array_equal(d1, d2)
        dones += int(d1.sum())
        assert np.all(r1 <= 0.0)  # the squared reward is never positive
    assert dones >= 3  # episodes ended (lost or the 0.5 s = 50-step limit), so the reset rows were compared too
