"""Keyword arguments of the environments: defaults, validation, bounds and domain randomisation.

Every physical option of the environments is a keyword argument to ``gym.make``, declared once as a
field of :class:`EnvConfig` with its :class:`Option` (default, kind, bound or choices, unit, meaning,
the bound's reason). :func:`make_config` checks each one by its declaration and raises a one-line
ValueError that names the argument and its allowed values; :mod:`omni_gym.envs.docgen` writes the
tables of the environment docstrings, ``docs/environments.md`` and ``docs/bounds.md`` from the same
declarations.
numpy scalars (``np.float32(0.6)``, ``np.int64(100)``, ``np.bool_(True)``) are accepted and stored as
Python numbers; strings, complex numbers and booleans are never taken for numbers.

``model=`` takes a calibrated model (a model JSON file path, or the dict ``omni-gym model show --json``
prints, effects included). It then defines the robot, surface, friction model and effects, and the
``robot``, ``surface`` and ``friction`` keywords are ignored (the registered ids always pass them, so
an explicit value cannot be told from the id's default). A ``wheel_liftoff`` effect sets the rates of
the contact process in place of ``lift_rate``/``recover_rate``. Domain randomisation applies on top.

``randomize_floor`` draws one floor per robot at every reset from a tuple of :class:`Floor` entries
(``"grip"``, or ``"carpet:roller_gap"`` with its friction model); with ``model=`` the drawn floor replaces
the model's surface (and friction model, if the entry names one) and keeps its other effects, and a model
with an effect that holds friction coefficients of its own floor (``roller_gap``) is refused.
"""

from __future__ import annotations

import math
import numbers
import os
import re
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from omni_gym.bounds import RATE_MAX, Bound, wheel_count
from omni_gym.checks import is_number, unknown_key
from omni_gym.envs import CUSTOM_ID  # robot, floor and lift-off all from model= (omni_gym.envs.omni_env)
from omni_gym.envs.reward import Reward, check_reward
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
KINEMATICS = ("nominal", "model")  # the wheel matrix of twist actions and controllers (omni_gym.physics.kinematics)
RENDER_MODES = (None, "rgb_array", "human")
MODEL_DEFINES = ("robot", "surface", "friction")  # the keywords a model replaces
RESET_OPTIONS: tuple[str, ...] = ()  # reset(options=...) keys the environments understand (none yet)

MAX_EPISODE_STEPS = 1_000_000  # reference tables: 48 bytes per step and robot (48 MB at the bound)
MAX_OBSTACLES = 1000  # each is a pymunk shape in every robot's arena
MAX_RATE = RATE_MAX  # 1/s: a mean holding time of 1 ms, two default physics substeps (omni_gym.physics.liftoff)
WHEEL_COUNT = wheel_count()  # (3, 16): the one wheel-count bound (omni_gym.bounds, also model files and regularN)
MIN_OBSTACLE_RADIUS = 0.001  # m
WALL_RADIUS = 0.01  # m, thickness of the wall segments (omni_gym.physics.world)

# How a keyword is checked (Option.kind); the last four have checks of their own.
KINDS = ("choice", "number", "range", "flag", "robot", "model", "obstacles", "floors", "reward")


@dataclass(frozen=True)
class Floor:
    """One entry of ``randomize_floor``: a surface of :data:`omni_gym.physics.friction.SURFACES` and the
    friction model it carries (one of :data:`omni_gym.physics.friction.FRICTION_MODELS`; None: the
    environment's own, the ``friction`` keyword or the model's). Written ``"surface"`` or
    ``"surface:friction_model"``."""

    surface: str
    friction: str | None = None

    def __str__(self) -> str:
        return self.surface if self.friction is None else f"{self.surface}:{self.friction}"


