"""Scripted baselines for N robots at once over a native vector environment's (N, D) sensor observations.

The batched counterparts of :mod:`agents.policies` (``open-loop``, ``odometry-pid``, ``ekf-pid``,
``ekf-pid-traction``): the
same estimates, twists and actions robot by robot (``tests/test_batched_estimation.py``), with the
EKF, detector and PID of :mod:`agents.batched`. Protocol, for a vector environment ``venv`` built by
``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point", obs_mode="sensors")``::

    policy = make_vector_policy("ekf-pid", venv)
    obs, info = venv.reset(seed=0)
    policy.reset(obs)
    while ...:
        obs, reward, terminated, truncated, info = venv.step(policy.act(obs))
        # NEXT_STEP autoreset: robots that ended get their first observation on the *next* step;
        # call policy.reset(obs, mask) with that step's mask before the next act.

``reset(obs, mask)`` restarts the selected robots only (boolean mask (N,), indices or None: all);
``act(obs, robots=None)`` returns the (N, A) float32 actions and advances only the selected robots
(the other rows repeat their previous action).

Twist limiter hook: ``limiter(twist, estimate, policy) -> twist``, called on every act with the
unsaturated-by-the-limiter body twists (N, 3) [m/s, m/s, rad/s] the policy computed (the rows being
acted on; rows of other robots are their previous twist), ``estimate`` (N, 3) the policy's current
estimate of the body twist (vx, vy, ω) (the EKF's for ``ekf-pid``, the odometry's for
``odometry-pid``, the last commanded twist for ``open-loop``) and the policy itself (for anything
else: ``policy.ekf.wheel_belief``, ``policy.dt``, ``policy.cfg``...). It must return an (N, 3) array;
its rows are what is sent (after scaling and clipping to [−1, 1]) and stored in ``policy.twist``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from agents.batched.estimation import BatchEKF, robot_mask
from agents.batched.pid import BatchPathPID
from agents.pid import PIDGains
from agents.registry import Registry
from omni_gym.envs.observations import BatchSensorObs, BatchSensorObsDecoder

Limiter = Callable[[np.ndarray, np.ndarray, "VectorPolicy"], np.ndarray]


class VectorPolicy:
    """Common machinery: batched decoding, twist → action, the per-robot reset/act protocol."""

    name = "scripted"

    def __init__(self, env, limiter: Limiter | None = None) -> None:
        u = env.unwrapped
        cfg = getattr(u, "cfg", None)
        if cfg is None or not hasattr(u, "observation_layout") or not hasattr(env, "num_envs"):
            raise ValueError(f"vector policy {self.name!r} needs an omni-gym vector environment, got "
                             f"{type(u).__name__}")
        if cfg.obs_mode != "sensors":
            raise ValueError(f"vector policy {self.name!r} needs obs_mode='sensors', got {cfg.obs_mode!r}")
        if limiter is not None and not callable(limiter):
            raise ValueError(f"limiter must be a callable (twist, estimate, policy) -> twist, got {limiter!r}")
        self.cfg = cfg
        self.num = int(env.num_envs)
        self.robot = u.robot
        self.kinematics = u.wheel_kinematics  # nominal, or the model's effective one (kinematics="model")
        self.decode = BatchSensorObsDecoder(u.observation_layout, u.obs_scales)
        self.dt = cfg.control_dt
        self.twist_mode = cfg.action_mode == "twist"
        self.W = self.kinematics.wheel_matrix()
        self.twist_scale = np.array([cfg.max_speed, cfg.max_speed, cfg.max_yaw_rate])
        self.wheel_scale = float(u.wheel_scale)
        self.limiter = limiter
        self.estimate: np.ndarray | None = None  # (N, 3) pose estimate x, y [m], θ [rad]; None for open-loop
        self.twist = np.zeros((self.num, 3))
        self._started = np.zeros(self.num, dtype=bool)

    def reset(self, obs: np.ndarray, mask=None) -> None:
        """Start the episodes of the selected robots from their first observations (rows of ``obs`` (N, D))."""
        m = robot_mask(mask, self.num)
        self._started[m] = False
        self.twist[m] = 0.0
        self._reset(self.decode(obs), m)

    def act(self, obs: np.ndarray, robots=None) -> np.ndarray:
        """Actions (N, A) float32 in [−1, 1] for the observations ``obs`` (N, D); only ``robots`` advance."""
        m = robot_mask(robots, self.num)
        s = self.decode(obs)
        advance = self._started & m  # every observation after the reset one closes one control period
        if advance.any():
            self._advance(s, advance)
        self._started |= m
        twist = self.twist.copy()
        twist[m] = self._twist(s, m)[m]
        if self.limiter is not None:
            limited = np.asarray(self.limiter(twist, self.body_twist_estimate(), self), dtype=float)
            if limited.shape != twist.shape:
                raise ValueError(f"limiter must return shape {twist.shape}, got {limited.shape}")
            twist[m] = limited[m]
        self.twist = twist
        return self._to_action(twist)

    def body_twist_estimate(self) -> np.ndarray:
        """(N, 3) estimated body twist (vx, vy, ω) handed to the limiter (subclasses refine it)."""
        return self.twist.copy()

    def _to_action(self, twist: np.ndarray) -> np.ndarray:
        if self.twist_mode:
            a = twist / self.twist_scale
        else:
            W = self.W
            a = np.stack([W[j, 0] * twist[:, 0] + W[j, 1] * twist[:, 1] + W[j, 2] * twist[:, 2]
                          for j in range(W.shape[0])], axis=1) / self.wheel_scale
        return np.clip(a, -1.0, 1.0).astype(np.float32)

    # Subclass hooks (mask m: the robots concerned).
    def _reset(self, s: BatchSensorObs, m: np.ndarray) -> None:
        pass

    def _advance(self, s: BatchSensorObs, m: np.ndarray) -> None:
        """Update the estimates of robots ``m`` with the period their observations close."""

    def _twist(self, s: BatchSensorObs, m: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class VectorOpenLoopPolicy(VectorPolicy):
    """Feed-forward body twist R(θ_ref + ω_ref·dt/2)ᵀ·ṗ_ref for every robot (agents.policies.OpenLoopPolicy)."""

    name = "open-loop"

    def _twist(self, s: BatchSensorObs, m: np.ndarray) -> np.ndarray:
        vx_w, vy_w, om = s.ref_velocity[:, 0], s.ref_velocity[:, 1], s.ref_velocity[:, 2]
        mid = s.ref_pose[:, 2] + 0.5 * om * self.dt
        c, si = np.cos(mid), np.sin(mid)
        return np.column_stack([c * vx_w + si * vy_w, -si * vx_w + c * vy_w, om])


class VectorPIDPolicy(VectorPolicy):
    """A batched pose estimator (subclass) followed by :class:`~agents.batched.pid.BatchPathPID`."""

    def __init__(self, env, gains: PIDGains | None = None, limiter: Limiter | None = None) -> None:
        super().__init__(env, limiter)
        self.pid = BatchPathPID(self.num, self.cfg.max_speed, self.cfg.max_yaw_rate, self.dt, gains)

    def reset(self, obs: np.ndarray, mask=None) -> None:
        self.pid.reset(mask)
        super().reset(obs, mask)

    def _twist(self, s: BatchSensorObs, m: np.ndarray) -> np.ndarray:
        return self.pid.update(self.estimate, s.ref_pose, s.ref_velocity, robots=m)


class VectorOdometryPIDPolicy(VectorPIDPolicy):
    """Dead reckoning + PID for N robots (agents.policies.OdometryPIDPolicy, its gyro-offset tracking included)."""

    name = "odometry-pid"

    def __init__(self, env, gains: PIDGains | None = None, limiter: Limiter | None = None) -> None:
        super().__init__(env, gains, limiter)
        from agents.policies import OdometryPIDPolicy as Single  # the constants and the noise model

        self.CALIB_SPEED, self.CALIB_YAW_RATE = Single.CALIB_SPEED, Single.CALIB_YAW_RATE
        self._pinv = np.linalg.pinv(self.W)
        sc = self.cfg.sensor_config()
        quantum = 2.0 * math.pi / sc.counts_per_rev
        self._window_q_var = float(np.sum(self._pinv[2] ** 2)) * quantum**2 / 6.0
        self._gyro_var = sc.gyro_noise_std**2
        self._walk_var = sc.gyro_bias_walk_std**2
        N = self.num
        self.estimate = np.zeros((N, 3))
        self.odometry_twist = np.zeros((N, 3))  # last (vx, vy, ω) of the dead reckoning
        self.gyro_offset = np.zeros(N)
        self.gyro_offset_var = np.zeros(N)
        self._win_sum = np.zeros(N)
        self._win_n = np.zeros(N, dtype=np.int64)
        self._calib_ref = np.zeros((N, 3))
        self._last_gyro = np.zeros(N)

    def body_twist_estimate(self) -> np.ndarray:
        return self.odometry_twist.copy()

    def _reset(self, s: BatchSensorObs, m: np.ndarray) -> None:
        self.estimate[m] = s.ref_pose[m]
        self.odometry_twist[m] = 0.0
        self.gyro_offset[m] = s.gyro[m]
        self.gyro_offset_var[m] = self._gyro_var
        self._win_sum[m] = 0.0
        self._win_n[m] = 0
        self._calib_ref[m] = s.ref_velocity[m]
        self._last_gyro[m] = s.gyro[m]

    def _close_windows(self, m: np.ndarray) -> None:
        """Fuse the finished rest windows of robots ``m`` into their offset estimates (as the single policy)."""
        m = m & (self._win_n > 0)
        if not m.any():
            return
        span = self._win_n[m] * self.dt
        z = self._win_sum[m] / span
        r = self._window_q_var / span**2 + self._gyro_var / self._win_n[m]
        var = self.gyro_offset_var[m]
        total = var + r
        gain = np.where(total > 0, var / np.where(total > 0, total, 1.0), 0.0)
        self.gyro_offset[m] += gain * (z - self.gyro_offset[m])
        self.gyro_offset_var[m] = var * (1.0 - gain)
        self._win_sum[m] = 0.0
        self._win_n[m] = 0

    def _advance(self, s: BatchSensorObs, m: np.ndarray) -> None:
        P = self._pinv
        e = s.encoder_rates[m]
        q = np.stack([e @ P[r] for r in range(3)], axis=1)  # W⁺·w per robot
        vx, vy, om_enc = q[:, 0], q[:, 1], q[:, 2]
        self.gyro_offset_var[m] += self._walk_var * self.dt
        ref = self._calib_ref[m]
        rest = (np.hypot(ref[:, 0], ref[:, 1]) < self.CALIB_SPEED) & (np.abs(ref[:, 2]) < self.CALIB_YAW_RATE)
        idx = np.flatnonzero(m)
        r_idx = idx[rest]
        self._win_sum[r_idx] += (0.5 * (s.gyro[r_idx] + self._last_gyro[r_idx]) - om_enc[rest]) * self.dt
        self._win_n[r_idx] += 1
        closing = np.zeros(self.num, dtype=bool)
        closing[idx[~rest]] = True
        self._close_windows(closing)
        self._calib_ref[m] = s.ref_velocity[m]
        self._last_gyro[m] = s.gyro[m]
        om = s.gyro[m] - self.gyro_offset[m]
        x, y, th = self.estimate[m].T
        mid = th + 0.5 * om * self.dt
        c, si = np.cos(mid), np.sin(mid)
        self.estimate[m] = np.column_stack([x + (c * vx - si * vy) * self.dt, y + (si * vx + c * vy) * self.dt,
                                            th + om * self.dt])
        self.odometry_twist[m] = np.column_stack([vx, vy, om])


class VectorEKFPIDPolicy(VectorPIDPolicy):
    """:class:`~agents.batched.estimation.BatchEKF` + PID; each filter starts at rest at its reset reference pose."""

    name = "ekf-pid"

    def __init__(self, env, gains: PIDGains | None = None, limiter: Limiter | None = None,
                 threads: bool = False) -> None:
        super().__init__(env, gains, limiter)
        from agents.ekf import EKFConfig

        cfg = self.cfg
        self.ekf = BatchEKF(self.kinematics, self.num,
                            EKFConfig.from_sensor_config(cfg.sensor_config(), cfg.control_hz), threads=threads)
        self.estimate = self.ekf.pose

    def body_twist_estimate(self) -> np.ndarray:
        return self.ekf.body_twist

    def _reset(self, s: BatchSensorObs, m: np.ndarray) -> None:
        self.ekf.reset(m, s.ref_pose[m])
        self.estimate = self.ekf.pose

    def _advance(self, s: BatchSensorObs, m: np.ndarray) -> None:
        self.ekf.process(s, self.dt, m)
        self.estimate = self.ekf.pose


class VectorEKFPIDTractionPolicy(VectorEKFPIDPolicy):
    """``ekf-pid`` with the traction limiter inside the PID (agents.policies.EKFPIDTractionPolicy) for N robots.

    The same :class:`agents.traction.TractionLimiter` (nominal model, the single policy's MODE and MARGIN)
    in :class:`~agents.batched.pid.BatchLimitedPathPID`: a limited axis counts as saturated for the
    anti-windup. The ``limiter`` hook of :class:`VectorPolicy`, if given, still acts after it.
    """

    name = "ekf-pid-traction"

    def __init__(self, env, gains: PIDGains | None = None, limiter: Limiter | None = None,
                 threads: bool = False) -> None:
        super().__init__(env, gains, limiter, threads)
        from agents.batched.pid import BatchLimitedPathPID
        from agents.policies import EKFPIDTractionPolicy as Single  # MODE and MARGIN
        from agents.traction import TractionLimiter

        model = self.cfg.base_model()
        self.traction = TractionLimiter(model.robot, model.surface, mode=Single.MODE, margin=Single.MARGIN,
                                        com=model.com)
        self.pid = BatchLimitedPathPID(self.traction, self.num, self.cfg.max_speed, self.cfg.max_yaw_rate, self.dt,
                                       gains)


# The batched twins of agents.policies.POLICIES, by the same names (a test keeps the two tables equal).
VECTOR_POLICIES: Registry[type[VectorPolicy]] = Registry(
    "vector policy", [(c.name, c) for c in (VectorOpenLoopPolicy, VectorOdometryPIDPolicy, VectorEKFPIDPolicy,
                                            VectorEKFPIDTractionPolicy)])
VECTOR_POLICY_NAMES = VECTOR_POLICIES.names()


def make_vector_policy(name: str, env, gains: PIDGains | None = None, limiter: Limiter | None = None,
                       **kwargs) -> VectorPolicy:
    """The vector policy ``name`` (one of :data:`VECTOR_POLICY_NAMES`) for a vector env (obs_mode='sensors')."""
    cls = VECTOR_POLICIES.get(name)
    if not issubclass(cls, VectorPIDPolicy):
        if gains is not None:
            raise ValueError(f"policy {name!r} takes no PID gains")
        return cls(env, limiter, **kwargs)
    return cls(env, gains, limiter, **kwargs)
