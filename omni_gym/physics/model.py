"""The simulation model: robot + surface + friction model + model effects, and its JSON form.

The JSON form is a contract read by the CLI and the discrepancy workflow (``docs/formats.md``)::

    {"name", "mass" [kg], "inertia" [kg·m²], "gravity" [m/s²], "wheel_radius" [m],
     "wheels": [{"position": [x, y], "drive": [dx, dy]}, ...],   body frame, metres
     "com": [x, y], "rollers", "roller_fraction", "friction": "initial" | "roller_gap",
     "surface": {"name", "mu_drive", "mu_transverse", "mu_gap", "k"},
     "effects": {EFFECT: {params}, ...},
     "tracker": {EFFECT: {params}, ...}}      optional: measurement effects (kind "tracker")

Effects are extensions of the nominal model, each defined in one module of
:mod:`omni_gym.physics.effects` (its parameters, their bounds and validation, and what it changes).
An effect changes the numbers the force kernel reads (:meth:`SimModel.kernel_params`), or supplies a
wheel contact process that the world's user installs (:meth:`SimModel.contact_process`: ``replay``,
the environments, ``omni_gym.discrepancy.replay.simulate``), or both. Tracker effects (``tracker_offset``,
``time_offset``) change neither: they say how the data's pose tracker measures the robot, live in
:attr:`SimModel.effects` like the others and are written under their own ``tracker`` key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from omni_gym import bounds
from omni_gym.checks import json_number, known_keys
from omni_gym.io import read_json
from omni_gym.physics import effects as effect_library
from omni_gym.physics.friction import DEFAULT_K, Surface, check_friction_model, surface_preset
from omni_gym.physics.layout import (
    N_SP,
    N_WP,
    SP_CX,
    SP_CY,
    SP_GAP,
    SP_INERTIA,
    SP_JW,
    SP_K,
    SP_KI,
    SP_KIN_RATIO,
    SP_KP,
    SP_MASS,
    SP_MODE,
    SP_PITCH,
    SP_TAU,
    SP_TMAX,
    SP_VS,
    WP_COSG,
    WP_DX,
    WP_DY,
    WP_GAPT,
    WP_GAPW,
    WP_MUT,
    WP_MUW,
    WP_PX,
    WP_PY,
    WP_R,
    WP_SING,
)
from omni_gym.physics.liftoff import ContactProcess
from omni_gym.physics.robot import GRAVITY, RobotSpec, Wheel, robot_preset

ACTUATIONS = ("ideal", "servo")

# Effect name → its parameter keys (all required), from the effect library.
EFFECT_PARAMS: dict[str, tuple[str, ...]] = {name: e.keys for name, e in effect_library.REGISTRY.items()}
# Every bound of a model file: the nominal model's (omni_gym.bounds.MODEL), then the effects' parameters.
MODEL_BOUNDS = {**bounds.MODEL, **effect_library.bounds()}

# The keys of a model file, per level; any other key is refused with a "did you mean" (a misspelt
# optional key would otherwise fall back to its default without a word). ``roller_angle`` [rad] is
# the optional roller axis angle of a mecanum wheel.
MODEL_KEYS = ("name", "mass", "inertia", "gravity", "wheel_radius", "wheels", "com", "rollers", "roller_fraction",
              "body_radius", "friction", "surface", "effects", "tracker")
WHEEL_KEYS = ("position", "drive", "roller_angle")
SURFACE_KEYS = ("name", "mu_drive", "mu_transverse", "mu_gap", "k")


@dataclass(frozen=True)
class Actuation:
    """How wheel speeds follow their commands.

    ``ideal``: the paper's ideal velocity source, wheel speed = command.
    ``servo``: a PI speed loop (``kp`` [N·m·s/rad], ``ki`` [N·m/rad]) with a motor torque limit
    ``torque_limit`` [N·m] driving a wheel of inertia ``wheel_inertia`` [kg·m²] (rotor reflected
    through the gearbox included), loaded by the ground reaction torque r·F_drive.
    """

    kind: str = "ideal"
    kp: float = 0.02
    ki: float = 1.0
    torque_limit: float = 0.3
    wheel_inertia: float = 1e-4

    def __post_init__(self) -> None:
        if self.kind not in ACTUATIONS:
            raise ValueError(f"unknown actuation {self.kind!r}; choose one of {list(ACTUATIONS)}")
        for attr in ("kp", "ki", "torque_limit", "wheel_inertia"):
            v = getattr(self, attr)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"actuation {attr} must be a positive number, got {v}")


@dataclass(frozen=True)
class SimModel:
    """Everything the world needs to simulate one robot (SI units throughout)."""

    robot: RobotSpec
    surface: Surface
    friction: str = "roller_gap"
    gravity: float = GRAVITY
    effects: dict[str, dict] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_friction_model(self.friction)
        if self.friction == "roller_gap" and self.robot.has_angled_rollers:
            raise ValueError("friction model 'roller_gap' applies to omni wheels only (rigid material between "
                             "rollers in the wheel plane); this robot has mecanum wheels (roller_angle ≠ 0): "
                             "use 'initial'")
        if not (math.isfinite(self.gravity) and self.gravity > 0):
            raise ValueError(f"gravity must be a positive number, got {self.gravity}")
        for name, params in self.effects.items():
            validate_effect(name, params, self.robot.n_wheels)
            effect_library.get(name).check_robot(self.robot)

    @property
    def n_wheels(self) -> int:
        return self.robot.n_wheels

    def with_effect(self, name: str, params: dict) -> SimModel:
        effects = dict(self.effects)
        effects[name] = params
        return replace(self, effects=effects)

    @property
    def com(self) -> np.ndarray:
        """Centre of mass [m], body frame, after the effects (``com_offset`` moves it)."""
        return self.kernel_params()[0][[SP_CX, SP_CY]]

    def kernel_params(self, actuation: Actuation = Actuation()) -> tuple[np.ndarray, np.ndarray]:
        """(scalars (N_SP,), per-wheel rows (n, N_WP)) in the layout the force kernel reads.

        The nominal model's numbers first; then every effect, in the model's order, changes its own
        (:meth:`omni_gym.physics.effects.base.Effect.write_kernel`).
        """
        r = self.robot
        s = self.surface
        n = r.n_wheels
        sp = np.zeros(N_SP)
        sp[SP_MASS] = r.mass
        sp[SP_INERTIA] = r.inertia
        sp[SP_K] = s.k
        sp[SP_KIN_RATIO] = 1.0  # no Stribeck drop
        sp[SP_VS] = 1.0  # unused at ratio 1; 1 keeps the law's division finite
        pitch = 2.0 * math.pi / r.rollers
        sp[SP_PITCH] = pitch
        sp[SP_GAP] = (1.0 - r.roller_fraction) * pitch if self.friction == "roller_gap" else 0.0
        sp[SP_CX], sp[SP_CY] = np.asarray(r.com, dtype=float)
        sp[SP_TAU] = 0.0  # ideal velocity source
        sp[SP_MODE] = ACTUATIONS.index(actuation.kind)
        sp[SP_KP], sp[SP_KI] = actuation.kp, actuation.ki
        sp[SP_TMAX], sp[SP_JW] = actuation.torque_limit, actuation.wheel_inertia
        wp = np.zeros((n, N_WP))
        wp[:, [WP_PX, WP_PY]] = r.positions()
        wp[:, [WP_DX, WP_DY]] = r.drives()
        wp[:, WP_R] = r.wheel_radius
        wp[:, WP_MUW] = s.mu_drive
        wp[:, WP_MUT] = s.mu_transverse
        wp[:, WP_GAPW] = s.mu_gap
        wp[:, WP_GAPT] = s.mu_gap
        gamma = r.roller_angles()
        wp[:, WP_COSG] = np.cos(gamma)  # exactly 1 and 0 for omni wheels: the kernel's γ = 0 path
        wp[:, WP_SING] = np.sin(gamma)
        for name, params in self.effects.items():
            effect_library.get(name).write_kernel(params, sp, wp, self)
        return sp, wp

    def contact_process(self, rng: np.random.Generator) -> ContactProcess | None:
        """The wheel contact process an effect asks the world to install (drawing from ``rng``), or
        None. At most one effect of the library supplies one (``wheel_liftoff``)."""
        procs = [effect_library.get(name).contact_process(params, self.n_wheels, rng)
                 for name, params in self.effects.items()]
        procs = [p for p in procs if p is not None]
        return procs[0] if procs else None

    # --- JSON ---------------------------------------------------------------------------------

    def to_json(self) -> dict:
        r = self.robot
        return {
            "name": r.name,
            "mass": r.mass,
            "inertia": r.inertia,
            "gravity": self.gravity,
            "wheel_radius": r.wheel_radius,
            "wheels": [_wheel_json(w) for w in r.wheels],
            "com": list(r.com),
            "rollers": r.rollers,
            "roller_fraction": r.roller_fraction,
            "body_radius": r.body_radius,
            "friction": self.friction,
            "surface": self.surface.to_json(),
            "effects": {k: dict(v) for k, v in self.effects.items() if effect_library.get(k).kind != "tracker"},
            # The tracker's measurement effects explain the data, not the robot: a key of their own,
            # written only when there are some (simulators and environments ignore them).
            **({"tracker": tracker} if (tracker := {k: dict(v) for k, v in self.effects.items()
                                                   if effect_library.get(k).kind == "tracker"}) else {}),
        }

    @classmethod
    def from_json(cls, data: dict, where: str = "model") -> SimModel:
        """Build a model from its JSON form; errors name the offending key and ``where``."""
        if not isinstance(data, dict):
            raise ValueError(f"{where}: expected a JSON object")
        try:
            known_keys(data, MODEL_KEYS)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        required = ("name", "mass", "inertia", "wheel_radius", "wheels", "rollers", "roller_fraction",
                    "friction", "surface")
        for key in required:
            if key not in data:
                raise ValueError(f"{where}: missing key {key!r}")
        wheels = data["wheels"]
        if not isinstance(wheels, list) or not wheels:
            raise ValueError(f"{where}: 'wheels' must be a non-empty list")
        try:  # the count first: a 10⁶-wheel file is refused before any wheel is read
            _bounded(len(wheels), bounds.WHEELS)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        parsed = [_wheel(w, i, where) for i, w in enumerate(wheels)]
        surf = data["surface"]
        if not isinstance(surf, dict):
            raise ValueError(f"{where}: 'surface' must be an object")
        try:
            known_keys(surf, SURFACE_KEYS, "surface")
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        for key in ("mu_drive", "mu_transverse", "mu_gap"):
            if key not in surf:
                raise ValueError(f"{where}: missing key 'surface.{key}'")
        try:
            surface = Surface(
                name=str(surf.get("name", "custom")),
                mu_drive=_bounded(surf["mu_drive"], "surface.mu_drive"),
                mu_transverse=_bounded(surf["mu_transverse"], "surface.mu_transverse"),
                mu_gap=_bounded(surf["mu_gap"], "surface.mu_gap"),
                k=_bounded(surf.get("k", DEFAULT_K), "surface.k"),
            )
            com = _vec2(data.get("com", [0.0, 0.0]), "com")
            robot = RobotSpec(
                name=str(data["name"]),
                wheels=tuple(parsed),
                wheel_radius=_bounded(data["wheel_radius"], "wheel_radius"),
                mass=_bounded(data["mass"], "mass"),
                inertia=_bounded(data["inertia"], "inertia"),
                com=com,
                rollers=int(_bounded(data["rollers"], "rollers")),
                roller_fraction=_bounded(data["roller_fraction"], "roller_fraction"),
                body_radius=_bounded(data.get("body_radius", _default_body_radius(parsed)), "body_radius"),
            )
            effects = _effects(data.get("effects", {}))
            tracker = _effects(data.get("tracker", {}), "tracker")
            for name in effects:
                if effect_library.get(name).kind == "tracker":
                    raise ValueError(f"'effects.{name}' is a tracker (measurement) effect: put it under 'tracker'")
            for name in tracker:
                if effect_library.get(name).kind != "tracker":
                    raise ValueError(f"'tracker.{name}' is a physics effect: put it under 'effects'")
            effects = {**effects, **tracker}
            return cls(robot=robot, surface=surface, friction=str(data["friction"]),
                       gravity=_bounded(data.get("gravity", GRAVITY), "gravity"), effects=effects)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None


def _effects(value, key: str = "effects") -> dict[str, dict]:
    """The ``effects`` (or ``tracker``) object ``{EFFECT: {params}}``; names and parameter keys checked
    against the library.

    A list (``[]`` or ``["motor_lag"]``) is refused alike: an effect needs its parameters.
    """
    if not isinstance(value, dict):
        kind = "a list" if isinstance(value, list) else repr(value)
        raise ValueError(f"'{key}' must be an object {{EFFECT: {{parameters}}}}, e.g. {{}} for none or "
                         f'{{"motor_lag": {{"tau": 0.05}}}}; got {kind}')
    known_keys(value, effect_library.REGISTRY, key)
    for name, params in value.items():
        if isinstance(params, dict):
            known_keys(params, effect_library.REGISTRY[name].keys, f"{key}.{name}")
    return value


def _bounded(value, key: str, name: str | None = None) -> float:
    """A finite number inside ``MODEL_BOUNDS[key]``; ValueError naming ``name`` (default ``key``)."""
    name = name or key
    return MODEL_BOUNDS[key].check(json_number(value, name), name)


def _vec2(value, name: str, key: str | None = None) -> tuple[float, float]:
    """``[x, y]`` as two numbers, each inside ``MODEL_BOUNDS[key]`` (default ``name``) [m]."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ValueError(f"{name} must be [x, y], got {value!r}")
    return (_bounded(value[0], key or name, f"{name}[0]"), _bounded(value[1], key or name, f"{name}[1]"))


