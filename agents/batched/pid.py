"""Batched path PID: :class:`agents.pid.PathPID` for N robots (numpy over a leading robot axis).

Same law, saturation and clamping anti-windup as the single class (see :mod:`agents.pid`); the
arithmetic is element-wise in the same order, so each row matches the single controller to the last
bits of numpy's vectorised cos/sin (relative 1e-16). A PID step is a few dozen element-wise operations
on (N, 3) arrays, cheap next to the EKF, so plain numpy is enough here.
"""

from __future__ import annotations

import numpy as np

from agents.batched.estimation import robot_mask
from agents.pid import PIDGains, configure_pid
from omni_gym.angles import wrap_angle


class BatchPathPID:
    """:class:`agents.pid.PathPID` for ``num`` robots; arguments as the single class.

    State (row i for robot i): ``integral`` (N, 3) in output units (world frame), ``derivative`` (N, 3),
    ``error`` (N, 3), ``saturated`` (N, 2) (translation, rotation).
    """

    def __init__(self, num: int, max_speed: float, max_yaw_rate: float, dt: float, gains: PIDGains | None = None,
                 anti_windup: bool = True) -> None:
        configure_pid(self, max_speed, max_yaw_rate, dt, gains, anti_windup)
        self.num = int(num)
        N = self.num
        self.integral = np.zeros((N, 3))
        self.derivative = np.zeros((N, 3))
        self.error = np.zeros((N, 3))
        self.saturated = np.zeros((N, 2), dtype=bool)
        self._prev_error = np.zeros((N, 3))
        self._has_prev = np.zeros(N, dtype=bool)

    def reset(self, robots=None) -> None:
        """Zero the integrators and derivative filters of the selected robots (mask, indices or None: all)."""
        m = robot_mask(robots, self.num)
        self.integral[m] = 0.0
        self.derivative[m] = 0.0
        self.error[m] = 0.0
        self.saturated[m] = False
        self._has_prev[m] = False

    def update(self, pose: np.ndarray, ref_pose: np.ndarray, ref_velocity: np.ndarray, robots=None) -> np.ndarray:
        """Body twists (N, 3) (vx, vy [m/s], ω [rad/s]) within the limits: one control period for ``robots``.

        Args: (N, 3) arrays: estimated poses, reference poses, reference world velocities (world frame);
        ``robots`` a mask, indices or None (all). Only the selected robots' states change; the other rows of
        the result are zero.
        """
        m = robot_mask(robots, self.num)
        pose = np.asarray(pose, dtype=float)[m]
        ref_pose = np.asarray(ref_pose, dtype=float)[m]
        ref_velocity = np.asarray(ref_velocity, dtype=float)[m]
        e = np.column_stack([ref_pose[:, 0] - pose[:, 0], ref_pose[:, 1] - pose[:, 1],
                             wrap_angle(ref_pose[:, 2] - pose[:, 2])])
        dt = self.dt
        de = e - self._prev_error[m]
        de[:, 2] = wrap_angle(de[:, 2])
        rate = np.where(self._has_prev[m][:, None], de / dt, 0.0)
        self._prev_error[m] = e
        self._has_prev[m] = True
        self.error[m] = e
        derivative = self.derivative[m]
        derivative += dt / (self.gains.d_tau + dt) * (rate - derivative)
        self.derivative[m] = derivative

        integral = self.integral[m]
        u = ref_velocity + self._kp * e + integral + self._kd * derivative
        body, sat_t, sat_r = self._saturate(u, pose[:, 2])
        self.saturated[m, 0], self.saturated[m, 1] = sat_t, sat_r

        step = self._ki * e * dt
        if self.anti_windup:
            # Freeze an axis while its output is saturated and its error would push further out.
            pushing = e * u > 0
            freeze = np.column_stack([sat_t, sat_t, sat_r]) & pushing
            step = np.where(freeze, 0.0, step)
        integral += step
        if self.anti_windup:
            np.clip(integral, -self._ilim, self._ilim, out=integral)
        self.integral[m] = integral
        out = np.zeros((self.num, 3))
        out[m] = body
        return out

    def _saturate(self, u: np.ndarray, th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World commands (N, 3) → body twists within the limits; (twists, translation / rotation saturated)."""
        om = np.clip(u[:, 2], -self.max_yaw_rate, self.max_yaw_rate)
        sat_r = np.abs(u[:, 2]) > self.max_yaw_rate
        mid = th + 0.5 * om * self.dt
        c, s = np.cos(mid), np.sin(mid)
        vx, vy = c * u[:, 0] + s * u[:, 1], -s * u[:, 0] + c * u[:, 1]
        peak = np.maximum(np.abs(vx), np.abs(vy))
        sat_t = peak > self.max_speed
        safe = np.where(sat_t, peak, 1.0)  # (v·max_speed)/peak as the single class, only where saturated
        vx = np.where(sat_t, vx * self.max_speed / safe, vx)
        vy = np.where(sat_t, vy * self.max_speed / safe, vy)
        return np.column_stack([vx, vy, om]), sat_t, sat_r


class BatchLimitedPathPID(BatchPathPID):
    """:class:`agents.traction.LimitedPathPID` for ``num`` robots: the saturated twists go through a limiter.

    ``limiter(twist (K, 3), previous twist (K, 3), estimate (K, 3), dt) -> twist (K, 3)`` (the hook of
    :class:`agents.traction.TractionLimiter`) sees the rows of the robots being updated: their saturated body
    twists, the twists they were commanded in their previous period (zero after :meth:`reset`) and their pose
    estimates. An axis the hook changes counts as saturated for the anti-windup (translation: vx or vy;
    rotation: ω), exactly as the single class, so an integrator does not wind up against a limit it cannot
    push through. ``prev_twist`` (N, 3) [m/s, m/s, rad/s], body frame.
    """

    def __init__(self, limiter, num: int, max_speed: float, max_yaw_rate: float, dt: float,
                 gains: PIDGains | None = None) -> None:
        if not callable(limiter):
            raise ValueError(f"limiter must be a callable (twist, prev_twist, estimate, dt) -> twist, got {limiter!r}")
        super().__init__(num, max_speed, max_yaw_rate, dt, gains)
        self.limiter = limiter
        self.prev_twist = np.zeros((self.num, 3))
        self._rows = np.zeros(self.num, dtype=bool)
        self._pose = np.zeros((0, 3))

    def reset(self, robots=None) -> None:
        super().reset(robots)
        self.prev_twist[robot_mask(robots, self.num)] = 0.0

    def update(self, pose: np.ndarray, ref_pose: np.ndarray, ref_velocity: np.ndarray, robots=None) -> np.ndarray:
        m = robot_mask(robots, self.num)
        self._rows = m
        self._pose = np.asarray(pose, dtype=float)[m]
        out = super().update(pose, ref_pose, ref_velocity, robots=m)
        self.prev_twist[m] = out[m]
        return out

    def _saturate(self, u: np.ndarray, th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        body, sat_t, sat_r = super()._saturate(u, th)
        limited = np.asarray(self.limiter(body, self.prev_twist[self._rows], self._pose, self.dt), dtype=float)
        if limited.shape != body.shape:
            raise ValueError(f"limiter must return shape {body.shape}, got {limited.shape}")
        changed = np.abs(limited - body) > 1e-12 * (1.0 + np.abs(body))  # rounding of an untouched row
        return limited, sat_t | changed[:, 0] | changed[:, 1], sat_r | changed[:, 2]
