"""The simulation model: robot + surface + friction model + model effects, and its JSON form.

The JSON form is a contract read by the CLI and the discrepancy workflow (``docs/formats.md``)::

    {"name", "mass" [kg], "inertia" [kg·m²], "gravity" [m/s²], "wheel_radius" [m],
     "wheels": [{"position": [x, y], "drive": [dx, dy]}, ...],   body frame, metres
     "com": [x, y], "rollers", "roller_fraction", "friction": "initial" | "roller_gap",
     "surface": {"name", "mu_drive", "mu_transverse", "mu_gap", "k"},
     "effects": {EFFECT: {params}, ...}}

Effects are extensions of the nominal model. Each one only changes the numbers the force kernel
reads (:meth:`SimModel.kernel_params`), so a new effect never needs a change to the world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from omni_gym.friction import Surface, check_friction_model, surface_preset
from omni_gym.robot import GRAVITY, RobotSpec, Wheel, robot_preset

# Layout of the per-robot scalar parameter vector read by the kernel.
SP_MASS, SP_INERTIA, SP_K, SP_KIN_RATIO, SP_VS, SP_PITCH, SP_GAP, SP_CX, SP_CY, SP_TAU = range(10)
SP_MODE, SP_KP, SP_KI, SP_TMAX, SP_JW = range(10, 15)
N_SP = 15
# Layout of the per-wheel parameter rows.
WP_PX, WP_PY, WP_DX, WP_DY, WP_R, WP_MUW, WP_MUT, WP_GAPW, WP_GAPT, WP_PHASE = range(10)
N_WP = 10

ACTUATIONS = ("ideal", "servo")

# Effect name → allowed parameter keys (all required unless they have a default below).
EFFECT_PARAMS: dict[str, tuple[str, ...]] = {
    "roller_gap": ("mu_gap", "roller_fraction", "phase"),
    "kinetic_friction": ("ratio", "v_s"),
    "com_offset": ("com",),
    "wheel_radius": ("scale",),
    "motor_lag": ("tau",),
    "wheel_liftoff": ("lift_rate", "recover_rate"),
}


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
        if not (math.isfinite(self.gravity) and self.gravity > 0):
            raise ValueError(f"gravity must be a positive number, got {self.gravity}")
        for name, params in self.effects.items():
            validate_effect(name, params, self.robot.n_wheels)

    @property
    def n_wheels(self) -> int:
        return self.robot.n_wheels

    def with_effect(self, name: str, params: dict) -> SimModel:
        effects = dict(self.effects)
        effects[name] = params
        return replace(self, effects=effects)

    @property
    def com(self) -> np.ndarray:
        """Centre of mass [m], body frame, after the ``com_offset`` effect."""
        if "com_offset" in self.effects:
            return np.asarray(self.effects["com_offset"]["com"], dtype=float)
        return np.asarray(self.robot.com, dtype=float)

    def kernel_params(self, actuation: Actuation = Actuation()) -> tuple[np.ndarray, np.ndarray]:
        """(scalars (N_SP,), per-wheel rows (n, N_WP)) in the layout the force kernel reads."""
        r = self.robot
        s = self.surface
        n = r.n_wheels
        fx = self.effects
        sp = np.zeros(N_SP)
        sp[SP_MASS] = r.mass
        sp[SP_INERTIA] = r.inertia
        sp[SP_K] = s.k
        sp[SP_KIN_RATIO] = fx["kinetic_friction"]["ratio"] if "kinetic_friction" in fx else 1.0
        sp[SP_VS] = fx["kinetic_friction"]["v_s"] if "kinetic_friction" in fx else 1.0
        rollers = r.rollers
        roller_fraction = r.roller_fraction
        mu_gap = s.mu_gap
        phase = np.zeros(n)
        use_gap = self.friction == "roller_gap"
        if "roller_gap" in fx:
            use_gap = True
            mu_gap = fx["roller_gap"]["mu_gap"]
            roller_fraction = fx["roller_gap"]["roller_fraction"]
            phase = np.asarray(fx["roller_gap"]["phase"], dtype=float)
        pitch = 2.0 * math.pi / rollers
        sp[SP_PITCH] = pitch
        sp[SP_GAP] = (1.0 - roller_fraction) * pitch if use_gap else 0.0
        sp[SP_CX], sp[SP_CY] = self.com
        sp[SP_TAU] = fx["motor_lag"]["tau"] if "motor_lag" in fx else 0.0
        sp[SP_MODE] = ACTUATIONS.index(actuation.kind)
        sp[SP_KP], sp[SP_KI] = actuation.kp, actuation.ki
        sp[SP_TMAX], sp[SP_JW] = actuation.torque_limit, actuation.wheel_inertia
        wp = np.zeros((n, N_WP))
        wp[:, [WP_PX, WP_PY]] = r.positions()
        wp[:, [WP_DX, WP_DY]] = r.drives()
        scale = np.asarray(fx["wheel_radius"]["scale"], dtype=float) if "wheel_radius" in fx else np.ones(n)
        wp[:, WP_R] = r.wheel_radius * scale
        wp[:, WP_MUW] = s.mu_drive
        wp[:, WP_MUT] = s.mu_transverse
        wp[:, WP_GAPW] = mu_gap
        wp[:, WP_GAPT] = mu_gap
        wp[:, WP_PHASE] = phase
        return sp, wp

    # --- JSON ---------------------------------------------------------------------------------

    def to_json(self) -> dict:
        r = self.robot
        return {
            "name": r.name,
            "mass": r.mass,
            "inertia": r.inertia,
            "gravity": self.gravity,
            "wheel_radius": r.wheel_radius,
            "wheels": [{"position": list(w.position), "drive": list(w.drive)} for w in r.wheels],
            "com": list(r.com),
            "rollers": r.rollers,
            "roller_fraction": r.roller_fraction,
            "body_radius": r.body_radius,
            "friction": self.friction,
            "surface": self.surface.to_json(),
            "effects": {k: dict(v) for k, v in self.effects.items()},
        }

    @classmethod
    def from_json(cls, data: dict, where: str = "model") -> SimModel:
        """Build a model from its JSON form; errors name the offending key and ``where``."""
        if not isinstance(data, dict):
            raise ValueError(f"{where}: expected a JSON object")
        required = ("name", "mass", "inertia", "wheel_radius", "wheels", "rollers", "roller_fraction",
                    "friction", "surface")
        for key in required:
            if key not in data:
                raise ValueError(f"{where}: missing key {key!r}")
        wheels = data["wheels"]
        if not isinstance(wheels, list) or not wheels:
            raise ValueError(f"{where}: 'wheels' must be a non-empty list")
        parsed = []
        for i, w in enumerate(wheels):
            try:
                pos = _vec2(w["position"])
                drive = _vec2(w["drive"])
            except (KeyError, TypeError, ValueError) as exc:
                raise ValueError(f"{where}: wheels[{i}] needs 'position' and 'drive' as [x, y] numbers") from exc
            norm = math.hypot(*drive)
            if norm == 0 or not math.isfinite(norm):
                raise ValueError(f"{where}: wheels[{i}].drive must be a non-zero vector")
            parsed.append(Wheel(position=pos, drive=(drive[0] / norm, drive[1] / norm)))
        surf = data["surface"]
        if not isinstance(surf, dict):
            raise ValueError(f"{where}: 'surface' must be an object")
        for key in ("mu_drive", "mu_transverse", "mu_gap"):
            if key not in surf:
                raise ValueError(f"{where}: missing key 'surface.{key}'")
        try:
            surface = Surface(
                name=str(surf.get("name", "custom")),
                mu_drive=_number(surf["mu_drive"], "surface.mu_drive"),
                mu_transverse=_number(surf["mu_transverse"], "surface.mu_transverse"),
                mu_gap=_number(surf["mu_gap"], "surface.mu_gap"),
                k=_number(surf.get("k", 1000.0), "surface.k"),
            )
            com = _vec2(data.get("com", [0.0, 0.0]))
            robot = RobotSpec(
                name=str(data["name"]),
                wheels=tuple(parsed),
                wheel_radius=_number(data["wheel_radius"], "wheel_radius"),
                mass=_number(data["mass"], "mass"),
                inertia=_number(data["inertia"], "inertia"),
                com=com,
                rollers=int(_number(data["rollers"], "rollers")),
                roller_fraction=_number(data["roller_fraction"], "roller_fraction"),
                body_radius=_number(data.get("body_radius", _default_body_radius(parsed)), "body_radius"),
            )
            effects = data.get("effects", {}) or {}
            if not isinstance(effects, dict):
                raise ValueError("'effects' must be an object")
            return cls(robot=robot, surface=surface, friction=str(data["friction"]),
                       gravity=_number(data.get("gravity", GRAVITY), "gravity"), effects=effects)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None


def _number(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return float(value)


def _vec2(value) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ValueError(f"expected [x, y], got {value!r}")
    return (_number(value[0], "x"), _number(value[1], "y"))


def _default_body_radius(wheels: list[Wheel]) -> float:
    return max(math.hypot(*w.position) for w in wheels) + 0.01


def validate_effect(name: str, params: dict, n_wheels: int) -> None:
    """Raise ValueError naming the effect and key if ``params`` do not fit the effect library."""
    if name not in EFFECT_PARAMS:
        raise ValueError(f"unknown effect {name!r}; choose one of {sorted(EFFECT_PARAMS)}")
    if not isinstance(params, dict):
        raise ValueError(f"effect {name!r}: parameters must be an object")
    allowed = EFFECT_PARAMS[name]
    for key in params:
        if key not in allowed:
            raise ValueError(f"effect {name!r}: unknown parameter {key!r}; allowed {list(allowed)}")
    for key in allowed:
        if key not in params:
            raise ValueError(f"effect {name!r}: missing parameter {key!r}")
    per_wheel = {"phase", "scale"}
    for key, value in params.items():
        if key in per_wheel:
            arr = np.asarray(value, dtype=float)
            if arr.shape != (n_wheels,) or not np.all(np.isfinite(arr)):
                raise ValueError(f"effect {name!r}: {key} must be {n_wheels} finite numbers (one per wheel)")
        elif key == "com":
            arr = np.asarray(value, dtype=float)
            if arr.shape != (2,) or not np.all(np.isfinite(arr)):
                raise ValueError(f"effect {name!r}: com must be [x, y] finite numbers")
        else:
            _number(value, f"effect {name!r} {key}")
            if value < 0:
                raise ValueError(f"effect {name!r}: {key} must be >= 0, got {value}")


def load_model(name_or_path: str, surface: str | None = None, friction: str | None = None) -> SimModel:
    """A preset robot name or a model JSON file, with optional surface/friction overrides."""
    import json
    from pathlib import Path

    path = Path(name_or_path)
    if name_or_path.endswith(".json") or path.is_file():
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise ValueError(f"{name_or_path}: file not found") from None
        except json.JSONDecodeError as exc:
            raise ValueError(f"{name_or_path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
        model = SimModel.from_json(data, where=name_or_path)
        if surface is not None:
            model = replace(model, surface=surface_preset(surface))
        if friction is not None:
            model = replace(model, friction=check_friction_model(friction))
        return model
    return SimModel(robot=robot_preset(name_or_path), surface=surface_preset(surface or "carpet"),
                    friction=check_friction_model(friction or "roller_gap"))