@dataclass(frozen=True)
class Option:
    """The declaration of one environment keyword: everything about it that is written down anywhere.

    :func:`make_config` checks the keyword by ``kind``; :mod:`omni_gym.envs.docgen` writes the keyword
    tables of the environment docstrings and ``docs/environments.md`` from it (the default beside each
    registered id's own value, ``omni_gym.envs.ENV_IDS``), and the bounds table of ``docs/bounds.md``.

    ``kind``: ``choice`` (one of ``choices``), ``number`` (finite, in [``lo``, ``hi``] ``unit``, open
    at ``lo`` if ``lo_open``), ``range`` (None or a (low, high) pair inside [``lo``, ``hi``]), ``flag``
    (True/False), or one of the keywords with their own check: ``robot``, ``model``, ``obstacles``,
    ``floors``, ``reward``.
    ``doc``: one line of meaning; ``also``: a condition across keywords (:func:`_check_combination`);
    ``reason``: why the bound is where it is (the keywords with one are the rows of ``docs/bounds.md``).
    """

    kind: str
    doc: str
    unit: str = ""
    choices: tuple = ()
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    also: str = ""
    reason: str = ""
    name: str = ""  # the field's name, filled in by OPTIONS

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"option kind must be one of {KINDS}, got {self.kind!r}")

    def bound(self) -> Bound:
        """The numeric bound of a ``number`` keyword (the package's one bound class)."""
        return Bound(self.name, self.lo, self.hi, self.unit, self.reason, lo_open=self.lo_open)


def option(default, kind: str, doc: str, **spec):
    """An :class:`EnvConfig` field with its default and its :class:`Option` declaration."""
    return field(default=default, metadata={"option": Option(kind, doc, **spec)})


