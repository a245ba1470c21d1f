"""The SB3 algorithms the trainer and the model loader know, by name (a leaf module: no agents imports).

``ALGOS`` are the names used on the command line (``--algo``), in ``meta.json`` and in the RL Zoo's
``args.yml``. :func:`algorithm_class` imports stable-baselines3 only when called (the ``agents`` extra).
"""

from __future__ import annotations

ALGOS = ("ppo", "sac", "td3")


def algorithm_class(name: str):
    """The stable-baselines3 class of algorithm ``name`` (one of :data:`ALGOS`); ValueError otherwise."""
    if name not in ALGOS:
        raise ValueError(f"unknown algo {name!r}; choose one of {', '.join(ALGOS)}")
    from stable_baselines3 import PPO, SAC, TD3

    return {"ppo": PPO, "sac": SAC, "td3": TD3}[name]
