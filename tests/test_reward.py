"""The reward: the built-in one written once (omni_gym.envs.reward), and ``reward=`` for your own."""

from __future__ import annotations

import math
from dataclasses import fields, replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.envs import reward as rw

ROOT = Path(__file__).resolve().parents[1]
ENV = "OmniPathFollow-Phunopas-v0"


def rollout(env_id: str = ENV, steps: int = 25, **kwargs) -> tuple[list[float], list]:
    """Rewards and the core's reward inputs after each of ``steps`` random actions (seeded)."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    rewards, inputs = [], []
    for _ in range(steps):
        _, r, *_ = env.step(rng.uniform(-1.2, 1.2, env.action_space.shape))  # some actions clipped
        rewards.append(r)
        x = env.unwrapped.core._reward_inputs()  # views of the core's buffers: copied before the next step
        inputs.append(replace(x, **{f.name: np.copy(getattr(x, f.name)) for f in fields(x) if f.name != "control_dt"}))
    return rewards, inputs


def test_the_fused_builtin_is_the_formula_and_tracking_reward_computes_the_same_bits():
    rewards, inputs = rollout()
    builtin = rw.BuiltinReward()
    for r, x in zip(rewards, inputs, strict=True):
        assert builtin(x)[0] == r  # the kernel's inline call and the stand-alone one: same bits
        e, eth, a = x.position_error[0], x.heading_error[0], x.action[0]
        formula = 0.7 * math.exp(-e / 0.1) + 0.3 * math.exp(-abs(eth) / 0.3) - 0.05 * float(np.mean(a**2))
        assert r == pytest.approx(formula, rel=1e-14, abs=1e-15)  # the documented numbers, computed apart
    assert any(np.abs(x.action).max() == 1.0 for x in inputs)  # the clipped action is the one scored


@pytest.mark.parametrize("builtin", [rw.BuiltinReward, rw.BuiltinReward(), None])
def test_passing_the_builtin_keeps_the_fast_path_and_its_values(builtin):
    env = gym.make(ENV, reward=builtin)
    assert env.unwrapped.cfg.reward is None and env.unwrapped.core._custom_reward is None
    assert rollout(reward=builtin)[0] == rollout()[0]


def test_a_custom_reward_function_replaces_the_builtin_in_single_and_vector_envs():
    seen = []

    def progress(x: rw.RewardInputs) -> np.ndarray:
        seen.append(x.step.copy())
        return -x.position_error - 0.1 * np.abs(x.heading_error)

    rewards, inputs = rollout(steps=5, reward=progress)
    assert [float(r) for r in rewards] == [float(-x.position_error[0] - 0.1 * abs(x.heading_error[0]))
                                           for x in inputs]
    assert [int(s[0]) for s in seen[1:]] == [1, 2, 3, 4, 5]  # reset, then once per step
    vec = gym.make_vec(ENV, num_envs=3, vectorization_mode="vector_entry_point", reward=progress)
    vec.reset(seed=1)
    _, r, *_ = vec.step(np.zeros(vec.action_space.shape))
    core = vec.unwrapped.core if hasattr(vec.unwrapped, "core") else vec.core
    np.testing.assert_array_equal(r, -core.err[:, 0] - 0.1 * np.abs(core.err[:, 1]))


def test_a_reward_class_is_made_and_sees_the_state_and_reference():
    class Speed:
        def __call__(self, x: rw.RewardInputs) -> np.ndarray:
            assert x.pose.shape == x.velocity.shape == x.reference_pose.shape == (1, 3)
            assert x.control_dt == pytest.approx(0.01)
            return np.hypot(x.velocity[:, 0], x.velocity[:, 1])

    env = gym.make(ENV, reward=Speed)
    env.reset(seed=0)
    _, r, *_ = env.step(np.array([1.0, 0.0, 0.0]))
    assert r == pytest.approx(float(np.hypot(*env.unwrapped.core.true[0, 3:5])), abs=0) and r > 0


@pytest.mark.parametrize(("value", "message"), [
    (3, "invalid reward=3: expected None"),
    ("squared", "invalid reward='squared'"),
])
def test_a_reward_that_is_not_callable_is_refused_in_one_line(value, message):
    with pytest.raises(ValueError, match=message) as err:
        gym.make(ENV, reward=value)
    assert "\n" not in str(err.value)


def test_a_reward_of_the_wrong_shape_or_not_finite_names_itself():
    def two(_x):
        return np.zeros(2)

    def nan(x):
        return np.full(len(x.step), np.nan)

    with pytest.raises(ValueError, match=r"reward .*two returned shape \(2,\); expected \(1,\)"):
        gym.make(ENV, reward=two).reset(seed=0)
    with pytest.raises(ValueError, match=r"reward .*nan returned a non-finite value: \[nan\]"):
        gym.make(ENV, reward=nan).reset(seed=0)


def test_the_formula_is_written_once_and_the_docs_quote_it():
    assert rw.FORMULA == "r = 0.7·exp(−e/0.1 m) + 0.3·exp(−|e_θ|/0.3 rad) − 0.05·mean(a²)"
    assert rw.FORMULA in (ROOT / "docs/environments.md").read_text(encoding="utf-8")
    assert rw.FORMULA in rw.__doc__
    # No other file spells the formula out (a second copy would drift).
    files = [*ROOT.glob("omni_gym/**/*.py"), *ROOT.glob("agents/**/*.py"), *ROOT.glob("docs/*.md"), ROOT / "README.md"]
    copies = [str(f.relative_to(ROOT)) for f in files if "0.7·exp(" in f.read_text(encoding="utf-8")]
    assert sorted(copies) == ["docs/environments.md", "omni_gym/envs/reward.py"]
