"""Reference trajectories for omnidirectional robots.

Every trajectory maps time t [s] (a scalar or any array) to

* pose (x, y, θ) [m, m, rad], world frame (θ: angle from world x to body x, *not* wrapped, so it
  is continuous in t),
* world velocity (ẋ, ẏ, θ̇) [m/s, m/s, rad/s],
* world acceleration (ẍ, ÿ, θ̈) [m/s², m/s², rad/s²],

each of shape ``np.shape(t) + (3,)``, through :meth:`Trajectory.sample`. ``duration`` [s] is the
nominal length of the reference (the episode length it is meant for).

Heading options (``heading`` argument of :class:`StraightLine`, :class:`Circle`, :class:`FigureEight`):
a number gives a constant heading [rad]; ``"tangent"`` points the body x axis along the direction
of travel.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.checks import finite_array, finite_scalar, positive
from omni_gym.physics.kinematics import forward, inverse, world_to_body
from omni_gym.physics.robot import RobotSpec

TWO_PI = 2.0 * math.pi


# --- validation helpers ---------------------------------------------------------------------------


def _times(t: float | np.ndarray) -> np.ndarray:
    """Sample times as a float array; ValueError if any is NaN/inf."""
    arr = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError("t must be finite (no NaN/inf)")
    return arr


def _heading_option(heading: float | str) -> float | str:
    """Validate a heading option: a finite constant [rad] or the string "tangent"."""
    if isinstance(heading, str):
        if heading != "tangent":
            raise ValueError(f"heading must be a number [rad] or 'tangent', got {heading!r}")
        return heading
    return finite_scalar("heading", heading)




def _stack(x: np.ndarray, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Stack three equally shaped arrays into one (..., 3) array."""
    return np.stack(np.broadcast_arrays(x, y, theta), axis=-1)


# --- base class ----------------------------------------------------------------------------------


class Trajectory(ABC):
    """A reference motion: ``sample(t)`` → (pose, velocity, acceleration), each (..., 3), world frame."""

    duration: float

    @abstractmethod
    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose [m, m, rad], world velocity [m/s, m/s, rad/s] and acceleration at time(s) ``t`` [s]."""

    def pose(self, t: float | np.ndarray) -> np.ndarray:
        """World pose (x, y, θ) [m, m, rad] at ``t`` [s], shape (..., 3)."""
        return self.sample(t)[0]

    def velocity(self, t: float | np.ndarray) -> np.ndarray:
        """World velocity (ẋ, ẏ, θ̇) [m/s, m/s, rad/s] at ``t`` [s], shape (..., 3)."""
        return self.sample(t)[1]

    def acceleration(self, t: float | np.ndarray) -> np.ndarray:
        """World acceleration (ẍ, ÿ, θ̈) [m/s², m/s², rad/s²] at ``t`` [s], shape (..., 3)."""
        return self.sample(t)[2]

    def body_twist(self, t: float | np.ndarray) -> np.ndarray:
        """Reference body twist (vx, vy, ω) [m/s, m/s, rad/s] at ``t`` [s], shape (..., 3)."""
        pose, vel, _ = self.sample(t)
        return world_to_body(vel, pose[..., 2])

    def wheel_speeds(self, robot: RobotSpec, t: float | np.ndarray) -> np.ndarray:
        """No-slip feed-forward wheel speeds [rad/s] of ``robot`` at ``t`` [s], shape (..., n_wheels)."""
        return inverse(robot, self.body_twist(t))


# --- quintic -------------------------------------------------------------------------------------


def quintic_coefficients(start: np.ndarray, goal: np.ndarray, duration: float) -> np.ndarray:
    """Coefficients (A, B, C, D, E, F) of S(t) = At⁵+Bt⁴+Ct³+Dt²+Et+F for a rest-to-rest move.

    Boundary conditions S(0)=S₀, Ṡ(0)=S̈(0)=0, S(T)=S₁, Ṡ(T)=S̈(T)=0 give F=S₀, E=D=0 and, with
    Δ=S₁−S₀, the linear system  A T⁵+B T⁴+C T³=Δ,  5A T⁴+4B T³+3C T²=0,  20A T³+12B T²+6C T=0,
    whose solution is A=6Δ/T⁵, B=−15Δ/T⁴, C=10Δ/T³. ``start``/``goal`` shape (k,) → result (k, 6).
    """
    s0, s1 = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    d, T = s1 - s0, float(duration)
    zero = np.zeros_like(d)
    return np.stack([6 * d / T**5, -15 * d / T**4, 10 * d / T**3, zero, zero, s0], axis=-1)


class Quintic(Trajectory):
    """Rest-to-rest fifth-order polynomial per coordinate (Phunopas & Inoue 2018, eqs. 4–6).

    S(t) = At⁵+Bt⁴+Ct³+Dt²+Et+F, Ṡ(t) = 5At⁴+4Bt³+3Ct²+2Dt+E, S̈(t) = 20At³+12Bt²+6Ct+2D for each
    of x, y, θ, with zero velocity and acceleration at t=0 and t=duration. Before t=0 the start pose
    is held, after ``duration`` the goal pose (velocity and acceleration zero). The heading moves
    from start θ to goal θ literally (a 2π difference is a full turn) unless ``shortest_turn``.
    Peak speed per coordinate is 15/8·|Δ|/T, at t=T/2.
    """

    def __init__(self, start_pose: np.ndarray, goal_pose: np.ndarray, duration: float,
                 shortest_turn: bool = False) -> None:
        self.start_pose = finite_array("start_pose", start_pose, (3,))
        goal = finite_array("goal_pose", goal_pose, (3,)).copy()
        if shortest_turn:
            goal[2] = self.start_pose[2] + wrap_angle(goal[2] - self.start_pose[2])
        self.goal_pose = goal
        self.duration = positive("duration", duration)
        self.coefficients = quintic_coefficients(self.start_pose, self.goal_pose, self.duration)

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose, velocity, acceleration at ``t`` [s], each shape np.shape(t) + (3,)."""
        t = _times(t)[..., None]
        tc = np.clip(t, 0.0, self.duration)
        A, B, C, D, E, F = (self.coefficients[:, k] for k in range(6))
        pose = ((((A * tc + B) * tc + C) * tc + D) * tc + E) * tc + F
        vel = (((5 * A * tc + 4 * B) * tc + 3 * C) * tc + 2 * D) * tc + E
        acc = ((20 * A * tc + 12 * B) * tc + 6 * C) * tc + 2 * D
        inside = (t > 0.0) & (t < self.duration)
        pose = np.where(t >= self.duration, self.goal_pose, pose)
        return pose, np.where(inside, vel, 0.0), np.where(inside, acc, 0.0)