def _wheel_json(w: Wheel) -> dict:
    """A wheel's JSON form; ``roller_angle`` only when non-zero (omni-wheel files stay as they were)."""
    out = {"position": list(w.position), "drive": list(w.drive)}
    if w.roller_angle != 0.0:
        out["roller_angle"] = w.roller_angle
    return out


def _wheel(w, i: int, where: str) -> Wheel:
    """Wheel ``i`` from ``{"position": [x, y], "drive": [dx, dy], "roller_angle": γ}`` (drive normalised;
    ``roller_angle`` [rad] optional, default 0: an omni wheel)."""
    name = f"wheels[{i}]"
    if not isinstance(w, dict) or "position" not in w or "drive" not in w:
        raise ValueError(f"{where}: {name} needs 'position' and 'drive' as [x, y] numbers")
    try:
        known_keys(w, WHEEL_KEYS, name)
        pos = _vec2(w["position"], f"{name}.position", "wheels[i].position")
        if not isinstance(w["drive"], (list, tuple)) or len(w["drive"]) != 2:
            raise ValueError(f"{name}.drive must be [x, y], got {w['drive']!r}")
        drive = (json_number(w["drive"][0], f"{name}.drive[0]"), json_number(w["drive"][1], f"{name}.drive[1]"))
        norm = math.hypot(*drive)
        if norm == 0:
            raise ValueError(f"{name}.drive must be a non-zero vector")
        MODEL_BOUNDS["wheels[i].drive (length)"].check(norm, f"{name}.drive length")
        gamma = _bounded(w.get("roller_angle", 0.0), "wheels[i].roller_angle", f"{name}.roller_angle")
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return Wheel(position=pos, drive=(drive[0] / norm, drive[1] / norm), roller_angle=gamma)


