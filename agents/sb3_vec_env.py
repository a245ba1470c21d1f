"""Stable-Baselines3 ``VecEnv`` over omni-gym's native vector environment (N robots in one pymunk space).

SB3 cannot step a Gymnasium ``VectorEnv``; :class:`NativeVecEnv` adapts one in ``same_step`` autoreset
mode (``omni_gym.envs.vector``) to SB3's semantics, so that an algorithm sees exactly what it would
see from ``DummyVecEnv([Monitor(gym.make(ID, ...)), ...])`` seeded the same way::

    venv = make_native_vec_env("OmniPathFollow-WilliamsPaper-v0", 64, obs_mode="state")
    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=4096)
    model.learn(1_000_000)

``step_wait`` returns the observations with the ended robots already reset, ``dones``, float32
rewards (DummyVecEnv's buffer type) and one info dict per robot with ``TimeLimit.truncated``
(truncated and not terminated) and, when the episode ended, ``terminal_observation`` (its last
observation), Monitor's ``episode`` = {"r": return, "l": length, "t": seconds since the adapter was
built} (so SB3 logs ``ep_rew_mean`` without a Monitor wrapper) and the environment's ``is_success``.
The environment's other info keys (``pose``, ``tracking_error``, …, as the single environment gives
them) are added only when asked for (``info_keys``): SB3's algorithms do not read them, and one dict
of nine keys per robot and step costs about 0.2 ms per step of 64 robots (a tenth of the physics).
With ``info_keys="all"`` the info dicts equal DummyVecEnv's. The info of a reset robot's new episode
goes to ``reset_infos[i]``, as in DummyVecEnv.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

# Keys of a same_step vector env's infos that are not per-robot step information.
_FINAL_KEYS = ("final_obs", "final_info")


def make_native_vec_env(env_id: str, num_envs: int, info_keys: Sequence[str] | str = (),
                        wrap: Callable[[gym.vector.VectorEnv], gym.vector.VectorEnv] | None = None,
                        **env_kwargs: Any) -> NativeVecEnv:
    """``NativeVecEnv(wrap(gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point",
    autoreset_mode="same_step", **env_kwargs)), info_keys)``; ``env_kwargs`` are the single environment's
    keywords, ``wrap`` (optional) puts vector wrappers around the native env (e.g.
    :class:`agents.wrappers.VectorEKFFeatures`)."""
    import omni_gym  # noqa: F401  (registers the ids)

    if "autoreset_mode" in env_kwargs:
        raise ValueError("make_native_vec_env sets autoreset_mode='same_step' itself; do not pass it")
    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode="same_step", **env_kwargs)
    return NativeVecEnv(venv if wrap is None else wrap(venv), info_keys)


def _info_rows(infos: dict, indices: Sequence[int] | None, n: int, keys: frozenset[str] | None) -> list[dict]:
    """One dict per robot (all, or ``indices``) from a dict of arrays over robots: the ``keys`` (None: all but
    the ``_key`` masks and the final_* entries).

    0-d rows become Python scalars (as the single environment's ``info`` has them), others are row views
    of the arrays (the vector env hands out fresh arrays every step, so nothing else writes to them).
    """
    names, columns = [], []
    for key, value in infos.items():
        if key[0] == "_" or key in _FINAL_KEYS or (keys is not None and key not in keys):
            continue
        arr = np.asarray(value)
        if indices is not None:
            arr = arr[indices]
        names.append(key)
        columns.append(arr.tolist() if arr.ndim == 1 else list(arr))
    count = n if indices is None else len(indices)
    if not names:
        return [{} for _ in range(count)]
    return [dict(zip(names, values, strict=True)) for values in zip(*columns, strict=True)]


class NativeVecEnv(VecEnv):
    """SB3 ``VecEnv`` over a Gymnasium vector env in ``same_step`` autoreset mode (see the module docstring).

    ``venv``: ``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point",
    autoreset_mode="same_step", ...)``, optionally under Gymnasium vector wrappers that keep that
    interface (``info["final_obs"]`` a float32 (N, D) array, ``info["final_info"]`` a dict of arrays
    over robots). A ``next_step`` env is refused with ValueError: its autoreset step would be a fake
    transition in SB3's rollouts. ``info_keys``: the environment's info keys copied into every robot's
    info dict (and ``reset_infos``), or "all"; ``is_success`` is always passed on at an episode's end.

    Seeding follows ``DummyVecEnv``: ``seed(s)`` then ``reset()`` resets robot i with seed s + i (later
    resets continue each robot's generator). The robots share one environment object, so ``get_attr``
    returns that object's attribute for every index (``observation_space`` and ``action_space`` as the
    single robot's spaces), ``set_attr`` and ``env_method`` act on it once and need every robot in
    ``indices``, and ``env_is_wrapped`` is False (no robot sits in a ``gymnasium.Wrapper``; the
    Monitor-style ``episode`` info is made here).
    """

    def __init__(self, venv: gym.vector.VectorEnv, info_keys: Sequence[str] | str = ()) -> None:
        mode = getattr(venv, "metadata", {}).get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"NativeVecEnv needs a vector env in same_step autoreset mode, got autoreset_mode={mode}; "
                             "create it with gym.make_vec(ID, num_envs=N, vectorization_mode='vector_entry_point', "
                             "autoreset_mode='same_step') or make_native_vec_env(ID, N)")
        if info_keys == "all":
            self._keys: frozenset[str] | None = None
        elif isinstance(info_keys, str) or not all(isinstance(k, str) for k in info_keys):
            raise ValueError(f"info_keys must be 'all' or a list of info key names, got {info_keys!r}")
        else:
            self._keys = frozenset(info_keys)
        self._final_keys = None if self._keys is None else self._keys | {"is_success"}
        self.venv = venv
        n = int(venv.num_envs)
        super().__init__(n, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(n)  # float64 running sums, as Monitor's sum(list of float rewards)
        self._lengths = np.zeros(n, dtype=np.int64)
        self._t0 = time.time()

    # --- stepping -------------------------------------------------------------------------------

    def reset(self) -> np.ndarray:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = next((o for o in self._options if o), None)  # the env refuses any key, naming it
        obs, infos = self.venv.reset(seed=seeds, options=options)
        self.reset_infos = _info_rows(infos, None, self.num_envs, self._keys)
        self._returns[:] = 0.0
        self._lengths[:] = 0
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        terminated = np.asarray(terminated, dtype=bool)
        truncated = np.asarray(truncated, dtype=bool)
        dones = terminated | truncated
        self._returns += rewards
        self._lengths += 1
        time_limit = (truncated & ~terminated).tolist()
        n = self.num_envs
        rows = _info_rows(infos, None, n, self._keys) if self._keys != frozenset() else [{} for _ in range(n)]
        if dones.any():
            ended = np.flatnonzero(dones)
            final_rows = _info_rows(infos["final_info"], ended, n, self._final_keys)
            final_obs = infos["final_obs"]
            elapsed = round(time.time() - self._t0, 6)
            for i, row in zip(ended.tolist(), final_rows, strict=True):
                self.reset_infos[i] = rows[i]  # the new episode's first info
                row["terminal_observation"] = final_obs[i]
                row["episode"] = {"r": round(float(self._returns[i]), 6), "l": int(self._lengths[i]), "t": elapsed}
                rows[i] = row
            self._returns[ended] = 0.0
            self._lengths[ended] = 0
        for row, flag in zip(rows, time_limit, strict=True):
            row["TimeLimit.truncated"] = flag
        return obs, np.asarray(rewards, dtype=np.float32), dones, rows

    def close(self) -> None:
        self.venv.close()

    # --- attributes -------------------------------------------------------------------------------

    def _all(self, indices, what: str) -> list[int]:
        idx = list(self._get_indices(indices))
        if sorted(set(idx)) != list(range(self.num_envs)):
            raise ValueError(f"NativeVecEnv: the {self.num_envs} robots share one environment object; {what} must "
                             f"target all of them (indices=None), got indices={indices!r}")
        return idx

    def get_attr(self, attr_name: str, indices: Iterable[int] | int | None = None) -> list[Any]:
        """The environment's attribute ``attr_name``, once per index (AttributeError if it has none)."""
        idx = list(self._get_indices(indices))
        if attr_name == "observation_space":
            value = self.venv.single_observation_space
        elif attr_name == "action_space":
            value = self.venv.single_action_space
        else:
            try:
                value = getattr(self.venv, attr_name)
            except AttributeError:
                value = getattr(self.venv.unwrapped, attr_name)
        return [value] * len(idx)

    def set_attr(self, attr_name: str, value: Any, indices: Iterable[int] | int | None = None) -> None:
        """Set ``attr_name`` on the shared environment object (``indices`` must cover every robot)."""
        self._all(indices, f"set_attr({attr_name!r})")
        setattr(self.venv.unwrapped, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: Iterable[int] | int | None = None,
                   **method_kwargs) -> list[Any]:
        """Call ``method_name`` once on the shared environment object; its result repeated per robot."""
        idx = self._all(indices, f"env_method({method_name!r})")
        result = getattr(self.venv.unwrapped, method_name)(*method_args, **method_kwargs)
        return [result] * len(idx)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper],
                       indices: Iterable[int] | int | None = None) -> list[bool]:
        """False for every robot: none is inside a ``gymnasium.Wrapper`` (there is no per-robot env)."""
        return [False] * len(list(self._get_indices(indices)))
