"""What every model effect declares: the :class:`Effect` base class and its parts.

An effect is a named extension of the nominal model (``"effects": {NAME: {params}}`` in a model
file, ``docs/formats.md``). Its one file in this package says everything the library needs to know
about it:

* the parameter schema (:class:`Param`: key, shape, unit, model-file bound, plausible range), from
  which validation, the bounds table of ``docs/bounds.md`` and the plausibility flags are derived;
* how it changes the simulation: the force kernel's numbers (:meth:`Effect.write_kernel`) and/or a
  wheel contact process the world installs (:meth:`Effect.contact_process`);
* how the discrepancy workflow fits it (:meth:`Effect.fit_dims`, :meth:`Effect.from_fit`, its null
  point :meth:`Effect.null_fit` and an optional extra design point :meth:`Effect.prior_fit`);
* how ``omni-gym synth`` hides it (:meth:`Effect.synth_default`) and how the recovery study scores a
  fit (:attr:`Effect.recovery_sizes`, :attr:`Effect.tolerances`, :meth:`Effect.param_error`).

The base class holds no discrepancy code: fit dimensions, sizes and tolerances are plain data here,
the workflow (``omni_gym.discrepancy``) reads them.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import ClassVar, Protocol

import numpy as np

from omni_gym.bounds import Bound
from omni_gym.checks import json_number, unknown_key
from omni_gym.physics.friction import Surface
from omni_gym.physics.liftoff import ContactProcess
from omni_gym.physics.robot import RobotSpec

SHAPES = ("scalar", "per_wheel", "xy")


@dataclass(frozen=True)
class Range:
    """Plausible closed interval [lo, hi] of a fitted parameter (per element for lists) and why."""

    lo: float
    hi: float
    why: str


@dataclass(frozen=True)
class Param:
    """One parameter of an effect.

    ``shape``: ``scalar`` (a number), ``per_wheel`` (one number per wheel, in wheel order) or ``xy``
    (``[x, y]`` in the body frame). ``unit``: the unit and meaning, as the report prints it.
    ``lo``/``hi``/``reason`` (and ``lo_open``): the model-file bound, checked on every element.
    ``plausible``: the range a fitted value is expected in (None: judged otherwise or not at all).
    """

    key: str
    shape: str
    unit: str
    lo: float
    hi: float
    bound_unit: str
    reason: str
    lo_open: bool = False
    plausible: Range | None = None

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f"parameter {self.key!r}: shape must be one of {SHAPES}, got {self.shape!r}")

    def bound(self, effect: str) -> Bound:
        """This parameter's row of the model-file bounds (``effects.EFFECT.KEY``)."""
        return Bound(f"effects.{effect}.{self.key}", self.lo, self.hi, self.bound_unit, self.reason,
                     lo_open=self.lo_open)

    def length(self, n_wheels: int) -> int | None:
        """Number of elements of a list-valued parameter (None for a scalar)."""
        return {"scalar": None, "per_wheel": n_wheels, "xy": 2}[self.shape]


