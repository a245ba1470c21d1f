"""Batched EKF and slip detector: :class:`agents.ekf.OmniEKF` and :class:`agents.slip_detector.SlipDetector`
for N robots of one design at once.

The single-robot classes are the readable reference; these hold the same state as arrays over a
leading robot axis and run the compiled kernels of :mod:`agents.batched.kernels` (the module docstring
there says why numba and how closely the results agree). Robots end episodes at different steps, so
every method takes a robot selection (a boolean mask (N,) or indices; None: all robots).

State of :class:`BatchEKF` (robot i in row i): ``x`` (N, 7) = [x, y, θ, vx, vy, ω, b_g] (world position
[m] and heading [rad] in (−π, π], body twist [m/s, m/s, rad/s], gyro bias [rad/s]), ``P`` (N, 7, 7),
``wheel_belief`` (N, n), ``wheel_ok`` (N, n), ``wheels_used`` (N, n), ``step_nis`` (N, 5): the NIS of
the accelerometer, gyro, compass, camera and the joint wheel innovation of the last period (NaN where
that update did not run). The single filter's other diagnostics (per-wheel NIS dictionaries, the
detector's residual and encoder yaw rate) are not kept.
"""

from __future__ import annotations

import itertools
import math

import numba
import numpy as np

from agents.batched import kernels as k
from agents.ekf import NX, EKFConfig
from agents.slip_detector import DetectorConfig
from omni_gym.angles import wrap_angle
from omni_gym.envs.observations import BatchSensorObs
from omni_gym.physics.kinematics import WheelKinematics
from omni_gym.physics.robot import RobotSpec


def robot_mask(select, num: int) -> np.ndarray:
    """Boolean mask (num,) from None (all), a boolean mask or robot indices; ValueError otherwise."""
    if select is None:
        return np.ones(num, dtype=bool)
    a = np.asarray(select)
    if a.dtype == bool:
        if a.shape != (num,):
            raise ValueError(f"robot mask must have shape ({num},), got {a.shape}")
        return a.copy()
    if a.ndim > 1 or (a.size and not np.issubdtype(a.dtype, np.integer)):
        raise ValueError(f"robots must be a boolean mask or integer indices, got {select!r}")
    idx = a.astype(np.int64).reshape(-1)
    if idx.size and (idx.min() < 0 or idx.max() >= num):
        raise ValueError(f"robot indices must be in [0, {num}), got {idx.tolist()}")
    mask = np.zeros(num, dtype=bool)
    mask[idx] = True
    return mask


def _hypotheses(n: int, max_faults: int | None) -> np.ndarray:
    """Fault sets (H, n), in the order of SlipDetector.hypotheses (row 0: no fault)."""
    max_f = n if max_faults is None else min(max_faults, n)
    return np.array([m for m in itertools.product((False, True), repeat=n) if sum(m) <= max_f], dtype=bool)


class BatchSlipDetector:
    """Fault beliefs and hysteresis of :class:`~agents.slip_detector.SlipDetector` for N robots.

    Args:
        num: number of robots N.
        W: wheel matrix (n, 3); wheel_radius [m]; wheel_rate_std σ_w [rad/s]; config as the single class.

    Attributes: ``belief`` (N, n) fault probabilities, ``ok`` (N, n) wheels the odometry may use.
    """

    def __init__(self, num: int, W: np.ndarray, wheel_radius: float, wheel_rate_std: float,
                 config: DetectorConfig | None = None) -> None:
        self.W = np.asarray(W, dtype=float)
        if self.W.ndim != 2 or self.W.shape[1] != 3 or self.W.shape[0] < 3:
            raise ValueError(f"W must have shape (n >= 3, 3), got {self.W.shape}")
        self.num = int(num)
        self.config = DetectorConfig() if config is None else config
        self.n = self.W.shape[0]
        self.sigma_w = float(wheel_rate_std)
        self.sigma_f = self.config.fault_speed_std / float(wheel_radius)
        self.hypotheses = _hypotheses(self.n, self.config.max_faults)
        self.belief = np.zeros((self.num, self.n))
        self.ok = np.ones((self.num, self.n), dtype=bool)
        self._agree = np.zeros((self.num, self.n), dtype=np.int64)

    def params(self, dt: float, fp: np.ndarray) -> None:
        """Write the detector's entries of the kernel parameter vector for a period ``dt`` [s]."""
        c = self.config
        fp[k.F_SIGMA_F2] = self.sigma_f**2
        fp[k.F_P_ON] = -math.expm1(-c.onset_rate * dt)
        fp[k.F_P_OFF] = -math.expm1(-c.recover_rate * dt)
        fp[k.F_EXCLUDE] = c.exclude_belief
        fp[k.F_INCLUDE] = c.include_belief

    def reset(self, robots=None) -> None:
        """Every wheel of the selected robots believed in contact and gripping."""
        m = robot_mask(robots, self.num)
        self.belief[m] = 0.0
        self.ok[m] = True
        self._agree[m] = 0

    def step(self, nu: np.ndarray, S: np.ndarray, dt: float, robots=None) -> np.ndarray:
        """One period for the selected robots: innovations ``nu`` (N, n) [rad/s] and covariances ``S`` (N, n, n)."""
        m = robot_mask(robots, self.num)
        fp = np.zeros(k.N_FP)
        self.params(dt, fp)
        k.detector_batch(np.ascontiguousarray(nu, dtype=float), np.ascontiguousarray(S, dtype=float), self.belief,
                         self.ok, self._agree, self.hypotheses, fp, int(self.config.include_steps), m)
        return self.ok.copy()


