"""The SB3 algorithms the trainer and the model loader know, by name (on agents.registry only).

``ALGOS`` are the names used on the command line (``--algo``), in ``meta.json`` and in the RL Zoo's
``args.yml``. :func:`algorithm_class` imports stable-baselines3 only when called (the ``agents`` extra).
"""

from __future__ import annotations

from agents.registry import Registry

# name -> the stable-baselines3 class name (looked up on call: importing SB3 takes seconds)
ALGORITHMS: Registry[str] = Registry("algo", [("ppo", "PPO"), ("sac", "SAC"), ("td3", "TD3")])
ALGOS = ALGORITHMS.names()


def algorithm_class(name: str):
    """The stable-baselines3 class of algorithm ``name`` (one of :data:`ALGOS`); ValueError otherwise."""
    class_name = ALGORITHMS.get(name)
    import stable_baselines3

    return getattr(stable_baselines3, class_name)
