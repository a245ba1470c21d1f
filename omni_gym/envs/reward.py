"""The environments' reward: the built-in tracking reward, written once, and the interface of your own.

The built-in reward of every id, per robot and control period::

    r = 0.7·exp(−e/0.1 m) + 0.3·exp(−|e_θ|/0.3 rad) − 0.05·mean(a²)

e [m]: distance of the geometric centre from the reference position now; e_θ [rad]: heading error,
wrapped to (−π, π]; a: the clipped action of the period that just ended (each component in [−1, 1]).
:data:`FORMULA` is that line, made from the constants below; the documentation quotes it
(``tests/test_reward.py`` checks every quote).

The compiled observation kernel (:mod:`omni_gym.envs.core`) calls :func:`tracking_reward` for each robot
while it computes the errors (the fast path). Another reward is the environment keyword ``reward=``: a
callable taking a :class:`RewardInputs` and returning one number per robot, or a class of such (made
with no arguments). It is called once per step for all robots of the environment, after the
observation::

    def progress(x: RewardInputs) -> np.ndarray:
        return -x.position_error - 0.1 * np.abs(x.heading_error)

    env = gym.make("OmniPathFollow-Phunopas-v0", reward=progress)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np

# Weights and length scales of the built-in reward (dimensionless weights; E_POS [m], E_HEAD [rad]).
W_POS, E_POS, W_HEAD, E_HEAD, W_EFFORT = 0.7, 0.1, 0.3, 0.3, 0.05
FORMULA = (f"r = {W_POS:g}·exp(−e/{E_POS:g} m) + {W_HEAD:g}·exp(−|e_θ|/{E_HEAD:g} rad) "
           f"− {W_EFFORT:g}·mean(a²)")


@numba.njit(cache=True, inline="always")
def tracking_reward(position_error: float, heading_error: float, effort: float, n_act: int) -> float:
    """The built-in reward of one robot (:data:`FORMULA`); ``effort`` = Σ a_j² over its ``n_act`` actions."""
    return (W_POS * math.exp(-position_error / E_POS) + W_HEAD * math.exp(-abs(heading_error) / E_HEAD)
            - W_EFFORT * effort / n_act)


@numba.njit(cache=True)
def _tracking_rewards(position_error, heading_error, action, out):
    for b in range(out.shape[0]):
        effort = 0.0
        for j in range(action.shape[1]):
            effort += action[b, j] * action[b, j]
        out[b] = tracking_reward(position_error[b], heading_error[b], effort, action.shape[1])


@dataclass(frozen=True)
class RewardInputs:
    """What a reward sees, one row per robot (B robots), after a control period. Arrays are the
    environment's own buffers: read them, do not keep or write them.

    Attributes:
        position_error: (B,) distance of the geometric centre from the reference position [m].
        heading_error: (B,) reference heading − heading, wrapped to (−π, π] [rad].
        action: (B, A) the clipped action of the period that just ended, each component in [−1, 1].
        pose: (B, 3) x, y [m] of the geometric centre in the arena frame, heading θ [rad].
        velocity: (B, 3) world-frame velocity of the geometric centre [m/s] and yaw rate [rad/s].
        reference_pose: (B, 3) the reference's x, y [m], θ [rad] now.
        reference_velocity: (B, 3) the reference's world-frame velocity [m/s] and yaw rate [rad/s] now.
        step: (B,) control periods since each robot's reset.
        control_dt: the control period [s].
    """

    position_error: np.ndarray
    heading_error: np.ndarray
    action: np.ndarray
    pose: np.ndarray
    velocity: np.ndarray
    reference_pose: np.ndarray
    reference_velocity: np.ndarray
    step: np.ndarray
    control_dt: float


class Reward(Protocol):
    """A reward: one finite number per robot from :class:`RewardInputs`."""

    def __call__(self, inputs: RewardInputs) -> np.ndarray: ...


class BuiltinReward:
    """The built-in reward (:data:`FORMULA`) as a :class:`Reward`. Passing it (the class or an instance)
    as ``reward=`` keeps the compiled fast path: the observation kernel computes the same numbers."""

    formula = FORMULA

    def __call__(self, inputs: RewardInputs) -> np.ndarray:
        out = np.empty(len(inputs.position_error))
        _tracking_rewards(np.ascontiguousarray(inputs.position_error, dtype=np.float64),
                          np.ascontiguousarray(inputs.heading_error, dtype=np.float64),
                          np.ascontiguousarray(inputs.action, dtype=np.float64), out)
        return out

    def __eq__(self, other: object) -> bool:
        return isinstance(other, BuiltinReward)

    def __hash__(self) -> int:
        return hash(BuiltinReward)

    def __repr__(self) -> str:
        return "BuiltinReward()"


def is_builtin(reward: object) -> bool:
    """True for None, :class:`BuiltinReward` and its instances: the fused kernel computes these."""
    return reward is None or reward is BuiltinReward or type(reward) is BuiltinReward


def check_reward(value: object) -> Reward | None:
    """The ``reward`` keyword's value: None (built-in), or a callable; a class is made with no arguments.
    ValueError naming the keyword otherwise."""
    if is_builtin(value):
        return None
    if isinstance(value, type):
        try:
            value = value()
        except Exception as exc:  # a user's class: whatever its constructor raises, name the keyword
            raise ValueError(f"invalid reward={value.__name__}: the class could not be made with no arguments "
                             f"({type(exc).__name__}: {exc})") from None
        if is_builtin(value):
            return None
    if not callable(value):
        raise ValueError(f"invalid reward={value!r}: expected None (the built-in reward), a callable taking "
                         "omni_gym.envs.reward.RewardInputs and returning one number per robot, or such a class")
    return value


def evaluate(reward: Reward, inputs: RewardInputs, out: np.ndarray) -> None:
    """Write ``reward(inputs)`` into ``out`` (B,), checking its shape (ValueError naming the reward)."""
    values = np.asarray(reward(inputs), dtype=np.float64)
    if values.shape != out.shape and not (values.size == 1 == out.size):  # one robot: a scalar will do
        raise ValueError(f"reward {_name(reward)} returned shape {values.shape}; expected ({out.shape[0]},): "
                         "one number per robot")
    if not np.isfinite(values).all():  # named here: the environment's own check would blame the physics
        raise ValueError(f"reward {_name(reward)} returned a non-finite value: {values.ravel().tolist()[:8]}")
    out[:] = values.reshape(out.shape)


def _name(reward: object) -> str:
    return getattr(reward, "__qualname__", None) or type(reward).__qualname__