class QuinticWaypoints(Trajectory):
    """Quintic segments through waypoints (x, y, θ), stopping at each one.

    Every segment is a rest-to-rest :class:`Quintic`, so the robot comes to rest at each waypoint:
    velocity and acceleration are continuous (both zero at the joints). Give either
    ``segment_durations`` [s] (one per segment) or ``speed``: the peak linear speed [m/s] of each
    segment, T = 15/8·distance/speed, lengthened where needed so the peak yaw rate stays within
    ``yaw_rate`` [rad/s]. After the last segment the final waypoint is held.
    """

    def __init__(self, waypoints: np.ndarray, segment_durations: Sequence[float] | None = None,
                 speed: float | None = None, yaw_rate: float = 1.0, shortest_turn: bool = False) -> None:
        wp = finite_array("waypoints", waypoints, (None, 3))
        if len(wp) < 2:
            raise ValueError(f"waypoints must hold at least 2 poses, got {len(wp)}")
        if (segment_durations is None) == (speed is None):
            raise ValueError("give exactly one of segment_durations and speed")
        if speed is not None:
            segment_durations = self._durations_from_speed(wp, positive("speed", speed),
                                                           positive("yaw_rate", yaw_rate), shortest_turn)
        durations = finite_array("segment_durations", segment_durations, (len(wp) - 1,))
        if np.any(durations <= 0):
            raise ValueError(f"segment_durations must all be > 0, got {durations}")
        self.waypoints = wp
        self.segments = self._build_segments(wp, durations, shortest_turn)
        self.start_times = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
        self.duration = float(np.sum(durations))
        self._coefficients = np.array([seg.coefficients for seg in self.segments])  # (segments, 3, 6)
        self._durations = np.array([seg.duration for seg in self.segments])
        self._goals = np.array([seg.goal_pose for seg in self.segments])

    @staticmethod
    def _durations_from_speed(wp: np.ndarray, speed: float, yaw_rate: float,
                              shortest_turn: bool) -> np.ndarray:
        """Segment durations [s] giving peak linear speed ``speed`` and yaw rate at most ``yaw_rate``."""
        dist = np.hypot(*np.diff(wp[:, :2], axis=0).T)
        turn = np.diff(wp[:, 2])
        turn = np.abs(wrap_angle(turn) if shortest_turn else turn)
        durations = 15.0 / 8.0 * np.maximum(dist / speed, turn / yaw_rate)
        if np.any(durations <= 0):
            i = int(np.argmin(durations))
            raise ValueError(f"waypoints {i} and {i + 1} are identical: cannot derive a duration from speed")
        return durations

    @staticmethod
    def _build_segments(wp: np.ndarray, durations: np.ndarray, shortest_turn: bool) -> tuple[Quintic, ...]:
        """Rest-to-rest quintics between consecutive waypoints; headings chained for continuity."""
        segments, start = [], wp[0]
        for goal, T in zip(wp[1:], durations, strict=True):
            seg = Quintic(start, goal, T, shortest_turn=shortest_turn)
            segments.append(seg)
            start = seg.goal_pose
        return tuple(segments)

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose, velocity, acceleration at ``t`` [s], each shape np.shape(t) + (3,).

        Each time is evaluated on its own segment's polynomial, gathered in one vectorised pass
        (the same formulas as :meth:`Quintic.sample`; environments sample thousands of times per reset).
        """
        t = _times(t)
        index = np.searchsorted(self.start_times[1:], t, side="right")
        local = (t - self.start_times[index])[..., None]
        duration = self._durations[index][..., None]
        coef = self._coefficients[index]
        tc = np.clip(local, 0.0, duration)
        A, B, C, D, E, F = (coef[..., k] for k in range(6))
        pose = ((((A * tc + B) * tc + C) * tc + D) * tc + E) * tc + F
        vel = (((5 * A * tc + 4 * B) * tc + 3 * C) * tc + 2 * D) * tc + E
        acc = ((20 * A * tc + 12 * B) * tc + 6 * C) * tc + 2 * D
        inside = (local > 0.0) & (local < duration)
        pose = np.where(local >= duration, self._goals[index], pose)
        return pose, np.where(inside, vel, 0.0), np.where(inside, acc, 0.0)


# --- step velocity (Williams et al. 2002) -------------------------------------------------------


def integrate_constant_twist(start_pose: np.ndarray, twist_body: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Pose (..., 3) [m, m, rad] after moving for ``t`` [s] with a constant body twist (vx, vy, ω).

    Closed form: θ(t) = θ₀ + ωt, p(t) = p₀ + R(θ₀)·M(t)·v with M = [[S, −C], [C, S]],
    S = sin(ωt)/ω and C = (1 − cos ωt)/ω. Written as S = t·sinc(ωt/π) and C = sin(ωt/2)·t·sinc(ωt/2π)
    (numpy's normalised sinc), which stays exact as ω → 0 (straight line, S → t, C → 0).
    """
    x0, y0, th0 = start_pose
    vx, vy, w = twist_body
    S = t * np.sinc(w * t / math.pi)
    C = np.sin(w * t / 2.0) * t * np.sinc(w * t / TWO_PI)
    dx_body, dy_body = S * vx - C * vy, C * vx + S * vy
    c, s = math.cos(th0), math.sin(th0)
    return _stack(x0 + c * dx_body - s * dy_body, y0 + s * dx_body + c * dy_body, th0 + w * t)