@dataclass(frozen=True)
class EnvConfig:
    """All options of a path-following or go-to-pose environment (SI units).

    Each field is one ``gym.make`` keyword, declared once here (:func:`option`): default, kind,
    bound or choices, unit and meaning. The validators, :data:`BOUNDS` and the documentation tables
    (``python -m omni_gym.envs.docgen``) are derived from these declarations.
    """

    robot: str = option(
        "williams2002", "robot",
        doc="robot preset (`optiodom_omni4` has mecanum wheels: needs `friction=\"initial\"`); ignored when `model` "
            "is given",
        reason="a planar omni robot needs 3 wheels; more than 16 is not a wheel layout of this kind",
    )
    surface: str = option(
        "carpet", "choice", choices=tuple(SURFACES),
        doc="floor, `omni_gym.physics.friction.SURFACES`; ignored when `model` is given",
    )
    friction: str = option(
        "roller_gap", "choice", choices=FRICTION_MODELS,
        doc="friction model (`roller_gap`: omni wheels only); ignored when `model` is given",
    )
    model: SimModel | None = option(
        None, "model",
        doc="a calibrated model; it defines the robot, surface, friction model and effects",
        also=f"the model JSON bounds (`docs/bounds.md`), {WHEEL_COUNT[0]} to {WHEEL_COUNT[1]} wheels, a "
             "`wheel_liftoff` effect's rates within the `lift_rate`, `recover_rate` bounds (`recover_rate` only "
             "when `lift_rate` > 0)",
        reason="the same physics as the keywords it replaces",
    )
    task: str = option(
        "path", "choice", choices=TASKS,
        doc="follow a moving reference (`path`) or reach a goal pose (`goto`)",
    )
    trajectory: str = option(
        "waypoints", "choice", choices=TRAJECTORIES,
        doc="the reference: `path` takes `waypoints`, `circle`, `figure_eight`, `line`; `goto` takes `goto`",
    )
    ref_heading: str = option(
        "forward", "choice", choices=REF_HEADINGS,
        doc="heading along the path: body +y along it (`forward`), body +x (`tangent`), or `random`",
    )
    ref_turn: str = option(
        "during", "choice", choices=REF_TURNS,
        doc="`waypoints` only: the heading turns while translating (`during`) or in place before each translation "
            "(`before`)",
    )
    ref_traction: float = option(
        0.0, "number", lo=0.0, hi=1.0,
        doc="the share r of the wheels' friction set (`omni_gym.physics.traction`, \"moving\" mode, the model's floor) "
            "left after the motion's rolling resistance u_s that a reference's accelerations may use: one that asks "
            "more than u_s + r·(1 − u_s) runs slower until it fits (up to 8×); 0 draws references as they are, "
            "feasible or not (`info[\"reference_traction\"]` reports the share u they ask either way)",
        reason="a share of a set: above 1 the wheels cannot transmit what the reference asks, even without feedback",
    )
    obs_mode: str = option(
        "state", "choice", choices=OBS_MODES,
        doc="observation: privileged `state` or what a real robot has (`sensors`)",
    )
    action_mode: str = option(
        "twist", "choice", choices=ACTION_MODES,
        doc="action: body twist (`twist`) or wheel speeds (`wheels`)",
    )
    kinematics: str = option(
        "nominal", "choice", choices=KINEMATICS,
        doc="wheel matrix that turns a `twist` action into wheel speeds and that controllers read "
            "(`env.unwrapped.wheel_kinematics`): the robot's `nominal` one, or the `model`'s effective one "
            "(its `wheel_radius`, `wheel_geometry`, `mecanum_lateral` effects)",
    )
    actuation: str = option(
        "ideal", "choice", choices=ACTUATIONS,
        doc="wheel drive: velocity source (`ideal`) or PI speed loop with torque limit and wheel inertia (`servo`)",
    )
    control_hz: float = option(
        100.0, "number", unit="Hz", lo=1.0, hi=10000.0,
        doc="control rate: one step is 1/control_hz",
        reason="below 1 Hz a control period is longer than any reference feature (`0.001` used to index past the "
               "reference table); above 10 kHz the period is shorter than 10 physics steps of the finest "
               "`physics_dt`; the bound also keeps `1/control_hz` finite (`1e-300` used to hang the first step)",
    )
    physics_dt: float = option(
        0.0005, "number", unit="s", lo=1e-5, hi=0.002,
        doc="physics substep",
        also="1/control_hz a whole number of substeps",
        reason="≤ 2 ms for accuracy (`benchmarks/convergence.py`: 0.5 ms meets 1 mm / 2 mrad); ≥ 10 µs, 50× finer "
               "than needed, keeps a step at 1 Hz to 10⁵ substeps",
    )
    episode_seconds: float = option(
        20.0, "number", unit="s", lo=0.0, hi=3600.0, lo_open=True,
        doc="reference length; truncation at its end",
        also=f"1 to {MAX_EPISODE_STEPS:,} control steps",
        reason="one hour is beyond any episode of these tasks; the step bound caps the reference tables at 48 MB "
               "per robot (`1e308` used to raise `OverflowError`)",
    )
    lift_rate: float = option(
        0.0, "number", unit="1/s", lo=0.0, hi=MAX_RATE,
        doc="rate of losing contact with a wheel (0: never); a model's `wheel_liftoff` effect replaces it",
        reason="0 disables lift-off; any tiny rate is safe (a switch beyond the episode is never scheduled, "
               "docs/model.md); above 1000 /s a wheel would lift within 2 default substeps, faster than the contact"
               " model resolves",
    )
    recover_rate: float = option(
        5.0, "number", unit="1/s", lo=0.0, hi=MAX_RATE,
        doc="rate of regaining it; a model's `wheel_liftoff` effect replaces it",
        reason="as `lift_rate`; 0 keeps a lifted wheel up until the next reset",
    )
    sensor_noise: float = option(
        1.0, "number", lo=0.0, hi=100.0,
        doc="scale on every sensor noise level of `SensorConfig` (0: noiseless, quantisation stays)",
        reason="a scale on the nominal noise levels; 100× already gives a 0.5 m camera and 5 rad compass noise",
    )
    arena_half_size: float = option(
        2.0, "number", unit="m", lo=0.1, hi=1000.0,
        doc="half the side of the square arena",
        reason="a 2 km square exceeds any lab; arenas share one pymunk space laid out along x (2²⁰ m from the "
               "origin, `omni_gym.physics.world`), so the size also sets how many robots a vector holds (≥ 255 at "
               "1000 m) (`1e308` used to raise `OverflowError`)",
    )
    walls: bool = option(
        False, "flag",
        doc="walls at the arena's edge",
        also=f"`arena_half_size` > body radius + {WALL_RADIUS:g} m",
        reason="the robot starts at the centre; smaller, it would touch the walls at once",
    )
    obstacles: tuple[tuple[float, float, float], ...] = option(
        (), "obstacles", unit="m",
        doc="disc obstacles: a sequence of (x, y, radius) triples, arena frame",
        also="each disc inside the arena (max(abs(x), abs(y)) + radius ≤ `arena_half_size`) and clear of the "
             "robot at the start pose (0, 0)",
        reason="each disc is a pymunk shape in every robot's arena; a disc outside the arena could reach a "
               "neighbouring robot's arena in the vector's shared space (`1e308` gave NaN); a disc on the start "
               "pose ends every episode on step 1",
    )
    ref_speed: float = option(
        0.25, "number", unit="m/s", lo=0.001, hi=10.0,
        doc="typical reference speed",
        reason="1 mm/s is standing still; no robot of this kind drives at 10 m/s",
    )
    max_speed: float = option(
        0.6, "number", unit="m/s", lo=0.001, hi=10.0,
        doc="the body speeds vx, vy at action ±1 (`twist`)",
        reason="the twist at action ±1 sets wheel commands: 10 m/s is 200–330 rad/s on the preset wheels (r = 3–5 "
               "cm); beyond, forces overflow (`1e308` gave NaN observations)",
    )
    max_yaw_rate: float = option(
        3.0, "number", unit="rad/s", lo=0.001, hi=100.0,
        doc="the body yaw rate ω at action ±1 (`twist`)",
        reason="100 rad/s is 16 rev/s, far beyond any such robot; beyond, the wheel commands overflow (`1e308` gave"
               " NaN)",
    )
    lost_distance: float = option(
        0.5, "number", unit="m", lo=0.001, hi=10000.0,
        doc="tracking error that terminates the episode",
        reason="errors below 1 mm are sensor noise; 10 km exceeds the largest arena's diagonal",
    )
    success_distance: float = option(
        0.05, "number", unit="m", lo=0.0, hi=10000.0, lo_open=True,
        doc="final position error counted as success (`info[\"is_success\"]`)",
        reason="as `lost_distance`; any positive threshold is meaningful",
    )
    success_heading: float = option(
        0.1, "number", unit="rad", lo=0.0, hi=math.pi, lo_open=True,
        doc="final heading error counted as success",
        reason="heading errors are wrapped to (−π, π]",
    )
    randomize_floor: tuple[Floor, ...] | None = option(
        None, "floors",
        doc="at each reset every robot draws one floor, uniformly, from this tuple: a surface name, or "
            "`\"surface:friction_model\"` (e.g. `\"grip:initial\"`, `\"carpet:roller_gap\"`; without one the "
            "`friction` keyword's or the model's); `randomize_friction` scales it; `info[\"floor\"]` names it",
        also="with `model`: the floor replaces the model's surface (and friction model), its effects stay; a "
             "`roller_gap` effect (friction coefficients of the model's own floor) is refused",
    )
    randomize_friction: tuple[float, float] | None = option(
        None, "range", lo=0.0, hi=10.0,
        doc="every friction coefficient scaled by U(lo, hi) at each reset",
        reason="a scale of 0 (frictionless) to 10 covers any floor; coefficients stay finite",
    )
    randomize_mass: tuple[float, float] | None = option(
        None, "range", lo=0.05, hi=20.0,
        doc="mass and inertia scaled by U(lo, hi) at each reset",
        reason="mass and inertia stay positive and within 20× of the model",
    )
    randomize_lift_rate: tuple[float, float] | None = option(
        None, "range", unit="1/s", lo=0.0, hi=MAX_RATE,
        doc="`lift_rate` drawn from U(lo, hi) at each reset",
        reason="as `lift_rate`",
    )
    randomize_sensor_noise: tuple[float, float] | None = option(
        None, "range", lo=0.0, hi=10.0,
        doc="every sensor noise and bias std (on top of `sensor_noise`) scaled by one U(lo, hi) per robot at each "
            "reset",
        reason="0 is noiseless; 10× the default levels (5 cm camera, 0.5 rad compass) is far beyond any usable "
               "sensor; the range of the SB3-side `SensorNoiseRandomizer`",
    )
    render_mode: str | None = option(
        None, "choice", choices=RENDER_MODES,
        doc="`rgb_array` (H×W×3 uint8) or `human` (pygame window); single environment only",
    )
    reward: Reward | None = option(
        None, "reward",
        doc="the reward: None is the built-in tracking reward (`omni_gym.envs.reward.FORMULA`, computed in the "
            "compiled observation kernel); your own is a callable on `omni_gym.envs.reward.RewardInputs` "
            "returning one number per robot",
    )

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


