"""The RLlib PPO configuration files (``agents/rllib/ppo.yml``) and the ``PPOConfig`` built from them.

An entry per environment id (see the file's header): ``env_kwargs``, ``env_wrapper`` and ``n_timesteps``
as in ``agents/hyperparams`` (read with the same code), ``n_envs`` (robots per env runner), ``training``
(keywords of ``PPOConfig.training``) and ``model`` (RLlib's ``DefaultModelConfig`` keywords).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.zoo_config import WrapperSpec, wrapper_spec

RLLIB_DIR = Path(__file__).resolve().parent
KEYS = ("env_kwargs", "env_wrapper", "n_timesteps", "n_envs", "training", "model")


@dataclass(frozen=True)
class RLlibHyperparams:
    """One entry of an RLlib configuration file.

    ``env_kwargs``: ``gym.make`` keywords of training; ``spec``: the wrapper stack (only the privileged
    agent's reward wrapper is supported: no EKF); ``n_timesteps``: default budget [env steps];
    ``n_envs``: robots per env runner; ``training``: ``PPOConfig.training`` keywords; ``model``:
    ``DefaultModelConfig`` keywords; ``raw``: the entry as read (recorded in meta.json).
    """

    env_kwargs: dict[str, Any]
    spec: WrapperSpec
    n_timesteps: int
    n_envs: int
    training: dict[str, Any] = field(default_factory=dict)
    model: dict[str, Any] = field(default_factory=dict)
    raw: dict[str, Any] = field(default_factory=dict)


def default_file(algo: str = "ppo") -> Path:
    """``agents/rllib/<algo>.yml`` (shipped as package data)."""
    return RLLIB_DIR / f"{algo}.yml"


def load(env_id: str, path: str | Path | None = None, algo: str = "ppo") -> RLlibHyperparams:
    """Read and check the entry for ``env_id`` in ``path`` (default :func:`default_file`); ValueError naming
    the file and key on any problem."""
    from agents.train import load_hyperparams  # the YAML reading and its messages

    where = str(path or default_file(algo))
    hp = load_hyperparams(algo, env_id, path or default_file(algo))
    unknown = sorted(set(hp) - set(KEYS))
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r} for RLlib (keys: {', '.join(KEYS)}; RLlib's PPO "
                         "options go under 'training', network options under 'model')")
    spec = wrapper_spec(hp, where)
    if spec.name != "none" or spec.sensor_noise_range is not None:
        raise ValueError(f"{where}: env_wrapper: the RLlib backend supports only agents.rewards.TrackingReward "
                         "(the privileged agent); the EKF wrappers train with --backend sb3")
    for key in ("training", "model", "env_kwargs"):
        if not isinstance(hp.get(key) or {}, dict):
            raise ValueError(f"{where}: key {key!r} must be a mapping")
    try:
        n_timesteps = int(float(hp.get("n_timesteps", 0)))
        n_envs = int(hp.get("n_envs", 1))
    except (TypeError, ValueError):
        raise ValueError(f"{where}: n_timesteps and n_envs must be numbers") from None
    return RLlibHyperparams(dict(hp.get("env_kwargs") or {}), spec, n_timesteps, n_envs,
                            dict(hp.get("training") or {}), dict(hp.get("model") or {}), hp)


def ppo_config(hp: RLlibHyperparams, env_config: dict[str, Any], n_envs: int, num_env_runners: int, seed: int,
               env_name: str, where: str = "the RLlib configuration"):
    """RLlib's ``PPOConfig`` for the entry: the env ``env_name`` (registered by :mod:`agents.rllib.env`) with
    ``env_config``, ``num_env_runners`` env runner actors (0: sample in the driver) of ``n_envs`` robots each
    in one native vector env, the entry's ``training`` and ``model``, seeded with ``seed`` (env runner k
    resets its vector env with ``seed + k``, robot i of it with ``seed + k + i``)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    try:
        model = DefaultModelConfig(**hp.model)
    except TypeError as exc:
        raise ValueError(f"{where}: model: {exc}") from None
    config = (PPOConfig()
              .environment(env_name, env_config=env_config)
              .env_runners(num_env_runners=num_env_runners, num_envs_per_env_runner=n_envs,
                           gym_env_vectorize_mode="vector_entry_point")
              .rl_module(model_config=model)
              .debugging(seed=seed))
    try:
        config = config.training(**hp.training)
    except TypeError as exc:
        raise ValueError(f"{where}: training: {exc}") from None
    return config