class StepVelocity(Trajectory):
    """Step wheel-speed profile of Williams et al. (2002): constant wheel speeds on at t=0, off at T.

    ``wheel_commands(t)`` gives the commanded wheel speeds [rad/s]. ``sample(t)`` gives the no-slip
    reference: the constant body twist q = forward(robot, wheel_speeds) (least squares for > 3
    wheels) integrated in closed form from ``start_pose``; the pose is held outside [0, T]. The
    acceleration is the smooth part only (centripetal ω × v while moving); the velocity steps at t=0
    and t=T are impulses that are not represented.
    """

    def __init__(self, wheel_speeds: np.ndarray, duration: float, robot: RobotSpec,
                 start_pose: np.ndarray = (0.0, 0.0, 0.0)) -> None:
        if not isinstance(robot, RobotSpec):
            raise ValueError(f"robot must be a RobotSpec, got {robot!r}")
        self.robot = robot
        self.wheel_speeds_cmd = finite_array("wheel_speeds", wheel_speeds, (robot.n_wheels,))
        self.duration = positive("duration", duration)
        self.start_pose = finite_array("start_pose", start_pose, (3,))
        self.twist_body = forward(robot, self.wheel_speeds_cmd)

    @classmethod
    def straight_line(cls, robot: RobotSpec, distance: float, duration: float, heading: float = 0.0,
                      direction: Sequence[float] = (1.0, 0.0),
                      start_position: Sequence[float] = (0.0, 0.0)) -> StepVelocity:
        """Constant wheel speeds that move ``distance`` [m] along world ``direction`` in ``duration`` [s].

        The heading stays at ``heading`` [rad]; the wheel speeds come from inverse kinematics of the
        body-frame twist R(heading)ᵀ·(distance/duration)·û, û the unit ``direction`` (world frame).
        """
        if not isinstance(robot, RobotSpec):
            raise ValueError(f"robot must be a RobotSpec, got {robot!r}")
        dist = finite_scalar("distance", distance)
        if dist < 0:
            raise ValueError(f"distance must be >= 0 (use direction for the sense), got {distance!r}")
        T = positive("duration", duration)
        th = finite_scalar("heading", heading)
        u = finite_array("direction", direction, (2,))
        norm = math.hypot(*u)
        if norm == 0:
            raise ValueError("direction must be a non-zero 2-vector")
        v_world = np.array([u[0], u[1], 0.0]) * (dist / T / norm)
        speeds = inverse(robot, world_to_body(v_world, th))
        p0 = finite_array("start_position", start_position, (2,))
        return cls(speeds, T, robot, start_pose=(p0[0], p0[1], th))

    def wheel_commands(self, t: float | np.ndarray) -> np.ndarray:
        """Commanded wheel speeds [rad/s] at ``t`` [s]: on for 0 ≤ t < T, else 0; shape (..., n)."""
        t = _times(t)[..., None]
        return np.where((t >= 0.0) & (t < self.duration), self.wheel_speeds_cmd, 0.0)

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """No-slip reference pose, world velocity and (smooth) acceleration at ``t`` [s]."""
        t = _times(t)
        pose = integrate_constant_twist(self.start_pose, self.twist_body, np.clip(t, 0.0, self.duration))
        vx, vy, w = self.twist_body
        c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
        xd, yd = c * vx - s * vy, s * vx + c * vy
        on = ((t >= 0.0) & (t < self.duration))[..., None]
        vel = np.where(on, _stack(xd, yd, np.full_like(xd, w)), 0.0)
        acc = np.where(on, _stack(-w * yd, w * xd, np.zeros_like(xd)), 0.0)
        return pose, vel, acc


