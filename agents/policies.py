"""Scripted baseline policies for the omni-gym environments with ``obs_mode="sensors"``.

Every policy reads only the sensor observation (decoded by :class:`~omni_gym.envs.observations.SensorObsDecoder`),
never ``info``, and is deterministic given the observations:

    policy = make_policy("ekf-pid", env)
    obs, info = env.reset(seed=0)
    policy.reset(obs)
    while True:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))
        ...

* ``open-loop``: feed-forward only. The reference world velocity is rotated into the body frame by
  the *reference* heading (at mid-period, see below) and sent as the twist, i.e. wheel speeds
  W·R(θ_ref)ᵀ·ṗ_ref — Phunopas & Inoue (2018) without their filter. Nothing corrects slip.
* ``odometry-pid``: dead reckoning — the body translation (vx, vy) from the encoder rates by
  least-squares forward kinematics over all wheels (W⁺·w; a policy cannot know which wheel is lifted),
  the yaw rate from the gyro reading at the end of the period (the wheel speeds are set at the start
  of each period and the body follows within milliseconds, so the end reading is the period's rate;
  averaging both ends would lag by ω·dt/2), minus a zero-rate offset: first the reset reading, at
  rest, then refined at every rest point of the reference (gyro against the encoders' yaw rate, where
  slip vanishes; fused by variance, see :class:`OdometryPIDPolicy`) — integrated from the start pose
  (the reference pose at reset: episodes start on the reference) — and :class:`~agents.pid.PathPID`
  on that estimate. The wheels are velocity-controlled, so the encoders read the commanded speeds
  whether a wheel grips, slips or is lifted: dead reckoning sees heading slip (through the gyro) but
  not translational slip, and under slip it is no better than open-loop on position
  (``benchmarks/results/baselines.md``).
* ``ekf-pid``: :class:`agents.ekf.OmniEKF` (encoders, gyro, compass, accelerometer, camera fixes) and
  the same PID on its pose.
* ``ekf-pid-traction``: ``ekf-pid`` whose twist changes stay within what the wheels' friction can
  transmit (:mod:`agents.traction`, Williams et al. 2002, Sec. IV-B).

A constant body twist held for one control period moves the robot along an arc; rotating the world
velocity by the heading at mid-period (θ + ω·dt/2) makes the straight-line chord match it to second
order. All three policies do this, so the no-slip condition measures control, not discretisation.

``policy.estimate`` is the current pose estimate (x, y, θ) (None for open-loop); ``policy.twist`` the
last commanded body twist [m/s, m/s, rad/s].
"""

from __future__ import annotations

import math

import numpy as np

from agents.pid import PathPID, PIDGains
from agents.registry import Registry
from omni_gym.envs.observations import SensorObs, SensorObsDecoder


