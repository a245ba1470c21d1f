"""Native vectorised environment: N robots in one pymunk space, wheel forces computed for all at once.

Reached through ``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point")``. Two
Gymnasium 1.x autoreset modes (keyword ``autoreset_mode``):

* ``"next_step"`` (default, ``AutoresetMode.NEXT_STEP``): the step after an episode ends resets that
  sub-environment, ignores its action and returns its first observation with reward 0 and both flags
  False.
* ``"same_step"`` (``AutoresetMode.SAME_STEP``): the step in which an episode ends resets that
  sub-environment at once and returns its first observation (with the ended step's reward and flags);
  ``info["final_obs"]`` and ``info["final_info"]`` hold the ended step's observation and infos. This is
  what Stable-Baselines3 needs (:mod:`agents.sb3_vec_env`).

``reset(seed=s)`` seeds sub-environment i with s + i, so the vector reproduces N single environments
reset with seeds s, s + 1, …, bit for bit, in either mode (same seeds: the same episodes; the
``same_step`` stream only skips the ``next_step`` stream's autoreset steps).

Keywords are those of the single environment (``model=`` included: every robot is built from the same
model). Actions must have shape (num_envs, A) and hold real numbers; ``reset`` takes no options.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from omni_gym.envs.config import check_reset_options, check_seed, custom_kwargs, is_number, make_config
from omni_gym.envs.core import OBS_CLIP, RobotEnvAttributes, TaskCore, as_actions
from omni_gym.physics.world import ARENA_ROOM


def max_robots(arena_half_size: float) -> int:
    """How many robots one space holds: arenas are laid out along x, each ``2^ceil(log2(2h + 4))`` m wide,
    within ``ARENA_ROOM`` (the rule of :class:`omni_gym.physics.world.World`)."""
    spacing = 2.0 ** math.ceil(math.log2(2.0 * arena_half_size + 4.0))
    return int(ARENA_ROOM // spacing) - 1


MAX_NUM_ENVS = max_robots(0.1)  # 65535: the smallest arenas (arena_half_size <= 2 m: 8 m apart)


class OmniPathVectorEnv(RobotEnvAttributes, VectorEnv):
    """``num_envs`` copies of :class:`~omni_gym.envs.omni_env.OmniPathEnv` stepped together.

    ## Description

    N robots, each in its own arena, in one pymunk space; wheel forces for all of them are computed
    in one compiled call per physics substep. Each robot has its own generator and clock, so the
    vector reproduces N single environments exactly (see the module docstring for autoreset and
    seeding). Reached through ``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point")``.

    ## Action Space

    ``Box(-1, 1, (N, A), float32)``, row i for robot i; each row as the single environment's action
    (``action_mode="twist"``: A = 3, body vx, vy [m/s], ω [rad/s] over (max_speed, max_speed,
    max_yaw_rate); ``"wheels"``: A = n, wheel speeds [rad/s] over w_max). Values outside [−1, 1] are
    clipped; any NaN or infinity raises ValueError before any robot moves.

    ## Observation Space

    ``Box(-10, 10, (N, D), float32)``: row i is robot i's observation, with the single environment's
    layout (n wheels, A action values; "index" is inclusive; ``observation_layout`` names the slices;
    v_max = ``max_speed``, ω_max = ``max_yaw_rate``, w_max = ``wheel_scale``, h = ``arena_half_size``).

    ``obs_mode="state"`` (privileged; D = 18 + A):

    | index | name | quantity | unit | scale | range |
    |---|---|---|---|---|---|
    | 0…1 | `tracking_error_body` | reference − robot position, body frame | m | / 0.25 m | ±10 |
    | 2 | `heading_error` | wrap(θ_ref − θ) | rad | / π | ±1 |
    | 3…5 | `body_velocity` | robot vx, vy (body frame), ω | m/s, m/s, rad/s | / v_max, v_max, ω_max | ±10 |
    | 6…8 | `reference_velocity` | reference vx, vy (body frame), ω | m/s, m/s, rad/s | / v_max, v_max, ω_max | ±10 |
    | 9…11 | `lookahead[0]` | reference at +0.25 s: offset x, y (body frame), heading error | m, m, rad | / 0.5 m, / π | ±10 |
    | 12…14 | `lookahead[1]` | reference at +0.5 s: offset x, y (body frame), heading error | m, m, rad | / 0.5 m, / π | ±10 |
    | 15…17 | `lookahead[2]` | reference at +1 s: offset x, y (body frame), heading error | m, m, rad | / 0.5 m, / π | ±10 |
    | 18…17+A | `last_action` | previous (clipped) action |  |  | ±1 |

    ``obs_mode="sensors"`` (D = n + 29 + A):

    | index | name | quantity | unit | scale | range |
    |---|---|---|---|---|---|
    | 0…n−1 | `encoder_rates` | change of the quantised wheel angles over the control period | rad/s | / w_max | ±10 |
    | n | `gyro` | yaw rate (noise, bias, bias walk) | rad/s | / ω_max | ±10 |
    | n+1…n+2 | `compass_sin_cos` | compass heading (noise) as sin, cos |  |  | ±1 |
    | n+3…n+4 | `accelerometer` | acceleration, body frame (noise, bias) | m/s² | / 5 m/s² | ±10 |
    | n+5…n+8 | `camera_fix` | last camera fix (10 Hz): x, y (world frame), sin θ, cos θ | m, m, –, – | / h (x, y) | ±10 |
    | n+9 | `fix_age` | time since that fix, capped at 1 s | s |  | [0, 1] |
    | n+10…n+13 | `reference_now` | reference now: x, y (world frame), sin θ, cos θ | m, m, –, – | / h (x, y) | ±10 |
    | n+14…n+16 | `reference_velocity` | reference velocity now: ẋ, ẏ (world frame), θ̇ | m/s, m/s, rad/s | / v_max, v_max, ω_max | ±10 |
    | n+17…n+20 | `reference_lookahead[0]` | reference at +0.25 s: x, y (world frame), sin θ, cos θ | m, m, –, – | / h (x, y) | ±10 |
    | n+21…n+24 | `reference_lookahead[1]` | reference at +0.5 s: x, y (world frame), sin θ, cos θ | m, m, –, – | / h (x, y) | ±10 |
    | n+25…n+28 | `reference_lookahead[2]` | reference at +1 s: x, y (world frame), sin θ, cos θ | m, m, –, – | / h (x, y) | ±10 |
    | n+29…n+28+A | `last_action` | previous (clipped) action |  |  | ±1 |

    ## Rewards

    Per robot, as the single environment (:data:`omni_gym.envs.reward.FORMULA`, or the ``reward=``
    keyword's); 0 on the autoreset step (``next_step`` mode).

    ## Starting State

    Each robot at rest on its reference's first pose (its arena's centre); ``reset(seed=s)`` seeds
    robot i with s + i (or takes a list of N seeds).

    ## Episode End

    Per robot: terminated when its tracking error exceeds ``lost_distance`` or it touches a wall or
    an obstacle; truncated at ``max_episode_steps`` (default: the reference's length).

    ``autoreset_mode="next_step"`` (default): the next step resets that robot, ignores its action row
    and returns its first observation, reward 0 and both flags False.

    ``autoreset_mode="same_step"``: the step in which robot i's episode ends resets it at once.
    ``obs[i]`` is then its new episode's first observation, while ``rewards[i]``, ``terminated[i]`` and
    ``truncated[i]`` are those of the ended step, and the returned infos are the reset's for robot i.
    The ended step is in the infos: ``info["final_obs"]`` (float32, (N, D)) holds the last observation
    of each ended episode, ``info["final_info"]`` the ended step's infos (a dict of arrays over robots,
    with Gymnasium's ``_key`` masks), valid in the rows where ``info["_final_obs"]`` and
    ``info["_final_info"]`` (bool, (N,)) are True; the other rows are zero. Both keys are present only
    on steps in which some episode ends.

    ## Arguments

    ``num_envs`` (N, a positive integer, at most :data:`MAX_NUM_ENVS` and at most what
    :func:`max_robots` allows for the arena size), ``max_episode_steps`` (a positive integer, capped
    at the reference's length), ``autoreset_mode`` ("next_step" or "same_step", or the
    ``gymnasium.vector.AutoresetMode`` member; sets ``metadata["autoreset_mode"]``), ``render_mode``
    (only None), and every keyword of the single environment (``model=`` included: every robot is
    built from the same model; the table of keywords, defaults and bounds is in the Arguments of
    :class:`~omni_gym.envs.omni_env.OmniPathEnv` and ``docs/environments.md``, both written from
    :class:`omni_gym.envs.config.EnvConfig`).
    The public attributes of the single environment (``robot``, ``wheel_matrix``, ``wheel_kinematics``,
    ``wheel_scale``, ``observation_layout``, ``obs_scales``, ``sensor_config``) are available here too.

    ## Version History

    * v0: initial version; ``autoreset_mode="same_step"`` added later (the default is unchanged).
    """  # noqa: E501 (observation tables: one row per line)

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None, render_mode: str | None = None,
                 autoreset_mode: str | AutoresetMode = "next_step", **kwargs: Any) -> None:
        num_envs = _positive_int("num_envs", num_envs)
        mode = _autoreset_mode(autoreset_mode)
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
        self.autoreset_mode = mode
        self.metadata = dict(type(self).metadata, autoreset_mode=mode)  # per instance; the class dict stays
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
        if self.autoreset_mode is AutoresetMode.SAME_STEP:
            return self._step_same()
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

    def _step_same(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """The rest of a ``same_step`` step, after ``advance``: observe, then reset the robots whose episode ended."""
        core = self.core
        core.observe()
        rewards = core.rewards()
        terminated = core.terminated()
        truncated = (core.step_count >= self.max_episode_steps) & ~terminated
        ended = terminated | truncated
        if not ended.any():
            return core.obs.astype(np.float32), rewards, terminated, truncated, self._infos()
        idx = np.flatnonzero(ended)
        # Snapshot the ended step before the reset overwrites those rows; observing only the reset robots
        # keeps every robot at one sensor reading per step or reset (the same draws as next_step mode).
        final_obs = np.zeros((self.num_envs, core.obs_dim), dtype=np.float32)
        final_obs[idx] = core.obs[idx]
        final_info = core.infos()
        for key in list(final_info):
            final_info[key][~ended] = 0  # core.infos() returns copies
            final_info["_" + key] = ended.copy()
        for i in idx:
            core.reset_robot(i, self._rngs[i])
        core.observe(robots=idx)
        infos = self._infos()
        infos["final_obs"] = final_obs
        infos["_final_obs"] = ended.copy()
        infos["final_info"] = final_info
        infos["_final_info"] = ended
        return core.obs.astype(np.float32), rewards, terminated, truncated, infos

    def _infos(self) -> dict:
        infos: dict[str, Any] = self.core.infos()
        for key in list(infos):
            infos["_" + key] = np.ones(self.num_envs, dtype=bool)
        return infos


def _autoreset_mode(value: Any) -> AutoresetMode:
    """``autoreset_mode`` as an :class:`AutoresetMode`: "next_step", "same_step" or those two members."""
    modes = {"next_step": AutoresetMode.NEXT_STEP, "same_step": AutoresetMode.SAME_STEP}
    if isinstance(value, AutoresetMode) and value in modes.values():
        return value
    if isinstance(value, str) and value in modes:
        return modes[value]
    raise ValueError(f"invalid autoreset_mode={value!r}; allowed: 'next_step', 'same_step' "
                     "(or AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)")


def _positive_int(name: str, value: Any) -> int:
    """A count: a positive integer (numpy integers accepted), as a Python int; floats (``4.0``), bools
    and strings are refused, as the environments' other integer inputs are (``check_seed``)."""
    if isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_)) and value >= 1:
        return int(value)
    raise ValueError(f"invalid {name}={value!r}; must be a positive integer")


class OmniCustomVectorEnv(OmniPathVectorEnv):
    """The vector form of ``OmniPathFollow-Custom-v0`` (:class:`~omni_gym.envs.omni_env.OmniCustomEnv`):
    ``model=`` required, ``robot``/``surface``/``friction`` refused."""

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None, render_mode: str | None = None,
                 autoreset_mode: str | AutoresetMode = "next_step", **kwargs: Any) -> None:
        super().__init__(num_envs, max_episode_steps, render_mode, autoreset_mode, **custom_kwargs(kwargs))