# --- geometric paths -----------------------------------------------------------------------------


class StraightLine(Trajectory):
    """Straight line from ``start`` to ``goal`` (x, y) [m] with quintic time scaling over ``duration``.

    The position follows a rest-to-rest :class:`Quintic` (Williams et al.'s straight-line test, made
    smooth); the heading is constant: ``heading`` [rad] (default 0), or ``"tangent"`` for the
    direction from start to goal. Holds the goal after ``duration``.
    """

    def __init__(self, start: Sequence[float], goal: Sequence[float], duration: float,
                 heading: float | str = 0.0) -> None:
        p0 = finite_array("start", start, (2,))
        p1 = finite_array("goal", goal, (2,))
        heading = _heading_option(heading)
        if heading == "tangent":
            if np.allclose(p0, p1, rtol=0.0, atol=0.0):
                raise ValueError("heading='tangent' needs goal != start")
            heading = math.atan2(p1[1] - p0[1], p1[0] - p0[0])
        self.heading = float(heading)
        self._quintic = Quintic((p0[0], p0[1], self.heading), (p1[0], p1[1], self.heading), duration)
        self.duration = self._quintic.duration
        self.start, self.goal = p0, p1

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose, velocity, acceleration at ``t`` [s], each shape np.shape(t) + (3,)."""
        return self._quintic.sample(t)


class _PeriodicPath(Trajectory):
    """Common part of closed paths traversed at constant parameter rate φ̇ = ±2π/period.

    Subclasses give the planar point and its first three φ-derivatives; this class applies the chain
    rule (constant φ̇) and the heading option. Defined for every t (periodic);
    ``duration = laps · period``.
    """

    def __init__(self, center: Sequence[float], period: float, phase: float, clockwise: bool,
                 heading: float | str, laps: float) -> None:
        self.center = finite_array("center", center, (2,))
        self.period = positive("period", period)
        self.phase = finite_scalar("phase", phase)
        self.clockwise = bool(clockwise)
        self.heading = _heading_option(heading)
        self.laps = positive("laps", laps)
        self.duration = self.laps * self.period
        self.rate = (-1.0 if self.clockwise else 1.0) * TWO_PI / self.period  # φ̇ [rad/s]

    @abstractmethod
    def _path(self, phi: np.ndarray) -> tuple[np.ndarray, ...]:
        """(x, y, x', y', x'', y'', x''', y''') relative to the centre, primes = d/dφ."""

    @abstractmethod
    def _tangent_angle(self, phi: np.ndarray) -> np.ndarray:
        """Continuous (unwrapped) direction of d(x, y)/dφ [rad] for increasing φ."""

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose, velocity, acceleration at ``t`` [s], each shape np.shape(t) + (3,)."""
        t = _times(t)
        w = self.rate
        phi = self.phase + w * t
        x, y, x1, y1, x2, y2, x3, y3 = self._path(phi)
        xd, yd, xdd, ydd = w * x1, w * y1, w**2 * x2, w**2 * y2
        if self.heading == "tangent":
            theta = self._tangent_angle(phi) + (math.pi if self.clockwise else 0.0)
            th_d, th_dd = _tangent_rates(xd, yd, xdd, ydd, w**3 * x3, w**3 * y3)
        else:
            theta, th_d, th_dd = np.full_like(x, self.heading), np.zeros_like(x), np.zeros_like(x)
        pose = _stack(self.center[0] + x, self.center[1] + y, theta)
        return pose, _stack(xd, yd, th_d), _stack(xdd, ydd, th_dd)


