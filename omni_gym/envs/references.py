"""Reference trajectories of the environments, drawn at reset and sampled once into tables.

Every family starts at rest at the robot's start pose (the reference pose at t = 0) and is sampled
at the control rate over the episode plus the longest look-ahead, so that observations only index
tables (cheap and identical for single and vectorised environments). ``ref_heading`` sets the heading
along the path: ``forward`` (default: the body +y axis, the robots' front, points along the path),
``tangent`` (body +x along the path) or ``random``.

| family | path | speed |
|---|---|---|
| ``waypoints`` | rest-to-rest quintics through random waypoints in the arena | peak ≈ 1.9·ref_speed per segment |
| ``circle`` | circle through the start, radius 0.25–0.45·arena_half_size | ref_speed after a 1 s ramp |
| ``figure_eight`` | lemniscate of Gerono of random size through the start | ≈ ref_speed after a 1 s ramp |
| ``line`` | the paper's straight line, quintic time scaling, constant heading | mean ref_speed |
| ``goto`` | one quintic to a random goal pose (Phunopas & Inoue 2018), then hold | mean ≈ ref_speed |
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.envs.config import EnvConfig
from omni_gym.physics.traction import ReferenceUse, TractionLimiter, reference_use
from omni_gym.trajectories import Circle, FigureEight, Quintic, StraightLine, Trajectory

RAMP_SECONDS = 1.0  # s, smooth start of the periodic paths
SETTLE_SECONDS = 1.0  # s at the end of line and goto references, holding the goal


@numba.njit(cache=True)
def _sample_rest_to_rest(waypoints, durations, t, out_pose, out_vel):
    """Rest-to-rest quintic segments through ``waypoints`` (S+1, 3) at increasing times ``t`` [s].

    Segment s moves from waypoint s to s+1 in durations[s] as S(u) = S_s + Δ·(10u³ − 15u⁴ + 6u⁵),
    u = τ/T (Phunopas & Inoue 2018, eq. 4 with zero boundary velocity and acceleration); the last
    waypoint is held afterwards.
    """
    seg = 0
    start = 0.0
    n_seg = durations.shape[0]
    for k in range(t.shape[0]):
        while seg < n_seg - 1 and t[k] >= start + durations[seg]:
            start += durations[seg]
            seg += 1
        T = durations[seg]
        u = min(max((t[k] - start) / T, 0.0), 1.0)
        shape = u * u * u * (10.0 + u * (-15.0 + 6.0 * u))
        rate = u * u * (30.0 + u * (-60.0 + 30.0 * u)) / T
        for c in range(3):
            delta = waypoints[seg + 1, c] - waypoints[seg, c]
            out_pose[k, c] = waypoints[seg, c] + delta * shape
            out_vel[k, c] = delta * rate


def _ramp(t: np.ndarray, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """Time warp τ(t) with τ'(0) = 0 rising smoothly (quintic blend) to τ' = 1 at t = ramp."""
    u = np.clip(t / ramp, 0.0, 1.0)
    tau_rate = u**3 * (10.0 - 15.0 * u + 6.0 * u**2)
    tau = np.where(t < ramp, ramp * u**4 * (2.5 - 3.0 * u + u**2), ramp / 2.0 + (t - ramp))
    return tau, tau_rate


def _sample(traj: Trajectory, t: np.ndarray, ramp: float | None) -> tuple[np.ndarray, np.ndarray]:
    if ramp is None:
        pose, vel, _ = traj.sample(t)
        return pose, vel
    tau, rate = _ramp(t, ramp)
    pose, vel, _ = traj.sample(tau)
    return pose, vel * rate[:, None]


def _lemniscate_length(half_width: float) -> float:
    phi = np.linspace(0.0, 2.0 * math.pi, 4001)
    x, y = half_width * np.sin(phi), half_width / 2.0 * np.sin(2.0 * phi)
    return float(np.sum(np.hypot(np.diff(x), np.diff(y))))


def _waypoint_reference(cfg: EnvConfig, rng: np.random.Generator, offset: float) -> Sampler:
    """Rest-to-rest quintics through random waypoints until the segments fill the episode.

    Waypoints lie 0.4–0.9 arena half-sizes apart, inside the arena's inner 70 %; each segment lasts
    as long as QuinticWaypoints would make it (peak speed 1.875·ref_speed, yaw rate ≤ 1 rad/s). With
    ``ref_turn="before"`` each heading change is a rest-to-rest turn in place of its own before the
    translation (same peak yaw rate), which then keeps its heading. Candidate
    steps are drawn in blocks and the loop runs on Python floats: resets are frequent in training
    (thousands per second in a large vector) and building arrays per waypoint cost more than a step.
    """
    h = cfg.arena_half_size
    inner = 0.7 * h
    peak, yaw_rate = 1.875 * cfg.ref_speed, 1.0
    x = y = heading = 0.0
    pts, durations, total = [[0.0, 0.0, 0.0]], [], 0.0
    block = rng.uniform(size=(64, 3)).tolist()
    used = 0
    while total < cfg.episode_seconds and len(pts) <= 50:
        for _ in range(100):
            if used == len(block):
                block, used = rng.uniform(size=(64, 3)).tolist(), 0
            u_ang, u_dist, turn_draw = block[used]
            ang = math.pi * (2.0 * u_ang - 1.0)
            dist = (0.4 + 0.5 * u_dist) * h
            used += 1
            nx, ny = x + dist * math.cos(ang), y + dist * math.sin(ang)
            if abs(nx) <= inner and abs(ny) <= inner:
                break
        nx, ny = min(max(nx, -inner), inner), min(max(ny, -inner), inner)
        if cfg.ref_heading == "random":
            turn = math.pi * (turn_draw - 0.5)
        else:  # arrive facing along the segment (tangent) or with the forward (+y) axis along it
            target = math.atan2(ny - y, nx - x) + offset
            if len(pts) == 1:  # the start pose already faces the first segment
                heading = target
                pts[0][2] = target
            turn = wrap_angle(target - heading)
        if cfg.ref_turn == "before" and turn != 0.0:
            # Turn in place first, then translate at the new heading: a three-wheeled robot on carpet can
            # hold straight motion along its strong axis but not the sweep of body directions a turn
            # during translation asks for (docs/agents.md, "Traction-aware baseline").
            # Peak yaw rate 1 rad/s, and peak yaw acceleration (10/√3)·|turn|/T² ≤ 1 rad/s² (v0's largest):
            # a small turn would otherwise be a jerk.
            durations.append(max(15.0 / 8.0 * abs(turn) / yaw_rate, math.sqrt(10.0 / math.sqrt(3.0) * abs(turn))))
            heading += turn
            pts.append([x, y, heading])
            total += durations[-1]
            turn = 0.0
        durations.append(15.0 / 8.0 * max(math.hypot(nx - x, ny - y) / peak, abs(turn) / yaw_rate))
        total += durations[-1]
        x, y, heading = nx, ny, heading + turn
        pts.append([x, y, heading])
    waypoints, seconds = np.array(pts), np.array(durations)

    def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pose, vel = np.empty((len(t), 3)), np.empty((len(t), 3))
        _sample_rest_to_rest(waypoints, seconds, t, pose, vel)
        return pose, vel

    return sample


Sampler = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]  # times [s] -> (poses (K, 3), velocities (K, 3))
MAX_STRETCH = 8.0  # a reference is slowed down at most this much to fit the wheels' traction


@dataclass(frozen=True)
class TaskReference:
    """A drawn reference: ``pose`` (n, 3) and world ``velocity`` (n, 3) at t = k / control_hz; ``stretch``, how
    much slower than drawn it runs to fit the wheels' traction (1: as drawn); ``use``, the share of the
    friction set it asks for (:class:`omni_gym.physics.traction.ReferenceUse`; None without a limiter)."""

    pose: np.ndarray
    velocity: np.ndarray
    stretch: float = 1.0
    use: ReferenceUse | None = None

    @property
    def feasible(self) -> bool | None:
        """Whether the wheels can transmit what it asks (its peak use ≤ 1); None without a limiter."""
        return None if self.use is None else self.use.peak <= 1.0


def allowed_use(steady: float, ref_traction: float) -> float:
    """The largest share of the friction set a reference may ask for: its steady part (the rolling resistance
    of the motion itself, which no slowing lowers) plus ``ref_traction`` of what is left for accelerating."""
    return steady + ref_traction * (1.0 - steady) if steady < 1.0 else steady


def draw_reference(cfg: EnvConfig, rng: np.random.Generator, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(poses (n_samples, 3), world velocities (n_samples, 3)) at t = k / control_hz, as drawn (no traction
    fitting: :func:`draw_task_reference` does that).

    All random draws come from ``rng``, in a fixed order per family.
    """
    t = np.arange(n_samples) / cfg.control_hz
    return _sampler(cfg, rng)(t)


