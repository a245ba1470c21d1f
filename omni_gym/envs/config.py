"""Keyword arguments of the environments: defaults, validation, bounds and domain randomisation.

Every physical option of the environments is a keyword argument to ``gym.make`` (see the table in
``docs/environments.md``; the bounds and their reasons are in ``docs/bounds.md``). :func:`make_config`
checks each one and raises a one-line ValueError that names the argument and its allowed values.
numpy scalars (``np.float32(0.6)``, ``np.int64(100)``, ``np.bool_(True)``) are accepted and stored as
Python numbers; strings, complex numbers and booleans are never taken for numbers.

``model=`` takes a calibrated model (a model JSON file path, or the dict ``omni-gym model show --json``
prints, effects included). It then defines the robot, surface, friction model and effects, and the
``robot``, ``surface`` and ``friction`` keywords are ignored (the registered ids always pass them, so
an explicit value cannot be told from the id's default). A ``wheel_liftoff`` effect sets the rates of
the contact process in place of ``lift_rate``/``recover_rate``. Domain randomisation applies on top.
"""

from __future__ import annotations

import math
import numbers
import os
import re
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from omni_gym.bounds import RATE_MAX, Bound, wheel_count
from omni_gym.checks import is_number, unknown_key
from omni_gym.io import read_json
from omni_gym.physics import effects as effect_library
from omni_gym.physics.friction import FRICTION_MODELS, SURFACES, Surface
from omni_gym.physics.model import ACTUATIONS, SimModel
from omni_gym.physics.robot import PRESETS, robot_preset
from omni_gym.sensors import SensorConfig

TASKS = ("path", "goto")
TRAJECTORIES = ("waypoints", "circle", "figure_eight", "line", "goto")
REF_HEADINGS = ("forward", "tangent", "random")
REF_TURNS = ("during", "before")  # waypoints: turn while translating, or in place before each translation
OBS_MODES = ("state", "sensors")
ACTION_MODES = ("wheels", "twist")
RENDER_MODES = (None, "rgb_array", "human")
CUSTOM_ID = "OmniPathFollow-Custom-v0"  # robot, floor and lift-off all from model= (omni_gym.envs.omni_env)
MODEL_DEFINES = ("robot", "surface", "friction")  # the keywords a model replaces
RESET_OPTIONS: tuple[str, ...] = ()  # reset(options=...) keys the environments understand (none yet)

MAX_EPISODE_STEPS = 1_000_000  # reference tables: 48 bytes per step and robot (48 MB at the bound)
MAX_OBSTACLES = 1000  # each is a pymunk shape in every robot's arena
MAX_RATE = RATE_MAX  # 1/s: a mean holding time of 1 ms, two default physics substeps (omni_gym.physics.liftoff)
WHEEL_COUNT = wheel_count()  # (3, 16): the one wheel-count bound (omni_gym.bounds, also model files and regularN)
MIN_OBSTACLE_RADIUS = 0.001  # m
WALL_RADIUS = 0.01  # m, thickness of the wall segments (omni_gym.physics.world)


# Reasons: docs/bounds.md, "Environment keywords" (the bound class is omni_gym.bounds.Bound).
BOUNDS: dict[str, Bound] = {b.name: b for b in (
    Bound("control_hz", 1.0, 10000.0, "Hz"),
    Bound("physics_dt", 1e-5, 0.002, "s"),
    Bound("episode_seconds", 0.0, 3600.0, "s", lo_open=True),
    Bound("lift_rate", 0.0, MAX_RATE, "1/s"),  # 0: never lifts; any tiny rate schedules safely (liftoff.py)
    Bound("recover_rate", 0.0, MAX_RATE, "1/s"),  # 0: a lifted wheel stays up until reset
    Bound("sensor_noise", 0.0, 100.0, ""),
    Bound("arena_half_size", 0.1, 1000.0, "m"),
    Bound("ref_speed", 0.001, 10.0, "m/s"),
    Bound("max_speed", 0.001, 10.0, "m/s"),
    Bound("max_yaw_rate", 0.001, 100.0, "rad/s"),
    Bound("lost_distance", 0.001, 10000.0, "m"),
    Bound("success_distance", 0.0, 10000.0, "m", lo_open=True),
    Bound("success_heading", 0.0, math.pi, "rad", lo_open=True),
)}
RANDOM_BOUNDS = {"randomize_friction": (0.0, 10.0), "randomize_mass": (0.05, 20.0),
                 "randomize_lift_rate": (0.0, MAX_RATE), "randomize_sensor_noise": (0.0, 10.0)}


