"""The training environment of ``omni-gym train --backend rllib``: an RLlib env creator.

RLlib calls :class:`TrainingEnvCreator` in each env runner (a fresh process) with ``env_config`` plus
``num_envs`` (``gym_env_vectorize_mode="vector_entry_point"``). It builds what the SB3 ``native`` path
builds (``agents.train.make_training_vec_env``): the native vector env of ``num_envs`` robots
(:class:`omni_gym.rllib.EnvCreator`, ``next_step`` autoreset as RLlib needs) with the training reward
(``agents.wrappers.wrap_vector_env``: :class:`agents.rewards.VectorTrackingReward`), so the reward
wrapper, which lives in agents, stays out of the environment package.

Seeds: RLlib resets env runner k's env with ``seed + k`` (k = 0 for sampling in the driver, 1… for env
runner actors); :class:`DistinctSeeds` turns that into ``seed + k·num_envs``, so robot i of runner k
starts from ``seed + k·num_envs + i`` and no two robots share a seed (the SB3 path: robot i from
``seed + i``). RLlib does not pass the runner's index with ``num_envs``, so ``env_config["seed"]`` (the
training seed) gives k.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gymnasium.vector import VectorWrapper

TRAIN_ENV = "omni-gym-agents-train"  # the RLlib registry name of TrainingEnvCreator
OWN_KEYS = ("env_id", "reward", "seed", "num_envs")


class DistinctSeeds(VectorWrapper):
    """Map RLlib's reset seed ``base + k`` to ``base + k·num_envs`` (see the module doc); other seeds
    (None, lists, seeds below ``base``) pass unchanged."""

    def __init__(self, env, base: int) -> None:
        super().__init__(env)
        self.base = int(base)

    def reset(self, *, seed=None, options: dict | None = None):
        if isinstance(seed, int) and not isinstance(seed, bool) and seed >= self.base:
            seed = self.base + (seed - self.base) * int(self.num_envs)
        return self.env.reset(seed=seed, options=options)


@dataclass(frozen=True)
class TrainingEnvCreator:
    """``env_config`` keys: ``env_id`` (an omni-gym id), ``reward`` (one of ``agents.rewards.REWARDS``),
    ``seed`` (the training seed), ``num_envs`` (RLlib adds it) and the ``gym.make`` keywords of the id
    (``obs_mode``, ``randomize_*``, ...).
    Without ``num_envs``: one single environment with :class:`agents.rewards.TrackingReward`."""

    def __call__(self, env_config: dict[str, Any]):
        from agents.wrappers import wrap_env, wrap_vector_env
        from omni_gym.rllib import EnvCreator

        kw = dict(env_config)
        env_id, reward, seed = kw.pop("env_id"), kw.pop("reward", "env"), kw.pop("seed", 0)
        if "num_envs" not in kw:
            return wrap_env(EnvCreator(env_id)(kw), "none", reward=reward)
        # max_episode_steps=None: episodes end with the reference, as agents.rollout.make_env matches it.
        venv = EnvCreator(env_id)({**kw, "max_episode_steps": None})
        venv = wrap_vector_env(venv, "none", reward=reward)
        return DistinctSeeds(venv, seed)


def register_training_env() -> str:
    """Register :class:`TrainingEnvCreator` with RLlib as :data:`TRAIN_ENV` (in this process); returns the name."""
    from omni_gym.rllib import register_envs, require_ray

    require_ray("RLlib training")
    from ray.tune.registry import register_env

    register_envs()  # the plain ids too: a restored algorithm may name either
    register_env(TRAIN_ENV, TrainingEnvCreator())
    return TRAIN_ENV