def draw_task_reference(cfg: EnvConfig, rng: np.random.Generator, n_samples: int,
                        limiter: TractionLimiter | None = None) -> TaskReference:
    """The reference an environment drives: :func:`draw_reference`'s, slowed down to fit the wheels' traction.

    With a ``limiter`` (the model's friction set, ``omni_gym.physics.traction``, "moving" mode) and
    ``cfg.ref_traction`` = r > 0, a reference runs slower by a time stretch s (poses at t/s, velocities /s)
    until its peak use over the episode is within :func:`allowed_use`: its steady part u_s (the motion's own
    rolling resistance, which no slowing lowers) plus r of the rest, u ≤ u_s + r·(1 − u_s). Accelerations
    fall as 1/s², so the use falls towards u_s; s stops at :data:`MAX_STRETCH`. With r = 1 only references the
    wheels cannot follow at all (u > 1) are slowed; a smaller r keeps headroom for the feedback's corrections.
    A reference whose steady part alone exceeds 1 asks what no speed makes possible (``feasible`` tells).
    The draws from ``rng`` are the same as :func:`draw_reference`'s: fitting changes no later draw.
    """
    t = np.arange(n_samples) / cfg.control_hz
    sample = _sampler(cfg, rng)
    pose, vel = sample(t)
    if limiter is None:
        return TaskReference(pose, vel)
    driven = cfg.episode_steps + 1  # the look-ahead tail beyond the episode is seen, never driven
    use = reference_use(limiter, pose[:driven], vel[:driven], cfg.control_dt)
    stretch = 1.0
    while cfg.ref_traction > 0 and use.peak > allowed_use(use.steady, cfg.ref_traction) and stretch < MAX_STRETCH:
        target = allowed_use(use.steady, cfg.ref_traction)
        factor = math.sqrt((use.peak - use.steady) / (target - use.steady)) if target > use.steady else MAX_STRETCH
        stretch = min(MAX_STRETCH, stretch * max(1.02, 1.02 * factor))  # 2 %: the steady part moves with s too
        pose, vel = sample(t / stretch)
        vel /= stretch
        use = reference_use(limiter, pose[:driven], vel[:driven], cfg.control_dt)
    return TaskReference(pose, vel, stretch, use)


