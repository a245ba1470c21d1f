"""The single Gymnasium environment (path following or go-to-pose), a :class:`TaskCore` with one robot."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from omni_gym.envs.config import check_reset_options, check_seed, make_config
from omni_gym.envs.core import OBS_CLIP, TaskCore, as_actions


class OmniPathEnv(gym.Env):
    """An omnidirectional robot that slips (and may lose wheel contact) follows a reference.

    Keyword arguments: see :class:`omni_gym.envs.config.EnvConfig` and ``docs/environments.md``; a bad
    one raises a one-line ValueError naming it. ``model=`` takes a calibrated model (a model JSON file
    path or the dict ``omni-gym model show --json`` prints, effects included): it then defines the
    robot, surface, friction model and effects, ``robot``/``surface``/``friction`` are ignored, and a
    ``wheel_liftoff`` effect sets the contact process's rates in place of ``lift_rate``/``recover_rate``.
    The action and observation sizes follow the model's wheel count.

    Actions must have shape ``action_space.shape`` and hold real numbers; values outside [−1, 1] are
    clipped; an action with NaN or infinity raises ValueError and leaves the state untouched.
    ``reset`` takes no options (any key is refused with ValueError).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 100}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        self.cfg = make_config(render_mode=render_mode, **kwargs)
        self.render_mode = render_mode
        self.metadata = dict(self.metadata, render_fps=int(round(self.cfg.control_hz)))
        self.core = TaskCore(self.cfg, 1)
        self.observation_space = spaces.Box(-OBS_CLIP, OBS_CLIP, shape=(self.core.obs_dim,), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(self.core.action_dim,), dtype=np.float32)
        self._renderer = None
        self._needs_reset = True

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        check_reset_options(options)
        super().reset(seed=check_seed(seed))
        self.core.reset_robot(0, self.np_random)
        self.core.observe()
        self._needs_reset = False
        if self._renderer is not None:
            self._renderer.reset(self.core)
        if self.render_mode == "human":
            self.render()
        return self.core.obs[0].astype(np.float32), self.core.info(0)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._needs_reset:
            raise RuntimeError("call reset() before step() (and after an episode ends)")
        core = self.core
        core.advance(as_actions(action, self.action_space.shape))
        core.observe()
        reward = float(core.rewards()[0])
        terminated = bool(core.terminated()[0])
        truncated = bool(core.truncated()[0]) and not terminated
        self._needs_reset = terminated or truncated
        if self._renderer is not None:
            self._renderer.record(core)
        if self.render_mode == "human":
            self.render()
        return core.obs[0].astype(np.float32), reward, terminated, truncated, core.info(0)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self._renderer is None:
            from omni_gym.envs.render import Renderer

            self._renderer = Renderer(self.cfg, self.core.robot, human=self.render_mode == "human",
                                      fps=self.metadata["render_fps"])
            self._renderer.reset(self.core)
        return self._renderer.draw(self.core)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_renderer"] = None  # windows and surfaces are not picklable; rebuilt on the next render()
        return state

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