@dataclass(frozen=True)
class EnvConfig:
    """All options of a path-following or go-to-pose environment (SI units)."""

    robot: str = "williams2002"  # ignored when ``model`` is given
    surface: str = "carpet"  # ignored when ``model`` is given
    friction: str = "roller_gap"  # ignored when ``model`` is given
    model: SimModel | None = None  # a calibrated model: robot, surface, friction and effects
    task: str = "path"
    trajectory: str = "waypoints"
    ref_heading: str = "forward"  # reference heading along the path: forward (+y along it), tangent, random
    ref_turn: str = "during"  # waypoints: heading turns during each segment, or in place "before" it
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
    randomize_sensor_noise: tuple[float, float] | None = None  # scale range on every sensor noise std
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
        """The nominal simulation model: ``model`` if given, else the robot/surface/friction presets."""
        if self.model is not None:
            return self.model
        return SimModel(robot=robot_preset(self.robot), surface=SURFACES[self.surface], friction=self.friction)

    def contact_rates(self) -> tuple[float, float]:
        """(lift_rate, recover_rate) [1/s] of the contact process: the model's ``wheel_liftoff`` effect
        if it has one, else the keywords."""
        if self.model is not None and "wheel_liftoff" in self.model.effects:
            p = self.model.effects["wheel_liftoff"]
            return float(p["lift_rate"]), float(p["recover_rate"])
        return self.lift_rate, self.recover_rate

    def sensor_config(self) -> SensorConfig:
        base = SensorConfig()
        scaled = {f.name: getattr(base, f.name) * self.sensor_noise for f in fields(base) if f.name.endswith("_std")}
        return replace(base, **scaled)


# --- value checks (each returns the value as a plain Python object or raises ValueError) ---------


def _show(value) -> str:
    """repr of a user value on one line, cut to 60 characters (a 400-digit integer stays readable)."""
    text = " ".join(repr(value).split())  # one line: numpy wraps long arrays
    return text if len(text) <= 60 else text[:57] + "..."


class RenderModes(list):
    """``metadata["render_modes"]``: a list whose ``in`` refuses a render mode that is not a string.

    ``gym.make`` looks the requested mode up here before it calls the constructor, and for a mode that
    is not listed it calls ``render_mode.endswith(...)``: ``render_mode=3`` raised AttributeError from
    inside Gymnasium. The lookup raises our one-line ValueError first.
    """

    def __contains__(self, mode) -> bool:
        if mode is not None and not isinstance(mode, str):
            raise ValueError(f"invalid render_mode={_show(mode)}; allowed values: {', '.join(map(repr, RENDER_MODES))}")
        return super().__contains__(mode)


def check_custom(kwargs: dict) -> None:
    """The keywords of :data:`CUSTOM_ID`: ``model=`` required, ``robot``/``surface``/``friction`` refused
    (the model defines them; the other ids ignore them, which here would hide a mistake)."""
    if kwargs.get("model") is None:
        raise ValueError(f"{CUSTOM_ID} needs model=: a model JSON file path or its dict, e.g. "
                         f"gym.make({CUSTOM_ID!r}, model='my_robot.json') (omni-gym model show NAME --json writes one)")
    for key in MODEL_DEFINES:
        if key in kwargs:
            raise ValueError(f"invalid {key}={_show(kwargs[key])} for {CUSTOM_ID}: the robot, surface and friction "
                             "come from model=")


def _number(name: str, value, bound: Bound | None = None) -> float:
    if not is_number(value):
        raise ValueError(f"invalid {name}={_show(value)}; must be a number" + (f" {bound.within()}" if bound
                                                                                else ""))
    try:
        v = float(value)
    except OverflowError:  # an integer beyond float range
        v = math.inf
    if not math.isfinite(v) or (bound is not None and not bound.contains(v)):
        raise ValueError(f"invalid {name}={_show(value)}; must be a finite number" + (f" {bound.within()}" if bound
                                                                                      else ""))
    return v


def _choice(name: str, value, allowed) -> str | None:
    if value is not None and not isinstance(value, str):
        raise ValueError(f"invalid {name}={_show(value)}; allowed values: {', '.join(map(repr, allowed))}")
    if value not in allowed:
        raise ValueError(f"invalid {name}={_show(value)}; allowed values: {', '.join(map(repr, allowed))}")
    return None if value is None else str(value)