@dataclass(frozen=True)
class Dim:
    """One fitted dimension: bounds [lo, hi] (log-spaced if ``log``; ``periodic`` wraps).

    The fit searches the unit cube; :meth:`value` maps a unit coordinate ``u`` to the parameter.
    """

    name: str
    lo: float
    hi: float
    log: bool = False
    periodic: bool = False

    def value(self, u: float) -> float:
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))

    def unit(self, v: float) -> float:
        """Inverse of :meth:`value`: the unit coordinate of parameter value ``v`` (not clipped)."""
        if self.log:
            return (math.log(v) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (v - self.lo) / (self.hi - self.lo)


@dataclass(frozen=True)
class Flag:
    """A fitted value outside its plausible range (``value``: the offending element for lists)."""

    effect: str
    param: str
    value: float
    lo: float
    hi: float
    why: str

    def to_json(self) -> dict:
        return asdict(self)

    def text(self) -> str:
        return f"{self.param} = {self.value:.4g} outside the plausible [{self.lo:.4g}, {self.hi:.4g}]"


class ModelView(Protocol):
    """What an effect reads from the model it changes, fits or judges: the attributes of
    :class:`omni_gym.physics.model.SimModel` that the hooks below use, and nothing more.

    The effects are typed by this narrow view, not by ``SimModel``, so the effect library does not
    import the model module that imports it (no circle, not even a type-only one).
    """

    @property
    def robot(self) -> RobotSpec:
        """The nominal robot: wheel layout, radius, rollers, mass (body frame, SI units)."""
        ...

    @property
    def surface(self) -> Surface:
        """The floor's friction coefficients."""
        ...

    @property
    def gravity(self) -> float:
        """Gravitational acceleration [m/s²]."""
        ...

    @property
    def effects(self) -> dict[str, dict]:
        """The model's effects so far, name → parameters (an effect's current value as the fit's start)."""
        ...

    @property
    def n_wheels(self) -> int:
        """Number of wheels."""
        ...

    @property
    def com(self) -> np.ndarray:
        """Centre of mass [m], body frame, after the model's effects."""
        ...


class Effect:
    """Base class of the model effects; one subclass (one instance in the registry) per effect.

    Subclasses set :attr:`name`, :attr:`summary`, :attr:`params`, :attr:`recovery_sizes` and
    :attr:`tolerances`, and override what their physics needs: :meth:`write_kernel` or
    :meth:`contact_process` (or both), :meth:`fit_dims`/:meth:`from_fit`/:meth:`null_fit`,
    :meth:`synth_default` and :meth:`param_error`.
    """

    name: ClassVar[str]
    summary: ClassVar[str]
    params: ClassVar[tuple[Param, ...]]
    # True when the effect is a random process (fitted by event inference, not by a parameter search).
    stochastic: ClassVar[bool] = False
    # "physics": the effect changes how the robot moves (the simulator's business); "tracker": it changes
    # only what the pose tracker reports (a measurement model: the simulation ignores it, the
    # discrepancy workflow applies it to simulated poses, model files keep it under "tracker").
    kind: ClassVar[str] = "physics"
    # True when the parameters hold friction coefficients of the floor the model was fitted on: they scale
    # with scale_friction, and moving the model to another floor would keep the old floor's values.
    has_friction_coefficients: ClassVar[bool] = False
    # Two sizes for the recovery study ("small", "large"): parameters given on top of synth_default.
    recovery_sizes: ClassVar[dict[str, dict]] = {}
    # Largest parameter error that counts as recovered, per key of param_error (units there).
    tolerances: ClassVar[dict[str, float]] = {}

    # --- schema and validation -----------------------------------------------------------------

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.params)

    def bounds(self) -> list[Bound]:
        return [p.bound(self.name) for p in self.params]

    def validate(self, params: dict, n_wheels: int) -> None:
        """Raise ValueError naming the effect and key if ``params`` do not fit the schema and bounds."""
        if not isinstance(params, dict):
            raise ValueError(f"effect {self.name!r}: parameters must be an object")
        allowed = self.keys
        for key in params:
            if key not in allowed:
                raise ValueError(f"effect {self.name!r}: {unknown_key(key, allowed, what='parameter')}")
        for key in allowed:
            if key not in params:
                raise ValueError(f"effect {self.name!r}: missing parameter {key!r}")
        schema = {p.key: p for p in self.params}
        for key, value in params.items():
            p = schema[key]
            bound = p.bound(self.name)
            label = f"effect {self.name!r}: {key}"
            length = p.length(n_wheels)
            if length is not None:
                what = "one per wheel" if p.shape == "per_wheel" else "[x, y]"
                if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != length:
                    raise ValueError(f"{label} must be {length} numbers ({what}), got {value!r}")
                for j, v in enumerate(value):
                    bound.check(json_number(v, f"{label}[{j}]"), f"{label}[{j}]")
            else:
                bound.check(json_number(value, label), label)

    def check_robot(self, robot) -> None:
        """Raise ValueError (one line, saying why) if the effect does not apply to ``robot`` (a
        RobotSpec). Default: applies to every wheel type (omni and mecanum)."""

    def applies_to(self, robot) -> bool:
        """True if the effect applies to ``robot`` (:meth:`check_robot` passes): e.g. which candidates
        a fit can try on a mecanum robot."""
        try:
            self.check_robot(robot)
        except ValueError:
            return False
        return True

    # --- simulation ----------------------------------------------------------------------------

    def write_kernel(self, params: dict, sp: np.ndarray, wp: np.ndarray, model: ModelView) -> None:
        """Change the force kernel's scalars ``sp`` (N_SP,) and wheel rows ``wp`` (n, N_WP) in place.

        Called by :meth:`omni_gym.physics.model.SimModel.kernel_params` after the nominal values are
        written, in the order of the model's ``effects``. Default: no kernel numbers.
        """

    def contact_process(self, params: dict, n_wheels: int, rng: np.random.Generator) -> ContactProcess | None:
        """A wheel contact process for the world to install, drawing from ``rng`` (default: none)."""
        return None

    def measure(self, params: dict, t: np.ndarray, pose: np.ndarray,
                velocity: np.ndarray | None = None) -> np.ndarray:
        """Tracker effects: the pose (K, 3) the tracker reports at times ``t`` (K,) [s] for the
        geometric-centre poses ``pose`` (K, 3) [m, m, rad] at the same times (world frame). Physics
        effects: ``pose`` unchanged."""
        return pose

    def unmeasure(self, params: dict, pose: np.ndarray, velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tracker effects: the geometric centre's pose (3,) and velocity (3,) from a tracked start state
        (the inverse of :meth:`measure` to first order). Physics effects: unchanged."""
        return pose, velocity

    def scale_friction(self, params: dict, factor: float) -> dict:
        """Parameters after every friction coefficient of the model is multiplied by ``factor``
        (the environments' friction randomisation). Default: the effect has no friction coefficient."""
        return params

    # --- fitting (read by omni_gym.discrepancy) ------------------------------------------------

    def fit_dims(self, model: ModelView) -> tuple[Dim, ...]:
        """The fitted dimensions for ``model``, bounds wide enough for real robots."""
        raise NotImplementedError

    def from_fit(self, values: list[float], model: ModelView) -> dict:
        """Effect parameters from one value per fitted dimension."""
        raise NotImplementedError

    def null_fit(self, model: ModelView) -> dict[str, float] | None:
        """Fitted-dimension values at which the effect changes nothing (dimensions left out do not
        matter there and sit mid-range); None when the effect has no such point."""
        return None

    def prior_fit(self, model: ModelView) -> dict[str, float] | None:
        """An extra design point the fit should try (e.g. the nominal model's own values), or None."""
        return None

    # --- synthetic data and recovery -----------------------------------------------------------

    def synth_default(self, model: ModelView, rng: np.random.Generator) -> dict:
        """Moderate default parameters when ``omni-gym synth`` hides this effect."""
        raise NotImplementedError

    def param_error(self, truth: dict, fitted: dict, model: ModelView) -> dict[str, float]:
        """Per key of :attr:`tolerances`, the error of ``fitted`` against ``truth``."""
        raise NotImplementedError

    # --- plausibility --------------------------------------------------------------------------

    def plausible_ranges(self) -> dict[str, Range]:
        return {p.key: p.plausible for p in self.params if p.plausible is not None}

    def extra_ranges(self) -> dict[str, Range]:
        """Ranges of derived quantities that :meth:`extra_flags` checks (default: none)."""
        return {}

    def extra_flags(self, params: dict, model: ModelView) -> list[Flag]:
        """Flags on derived quantities, before the per-parameter ranges (default: none)."""
        return []

    def flags(self, params: dict, model: ModelView) -> list[Flag]:
        """Fitted values outside their plausible ranges (empty: all plausible)."""
        flags = self.extra_flags(params, model)
        for key, rng in self.plausible_ranges().items():
            values = params.get(key)
            if values is None:
                continue
            items = list(enumerate(values, start=1)) if isinstance(values, list) else [(None, values)]
            for i, v in items:
                v = float(v)
                if not (math.isfinite(v) and rng.lo <= v <= rng.hi):
                    label = key if i is None else f"{key}[{i}]"
                    flags.append(Flag(self.name, label, v, rng.lo, rng.hi, rng.why))
        return flags