def _tangent_rates(xd: np.ndarray, yd: np.ndarray, xdd: np.ndarray, ydd: np.ndarray, x3: np.ndarray,
                   y3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """θ̇ and θ̈ of the tangent angle atan2(ẏ, ẋ) from velocity, acceleration and jerk.

    θ̇ = N/D with N = ẋÿ − ẏẍ, D = ẋ² + ẏ²; θ̈ = (Ṅ D − N Ḋ)/D², Ṅ = ẋ y⃛ − ẏ x⃛, Ḋ = 2(ẋẍ + ẏÿ).
    """
    N, D = xd * ydd - yd * xdd, xd**2 + yd**2
    N_dot, D_dot = xd * y3 - yd * x3, 2.0 * (xd * xdd + yd * ydd)
    return N / D, (N_dot * D - N * D_dot) / D**2


class Circle(_PeriodicPath):
    """Circle of ``radius`` [m] about ``center`` [m], one lap per ``period`` [s].

    Position c + r(cos φ, sin φ), φ = phase ± 2πt/period (counter-clockwise unless ``clockwise``).
    Heading: a constant [rad] or ``"tangent"`` (φ ± π/2, unwrapped). Periodic for all t; ``duration``
    is ``laps · period``. Speed 2πr/period starts at t=0 without ramp.
    """

    def __init__(self, center: Sequence[float], radius: float, period: float, phase: float = 0.0,
                 clockwise: bool = False, heading: float | str = "tangent", laps: float = 1.0) -> None:
        self.radius = positive("radius", radius)
        super().__init__(center, period, phase, clockwise, heading, laps)

    def _path(self, phi: np.ndarray) -> tuple[np.ndarray, ...]:
        r, c, s = self.radius, np.cos(phi), np.sin(phi)
        return r * c, r * s, -r * s, r * c, -r * c, -r * s, r * s, -r * c

    def _tangent_angle(self, phi: np.ndarray) -> np.ndarray:
        return phi + math.pi / 2.0


class FigureEight(_PeriodicPath):
    """Figure eight (lemniscate of Gerono) about ``center`` [m], one lap per ``period`` [s].

    Position c + (a sin φ, (a/2) sin 2φ), a = ``half_width`` [m], φ = phase ± 2πt/period: the right
    lobe first for increasing φ, crossing the centre at 45°. Heading: a constant [rad] or
    ``"tangent"`` (continuous; the speed never vanishes on this curve). Periodic for all t;
    ``duration`` is ``laps · period``.
    """

    def __init__(self, center: Sequence[float] = (0.0, 0.0), half_width: float = 1.0, period: float = 20.0,
                 phase: float = 0.0, clockwise: bool = False, heading: float | str = "tangent",
                 laps: float = 1.0) -> None:
        self.half_width = positive("half_width", half_width)
        super().__init__(center, period, phase, clockwise, heading, laps)

    def _path(self, phi: np.ndarray) -> tuple[np.ndarray, ...]:
        a, s1, c1, s2, c2 = self.half_width, np.sin(phi), np.cos(phi), np.sin(2 * phi), np.cos(2 * phi)
        return a * s1, a / 2 * s2, a * c1, a * c2, -a * s1, -2 * a * s2, -a * c1, -4 * a * c2

    def _tangent_angle(self, phi: np.ndarray) -> np.ndarray:
        # Direction of (cos φ, cos 2φ). Over a lap the tangent turns −3π/2 (right lobe) then +3π/2
        # (left lobe), staying within [−5π/4, π/4]; centring the branch cut at −π/2 ± π keeps it
        # continuous: −π/2 + wrap(atan2(cos 2φ, cos φ) + π/2).
        raw = np.arctan2(np.cos(2 * phi), np.cos(phi))
        return -math.pi / 2.0 + wrap_angle(raw + math.pi / 2.0)


# --- random waypoints ----------------------------------------------------------------------------


def random_waypoints(rng: np.random.Generator, n: int, arena_half_size: float, margin: float = 0.0,
                     min_separation: float = 0.0, heading: float | str = "random",
                     start: Sequence[float] | None = None, max_tries: int = 1000) -> np.ndarray:
    """``n`` random waypoints (x, y, θ) [m, m, rad], shape (n, 3), inside a square arena.

    Positions are uniform in [−h + margin, h − margin]² (h = ``arena_half_size`` [m], world frame,
    centred on the origin); consecutive positions are at least ``min_separation`` [m] apart
    (rejection sampling, ValueError after ``max_tries`` failures for one point). ``heading``:
    ``"random"`` (uniform in (−π, π]), ``"tangent"`` (direction from the previous waypoint; the first
    takes the direction to the second) or a constant [rad]. ``start`` (x, y, θ), if given, is the
    first waypoint as is. All draws come from ``rng``.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {rng!r}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    half = positive("arena_half_size", arena_half_size) - finite_scalar("margin", margin)
    if half <= 0 or margin < 0:
        raise ValueError(f"margin must be in [0, arena_half_size), got {margin!r}")
    sep = finite_scalar("min_separation", min_separation)
    if sep < 0:
        raise ValueError(f"min_separation must be >= 0, got {min_separation!r}")
    if not isinstance(heading, str) or heading != "random":
        heading = _heading_option(heading)
    first = None if start is None else finite_array("start", start, (3,))
    xy = _random_positions(rng, n, half, sep, None if first is None else first[:2], max_tries)
    theta = _waypoint_headings(rng, xy, heading)
    if first is not None:
        theta[0] = first[2]
    return np.column_stack([xy, theta])


def _random_positions(rng: np.random.Generator, n: int, half: float, sep: float, first: np.ndarray | None,
                      max_tries: int) -> np.ndarray:
    """(n, 2) uniform positions in [−half, half]², consecutive ones at least ``sep`` apart."""
    points = [first] if first is not None else [rng.uniform(-half, half, size=2)]
    while len(points) < n:
        for _ in range(max_tries):
            p = rng.uniform(-half, half, size=2)
            if math.hypot(*(p - points[-1])) >= sep:
                break
        else:
            raise ValueError(f"min_separation {sep} unreachable in {max_tries} tries inside the arena")
        points.append(p)
    return np.array(points, dtype=float)


def _waypoint_headings(rng: np.random.Generator, xy: np.ndarray, heading: float | str) -> np.ndarray:
    """Headings [rad] for positions ``xy`` according to the ``heading`` option."""
    n = len(xy)
    if heading == "random":
        return -rng.uniform(-math.pi, math.pi, size=n)  # −U[−π, π) is uniform on (−π, π]
    if heading == "tangent":
        if n < 2:
            return np.zeros(n)
        steps = np.diff(xy, axis=0)
        angles = np.arctan2(steps[:, 1], steps[:, 0])
        return np.concatenate([[angles[0]], angles])
    return np.full(n, float(heading))
