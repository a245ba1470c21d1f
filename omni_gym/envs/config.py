"""Keyword arguments of the environments: defaults, validation and domain randomisation.

Every physical option of the environments is a keyword argument to ``gym.make`` (see the table in
``docs/environments.md``). :func:`make_config` checks each one and raises a one-line ValueError that
names the argument and its allowed values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from omni_gym.friction import FRICTION_MODELS, SURFACES, Surface
from omni_gym.model import ACTUATIONS, SimModel
from omni_gym.robot import PRESETS, robot_preset
from omni_gym.sensors import SensorConfig

TASKS = ("path", "goto")
TRAJECTORIES = ("waypoints", "circle", "figure_eight", "line", "goto")
REF_HEADINGS = ("forward", "tangent", "random")
OBS_MODES = ("state", "sensors")
ACTION_MODES = ("wheels", "twist")
RENDER_MODES = (None, "rgb_array", "human")


@dataclass(frozen=True)
class EnvConfig:
    """All options of a path-following or go-to-pose environment (SI units)."""

    robot: str = "williams2002"
    surface: str = "carpet"
    friction: str = "roller_gap"
    task: str = "path"
    trajectory: str = "waypoints"
    ref_heading: str = "forward"  # reference heading along the path: forward (+y along it), tangent, random
    obs_mode: str = "state"
    action_mode: str = "twist"
    actuation: str = "ideal"
    control_hz: float = 100.0
    physics_dt: float = 0.0005
    episode_seconds: float = 20.0
    lift_rate: float = 0.0  # 1/s, rate of losing contact with a wheel (0: never)
    recover_rate: float = 5.0  # 1/s, rate of regaining it
    sensor_noise: float = 1.0  # scale on every sensor noise of SensorConfig (0: noiseless)
    arena_half_size: float = 2.0  # m
    walls: bool = False
    obstacles: tuple[tuple[float, float, float], ...] = ()
    ref_speed: float = 0.25  # m/s, typical reference speed
    max_speed: float = 0.6  # m/s, |vx|, |vy| at action ±1 (twist mode)
    max_yaw_rate: float = 3.0  # rad/s, |ω| at action ±1 (twist mode)
    lost_distance: float = 0.5  # m, tracking error that ends the episode
    success_distance: float = 0.05  # m, final position error counted as success
    success_heading: float = 0.1  # rad
    randomize_friction: tuple[float, float] | None = None  # scale range on every friction coefficient
    randomize_mass: tuple[float, float] | None = None  # scale range on mass and inertia
    randomize_lift_rate: tuple[float, float] | None = None  # range [1/s] of lift_rate
    render_mode: str | None = None

    @property
    def control_dt(self) -> float:
        return 1.0 / self.control_hz

    @property
    def substeps(self) -> int:
        return int(round(self.control_dt / self.physics_dt))

    @property
    def episode_steps(self) -> int:
        return int(round(self.episode_seconds * self.control_hz))

    def base_model(self) -> SimModel:
        return SimModel(robot=robot_preset(self.robot), surface=SURFACES[self.surface], friction=self.friction)

    def sensor_config(self) -> SensorConfig:
        base = SensorConfig()
        scaled = {f.name: getattr(base, f.name) * self.sensor_noise for f in fields(base) if f.name.endswith("_std")}
        return replace(base, **scaled)


def _choice(name: str, value, allowed) -> None:
    if value not in allowed:
        raise ValueError(f"invalid {name}={value!r}; allowed values: {', '.join(map(repr, allowed))}")


def _positive(name: str, value, allow_zero: bool = False) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        need = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"invalid {name}={value!r}; must be a finite number {need}")
    return float(value)


def _range(name: str, value, lower: float, upper: float) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"invalid {name}={value!r}; must be None or a (low, high) pair") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lower <= lo <= hi <= upper):
        raise ValueError(f"invalid {name}={value!r}; need {lower} <= low <= high <= {upper}")
    return (lo, hi)


def make_config(**kwargs) -> EnvConfig:
    """Validated :class:`EnvConfig` from ``gym.make`` keyword arguments."""
    known = {f.name for f in fields(EnvConfig)}
    for key in kwargs:
        if key not in known:
            raise ValueError(f"unknown keyword argument {key!r}; allowed: {', '.join(sorted(known))}")
    cfg = EnvConfig(**kwargs)
    if cfg.robot not in PRESETS and not (cfg.robot.startswith("regular") and cfg.robot[7:].isdigit()
                                         and int(cfg.robot[7:]) >= 3):
        raise ValueError(f"invalid robot={cfg.robot!r}; allowed values: {', '.join(map(repr, PRESETS))}, 'regularN'")
    _choice("surface", cfg.surface, tuple(SURFACES))
    _choice("friction", cfg.friction, FRICTION_MODELS)
    _choice("task", cfg.task, TASKS)
    _choice("trajectory", cfg.trajectory, TRAJECTORIES)
    _choice("ref_heading", cfg.ref_heading, REF_HEADINGS)
    _choice("obs_mode", cfg.obs_mode, OBS_MODES)
    _choice("action_mode", cfg.action_mode, ACTION_MODES)
    _choice("actuation", cfg.actuation, ACTUATIONS)
    _choice("render_mode", cfg.render_mode, RENDER_MODES)
    if (cfg.task == "goto") != (cfg.trajectory == "goto"):
        raise ValueError(f"invalid trajectory={cfg.trajectory!r} for task={cfg.task!r}; task 'goto' uses "
                         "trajectory 'goto' and task 'path' one of 'waypoints', 'circle', 'figure_eight', 'line'")
    for name in ("control_hz", "physics_dt", "episode_seconds", "recover_rate", "arena_half_size", "ref_speed",
                 "max_speed", "max_yaw_rate", "lost_distance", "success_distance", "success_heading"):
        _positive(name, getattr(cfg, name))
    for name in ("lift_rate", "sensor_noise"):
        _positive(name, getattr(cfg, name), allow_zero=True)
    ratio = (1.0 / cfg.control_hz) / cfg.physics_dt
    if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
        raise ValueError(f"invalid physics_dt={cfg.physics_dt!r}; the control period 1/control_hz "
                         f"({1.0 / cfg.control_hz:g} s) must be a whole number of physics steps")
    if cfg.physics_dt > 0.002:
        raise ValueError(f"invalid physics_dt={cfg.physics_dt!r}; must be <= 0.002 s for accuracy (default 0.0005)")
    if not isinstance(cfg.walls, bool):
        raise ValueError(f"invalid walls={cfg.walls!r}; allowed values: True, False")
    obstacles = tuple(tuple(float(v) for v in o) for o in cfg.obstacles)
    for o in obstacles:
        if len(o) != 3 or not all(math.isfinite(v) for v in o) or o[2] <= 0:
            raise ValueError(f"invalid obstacles entry {o!r}; each obstacle is (x, y, radius > 0) in metres")
    return replace(
        cfg,
        obstacles=obstacles,
        randomize_friction=_range("randomize_friction", cfg.randomize_friction, 0.0, 10.0),
        randomize_mass=_range("randomize_mass", cfg.randomize_mass, 0.05, 20.0),
        randomize_lift_rate=_range("randomize_lift_rate", cfg.randomize_lift_rate, 0.0, 1000.0),
    )


def randomized_model(cfg: EnvConfig, base: SimModel, rng: np.random.Generator) -> tuple[SimModel, float]:
    """(model, lift_rate) for one episode, drawing every randomised factor from ``rng``.

    Draws are made in a fixed order (friction, mass, lift rate) and only for the ranges that are set,
    so the same seed gives the same episode.
    """
    model = base
    if cfg.randomize_friction is not None:
        s = float(rng.uniform(*cfg.randomize_friction))
        surf = base.surface
        model = replace(model, surface=Surface(surf.name, surf.mu_drive * s, surf.mu_transverse * s,
                                               surf.mu_gap * s, surf.k))
    if cfg.randomize_mass is not None:
        s = float(rng.uniform(*cfg.randomize_mass))
        model = replace(model, robot=model.robot.with_changes(mass=base.robot.mass * s,
                                                              inertia=base.robot.inertia * s))
    lift = cfg.lift_rate
    if cfg.randomize_lift_rate is not None:
        lift = float(rng.uniform(*cfg.randomize_lift_rate))
    return model, lift