OPTIONS: dict[str, Option] = {f.name: replace(f.metadata["option"], name=f.name) for f in fields(EnvConfig)}
# The numeric bounds (with their reasons, shown in docs/bounds.md, "Environment keywords").
BOUNDS: dict[str, Bound] = {name: o.bound() for name, o in OPTIONS.items() if o.kind == "number"}
RANDOM_BOUNDS: dict[str, tuple[float, float]] = {name: (o.lo, o.hi) for name, o in OPTIONS.items()
                                                 if o.kind == "range"}
# The order of the checks, by kind (each kind in field order): the first bad keyword is the one named,
# and obstacles are checked last, inside the arena already checked.
CHECK_ORDER = (("robot", "choice", "model", "reward"), ("flag",), ("number",), ("range", "floors"), ("obstacles",))
assert sorted(k for kinds in CHECK_ORDER for k in kinds) == sorted(KINDS)


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


# The keyword defaults of CUSTOM_ID that differ from the other ids': the robot is the model (a calibrated one,
# typically), so twist actions and the scripted controllers use its effective kinematics (docs/environments.md).
# Its random-waypoint references turn in place before each translation (as OmniPathFollow-Williams-v1's): a robot
# whose traction is not known gets a task it can do (docs/environments.md, "Tasks within reach").
CUSTOM_DEFAULTS = {"kinematics": "model"}
CUSTOM_WAYPOINT_DEFAULTS = {"ref_turn": "before"}