class ScriptedPolicy:
    """Common machinery: decoding, twist → action (twist or wheel actions), the reset/act protocol."""

    name = "scripted"

    def __init__(self, env) -> None:
        u = env.unwrapped
        cfg = getattr(u, "cfg", None)
        if cfg is None or not hasattr(u, "observation_layout"):
            raise ValueError(f"policy {self.name!r} needs an omni-gym environment, got {type(u).__name__}")
        if cfg.obs_mode != "sensors":
            raise ValueError(f"policy {self.name!r} needs obs_mode='sensors', got {cfg.obs_mode!r}")
        self.cfg = cfg
        self.robot = u.robot
        self.kinematics = u.wheel_kinematics  # nominal, or the model's effective one (kinematics="model")
        self.decode = SensorObsDecoder.for_env(env)
        self.dt = cfg.control_dt
        self.twist_mode = cfg.action_mode == "twist"
        self.W = self.kinematics.wheel_matrix()
        self.twist_scale = np.array([cfg.max_speed, cfg.max_speed, cfg.max_yaw_rate])
        self.wheel_scale = float(u.wheel_scale)
        self.action_shape = env.action_space.shape
        self.estimate: np.ndarray | None = None
        self.twist = np.zeros(3)
        self._started = False

    def reset(self, obs: np.ndarray) -> None:
        """Start an episode from its first observation (the robot is at rest on the reference)."""
        self._started = False
        self.twist = np.zeros(3)
        self._reset(self.decode(obs))

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Action (float32, the env's action shape, within [−1, 1]) for the observation ``obs``."""
        s = self.decode(obs)
        if self._started:  # every observation after the reset one closes one control period
            self._advance(s)
        self._started = True
        self.twist = self._twist(s)
        return self._to_action(self.twist)

    def _to_action(self, twist: np.ndarray) -> np.ndarray:
        if self.twist_mode:
            a = twist / self.twist_scale
        else:
            a = self.W @ twist / self.wheel_scale
        return np.clip(a, -1.0, 1.0).astype(np.float32).reshape(self.action_shape)

    # Subclass hooks.
    def _reset(self, s: SensorObs) -> None:
        pass

    def _advance(self, s: SensorObs) -> None:
        """Update the state estimate with the period that ``s`` closes."""

    def _twist(self, s: SensorObs) -> np.ndarray:
        raise NotImplementedError


class OpenLoopPolicy(ScriptedPolicy):
    """Feed-forward body twist R(θ_ref + ω_ref·dt/2)ᵀ·ṗ_ref; no feedback, no estimate."""

    name = "open-loop"

    def _twist(self, s: SensorObs) -> np.ndarray:
        vx_w, vy_w, om = s.ref_velocity
        mid = s.ref_pose[2] + 0.5 * om * self.dt
        c, si = math.cos(mid), math.sin(mid)
        return np.array([c * vx_w + si * vy_w, -si * vx_w + c * vy_w, om])


class PIDPolicy(ScriptedPolicy):
    """A pose estimator (subclass) followed by :class:`~agents.pid.PathPID`."""

    def __init__(self, env, gains: PIDGains | None = None) -> None:
        super().__init__(env)
        self.pid = PathPID(self.cfg.max_speed, self.cfg.max_yaw_rate, self.dt, gains)

    def reset(self, obs: np.ndarray) -> None:
        self.pid.reset()
        super().reset(obs)

    def _twist(self, s: SensorObs) -> np.ndarray:
        return self.pid.update(self.estimate, s.ref_pose, s.ref_velocity)


class OdometryPIDPolicy(PIDPolicy):
    """Dead reckoning (encoders by least-squares forward kinematics, gyro yaw rate) + PID."""

    name = "odometry-pid"

    # Gyro offset tracking: near the reference's rest points (rest-to-rest segments stop at every
    # waypoint) wheel forces, hence slip, vanish, so the encoders' yaw rate is the true one and
    # gyro − encoder yaw rate measures the gyro's offset. Each contiguous rest window gives one such
    # measurement: summed over the window, the quantised encoder angles telescope (error: two uniform
    # quantisation errors per wheel, whatever the window's length). The gate uses the reference, not
    # the noisy encoder rates (gating on those would select quantisation errors). Windows are fused
    # with the reset reading by a scalar Kalman filter, so quantisation never spoils a better prior
    # (e.g. with noiseless sensors).
    CALIB_SPEED = 0.03  # m/s: reference speed below which a period counts as near-standstill
    CALIB_YAW_RATE = 0.1  # rad/s: same for the reference yaw rate

    def __init__(self, env, gains: PIDGains | None = None) -> None:
        super().__init__(env, gains)
        self._pinv = np.linalg.pinv(self.W)  # (3, n): W⁺, least-squares twist from wheel speeds
        sc = self.cfg.sensor_config()
        quantum = 2.0 * math.pi / sc.counts_per_rev
        # Yaw-angle variance of one window's quantisation error [rad²]: per wheel, the difference of two
        # uniform errors has variance q²/6.
        self._window_q_var = float(np.sum(self._pinv[2] ** 2)) * quantum**2 / 6.0
        self._gyro_var = sc.gyro_noise_std**2  # [rad²/s²] per reading
        self._walk_var = sc.gyro_bias_walk_std**2  # [rad²/s³]
        self.gyro_offset = 0.0  # zero-rate offset estimate [rad/s]
        self.gyro_offset_var = 0.0  # its variance [rad²/s²]
        self._win_sum = 0.0  # Σ (gyro − encoder yaw rate)·dt over the current rest window [rad]
        self._win_n = 0  # periods in it
        self._calib_ref = np.zeros(3)  # reference velocity at the start of the period being closed
        self._last_gyro = 0.0  # gyro reading at the start of that period [rad/s]

    def _reset(self, s: SensorObs) -> None:
        self.estimate = np.array(s.ref_pose, dtype=float)
        self.gyro_offset = s.gyro  # at rest: the reading is bias + noise
        self.gyro_offset_var = self._gyro_var
        self._win_sum, self._win_n = 0.0, 0
        self._calib_ref = np.array(s.ref_velocity, dtype=float)
        self._last_gyro = s.gyro

    def _close_window(self) -> None:
        """Fuse the finished rest window's offset measurement into the estimate."""
        if self._win_n == 0:
            return
        span = self._win_n * self.dt
        z = self._win_sum / span
        r = self._window_q_var / span**2 + self._gyro_var / self._win_n
        gain = self.gyro_offset_var / (self.gyro_offset_var + r) if self.gyro_offset_var + r > 0 else 0.0
        self.gyro_offset += gain * (z - self.gyro_offset)
        self.gyro_offset_var *= 1.0 - gain
        self._win_sum, self._win_n = 0.0, 0

    def _advance(self, s: SensorObs) -> None:
        vx, vy, om_enc = self._pinv @ s.encoder_rates  # mean body twist over the period
        self.gyro_offset_var += self._walk_var * self.dt
        ref = self._calib_ref
        if math.hypot(ref[0], ref[1]) < self.CALIB_SPEED and abs(ref[2]) < self.CALIB_YAW_RATE:
            # The encoders give the period's mean rate; so does the mean of the gyro at its two ends
            # (the end reading alone is ahead by ω̇·dt/2, which does not cancel over a short window).
            self._win_sum += (0.5 * (s.gyro + self._last_gyro) - om_enc) * self.dt
            self._win_n += 1
        else:
            self._close_window()
        self._calib_ref = np.array(s.ref_velocity, dtype=float)
        self._last_gyro = s.gyro
        om = s.gyro - self.gyro_offset
        x, y, th = self.estimate
        mid = th + 0.5 * om * self.dt
        c, si = math.cos(mid), math.sin(mid)
        self.estimate = np.array([x + (c * vx - si * vy) * self.dt, y + (si * vx + c * vy) * self.dt,
                                  th + om * self.dt])


class EKFPIDPolicy(PIDPolicy):
    """:class:`agents.ekf.OmniEKF` + PID; the filter starts at rest at the reset reference pose."""

    name = "ekf-pid"

    def __init__(self, env, gains: PIDGains | None = None) -> None:
        super().__init__(env, gains)
        from agents.ekf import EKFConfig, OmniEKF

        self.ekf = OmniEKF(self.kinematics, EKFConfig.for_env(env))

    def _reset(self, s: SensorObs) -> None:
        self.ekf.reset(np.array(s.ref_pose, dtype=float))
        self.estimate = np.array(self.ekf.pose, dtype=float)

    def _advance(self, s: SensorObs) -> None:
        self.ekf.process(s, self.dt)
        self.estimate = np.array(self.ekf.pose, dtype=float)


class EKFPIDTractionPolicy(EKFPIDPolicy):
    """``ekf-pid`` with :class:`agents.traction.TractionLimiter` on the PID's output.

    The limiter is built from the environment's nominal model (robot, surface, centre of mass; not the
    per-episode randomisation, which a policy cannot observe) and, for a model that lifts wheels, the
    intersection over the lift-off process's contact cases. A limited axis counts as saturated for the
    PID's anti-windup (:class:`agents.traction.LimitedPathPID`).
    """

    name = "ekf-pid-traction"
    MODE = "static"  # the LP bound; "moving" measured worse on Williams (holds the twist while a gap wheel drags)
    MARGIN = 1.0

    def __init__(self, env, gains: PIDGains | None = None) -> None:
        super().__init__(env, gains)
        from agents.traction import LimitedPathPID, TractionLimiter

        model = self.cfg.base_model()
        self.limiter = TractionLimiter(model.robot, model.surface, mode=self.MODE, margin=self.MARGIN,
                                       com=model.com)
        self.pid = LimitedPathPID(self.limiter, self.cfg.max_speed, self.cfg.max_yaw_rate, self.dt, gains)


# The scripted policies by name (``--policy``), in the order tables and messages list them.
POLICIES: Registry[type[ScriptedPolicy]] = Registry(
    "policy", [(c.name, c) for c in (OpenLoopPolicy, OdometryPIDPolicy, EKFPIDPolicy, EKFPIDTractionPolicy)])
POLICY_NAMES = POLICIES.names()


def make_policy(name: str, env, gains: PIDGains | None = None) -> ScriptedPolicy:
    """The scripted policy ``name`` (one of :data:`POLICY_NAMES`) for ``env`` (obs_mode='sensors')."""
    cls = POLICIES.get(name)
    if gains is not None and not issubclass(cls, PIDPolicy):
        raise ValueError(f"policy {name!r} takes no PID gains")
    return cls(env) if gains is None else cls(env, gains)
