"""Batched evaluation: the first episode of N robots at once in a native vector environment.

:func:`run_episodes_vector` is :func:`agents.rollout.run_episode` for ``len(seeds)`` robots stepped
together in one ``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point")`` environment
(``next_step`` autoreset): robot i starts from ``reset(seed=seeds[i])``, which reproduces
``gym.make(ID).reset(seed=seeds[i])`` bit for bit, and only its first episode counts. The metrics are
exactly those of ``run_episode`` (definitions in :mod:`agents.evaluate`), accumulated per robot in the
same order, so a policy that acts identically gives identical :class:`~agents.rollout.Episode` values.

A robot whose episode has ended keeps being stepped (the vector env steps every robot) with zero
actions until the last robot ends; those later episodes are never read (the policy is still reset on
each autoreset step, as the ``next_step`` protocol asks, so its state stays well defined). The batch lasts as long as
its longest episode (at most ``max_episode_steps``).

Policies follow :class:`VectorActor`: the batched scripted policies of :mod:`agents.batched.policies`
and :class:`agents.sb3_policy.VectorSB3Policy` (on a vector env wrapped by
:class:`agents.wrappers.VectorEKFFeatures` for the EKF-feature models).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from agents.rollout import Episode


class VectorActor(Protocol):
    """What :func:`run_episodes_vector` needs of a policy for N robots.

    ``reset(obs, mask=None)`` starts the episodes of the selected robots from their first observations
    (rows of ``obs`` (N, D)); ``act(obs)`` returns the (N, A) actions for the observations (N, D).
    """

    def reset(self, obs: np.ndarray, mask=None) -> None: ...

    def act(self, obs: np.ndarray) -> np.ndarray: ...


def make_vector_env(env_id: str, num: int, env_kwargs: dict | None = None, obs_mode: str = "sensors"):
    """``gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point", obs_mode=obs_mode,
    action_mode="twist", autoreset_mode="next_step", **env_kwargs)`` with one-line ValueErrors.

    Episodes end with the reference (``max_episode_steps=None``), as :func:`agents.rollout.make_env` matches
    the registered time limit to the reference's length.
    """
    import gymnasium as gym

    from agents.rollout import make_env

    if not (isinstance(num, int) and num >= 1):
        raise ValueError(f"num must be a positive integer, got {num!r}")
    make_env(env_id, env_kwargs, obs_mode=obs_mode).close()  # the same checks and messages as the single path
    kw = dict(env_kwargs or {})
    kw.update(obs_mode=obs_mode, action_mode="twist")
    try:
        return gym.make_vec(env_id.rpartition(":")[2], num_envs=num, vectorization_mode="vector_entry_point",
                            autoreset_mode="next_step", max_episode_steps=None, **kw)
    except TypeError as exc:
        raise ValueError(f"bad env_kwargs for {env_id}: {exc}") from None


def run_episodes_vector(vec_env, policy: VectorActor, seeds: Sequence[int]) -> list[Episode]:
    """The first episode of every robot of ``vec_env`` (robot i from ``seeds[i]``), as :class:`Episode` s.

    ``vec_env``: a native vector env in ``next_step`` autoreset mode with ``num_envs == len(seeds)``
    (raw, or wrapped by :class:`agents.wrappers.VectorEKFFeatures`); ``policy`` a :class:`VectorActor` for it.
    The episodes carry metrics only (no recorded trajectories).
    """
    from gymnasium.vector import AutoresetMode

    seeds = [int(s) for s in seeds]
    num = int(vec_env.num_envs)
    if len(seeds) != num:
        raise ValueError(f"run_episodes_vector: {len(seeds)} seeds for {num} robots")
    if vec_env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP) != AutoresetMode.NEXT_STEP:
        raise ValueError("run_episodes_vector needs a vector env with autoreset_mode='next_step'")
    obs, _ = vec_env.reset(seed=seeds)
    policy.reset(obs)
    live = np.ones(num, dtype=bool)
    restart = np.zeros(num, dtype=bool)  # next_step: these rows of obs are first observations
    sq_sum = [0.0] * num  # Python floats, summed step by step as run_episode does
    ret = [0.0] * num  # the environment's own reward (a wrapper may replace what step returns)
    core = vec_env.unwrapped.core
    traction = core.ref_use.copy()  # each robot's first reference (info["reference_traction"] at reset)
    steps = np.zeros(num, dtype=np.int64)
    final: list[tuple[float, float, bool, bool] | None] = [None] * num
    while live.any():
        if restart.any():
            policy.reset(obs, restart)
        actions = np.asarray(policy.act(obs), dtype=np.float32).reshape(vec_env.action_space.shape).copy()
        actions[~live] = 0.0  # ended robots: their later episodes are not evaluated
        obs, _, terminated, truncated, info = vec_env.step(actions)
        err = np.asarray(info["tracking_error"], dtype=float)
        restart = np.asarray(terminated | truncated, dtype=bool)
        head = np.asarray(info["heading_error"], dtype=float)
        success = np.asarray(info["is_success"], dtype=bool)
        reward = core.rewards()
        for i in np.flatnonzero(live):
            steps[i] += 1
            sq_sum[i] += float(err[i]) ** 2
            ret[i] += float(reward[i])
            if terminated[i] or truncated[i]:
                final[i] = (float(err[i]), abs(float(head[i])), bool(success[i]) and not bool(terminated[i]),
                            bool(terminated[i]))
                live[i] = False
    episodes = []
    for i, seed in enumerate(seeds):
        err_i, head_i, success_i, term_i = final[i]
        episodes.append(Episode(seed=seed, tracking_rmse=math.sqrt(sq_sum[i] / int(steps[i])),
                                final_position_error=err_i, final_heading_error=head_i, success=success_i,
                                terminated=term_i, steps=int(steps[i]), episode_return=ret[i],
                                reference_traction=float(traction[i])))
    return episodes