def _default_body_radius(wheels: list[Wheel]) -> float:
    return max(math.hypot(*w.position) for w in wheels) + 0.01


def validate_effect(name: str, params: dict, n_wheels: int) -> None:
    """Raise ValueError naming the effect and key if ``params`` do not fit the effect library.

    Every parameter must lie inside its bound (``MODEL_BOUNDS["effects.EFFECT.KEY"]``).
    """
    effect_library.get(name).validate(params, n_wheels)


def load_model(name_or_path: str, surface: str | None = None, friction: str | None = None) -> SimModel:
    """A preset robot name or a model JSON file, with optional surface/friction overrides."""
    path = Path(name_or_path)
    if name_or_path.endswith(".json") or _is_file(path):
        data = read_json(path)
        model = SimModel.from_json(data, where=name_or_path)
        if surface is not None:
            model = replace(model, surface=surface_preset(surface))
        if friction is not None:
            model = replace(model, friction=check_friction_model(friction))
        return model
    robot = robot_preset(name_or_path)
    return SimModel(robot=robot, surface=surface_preset(surface or "carpet"),
                    friction=check_friction_model(friction or nominal_friction(robot)))


def nominal_friction(robot: RobotSpec) -> str:
    """A preset's default friction model: ``roller_gap`` for omni wheels, ``initial`` for mecanum wheels
    (the rigid-material model is an omni-wheel geometry, ``docs/model.md``)."""
    return "initial" if robot.has_angled_rollers else "roller_gap"


def _is_file(path: Path) -> bool:
    """``path.is_file()``, False where the name cannot be a file (too long for the file system)."""
    try:
        return path.is_file()
    except OSError:
        return False