def _robot(value) -> str:
    allowed = f"{', '.join(map(repr, PRESETS))}, 'regularN' ({WHEEL_COUNT[0]} <= N <= {WHEEL_COUNT[1]})"
    if isinstance(value, str):
        match = re.fullmatch(r"regular([0-9]{1,3})", value)
        if value in PRESETS or (match and WHEEL_COUNT[0] <= int(match.group(1)) <= WHEEL_COUNT[1]):
            return str(value)
        if value.endswith(".json") or os.sep in value:
            allowed += "; a model JSON file goes in model=, e.g. gym.make(ID, model='model.json')"
    raise ValueError(f"invalid robot={_show(value)}; allowed values: {allowed}")


def _flag(name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"invalid {name}={_show(value)}; allowed values: True, False")
    return bool(value)


def _sequence(value) -> list | None:
    """The items of a list, tuple or numpy array; None for anything else (strings included)."""
    if isinstance(value, np.ndarray):
        return list(value) if value.ndim >= 1 else None
    if isinstance(value, (list, tuple)):
        return list(value)
    return None


def _range(name: str, value, lower: float, upper: float) -> tuple[float, float] | None:
    if value is None:
        return None
    items = _sequence(value)
    if items is None or len(items) != 2 or not all(is_number(v) for v in items):
        raise ValueError(f"invalid {name}={_show(value)}; must be None or a (low, high) pair of numbers")
    try:
        lo, hi = float(items[0]), float(items[1])
    except OverflowError:  # an integer beyond float range
        lo, hi = math.nan, math.nan
    if not (math.isfinite(lo) and math.isfinite(hi) and lower <= lo <= hi <= upper):
        raise ValueError(f"invalid {name}={_show(value)}; need {lower:g} <= low <= high <= {upper:g}")
    return (lo, hi)


def _obstacles(value, half_size: float) -> tuple[tuple[float, float, float], ...]:
    """Disc obstacles (x, y, radius) [m], arena frame; each must lie inside the arena."""
    example = "e.g. obstacles=((0.8, 0.0, 0.1),)"
    items = _sequence(value)
    if items is None:
        raise ValueError(f"invalid obstacles={_show(value)}; must be a sequence of (x, y, radius) triples in metres, "
                         f"{example}")
    if len(items) > MAX_OBSTACLES:
        raise ValueError(f"invalid obstacles: {len(items)} obstacles; at most {MAX_OBSTACLES}")
    out = []
    for i, o in enumerate(items):
        entry = _sequence(o)
        if entry is None or len(entry) != 3 or not all(is_number(v) for v in entry):
            raise ValueError(f"invalid obstacles[{i}]={_show(o)}; each obstacle is an (x, y, radius) triple of numbers "
                             f"in metres, {example}")
        try:
            x, y, r = (float(v) for v in entry)
        except OverflowError:  # an integer beyond float range
            x = y = r = math.nan
        if not all(math.isfinite(v) for v in (x, y, r)) or r < MIN_OBSTACLE_RADIUS:
            raise ValueError(f"invalid obstacles[{i}]={_show(o)}; x, y must be finite and the radius >= "
                             f"{MIN_OBSTACLE_RADIUS} m")
        if max(abs(x), abs(y)) + r > half_size:
            raise ValueError(f"invalid obstacles[{i}]={_show(o)}; the disc must lie inside the arena "
                             f"(|x|, |y| <= arena_half_size - radius, arena_half_size={half_size:g} m)")
        out.append((x, y, r))
    return tuple(out)


def _read_model_file(value) -> SimModel:
    """A model JSON file (UTF-8, a byte-order mark allowed) → SimModel; errors name ``model=`` and the file."""
    path = Path(os.fsdecode(value))
    label = f"model={str(path)!r}"  # the whole path (repr of a str is one line)
    try:
        data = read_json(path)  # the one JSON file reader (omni_gym.io)
    except ValueError as exc:
        raise ValueError(f"invalid {label}: {str(exc).removeprefix(f'{path}: ')}") from None
    return _model_from_json(data, label)


def _model_from_json(data, label: str) -> SimModel:
    try:
        return SimModel.from_json(data, where=f"invalid {label}")
    except ValueError as exc:
        raise ValueError(" ".join(str(exc).split())) from None  # one line, whatever the value's repr
    except (TypeError, KeyError, AttributeError) as exc:  # defensive: a malformed value deep inside
        raise ValueError(f"invalid {label}: {exc}") from None


