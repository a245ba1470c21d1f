"""The robot as a plant: one small protocol for "the thing the wheel commands drive".

A controller evaluated in omni-gym normally drives the environment's own world. A *plant* replaces that
world: the simulator (:class:`SimulatorPlant`), the separately written event integrator in closed loop
(:class:`omni_gym.analysis.closed_loop.SecondGeneratorPlant`), or a user's robot behind its driver. The
environment keeps everything else (the reference path, the observation, the reward, the scoring).

Protocol (:class:`Plant`), frames and units as everywhere in omni-gym (``docs/conventions.md``):

* ``n_wheels``: the number of wheels the plant takes commands for.
* ``reset(pose, seed) -> PlantState``: put the robot at rest at ``pose`` = (x [m], y [m], θ [rad]), the
  geometric centre in the world frame; ``seed`` (an int) seeds whatever the plant draws at random
  (a simulated plant's lift-off schedule; a real robot ignores it).
* ``step(wheel_speeds, duration) -> PlantState``: hold the wheel speed commands (n,) [rad/s] for
  ``duration`` [s] (one control period) and return the state at its end.

:class:`PlantState` carries the robot's motion: the pose (x, y, θ) and velocity (ẋ, ẏ, ω) of the geometric
centre (world frame) and the wheel angles (n,) [rad]. A simulated plant returns the true motion, and the
environment measures it with its own sensor models (encoders, gyro, compass, accelerometer, camera) at
their rates and noise. A real robot returns what it measured in ``reading`` (:class:`SensorReading`),
which then replaces the sensor models; its pose and velocity are used for scoring only (a motion-capture
pose, or NaN where none is available, which leaves the tracking error undefined).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numba
import numpy as np

from omni_gym.physics.layout import SP_CX, SP_CY, WH_ANGLE, WH_CMD
from omni_gym.physics.liftoff import ContactProcess, contact_cases
from omni_gym.physics.model import Actuation, SimModel

__all__ = ["Plant", "PlantState", "SensorReading", "SimulatorPlant", "centre_velocity", "check_plant_state"]


@dataclass(frozen=True)
class SensorReading:
    """What a robot's own sensors read at the end of a control period (a real plant's ``reading``).

    wheel_angles (n,) [rad] (encoder counts × 2π / counts per revolution); gyro [rad/s]; compass [rad];
    accel (2,) [m/s², body frame]; fix (3,) the tracked pose (x, y [m], θ [rad], world frame) or None when
    no fix arrived in this period.
    """

    wheel_angles: np.ndarray
    gyro: float
    compass: float
    accel: np.ndarray
    fix: np.ndarray | None = None


@dataclass(frozen=True)
class PlantState:
    """The plant at the end of a reset or a control period.

    pose (3,): x, y [m] of the geometric centre and heading θ [rad], world frame; velocity (3,): ẋ, ẏ [m/s] of
    the geometric centre (world frame) and ω [rad/s]; wheel_angles (n,) [rad]; contact (n,) bool, True where
    the wheel is on the floor (None: not known); reading: the robot's own sensor readings (None: the
    environment measures ``pose``, ``velocity`` and ``wheel_angles`` with its sensor models).
    """

    pose: np.ndarray
    velocity: np.ndarray
    wheel_angles: np.ndarray
    contact: np.ndarray | None = None
    reading: SensorReading | None = None


@runtime_checkable
class Plant(Protocol):
    """A robot that wheel speed commands drive; see the module docstring."""

    n_wheels: int

    def reset(self, pose: np.ndarray, seed: int) -> PlantState: ...

    def step(self, wheel_speeds: np.ndarray, duration: float) -> PlantState: ...


def check_plant_state(state: object, n_wheels: int, where: str) -> PlantState:
    """``state`` if it is a :class:`PlantState` of ``n_wheels`` wheels with finite motion, else a one-line
    ValueError naming ``where`` (the plant's method) and what is wrong. A real plant's pose may be NaN
    (no motion capture) only when it brings its own ``reading``."""
    if not isinstance(state, PlantState):
        raise ValueError(f"{where} must return a PlantState, got {type(state).__name__}")
    shapes = {"pose": (3,), "velocity": (3,), "wheel_angles": (n_wheels,)}
    for name, shape in shapes.items():
        value = np.asarray(getattr(state, name))
        if value.shape != shape:
            raise ValueError(f"{where}: {name} must have shape {shape}, got {value.shape}")
        if state.reading is None and not np.all(np.isfinite(value)):
            raise ValueError(f"{where}: {name} is not finite ({value.tolist()}); a plant without its own "
                             "sensor reading must report its motion")
    return state


@numba.njit(cache=True)
def centre_velocity(state, com_x, com_y, out):
    """Velocity (ẋ, ẏ, ω) of the geometric centre from a body state row (x, y, θ, v_com,x, v_com,y, ω).

    The same arithmetic, in the same order, as the environments' observation kernel
    (``omni_gym.envs.core._observe_robot``): v_centre = v_com − ω z × R(θ)·com. A simulator plant reports
    its velocity through this function, so the environment measures exactly the numbers its own world
    would have given it.
    """
    th = state[2]
    c = math.cos(th)
    s = math.sin(th)
    om = state[5]
    rcx = c * com_x - s * com_y
    rcy = s * com_x + c * com_y
    out[0] = state[3] + om * rcy
    out[1] = state[4] - om * rcx
    out[2] = om


class SimulatorPlant:
    """The omni-gym world as a plant: one robot of ``model`` (its effects applied) in a pymunk world.

    Args:
        model: the robot, floor and effects; a ``wheel_liftoff`` effect sets the lift-off rates unless
            ``lift_rates`` is given.
        physics_dt: substep [s]; a control period must be a whole number of substeps.
        actuation: the wheel drive (default: the ideal velocity source).
        arena: walls and obstacles (:class:`omni_gym.physics.world.Arena`; default none).
        lift_rates: (lift_rate, recover_rate) [1/s] of the random contact process (default: the model's
            ``wheel_liftoff`` effect, else no lift-off).

    With the environment's model, substep, actuation, arena and lift-off rates (``TaskCore.simulator_plant``)
    it reproduces the environment's own episodes bit for bit.
    """

    def __init__(self, model: SimModel, physics_dt: float = 0.0005, actuation: Actuation | None = None,
                 arena=None, lift_rates: tuple[float, float] | None = None) -> None:
        from omni_gym.physics.world import World  # the world imports the kernel; keep this module light

        self.model = model
        self.world = World(model, n_robots=1, dt=physics_dt, actuation=actuation, arena=arena)
        self.n_wheels = model.robot.n_wheels
        if lift_rates is None:
            p = model.effects.get("wheel_liftoff")
            lift_rates = (float(p["lift_rate"]), float(p["recover_rate"])) if p is not None else (0.0, 0.0)
        self.lift_rates = (float(lift_rates[0]), float(lift_rates[1]))
        self._cases = contact_cases(self.n_wheels)
        self._velocity = np.zeros(3)

    def reset(self, pose: np.ndarray, seed: int) -> PlantState:
        """At rest at ``pose``; the lift-off process (if any) is seeded with ``seed``."""
        lift, recover = self.lift_rates
        world = self.world
        if lift > 0:
            proc = ContactProcess(self.n_wheels, lift, recover, np.random.default_rng(int(seed)), cases=self._cases)
            world.set_contact_process(0, proc)
        elif world.contact_processes[0] is not None:
            world.set_contact_process(0, None)
        world.reset(poses=np.asarray(pose, dtype=float).reshape(1, 3), robots=[0])
        return self._state()

    def step(self, wheel_speeds: np.ndarray, duration: float) -> PlantState:
        """Hold ``wheel_speeds`` (n,) [rad/s] for ``duration`` [s] (rounded to whole substeps, at least one)."""
        world = self.world
        world.wheels[0, :, WH_CMD] = np.asarray(wheel_speeds, dtype=float).reshape(self.n_wheels)
        world.substeps(max(1, int(round(duration / world.dt))))
        return self._state()

    def _state(self) -> PlantState:
        world = self.world
        st = world.body_states()[0]
        centre_velocity(st, world.sp[0, SP_CX], world.sp[0, SP_CY], self._velocity)
        pose = np.array([st[0] - world.origins[0, 0], st[1] - world.origins[0, 1], st[2]])
        return PlantState(pose=pose, velocity=self._velocity.copy(), wheel_angles=world.wheels[0, :, WH_ANGLE].copy(),
                          contact=world.contact[0].copy())
