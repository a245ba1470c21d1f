"""Register the omni-gym environment ids with RLlib (``ray.tune.registry``, which is not Gymnasium's registry).

    from omni_gym.rllib import register_envs
    register_envs()
    config = PPOConfig().environment("OmniPathFollow-Phunopas-v0", env_config={"obs_mode": "state"}) \\
        .env_runners(num_envs_per_env_runner=8, gym_env_vectorize_mode="vector_entry_point")

Each id is registered under its own name. Its creator (:class:`EnvCreator`) builds, from RLlib's
``env_config`` (the environment keywords of ``gym.make``):

* with ``gym_env_vectorize_mode="vector_entry_point"`` (RLlib then adds ``num_envs``): the native vector
  environment :class:`omni_gym.envs.vector.OmniPathVectorEnv` of ``num_envs`` robots, in the
  ``next_step`` autoreset mode RLlib's env runner expects (RLlib's default ``"sync"`` mode would wrap
  ``num_envs`` single environments instead, about 20 % fewer env steps per second in sampling);
* otherwise: one single environment (``gym.make``).

``action_mode`` defaults to ``"twist"`` as for every learned agent (``agents.rollout.make_env``). Rewards
are the environment's; agents/rllib applies the training rewards of ``agents/rewards.py``.

Ray is imported only by :func:`register_envs`: without it, a one-line ``ModuleNotFoundError`` names the
extra to install (``pip install -c constraints.txt -e '.[rllib]'`` from the checkout's root).
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import Any

from omni_gym.envs import all_ids

RLLIB_EXTRA = "pip install -c constraints.txt -e '.[rllib]' (from the omni-gym checkout's root)"


def require_ray(purpose: str) -> None:
    """Raise a one-line ``ModuleNotFoundError`` naming the ``rllib`` extra when ray or RLlib is missing."""
    if importlib.util.find_spec("ray") is None or importlib.util.find_spec("ray.rllib") is None:
        raise ModuleNotFoundError(f"{purpose} needs ray[rllib] (the rllib extra): {RLLIB_EXTRA}", name="ray")


@dataclass(frozen=True)
class EnvCreator:
    """RLlib environment creator for one omni-gym id (picklable: env runner actors receive it).

    ``__call__(env_config)``: the native vector env when ``env_config`` holds ``num_envs`` (RLlib's
    ``vector_entry_point`` mode), else a single environment; the other keys are ``gym.make`` keywords.
    """

    env_id: str

    def __call__(self, env_config: dict[str, Any] | None = None):
        import gymnasium as gym

        import omni_gym  # noqa: F401  (an env runner actor is a fresh process: register the Gymnasium ids there)

        kw = dict(env_config or {})
        kw.setdefault("action_mode", "twist")
        num_envs = kw.pop("num_envs", None)
        if num_envs is None:
            return gym.make(self.env_id, **kw)
        if kw.get("autoreset_mode", "next_step") not in ("next_step", gym.vector.AutoresetMode.NEXT_STEP):
            raise ValueError("RLlib's env runner needs autoreset_mode='next_step' (the default)")
        return gym.make_vec(self.env_id, num_envs=int(num_envs), vectorization_mode="vector_entry_point", **kw)


def register_envs() -> list[str]:
    """Register every omni-gym id (:data:`omni_gym.envs.ENV_IDS`, then ``OmniPathFollow-Custom-v0``, whose
    ``env_config`` must hold ``model``) with ``ray.tune.registry.register_env``
    under the same name; returns the names. Call it in every process that builds or restores an RLlib
    algorithm on these ids (the registry is per process; env runners receive the creators from it)."""
    require_ray("omni_gym.rllib.register_envs")
    from ray.tune.registry import register_env

    ids = list(all_ids())
    for env_id in ids:
        register_env(env_id, EnvCreator(env_id))
    return ids