def parse_model(value) -> SimModel | None:
    """``model=``: None, a model JSON path (str or os.PathLike), its dict form, or a SimModel."""
    if value is None:
        return None
    if isinstance(value, SimModel):
        model = value
        _model_from_json(model.to_json(), "model")  # same checks as the JSON form
    elif isinstance(value, dict):
        model = _model_from_json(value, "model (dict)")
    elif isinstance(value, (str, os.PathLike)):
        model = _read_model_file(value)
    else:
        raise ValueError(f"invalid model={_show(value)}; must be a model JSON file path or a dict as "
                         "'omni-gym model show --json' prints it")
    n = model.n_wheels
    if not WHEEL_COUNT[0] <= n <= WHEEL_COUNT[1]:
        raise ValueError(f"invalid model: {n} wheels; the environments need {WHEEL_COUNT[0]} to {WHEEL_COUNT[1]}")
    lift = model.effects.get("wheel_liftoff")
    if lift is not None:
        # recover_rate only matters once a wheel can lift.
        for key in ("lift_rate", "recover_rate") if float(lift["lift_rate"]) > 0 else ("lift_rate",):
            bound = BOUNDS[key]
            if not bound.contains(float(lift[key])):
                raise ValueError(f"invalid model: effect 'wheel_liftoff' {key}={_show(lift[key])}; the environments "
                                 f"need it {bound.within()}")
    return model


# --- the whole configuration -----------------------------------------------------------------------


def make_config(**kwargs) -> EnvConfig:
    """Validated :class:`EnvConfig` from ``gym.make`` keyword arguments (ValueError naming the keyword)."""
    known = {f.name for f in fields(EnvConfig)}
    for key in kwargs:
        if key not in known:
            raise ValueError(unknown_key(key, sorted(known), what="keyword argument"))
    d = EnvConfig()
    get = kwargs.get
    values = {
        "robot": _robot(get("robot", d.robot)),
        "surface": _choice("surface", get("surface", d.surface), tuple(SURFACES)),
        "friction": _choice("friction", get("friction", d.friction), FRICTION_MODELS),
        "model": parse_model(get("model")),
        "task": _choice("task", get("task", d.task), TASKS),
        "trajectory": _choice("trajectory", get("trajectory", d.trajectory), TRAJECTORIES),
        "ref_heading": _choice("ref_heading", get("ref_heading", d.ref_heading), REF_HEADINGS),
        "ref_turn": _choice("ref_turn", get("ref_turn", d.ref_turn), REF_TURNS),
        "obs_mode": _choice("obs_mode", get("obs_mode", d.obs_mode), OBS_MODES),
        "action_mode": _choice("action_mode", get("action_mode", d.action_mode), ACTION_MODES),
        "actuation": _choice("actuation", get("actuation", d.actuation), ACTUATIONS),
        "render_mode": _choice("render_mode", get("render_mode", d.render_mode), RENDER_MODES),
        "walls": _flag("walls", get("walls", d.walls)),
    }
    for name, bound in BOUNDS.items():
        values[name] = _number(name, get(name, getattr(d, name)), bound)
    for name, (lower, upper) in RANDOM_BOUNDS.items():
        values[name] = _range(name, get(name), lower, upper)
    values["obstacles"] = _obstacles(get("obstacles", d.obstacles), values["arena_half_size"])
    cfg = EnvConfig(**values)
    _check_combination(cfg)
    return cfg


def _check_combination(cfg: EnvConfig) -> None:
    """Checks across keywords: robot/friction, task/trajectory, control period vs physics step, episode length,
    start pose."""
    if cfg.model is None and cfg.friction == "roller_gap" and robot_preset(cfg.robot).has_angled_rollers:
        # The omni-wheel ids pass friction='roller_gap': a mecanum preset given to them needs friction='initial'.
        raise ValueError(f"invalid friction='roller_gap' for robot={cfg.robot!r}: its wheels are mecanum wheels "
                         "(rollers at an angle), to which only friction='initial' applies (docs/model.md); pass "
                         "friction='initial' or use OmniPathFollow-Mecanum-v0")
    if (cfg.task == "goto") != (cfg.trajectory == "goto"):
        raise ValueError(f"invalid trajectory={cfg.trajectory!r} for task={cfg.task!r}; task 'goto' uses "
                         "trajectory 'goto' and task 'path' one of 'waypoints', 'circle', 'figure_eight', 'line'")
    ratio = (1.0 / cfg.control_hz) / cfg.physics_dt
    if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
        raise ValueError(f"invalid physics_dt={cfg.physics_dt!r}; the control period 1/control_hz "
                         f"({1.0 / cfg.control_hz:g} s) must be a whole number of physics steps")
    steps = cfg.episode_steps
    if not 1 <= steps <= MAX_EPISODE_STEPS:
        raise ValueError(f"invalid episode_seconds={cfg.episode_seconds!r} at control_hz={cfg.control_hz:g}: "
                         f"{steps} control steps; need 1 to {MAX_EPISODE_STEPS}")
    _check_start_clear(cfg)


