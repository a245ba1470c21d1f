"""The single Gymnasium environment (path following or go-to-pose), a :class:`TaskCore` with one robot."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from omni_gym.envs.config import RenderModes, check_reset_options, check_seed, custom_kwargs, make_config
from omni_gym.envs.core import OBS_CLIP, RobotEnvAttributes, TaskCore, as_actions


class OmniPathEnv(RobotEnvAttributes, gym.Env):
    """An omnidirectional robot that slips (and may lose wheel contact) follows a reference.

    ## Description

    A robot with n omni wheels (3 for ``williams2002``, 4 for ``phunopas2018``, 3 to 16 for
    ``regularN`` or a calibrated model) drives in a square arena, simulated with pymunk and a per-wheel
    slip-friction model (Williams et al. 2002) and, on the Phunopas ids, random wheel lift-off
    (Phunopas & Inoue 2018). ``task="path"`` follows a moving reference (random waypoints, circle,
    figure eight, line); ``task="goto"`` reaches a random goal pose along a quintic. One step is one
    control period (``1 / control_hz`` s, 10 ms by default) of physics substeps.

    ## Action Space

    ``Box(-1, 1, (A,), float32)``. ``action_mode="twist"`` (A = 3): body vx, vy [m/s] and ω [rad/s]
    = action · (max_speed, max_speed, max_yaw_rate), body frame, mapped to wheel speeds by inverse
    kinematics. ``action_mode="wheels"`` (A = n): wheel speed commands [rad/s] = action · w_max
    (``wheel_scale``, the largest wheel speed a twist within those limits needs). Actions must have
    exactly this shape and hold real numbers; values outside [−1, 1] are clipped; NaN or infinity
    raises ValueError and leaves the state untouched.

    ## Observation Space

    ``Box(-10, 10, (D,), float32)``; every value is clipped to ±10. n is the wheel count, A the
    action size; "index" is inclusive; "range" is after scaling and clipping. Scales: v_max =
    ``max_speed`` [m/s], ω_max = ``max_yaw_rate`` [rad/s], w_max = ``wheel_scale`` [rad/s],
    h = ``arena_half_size`` [m]. Names are the fields of ``env.observation_layout``
    (:mod:`omni_gym.envs.observations`, whose decoders turn an observation back into SI units).

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

    ``obs_mode="sensors"`` (what a real robot has; D = n + 29 + A):

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

    The built-in tracking reward, :data:`omni_gym.envs.reward.FORMULA` (``docs/environments.md``), of the
    distance e [m] from the reference position, the heading error e_θ [rad] and the clipped action a: at
    most 1 per step and positive while tracking, so ending early never pays. ``reward=`` takes your own
    (:mod:`omni_gym.envs.reward`).

    ## Starting State

    The robot is at rest on the reference's first pose (the arena centre (0, 0)); the reference,
    domain-randomised parameters, contact process and sensor noise are drawn from ``np_random``, so
    the seed fixes the episode.

    ## Episode End

    * Termination: the tracking error exceeds ``lost_distance`` (0.5 m) or the robot touches a wall
      or an obstacle.
    * Truncation: the end of the reference (``episode_seconds · control_hz`` steps; the registered
      ``max_episode_steps`` equals it for the default length).

    ## Arguments

    Every physical option is a keyword of ``gym.make``, declared once in
    :class:`omni_gym.envs.config.EnvConfig` (this table is written from it by
    ``python -m omni_gym.envs.docgen``; the bounds' reasons are in ``docs/bounds.md``). "default" is the
    keyword's own, then the ids that pass another value. A bad keyword raises a one-line ValueError
    naming it.

    | keyword | default | allowed | unit | meaning |
    |---|---|---|---|---|
    | `robot` | `williams2002`; Phunopas-v0, GoToPose-v0: `phunopas2018`; Mecanum-v0: `optiodom_omni4` | `williams2002`, `phunopas2018`, `optiodom_omni3`, `optiodom_omni4`, `regularN` (3 ≤ N ≤ 16) | — | robot preset (`optiodom_omni4` has mecanum wheels: needs `friction="initial"`); ignored when `model` is given |
    | `surface` | `carpet` | `paper`, `carpet`, `grip` | — | floor, `omni_gym.physics.friction.SURFACES`; ignored when `model` is given |
    | `friction` | `roller_gap`; Mecanum-v0: `initial` | `initial`, `roller_gap` | — | friction model (`roller_gap`: omni wheels only); ignored when `model` is given |
    | `model` | None | None, a model JSON file path (str or `os.PathLike`), its dict, a `SimModel`; the model JSON bounds (`docs/bounds.md`), 3 to 16 wheels, a `wheel_liftoff` effect's rates within the `lift_rate`, `recover_rate` bounds (`recover_rate` only when `lift_rate` > 0) | — | a calibrated model; it defines the robot, surface, friction model and effects |
    | `task` | `path`; GoToPose-v0: `goto` | `path`, `goto` | — | follow a moving reference (`path`) or reach a goal pose (`goto`) |
    | `trajectory` | `waypoints`; GoToPose-v0: `goto` | `waypoints`, `circle`, `figure_eight`, `line`, `goto` | — | the reference: `path` takes `waypoints`, `circle`, `figure_eight`, `line`; `goto` takes `goto` |
    | `ref_heading` | `forward` | `forward`, `tangent`, `random` | — | heading along the path: body +y along it (`forward`), body +x (`tangent`), or `random` |
    | `ref_turn` | `during`; Williams-v1: `before` | `during`, `before` | — | `waypoints` only: the heading turns while translating (`during`) or in place before each translation (`before`) |
    | `ref_traction` | 0; Williams-v1, Phunopas-v0, Mecanum-v0, GoToPose-v0: 1 | [0, 1] | — | the share r of the wheels' friction set (`omni_gym.physics.traction`, "moving" mode, the model's floor) left after the motion's rolling resistance u_s that a reference's accelerations may use: one that asks more than u_s + r·(1 − u_s) runs slower until it fits (up to 8×); 0 draws references as they are, feasible or not (`info["reference_traction"]` reports the share u they ask either way) |
    | `obs_mode` | `state` | `state`, `sensors` | — | observation: privileged `state` or what a real robot has (`sensors`) |
    | `action_mode` | `twist` | `wheels`, `twist` | — | action: body twist (`twist`) or wheel speeds (`wheels`) |
    | `kinematics` | `nominal` | `nominal`, `model` | — | wheel matrix that turns a `twist` action into wheel speeds and that controllers read (`env.unwrapped.wheel_kinematics`): the robot's `nominal` one, or the `model`'s effective one (its `wheel_radius`, `wheel_geometry`, `mecanum_lateral` effects) |
    | `actuation` | `ideal` | `ideal`, `servo` | — | wheel drive: velocity source (`ideal`) or PI speed loop with torque limit and wheel inertia (`servo`) |
    | `control_hz` | 100 | [1, 10000] | Hz | control rate: one step is 1/control_hz |
    | `physics_dt` | 0.0005 | [1e-5, 0.002]; 1/control_hz a whole number of substeps | s | physics substep |
    | `episode_seconds` | 20; GoToPose-v0: 8 | (0, 3600]; 1 to 1,000,000 control steps | s | reference length; truncation at its end |
    | `lift_rate` | 0; Phunopas-v0, Mecanum-v0, GoToPose-v0: 0.5 | [0, 1000] | 1/s | rate of losing contact with a wheel (0: never); a model's `wheel_liftoff` effect replaces it |
    | `recover_rate` | 5 | [0, 1000] | 1/s | rate of regaining it; a model's `wheel_liftoff` effect replaces it |
    | `sensor_noise` | 1 | [0, 100] | — | scale on every sensor noise level of `SensorConfig` (0: noiseless, quantisation stays) |
    | `arena_half_size` | 2 | [0.1, 1000] | m | half the side of the square arena |
    | `walls` | False | True, False; `arena_half_size` > body radius + 0.01 m | — | walls at the arena's edge |
    | `obstacles` | () | at most 1000 discs, radius ≥ 0.001; each disc inside the arena (max(abs(x), abs(y)) + radius ≤ `arena_half_size`) and clear of the robot at the start pose (0, 0) | m | disc obstacles: a sequence of (x, y, radius) triples, arena frame |
    | `ref_speed` | 0.25 | [0.001, 10] | m/s | typical reference speed |
    | `max_speed` | 0.6 | [0.001, 10] | m/s | the body speeds vx, vy at action ±1 (`twist`) |
    | `max_yaw_rate` | 3 | [0.001, 100] | rad/s | the body yaw rate ω at action ±1 (`twist`) |
    | `lost_distance` | 0.5 | [0.001, 10000] | m | tracking error that terminates the episode |
    | `success_distance` | 0.05 | (0, 10000] | m | final position error counted as success (`info["is_success"]`) |
    | `success_heading` | 0.1 | (0, π] | rad | final heading error counted as success |
    | `randomize_floor` | None | None or a non-empty tuple of `paper`/`carpet`/`grip`, each optionally `:` `initial`/`roller_gap`; with `model`: the floor replaces the model's surface (and friction model), its effects stay; a `roller_gap` effect (friction coefficients of the model's own floor) is refused | — | at each reset every robot draws one floor, uniformly, from this tuple: a surface name, or `"surface:friction_model"` (e.g. `"grip:initial"`, `"carpet:roller_gap"`; without one the `friction` keyword's or the model's); `randomize_friction` scales it; `info["floor"]` names it |
    | `randomize_friction` | None | None or (lo, hi) with 0 ≤ lo ≤ hi ≤ 10 | — | every friction coefficient scaled by U(lo, hi) at each reset |
    | `randomize_mass` | None | None or (lo, hi) with 0.05 ≤ lo ≤ hi ≤ 20 | — | mass and inertia scaled by U(lo, hi) at each reset |
    | `randomize_lift_rate` | None | None or (lo, hi) with 0 ≤ lo ≤ hi ≤ 1000 | 1/s | `lift_rate` drawn from U(lo, hi) at each reset |
    | `randomize_sensor_noise` | None | None or (lo, hi) with 0 ≤ lo ≤ hi ≤ 10 | — | every sensor noise and bias std (on top of `sensor_noise`) scaled by one U(lo, hi) per robot at each reset |
    | `render_mode` | None | None, `rgb_array`, `human` | — | `rgb_array` (H×W×3 uint8) or `human` (pygame window); single environment only |
    | `reward` | None | None, `BuiltinReward` (the built-in), a callable `f(RewardInputs) -> (B,) array`, or a class of such | — | the reward: None is the built-in tracking reward (`omni_gym.envs.reward.FORMULA`, computed in the compiled observation kernel); your own is a callable on `omni_gym.envs.reward.RewardInputs` returning one number per robot |

    ``model=`` takes a calibrated model (a model JSON file path or the dict ``omni-gym model show --json``
    prints, effects included): it then defines the robot, surface, friction model and effects,
    ``robot``/``surface``/``friction`` are ignored, and a ``wheel_liftoff`` effect sets the contact
    process's rates in place of ``lift_rate``/``recover_rate``. ``reset`` takes no options (any key is
    refused with ValueError).

    Public attributes for controllers (read through ``env.unwrapped``): ``robot``, ``wheel_matrix``,
    ``wheel_kinematics`` (the wheel matrix and rolling radius twist actions go through: ``kinematics``),
    ``wheel_scale``, ``observation_layout``, ``obs_scales``, ``sensor_config`` (settable; used at the
    next reset) and ``cfg``.

    ## Version History

    * v0: initial version (ids ``OmniPathFollow-Phunopas-v0``, ``OmniGoToPose-v0`` and the paper's
      Williams task, now ``OmniPathFollow-WilliamsPaper-v0``). Before the first release, within v0:
      batched sensors (a seed's sensor noise values changed, same distributions) and
      ``randomize_sensor_noise`` (``docs/environments.md``, Version history).
    * ``OmniPathFollow-Williams-v1``: references turn in place before each translation
      (``ref_turn="before"``). On WilliamsPaper-v0 the heading turns while the robot translates,
      sweeping the motion through body x, where the robot's friction cannot sustain it
      (``benchmarks/results/feasibility.md``, moving mode); the new keyword ``ref_turn``. The paper's
      task was ``OmniPathFollow-Williams-v0`` until Gymnasium's "out of date, upgrade to v1" hint
      pointed its users at this different task; that id now raises an error naming both.
    * ``OmniPathFollow-Custom-v0``: robot, floor and lift-off entirely from ``model=``
      (:class:`OmniCustomEnv`).
    """  # noqa: E501 (observation tables: one row per line)

    metadata = {"render_modes": RenderModes(["human", "rgb_array"]), "render_fps": 100}

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
        reward, terminated, truncated = core.outcome(0)
        truncated = truncated and not terminated
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


class OmniCustomEnv(OmniPathEnv):
    """``OmniPathFollow-Custom-v0``: path following with the robot, surface, friction model, effects and
    lift-off of ``model=`` alone (required).

    The other ids keep their own lift-off rates under ``model=`` (``OmniPathFollow-Phunopas-v0``: 0.5 /s);
    here a wheel lifts only if the model has a ``wheel_liftoff`` effect (or ``lift_rate`` is given).
    ``robot``, ``surface`` and ``friction`` are refused: the model defines them. Everything else is as
    :class:`OmniPathEnv`.
    """

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(render_mode=render_mode, **custom_kwargs(kwargs))