class BatchEKF:
    """:class:`agents.ekf.OmniEKF` for ``num`` robots of the same design and configuration.

    Args:
        robot: the robot design (all robots share it): its wheel matrix and wheel radius are read, so a
            model's effective :class:`~omni_gym.physics.kinematics.WheelKinematics` may stand in.
        num: number of robots N.
        config: :class:`agents.ekf.EKFConfig` (the single filter's).
        threads: run blocks of robots on numba's threads (``numba.get_num_threads()`` blocks); the results
            do not change, robots being independent.
    """

    def __init__(self, robot: RobotSpec | WheelKinematics, num: int, config: EKFConfig | None = None,
                 threads: bool = False) -> None:
        if not (isinstance(num, (int, np.integer)) and num >= 1):
            raise ValueError(f"num must be a positive integer, got {num!r}")
        self.robot = robot
        self.num = int(num)
        self.config = EKFConfig() if config is None else config
        self.threads = bool(threads)
        c = self.config
        self.W = np.ascontiguousarray(robot.wheel_matrix(), dtype=float)
        self.n = self.W.shape[0]
        self.detector = BatchSlipDetector(self.num, self.W, robot.wheel_radius, c.wheel_rate_std, c.detector)
        self._fp = np.zeros(k.N_FP)
        fp = self._fp
        fp[k.F_ACCEL_PSD], fp[k.F_YAW_PSD], fp[k.F_BIAS_PSD] = c.accel_psd, c.yaw_accel_psd, c.gyro_bias_walk_std**2
        fp[k.F_R_WHEEL], fp[k.F_R_GYRO] = c.wheel_rate_std**2, c.gyro_noise_std**2
        fp[k.F_R_COMPASS] = c.compass_noise_std**2
        fp[k.F_R_CAM_POS], fp[k.F_R_CAM_HEAD] = c.camera_position_std**2, c.camera_heading_std**2
        fp[k.F_R_ACCEL] = c.accel_noise_std**2
        fp[k.F_GATE_WHEELS], fp[k.F_GATE_GYRO], fp[k.F_GATE_COMPASS] = c.gate(1), c.gate(1), c.gate(1)
        fp[k.F_GATE_CAMERA], fp[k.F_GATE_ACCEL] = c.gate(3), c.gate(2)
        fp[k.F_ACCEL_LIMIT] = c.accel_limit
        self._dt = math.nan  # the detector's Markov probabilities depend on Δt: refreshed when it changes
        self._ip = np.array([c.use_accel, c.use_compass, c.use_camera, c.use_detector, c.reacquire_after,
                             c.detector.include_steps], dtype=np.int64)
        N, n = self.num, self.n
        self.x = np.zeros((N, NX))
        self.P = np.zeros((N, NX, NX))
        self.wheel_ok = np.ones((N, n), dtype=bool)
        self.wheel_belief = np.zeros((N, n))
        self.wheels_used = np.ones((N, n), dtype=bool)
        self.step_nis = np.full((N, 5), np.nan)
        self._rejections = np.zeros((N, 3), dtype=np.int64)
        self._since_camera = np.zeros(N)
        self.reset(None, np.zeros((N, 3)))

    def reset(self, robots, poses: np.ndarray, pose_std=(0.01, 0.01, 0.02)) -> None:
        """Selected robots at rest at ``poses`` ((N, 3) rows for every robot, or one row per selected robot)."""
        m = robot_mask(robots, self.num)
        poses = np.asarray(poses, dtype=float)
        sel = int(m.sum())
        if poses.shape == (self.num, 3):
            poses = poses[m]
        elif poses.shape != (sel, 3):
            raise ValueError(f"poses must have shape ({self.num}, 3) or ({sel}, 3), got {poses.shape}")
        std = np.asarray(pose_std, dtype=float)
        if not (np.all(np.isfinite(poses)) and std.shape == (3,) and np.all(std > 0)):
            raise ValueError(f"poses must be finite and pose_std 3 numbers > 0, got {pose_std!r}")
        c = self.config
        self.x[m] = 0.0
        self.x[m, 0:3] = poses
        self.x[m, 2] = wrap_angle(poses[:, 2])
        v = c.rest_speed_std**2
        self.P[m] = np.diag([std[0] ** 2, std[1] ** 2, std[2] ** 2, v, v, v, c.gyro_bias_std**2])
        self.detector.reset(m)
        self.wheel_ok[m] = True
        self.wheel_belief[m] = 0.0
        self.wheels_used[m] = True
        self.step_nis[m] = np.nan
        self._rejections[m] = 0
        self._since_camera[m] = 0.0

    @property
    def pose(self) -> np.ndarray:
        """(N, 3) x, y [m], θ [rad] in (−π, π], world frame (a copy)."""
        return self.x[:, 0:3].copy()

    @property
    def body_twist(self) -> np.ndarray:
        """(N, 3) vx, vy [m/s] (body frame), ω [rad/s] (a copy)."""
        return self.x[:, 3:6].copy()

    def process(self, s: BatchSensorObs, dt: float, robots=None) -> None:
        """One control period of :meth:`agents.ekf.OmniEKF.process` for the selected robots (decoded batch ``s``)."""
        m = robot_mask(robots, self.num)
        if dt != self._dt:
            self._fp[k.F_DT] = dt
            self.detector.params(dt, self._fp)
            self._dt = dt
        d = self.detector
        args = (self.x, self.P, self._rejections, self._since_camera, d.belief, d.ok, d._agree, self.wheel_ok,
                self.wheel_belief, self.wheels_used, self.step_nis, _f64(s.encoder_rates), _f64(s.gyro),
                _f64(s.compass), _f64(s.accel), _f64(s.camera_fix), _f64(s.fix_age), self.W, d.hypotheses, self._fp,
                self._ip, m)
        if self.threads:
            k.ekf_process_threaded(*args, min(numba.get_num_threads(), self.num))
        else:
            k.ekf_process(*args)


def _f64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)
