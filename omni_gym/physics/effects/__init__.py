"""The effect library: one module per model effect, one registry that everything else loops over.

* :mod:`.base`: the :class:`~.base.Effect` base class (schema, kernel/contact hooks, fit data).
* :mod:`.roller_gap`, :mod:`.kinetic_friction`, :mod:`.com_offset`, :mod:`.wheel_radius`,
  :mod:`.motor_lag`, :mod:`.wheel_liftoff`, :mod:`.wheel_geometry`, :mod:`.mecanum_lateral` (mecanum
  robots only): the physics effects;
  :mod:`.tracker_offset`, :mod:`.time_offset`: the tracker (measurement) effects (``Effect.kind``).

:data:`REGISTRY` lists them in a fixed order: the order in which the discrepancy workflow fits its
candidates (it draws each fit's design from one seeded stream, so the order is part of a result)
and in which documentation tables list them. Adding an effect: write its module and add one line
here (``docs/discrepancy.md``, "Adding an effect").
"""

from __future__ import annotations

from omni_gym.bounds import Bound
from omni_gym.physics.effects.base import Dim, Effect, Flag, Param, Range
from omni_gym.physics.effects.com_offset import ComOffset
from omni_gym.physics.effects.kinetic_friction import KineticFriction
from omni_gym.physics.effects.mecanum_lateral import MecanumLateral
from omni_gym.physics.effects.motor_lag import MotorLag
from omni_gym.physics.effects.roller_gap import RollerGap
from omni_gym.physics.effects.time_offset import TimeOffset
from omni_gym.physics.effects.tracker_offset import TrackerOffset
from omni_gym.physics.effects.wheel_geometry import WheelGeometry
from omni_gym.physics.effects.wheel_liftoff import WheelLiftoff
from omni_gym.physics.effects.wheel_radius import WheelRadius

REGISTRY: dict[str, Effect] = {e.name: e for e in (
    RollerGap(), KineticFriction(), ComOffset(), WheelRadius(), MotorLag(), WheelLiftoff(),
    WheelGeometry(),  # after the first six: their candidates keep their seeded designs
    TrackerOffset(), TimeOffset(),  # measurement effects (kind "tracker"), after the physics for the same reason
    MecanumLateral(),  # added after the tracker effects: mecanum robots only, the others' designs unchanged
)}


def get(name: str) -> Effect:
    """The registered effect ``name``; ValueError listing the library if there is none."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; choose one of {sorted(REGISTRY)}") from None


def tracker_names() -> tuple[str, ...]:
    """The registered measurement effects (``kind == "tracker"``), in registry order."""
    return tuple(name for name, e in REGISTRY.items() if e.kind == "tracker")


def bounds() -> dict[str, Bound]:
    """Every effect parameter's model-file bound, keyed ``effects.EFFECT.KEY``, in registry order."""
    return {b.name: b for e in REGISTRY.values() for b in e.bounds()}


__all__ = ["REGISTRY", "Dim", "Effect", "Flag", "Param", "Range", "bounds", "get", "tracker_names"]