def custom_kwargs(kwargs: dict) -> dict:
    """The keywords of :data:`CUSTOM_ID` checked (:func:`check_custom`), with :data:`CUSTOM_DEFAULTS` filled in
    (and :data:`CUSTOM_WAYPOINT_DEFAULTS` for its random-waypoint references)."""
    check_custom(kwargs)
    waypoints = kwargs.get("trajectory", "waypoints") == "waypoints" and kwargs.get("task", "path") == "path"
    return {**CUSTOM_DEFAULTS, **(CUSTOM_WAYPOINT_DEFAULTS if waypoints else {}), **kwargs}


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


def _floors(name: str, value) -> tuple[Floor, ...] | None:
    """``randomize_floor``: None or a non-empty sequence of ``"surface"`` / ``"surface:friction_model"`` names."""
    if value is None:
        return None
    items = _sequence(value)
    example = "e.g. randomize_floor=('grip:initial', 'carpet:roller_gap')"
    if items is None or not items:
        raise ValueError(f"invalid {name}={_show(value)}; must be None or a non-empty sequence of floor names, "
                         f"{example}")
    surfaces, models = ", ".join(map(repr, SURFACES)), ", ".join(map(repr, FRICTION_MODELS))
    out = []
    for i, entry in enumerate(items):
        if not isinstance(entry, str):
            raise ValueError(f"invalid {name}[{i}]={_show(entry)}; each floor is a string 'surface' or "
                             f"'surface:friction_model', {example}")
        surface, sep, friction = str(entry).partition(":")
        if surface not in SURFACES:
            raise ValueError(f"invalid {name}[{i}]={_show(entry)}: unknown surface {surface!r}; choose one of "
                             f"{surfaces}")
        if sep and friction not in FRICTION_MODELS:
            raise ValueError(f"invalid {name}[{i}]={_show(entry)}: unknown friction model {friction!r}; choose one "
                             f"of {models}")
        out.append(Floor(surface, friction if sep else None))
    return tuple(out)


