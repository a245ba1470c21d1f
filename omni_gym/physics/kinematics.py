"""Omni-wheel kinematics: inverse, forward (least squares) and the wheel-consistency residual.

Body twist q = (vx, vy, ω): velocity [m/s] of the geometric centre in the body frame and yaw rate
[rad/s]. Wheel speeds w [rad/s] follow the sign convention of :mod:`omni_gym.physics.robot`.

:func:`effective_kinematics` is the one home of a model's *effective* kinematics: the wheel matrix
with every model effect that changes the no-slip rolling constraint (``wheel_radius``,
``wheel_geometry``, ``mecanum_lateral``, read from the force kernel's own per-wheel rows).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from omni_gym.physics.layout import WP_COSG, WP_DX, WP_DY, WP_PX, WP_PY, WP_R, WP_SING
from omni_gym.physics.model import SimModel
from omni_gym.physics.robot import RobotSpec

# The kernel's per-wheel columns that enter the no-slip constraint (kernel.py): position, drive,
# rolling radius and roller angle. An effect changes the kinematics iff it changes one of them.
_KINEMATIC_COLUMNS = [WP_PX, WP_PY, WP_DX, WP_DY, WP_R, WP_COSG, WP_SING]


@dataclass(frozen=True, eq=False)
class WheelKinematics:
    """What a controller needs of a robot's kinematics: the wheel matrix and a rolling radius.

    ``matrix`` W (n, 3): body twist (vx, vy [m/s] of the geometric centre, body frame; ω [rad/s]) →
    no-slip wheel speeds [rad/s], sign convention of :mod:`omni_gym.physics.robot`. ``wheel_radius``
    [m]: the mean effective rolling radius (controllers use it to turn speeds [m/s] into wheel rates).
    It offers the two members of :class:`~omni_gym.physics.robot.RobotSpec` that estimators read
    (``wheel_matrix()``, ``wheel_radius``), so either can be given to them.
    """

    matrix: np.ndarray
    wheel_radius: float

    @classmethod
    def of_robot(cls, robot: RobotSpec) -> WheelKinematics:
        """The nominal kinematics of ``robot`` (its own wheel matrix and radius, bit for bit)."""
        return cls(robot.wheel_matrix(), float(robot.wheel_radius))

    @property
    def n_wheels(self) -> int:
        return int(self.matrix.shape[0])

    def wheel_matrix(self) -> np.ndarray:
        """W (n, 3) [rad/s per (m/s, m/s, rad/s)]; a copy."""
        return np.array(self.matrix, dtype=float)


def effective_kinematics(model: SimModel) -> WheelKinematics:
    """The kinematics ``model`` simulates: W_eff (n, 3), body twist → wheel speeds without slip.

    Computed from the force kernel's per-wheel rows (:meth:`SimModel.kernel_params`, after every
    effect), so it includes each effect that moves a wheel's contact point or drive direction
    (``wheel_geometry``), scales its rolling radius (``wheel_radius``) or its effective roller angle
    and radius (``mecanum_lateral``); effects that leave those rows alone (friction, centre of mass,
    motor lag, lift-off, tracker effects) do not change it. Row i is u_i·(1, 0; 0, 1; z × p_i) /
    (r_i cos γ_i), u_i = cos γ_i d_i + sin γ_i (z × d_i), as in :meth:`RobotSpec.wheel_matrix`. A model
    none of whose effects changes those rows returns the robot's own matrix and radius, bit for bit.
    """
    robot = model.robot
    wp = model.kernel_params()[1]
    nominal = SimModel(robot, model.surface, model.friction, model.gravity).kernel_params()[1]
    if np.array_equal(wp[:, _KINEMATIC_COLUMNS], nominal[:, _KINEMATIC_COLUMNS]):
        return WheelKinematics.of_robot(robot)
    c, s = wp[:, WP_COSG], wp[:, WP_SING]
    dx, dy = wp[:, WP_DX], wp[:, WP_DY]
    ux, uy = c * dx - s * dy, c * dy + s * dx  # roller axis u = cos γ d + sin γ (z × d)
    lever = uy * wp[:, WP_PX] - ux * wp[:, WP_PY]  # u · (z × p)
    W = np.column_stack([ux, uy, lever]) / (wp[:, WP_R] * c)[:, None]
    return WheelKinematics(W, float(np.mean(wp[:, WP_R])))


def rotation(theta: float) -> np.ndarray:
    """2×2 rotation matrix R(θ) taking body-frame vectors to the world frame."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def inverse(robot: RobotSpec, twist_body: np.ndarray) -> np.ndarray:
    """No-slip wheel speeds [rad/s] for a body twist (vx, vy, ω); accepts (..., 3) arrays."""
    return np.asarray(twist_body, dtype=float) @ robot.wheel_matrix().T


def forward(robot: RobotSpec, wheel_speeds: np.ndarray, contact: np.ndarray | None = None) -> np.ndarray:
    """Least-squares body twist from wheel speeds, using only the wheels with ``contact`` True.

    With n > 3 wheels this is W⁺·w, the twist that best explains the measured speeds.
    Raises ValueError if the wheels in contact cannot determine the twist (rank < 3).
    """
    w = np.asarray(wheel_speeds, dtype=float)
    W = robot.wheel_matrix()
    if contact is not None:
        mask = np.asarray(contact, dtype=bool)
        W, w = W[mask], w[..., mask]
    if np.linalg.matrix_rank(W) < 3:
        raise ValueError("forward kinematics: the wheels in contact do not determine the body twist")
    return w @ np.linalg.pinv(W).T


def consistency_residual(robot: RobotSpec, wheel_speeds: np.ndarray) -> np.ndarray:
    """(I − W W⁺)·w [rad/s]: the part of the wheel speeds no rigid no-slip motion can produce.

    Zero (to rounding) for n = 3 wheels; for n > 3 a non-zero residual means some wheel slips or
    turns without load.
    """
    W = robot.wheel_matrix()
    P = np.eye(W.shape[0]) - W @ np.linalg.pinv(W)
    return np.asarray(wheel_speeds, dtype=float) @ P.T


def world_to_body(twist_world: np.ndarray, theta: float) -> np.ndarray:
    """World-frame twist (ẋ, ẏ, θ̇) → body-frame twist (vx, vy, ω) at heading θ [rad]."""
    tw = np.asarray(twist_world, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * tw[..., 0] + s * tw[..., 1], -s * tw[..., 0] + c * tw[..., 1], tw[..., 2]], axis=-1)


def body_to_world(twist_body: np.ndarray, theta: float) -> np.ndarray:
    """Body-frame twist (vx, vy, ω) → world-frame twist (ẋ, ẏ, θ̇) at heading θ [rad]."""
    tb = np.asarray(twist_body, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * tb[..., 0] - s * tb[..., 1], s * tb[..., 0] + c * tb[..., 1], tb[..., 2]], axis=-1)