def _sampler(cfg: EnvConfig, rng: np.random.Generator) -> Sampler:
    """Draw a reference of ``cfg``'s family from ``rng`` (every draw now, in a fixed order) and return its
    sampler: times [s] → (poses, world velocities)."""
    T = cfg.episode_seconds
    h = cfg.arena_half_size
    fam = cfg.trajectory
    ramp = None
    # Heading rule: body x along the path ("tangent"), body +y along it ("forward": the front of both
    # preset robots, between the front wheels of williams2002), or random constant headings.
    offset = -math.pi / 2 if cfg.ref_heading == "forward" else 0.0
    const_heading = rng.uniform(-math.pi, math.pi) if cfg.ref_heading == "random" else 0.0
    heading = const_heading if cfg.ref_heading == "random" else "tangent"
    if fam == "waypoints":
        return _waypoint_reference(cfg, rng, offset)
    elif fam == "circle":
        radius = rng.uniform(0.25, 0.45) * h  # the circle passes through the start: it spans 2·radius
        clockwise = bool(rng.integers(2))
        period = 2.0 * math.pi * radius / cfg.ref_speed
        # Start at the origin with the tangent heading 0: centre to the left (ccw) or right (cw).
        center = (0.0, -radius) if clockwise else (0.0, radius)
        phase = math.pi / 2 if clockwise else -math.pi / 2
        traj = Circle(center, radius, period, phase=phase, clockwise=clockwise, heading=heading,
                      laps=T * MAX_STRETCH / period + 1)
        ramp = RAMP_SECONDS
    elif fam == "figure_eight":
        a = rng.uniform(0.5, 0.8) * h
        period = _lemniscate_length(a) / cfg.ref_speed
        traj = FigureEight((0.0, 0.0), a, period, clockwise=bool(rng.integers(2)), heading=heading,
                           laps=T * MAX_STRETCH / period + 1)
        ramp = RAMP_SECONDS
    elif fam == "line":
        motion = max(T - SETTLE_SECONDS, 0.5)
        ang = rng.uniform(-math.pi, math.pi)
        dist = min(cfg.ref_speed * motion, 0.9 * h)
        goal = (dist * math.cos(ang), dist * math.sin(ang))
        line_heading = const_heading if cfg.ref_heading == "random" else ang + offset
        traj = StraightLine((0.0, 0.0), goal, motion, heading=line_heading)
    else:  # goto
        motion = max(T - SETTLE_SECONDS, 0.5)
        ang = rng.uniform(-math.pi, math.pi)
        dist = min(cfg.ref_speed * motion, 0.8 * h) * rng.uniform(0.6, 1.0)
        goal = (dist * math.cos(ang), dist * math.sin(ang), rng.uniform(-math.pi / 2, math.pi / 2))
        traj = Quintic((0.0, 0.0, 0.0), goal, motion)
    turned = fam in ("circle", "figure_eight") and cfg.ref_heading != "random"

    def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pose, vel = _sample(traj, t, ramp)
        if turned:
            pose[:, 2] += offset  # tangent heading, turned so the chosen body axis points along the path
        return pose, vel

    return sample