def parse_floors(value) -> tuple[Floor, ...] | None:
    """A ``randomize_floor`` value (None or names ``"surface"`` / ``"surface:friction_model"``) as the
    environment reads it; ValueError naming the bad entry."""
    return _floors("randomize_floor", value)


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
    for key in kwargs:
        if key not in OPTIONS:
            raise ValueError(unknown_key(key, sorted(OPTIONS), what="keyword argument"))
    d = EnvConfig()
    values: dict = {}
    for kinds in CHECK_ORDER:
        for name, opt in OPTIONS.items():
            if opt.kind in kinds:
                values[name] = _check(opt, kwargs.get(name, getattr(d, name)), values)
    model = values.get("model")
    if model is not None:  # the keywords the model replaces show the model's values, not the id's ignored ones
        values.update(robot=model.robot.name, surface=model.surface.name, friction=model.friction)
    cfg = EnvConfig(**values)
    _check_combination(cfg)
    _check_given(cfg, kwargs)
    return cfg


def _check_given(cfg: EnvConfig, given: dict) -> None:
    """Keywords given that contradict the rest: a reference option the task does not use, the model's kinematics
    without a model, a loss threshold below the success threshold (one-line ValueError naming them)."""
    if cfg.lost_distance <= cfg.success_distance:
        raise ValueError(f"invalid lost_distance={cfg.lost_distance!r}: it must exceed success_distance="
                         f"{cfg.success_distance!r} (m), or an episode would end lost before it could succeed")
    if cfg.kinematics == "model" and cfg.model is None:
        raise ValueError("invalid kinematics='model' without model=: the model's effective wheel matrix needs a model "
                         "file (kinematics='nominal' uses the robot preset's)")
    for name in ("ref_turn", "ref_heading"):
        if name in given and cfg.task == "goto":
            raise ValueError(f"invalid {name}={getattr(cfg, name)!r} for task='goto': the goal pose and its quintic "
                             "set the heading; ref_turn and ref_heading shape a path-following reference")
    if "ref_turn" in given and cfg.trajectory != "waypoints":
        raise ValueError(f"invalid ref_turn={cfg.ref_turn!r} for trajectory={cfg.trajectory!r}: turns in place "
                         "before each translation apply to trajectory='waypoints' only")


def _check(opt: Option, value, checked: dict):
    """One keyword's value, checked by its declared kind (``checked``: the keywords checked before it)."""
    kind, name = opt.kind, opt.name
    if kind == "robot":
        return _robot(value)
    if kind == "choice":
        return _choice(name, value, opt.choices)
    if kind == "model":
        return parse_model(value)
    if kind == "flag":
        return _flag(name, value)
    if kind == "number":
        return _number(name, value, BOUNDS[name])
    if kind == "range":
        return _range(name, value, opt.lo, opt.hi)
    if kind == "obstacles":
        return _obstacles(value, checked["arena_half_size"])
    if kind == "floors":
        return _floors(name, value)
    if kind == "reward":
        return check_reward(value)
    raise AssertionError(f"option {name!r}: unknown kind {kind!r}")  # a declaration error, not user input


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
    _check_floors(cfg)
    steps = cfg.episode_steps
    if not 1 <= steps <= MAX_EPISODE_STEPS:
        raise ValueError(f"invalid episode_seconds={cfg.episode_seconds!r} at control_hz={cfg.control_hz:g}: "
                         f"{steps} control steps; need 1 to {MAX_EPISODE_STEPS}")
    _check_start_clear(cfg)


