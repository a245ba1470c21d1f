"""Omni-wheel kinematics: inverse, forward (least squares) and the wheel-consistency residual.

Body twist q = (vx, vy, ω): velocity [m/s] of the geometric centre in the body frame and yaw rate
[rad/s]. Wheel speeds w [rad/s] follow the sign convention of :mod:`omni_gym.physics.robot`.
"""

from __future__ import annotations

import numpy as np

from omni_gym.physics.robot import RobotSpec


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