def _check_start_clear(cfg: EnvConfig) -> None:
    """Every reference starts at the arena centre: refuse a configuration whose robot starts in contact.

    A robot placed on an obstacle or across a wall would end every episode on its first step.
    """
    radius = cfg.base_model().robot.body_radius
    for i, (x, y, r) in enumerate(cfg.obstacles):
        if math.hypot(x, y) <= r + radius:
            raise ValueError(f"invalid obstacles[{i}]=({x:g}, {y:g}, {r:g}): it overlaps the robot at its start pose "
                             f"(every episode starts at the arena centre (0, 0); robot body radius {radius:g} m)")
    if cfg.walls and cfg.arena_half_size <= radius + WALL_RADIUS:
        raise ValueError(f"invalid arena_half_size={cfg.arena_half_size:g} with walls=True: the robot (body radius "
                         f"{radius:g} m) would touch the walls at its start pose, the arena centre")


def check_seed(seed, name: str = "seed") -> int | None:
    """A reset seed: None or a non-negative integer (numpy integers accepted), as a Python int."""
    if seed is None:
        return None
    if isinstance(seed, numbers.Integral) and not isinstance(seed, (bool, np.bool_)) and seed >= 0:
        return int(seed)
    raise ValueError(f"invalid {name}={_show(seed)}; must be None or a non-negative integer")


def check_reset_options(options) -> None:
    """``reset(options=...)``: None or a dict of supported keys (none are defined: refuse any key)."""
    if options is None:
        return
    if not isinstance(options, dict):
        raise ValueError(f"invalid reset options={_show(options)}; must be None or a dict")
    unknown = sorted(map(repr, options))
    if unknown:
        supported = ", ".join(RESET_OPTIONS) or "none (the episode is set by the seed and the keywords)"
        raise ValueError(f"unsupported reset option(s) {', '.join(unknown)}; supported: {supported}")


def randomized_model(cfg: EnvConfig, base: SimModel, rng: np.random.Generator) -> tuple[SimModel, float]:
    """(model, lift_rate) for one episode, drawing every randomised factor from ``rng``.

    Draws are made in a fixed order (friction, mass, lift rate) and only for the ranges that are set,
    so the same seed gives the same episode. The friction scale multiplies every coefficient of the
    surface and, if the model has one, the ``roller_gap`` effect's fitted gap coefficient.
    """
    model = base
    if cfg.randomize_friction is not None:
        s = float(rng.uniform(*cfg.randomize_friction))
        surf = base.surface
        model = replace(model, surface=Surface(surf.name, surf.mu_drive * s, surf.mu_transverse * s,
                                               surf.mu_gap * s, surf.k))
        for name, params in base.effects.items():  # effects with friction coefficients (roller_gap)
            scaled = effect_library.get(name).scale_friction(params, s)
            if scaled is not params:
                model = model.with_effect(name, scaled)
    if cfg.randomize_mass is not None:
        s = float(rng.uniform(*cfg.randomize_mass))
        model = replace(model, robot=model.robot.with_changes(mass=base.robot.mass * s,
                                                              inertia=base.robot.inertia * s))
    lift = cfg.contact_rates()[0]
    if cfg.randomize_lift_rate is not None:
        lift = float(rng.uniform(*cfg.randomize_lift_rate))
    return model, lift


def sensor_noise_scale(cfg: EnvConfig, rng: np.random.Generator) -> float:
    """The factor on every sensor noise std of one episode: U(lo, hi) of ``randomize_sensor_noise``
    drawn from ``rng``, else 1 with no draw (so seeded episodes without the keyword are unchanged).

    It multiplies the levels of ``sensor_config`` (already scaled by ``sensor_noise``); it is drawn in
    both observation modes, so the same seed gives the same physics whatever ``obs_mode``.
    """
    if cfg.randomize_sensor_noise is None:
        return 1.0
    return float(rng.uniform(*cfg.randomize_sensor_noise))
