"""Native vectorised environment: N robots in one pymunk space, wheel forces computed for all at once.

Reached through ``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point")``. Follows
Gymnasium 1.x's default autoreset mode (``NEXT_STEP``): the step after an episode ends resets that
sub-environment, ignores its action and returns its first observation with reward 0 and both flags
False. ``reset(seed=s)`` seeds sub-environment i with s + i, so the vector reproduces N single
environments reset with seeds s, s + 1, …, bit for bit.

Keywords are those of the single environment (``model=`` included: every robot is built from the same
model). Actions must have shape (num_envs, A) and hold real numbers; ``reset`` takes no options.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from omni_gym.envs.config import check_reset_options, check_seed, is_number, make_config
from omni_gym.envs.core import OBS_CLIP, TaskCore, as_actions
from omni_gym.world import ARENA_ROOM


def max_robots(arena_half_size: float) -> int:
    """How many robots one space holds: arenas are laid out along x, each ``2^ceil(log2(2h + 4))`` m wide,
    within ``ARENA_ROOM`` (the rule of :class:`omni_gym.world.World`)."""
    spacing = 2.0 ** math.ceil(math.log2(2.0 * arena_half_size + 4.0))
    return int(ARENA_ROOM // spacing) - 1


MAX_NUM_ENVS = max_robots(0.1)  # 65535: the smallest arenas (arena_half_size <= 2 m: 8 m apart)


class OmniPathVectorEnv(VectorEnv):
    """``num_envs`` copies of :class:`~omni_gym.envs.omni_env.OmniPathEnv` stepped together."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None, render_mode: str | None = None,
                 **kwargs: Any) -> None:
        num_envs = _positive_int("num_envs", num_envs)
        if num_envs > MAX_NUM_ENVS:  # checked before anything is allocated per robot
            raise ValueError(f"invalid num_envs={num_envs}; at most {MAX_NUM_ENVS} robots fit in one space")
        if max_episode_steps is not None:
            max_episode_steps = _positive_int("max_episode_steps", max_episode_steps)
        if render_mode is not None:
            raise ValueError(f"invalid render_mode={render_mode!r} for the vectorised environment; allowed: None "
                             "(render a single environment instead)")
        self.cfg = make_config(**kwargs)
        limit = max_robots(self.cfg.arena_half_size)
        if num_envs > limit:
            raise ValueError(f"invalid num_envs={num_envs} with arena_half_size={self.cfg.arena_half_size:g}: at most "
                             f"{limit} such arenas fit in one space")
        self.num_envs = num_envs
        self.core = TaskCore(self.cfg, self.num_envs)
        steps = self.cfg.episode_steps
        self.max_episode_steps = steps if max_episode_steps is None else min(int(max_episode_steps), steps)
        self.single_observation_space = spaces.Box(-OBS_CLIP, OBS_CLIP, shape=(self.core.obs_dim,), dtype=np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(self.core.action_dim,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        self._rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict | None = None) -> tuple[np.ndarray, dict]:
        check_reset_options(options)
        if seed is None or is_number(seed):
            first = check_seed(seed)
            seeds: list[int | None] = [None if first is None else first + i for i in range(self.num_envs)]
        else:
            if not isinstance(seed, (list, tuple, np.ndarray)):
                raise ValueError(f"invalid seed={seed!r}; must be None, a non-negative integer or a list of them")
            seeds = [check_seed(s, f"seed[{i}]") for i, s in enumerate(seed)]
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset: got {len(seeds)} seeds for {self.num_envs} environments")
        for i, s in enumerate(seeds):
            if s is not None:
                self._rngs[i] = seeding.np_random(s)[0]
            self.core.reset_robot(i, self._rngs[i])
        self.core.observe()
        self._autoreset[:] = False
        self._started = True
        return self.core.obs.astype(np.float32), self._infos()

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        core = self.core
        core.advance(as_actions(actions, self.action_space.shape))
        restart = np.flatnonzero(self._autoreset)
        for i in restart:
            core.reset_robot(i, self._rngs[i])  # replaces whatever the shared step did to it
        core.observe()
        rewards = core.rewards()
        terminated = core.terminated()
        truncated = (core.step_count >= self.max_episode_steps) & ~terminated
        if restart.size:
            rewards[restart] = 0.0
            terminated[restart] = False
            truncated[restart] = False
        self._autoreset = terminated | truncated
        return core.obs.astype(np.float32), rewards, terminated, truncated, self._infos()

    def _infos(self) -> dict:
        infos: dict[str, Any] = self.core.infos()
        for key in list(infos):
            infos["_" + key] = np.ones(self.num_envs, dtype=bool)
        return infos


def _positive_int(name: str, value: Any) -> int:
    """A count: a positive integer (numpy integers and integral floats accepted), as a Python int."""
    if is_number(value) and math.isfinite(value) and float(value).is_integer() and value >= 1:
        return int(value)
    raise ValueError(f"invalid {name}={value!r}; must be a positive integer")