def _check_floors(cfg: EnvConfig) -> None:
    """``randomize_floor`` against the robot and the model: every floor must make a valid model."""
    if cfg.randomize_floor is None:
        return
    base = cfg.base_model()
    if cfg.model is not None:
        for effect in cfg.model.effects:
            if effect_library.get(effect).has_friction_coefficients:
                raise ValueError(f"invalid randomize_floor with model=: its effect {effect!r} holds friction "
                                 f"coefficients fitted on the model's own floor ({base.surface.name!r}), which "
                                 "another floor would not have; remove the effect or the keyword")
    for i, floor in enumerate(cfg.randomize_floor):
        friction = floor.friction or base.friction
        if friction == "roller_gap" and base.robot.has_angled_rollers:
            raise ValueError(f"invalid randomize_floor[{i}]={str(floor)!r}: friction model 'roller_gap' applies to "
                             "omni wheels only and this robot has mecanum wheels; name 'initial', e.g. "
                             f"'{floor.surface}:initial'")


def draw_floor(cfg: EnvConfig, rng: np.random.Generator) -> Floor | None:
    """One entry of ``randomize_floor``, uniformly, from ``rng`` (no draw if the keyword is unset)."""
    if cfg.randomize_floor is None:
        return None
    return cfg.randomize_floor[int(rng.integers(len(cfg.randomize_floor)))]


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


@dataclass(frozen=True)
class ModelDraws:
    """The physical factors of one episode drawn at reset; None where the keyword is unset."""

    friction_scale: float | None
    mass_scale: float | None
    lift_rate: float  # [1/s]
    floor: Floor | None = None


def draw_model_factors(cfg: EnvConfig, rng: np.random.Generator) -> ModelDraws:
    """Friction scale, mass scale and lift rate of one episode, drawn from ``rng`` in that fixed order and only
    for the ranges that are set, so the same seed gives the same episode (the floor is drawn separately,
    :func:`draw_floor`, after every other draw of the reset)."""
    friction = None if cfg.randomize_friction is None else float(rng.uniform(*cfg.randomize_friction))
    mass = None if cfg.randomize_mass is None else float(rng.uniform(*cfg.randomize_mass))
    lift = cfg.contact_rates()[0]
    if cfg.randomize_lift_rate is not None:
        lift = float(rng.uniform(*cfg.randomize_lift_rate))
    return ModelDraws(friction, mass, lift)


def on_floor(base: SimModel, floor: Floor) -> SimModel:
    """``base`` on ``floor``: its surface preset and friction model (the base's if the floor names none)."""
    return replace(base, surface=SURFACES[floor.surface], friction=floor.friction or base.friction)


def randomized_model(base: SimModel, draws: ModelDraws) -> SimModel:
    """The model of one episode: ``base`` on the drawn floor, then every friction coefficient of its surface
    (and, if the model has one, the ``roller_gap`` effect's fitted gap coefficient) times the friction scale,
    then mass and inertia times the mass scale. ``base`` itself (the same object) when nothing is drawn.
    """
    model = base if draws.floor is None else on_floor(base, draws.floor)
    if draws.friction_scale is not None:
        s = draws.friction_scale
        surf = model.surface
        model = replace(model, surface=Surface(surf.name, surf.mu_drive * s, surf.mu_transverse * s,
                                               surf.mu_gap * s, surf.k))
        for name, params in base.effects.items():  # effects with friction coefficients (roller_gap)
            scaled = effect_library.get(name).scale_friction(params, s)
            if scaled is not params:
                model = model.with_effect(name, scaled)
    if draws.mass_scale is not None:
        s = draws.mass_scale
        model = replace(model, robot=model.robot.with_changes(mass=base.robot.mass * s,
                                                              inertia=base.robot.inertia * s))
    return model


def sensor_noise_scale(cfg: EnvConfig, rng: np.random.Generator) -> float:
    """The factor on every sensor noise std of one episode: U(lo, hi) of ``randomize_sensor_noise``
    drawn from ``rng``, else 1 with no draw (so seeded episodes without the keyword are unchanged).

    It multiplies the levels of ``sensor_config`` (already scaled by ``sensor_noise``); it is drawn in
    both observation modes, so the same seed gives the same physics whatever ``obs_mode``.
    """
    if cfg.randomize_sensor_noise is None:
        return 1.0
    return float(rng.uniform(*cfg.randomize_sensor_noise))
