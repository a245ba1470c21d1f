"""Path-following PID for omnidirectional robots: world-frame position loop, heading loop, body-twist output.

Given an estimated pose p̂ = (x̂, ŷ, θ̂), the reference pose p_r and the reference world velocity ṗ_r,
each control step computes, per world axis j ∈ {x, y} and for the heading,

    e      = p_r − p̂                     (heading error wrapped to (−π, π])
    u      = ṗ_r  +  Kp·e  +  I  +  Kd·ḋ     I = ∫ Ki·e dt (output units), ḋ = low-passed de/dt
    (vx, vy) = R(θ̂ + ω·dt/2)ᵀ·(u_x, u_y)    (body frame, rotated at the mid-period heading)

and saturates the body twist to the action limits: the translation is scaled down as a whole (its
direction is kept) until |vx|, |vy| ≤ max_speed, and ω is clipped to ±max_yaw_rate.

Design choices:

* **Feed-forward** ṗ_r carries the motion; the feedback only has to remove errors. With ideal
  velocity-source wheels and no slip, the feed-forward alone tracks (``test_policies.py``).
* **Integral with clamping anti-windup** (conditional integration): an axis' integrator does not
  integrate while the output it feeds is saturated *and* its error pushes further into saturation;
  each integral term is also hard-limited to ``i_limit_*``. Slip makes the robot consistently cover less
  ground than commanded (roller-gap contact, a lifted wheel); the integral supplies that missing
  velocity so the position error does not stay proportional to the speed.
* **Derivative on the error, filtered**: ḋ is the backward difference of e, passed through a
  first-order low-pass with time constant ``d_tau``. The references are smooth (quintics), so
  differentiating the error gives no kick, and unlike the derivative on the measurement it does not
  fight the feed-forward (it adds Kd·(ṗ_r − ṗ̂), a velocity-error term). The first step after
  :meth:`PathPID.reset` uses a zero derivative.

Gains and why (the plant is, to first order, an integrator from commanded to actual velocity, with a
one-period delay of 10 ms and a slip factor: the robot realises a fraction g ≈ 0.6–1 of the command):

* ``kp_pos`` = 3 1/s ((m/s)/m): the closed position loop s² + g·Kp·s + g·Ki has its bandwidth near
  g·Kp ≈ 2–3 rad/s, a time constant of ~0.4 s — far below the 100 Hz control rate and the 10 Hz camera
  fixes the estimator leans on, so estimator noise (a few mm) is not amplified into jerky commands,
  and a 5 cm error asks for 0.15 m/s, well within the 0.6 m/s limit.
* ``ki_pos`` = 2 1/s² ((m/s)/(m·s)): ζ = Kp/(2·√Ki) ≈ 1.06 at g = 1 (no overshoot) and ≈ 0.8 at g = 0.6.
* ``kd_pos`` = 0.1 (dimensionless, (m/s)/(m/s)): a light velocity-error term; larger values mostly
  feed the estimator's velocity noise through.
* ``kp_head`` = 4 1/s, ``ki_head`` = 3 1/s², ``kd_head`` = 0.05: the heading is measured better (gyro
  at 100 Hz, compass, camera) and a heading error rotates every later feed-forward step, so its loop
  is a little faster (ζ ≈ 1.15).
* ``d_tau`` = 0.05 s: the derivative is low-passed at ~3 Hz, above the loop bandwidth but below the
  10 Hz camera-correction steps of the estimate.
* ``i_limit_pos`` = 0.15 m/s, ``i_limit_head`` = 0.5 rad/s: the most the integrators may add, about a
  third of the reference's peak speed (0.47 m/s) — enough to make up for slip, bounded if the estimate
  goes wrong.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.angles import wrap_angle


@dataclass(frozen=True)
class PIDGains:
    """Gains of :class:`PathPID` (see the module docstring for the reasoning)."""

    kp_pos: float = 3.0  # 1/s
    ki_pos: float = 2.0  # 1/s²
    kd_pos: float = 0.1  # dimensionless
    kp_head: float = 4.0  # 1/s
    ki_head: float = 3.0  # 1/s²
    kd_head: float = 0.05  # dimensionless
    d_tau: float = 0.05  # s, derivative low-pass time constant
    i_limit_pos: float = 0.15  # m/s, bound on each position integral term
    i_limit_head: float = 0.5  # rad/s, bound on the heading integral term

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"PIDGains.{name} must be a finite number >= 0, got {value!r}")


def configure_pid(pid, max_speed: float, max_yaw_rate: float, dt: float, gains: PIDGains | None,
                  anti_windup: bool) -> None:
    """Check the limits and set the limits, gains and per-axis gain vectors (x, y, θ) of a path PID
    (:class:`PathPID` and the batched one share them)."""
    for name, value in (("max_speed", max_speed), ("max_yaw_rate", max_yaw_rate), ("dt", dt)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    pid.max_speed = float(max_speed)
    pid.max_yaw_rate = float(max_yaw_rate)
    pid.dt = float(dt)
    pid.gains = PIDGains() if gains is None else gains
    pid.anti_windup = anti_windup
    g = pid.gains
    pid._kp = np.array([g.kp_pos, g.kp_pos, g.kp_head])
    pid._ki = np.array([g.ki_pos, g.ki_pos, g.ki_head])
    pid._kd = np.array([g.kd_pos, g.kd_pos, g.kd_head])
    pid._ilim = np.array([g.i_limit_pos, g.i_limit_pos, g.i_limit_head])


class PathPID:
    """World-frame position + heading PID with feed-forward; outputs a saturated body twist (vx, vy, ω).

    Args:
        max_speed: |vx|, |vy| limit [m/s] (the env's ``cfg.max_speed``).
        max_yaw_rate: |ω| limit [rad/s] (``cfg.max_yaw_rate``).
        dt: control period [s].
        gains: :class:`PIDGains`.
        anti_windup: False disables conditional integration (for tests and comparisons only).

    State after each :meth:`update`: ``integral`` (3,) — the integral terms in output units (m/s, m/s,
    rad/s, world frame), ``derivative`` (3,) — the filtered error rates, ``saturated`` (2,) bools
    (translation, rotation), ``error`` (3,) — the last error (x, y [m], θ [rad]).
    """

    def __init__(self, max_speed: float, max_yaw_rate: float, dt: float, gains: PIDGains | None = None,
                 anti_windup: bool = True) -> None:
        configure_pid(self, max_speed, max_yaw_rate, dt, gains, anti_windup)
        self.reset()

    def reset(self) -> None:
        """Zero the integrators and the derivative filter (call at the start of every episode)."""
        self.integral = np.zeros(3)
        self.derivative = np.zeros(3)
        self.error = np.zeros(3)
        self.saturated = np.zeros(2, dtype=bool)
        self._prev_error: np.ndarray | None = None

    def update(self, pose: np.ndarray, ref_pose: np.ndarray, ref_velocity: np.ndarray) -> np.ndarray:
        """Body twist (vx, vy, ω) [m/s, m/s, rad/s] within the limits, for one control period.

        Args:
            pose: estimated pose (x, y, θ) [m, m, rad], world frame.
            ref_pose: reference pose (x, y, θ) now.
            ref_velocity: reference world velocity (ẋ, ẏ, θ̇) now (the feed-forward).
        """
        x, y, th = (float(v) for v in pose)
        e = np.array([ref_pose[0] - x, ref_pose[1] - y, wrap_angle(float(ref_pose[2]) - th)])
        dt = self.dt
        if self._prev_error is None:
            rate = np.zeros(3)
        else:
            de = e - self._prev_error
            de[2] = wrap_angle(de[2])
            rate = de / dt
        self._prev_error = e
        self.error = e
        self.derivative += dt / (self.gains.d_tau + dt) * (rate - self.derivative)

        # Unsaturated command with the integral of the previous steps; integrate after saturating.
        u = np.asarray(ref_velocity, dtype=float) + self._kp * e + self.integral + self._kd * self.derivative
        body, sat_t, sat_r = self._saturate(u, th)
        self.saturated[:] = (sat_t, sat_r)

        step = self._ki * e * dt
        if self.anti_windup:
            # Freeze an axis while its output is saturated and its error would push further out.
            pushing = e * u > 0
            freeze = np.array([sat_t, sat_t, sat_r]) & pushing
            step = np.where(freeze, 0.0, step)
        self.integral += step
        if self.anti_windup:
            np.clip(self.integral, -self._ilim, self._ilim, out=self.integral)
        return body

    def _saturate(self, u: np.ndarray, th: float) -> tuple[np.ndarray, bool, bool]:
        """World command u → body twist within the limits; (twist, translation saturated, rotation saturated)."""
        om = float(np.clip(u[2], -self.max_yaw_rate, self.max_yaw_rate))
        sat_r = abs(u[2]) > self.max_yaw_rate
        mid = th + 0.5 * om * self.dt  # heading at mid-period: the twist is held over the whole period
        c, s = math.cos(mid), math.sin(mid)
        vx, vy = c * u[0] + s * u[1], -s * u[0] + c * u[1]
        peak = max(abs(vx), abs(vy))
        sat_t = peak > self.max_speed
        if sat_t:
            vx, vy = vx * self.max_speed / peak, vy * self.max_speed / peak
        return np.array([vx, vy, om]), sat_t, sat_r
