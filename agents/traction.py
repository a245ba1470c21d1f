"""Traction-aware path following: the PID whose output goes through the traction limiter, and what a
reference asks of the wheels.

The friction set and the limiter itself (Williams et al. 2002, Sec. IV-B) are physics and live in
:mod:`omni_gym.physics.traction`, where the environments also use them to draw references the wheels can
follow; they are re-exported here for the policies.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from agents.pid import PathPID, PIDGains
from agents.registry import Registry
from omni_gym.envs.config import EnvConfig
from omni_gym.physics.traction import (
    TRACTION_MODES,
    TractionLimiter,
    reference_use,
    wrench_facets,
    wrench_generators,
)

__all__ = ["MODES", "LimitedPathPID", "ReferenceDemand", "TractionLimiter", "reference_demand", "wrench_facets",
           "wrench_generators"]

# The limiter's modes (omni_gym.physics.traction.TRACTION_MODES) as a registry, with its one-line error.
MODES: Registry[str] = Registry("traction mode", list(TRACTION_MODES.items()))


class LimitedPathPID(PathPID):
    """:class:`~agents.pid.PathPID` whose saturated output goes through a limiter hook.

    The hook ``limiter(twist (N, 3), previous twist (N, 3), estimate (N, 3), dt) -> twist (N, 3)`` sees the
    saturated twist and the twist commanded in the previous period (zero after :meth:`reset`). An axis the
    hook changes counts as saturated for the anti-windup (translation: vx or vy; rotation: ω), so an
    integrator does not wind up against a limit it cannot push through.
    """

    def __init__(self, limiter: Callable[[np.ndarray, np.ndarray, np.ndarray, float], np.ndarray],
                 max_speed: float, max_yaw_rate: float, dt: float, gains: PIDGains | None = None) -> None:
        self.limiter = limiter
        super().__init__(max_speed, max_yaw_rate, dt, gains)

    def reset(self) -> None:
        super().reset()
        self.prev_twist = np.zeros(3)

    def update(self, pose: np.ndarray, ref_pose: np.ndarray, ref_velocity: np.ndarray) -> np.ndarray:
        self._pose = np.asarray(pose, dtype=float)
        twist = super().update(pose, ref_pose, ref_velocity)
        self.prev_twist = twist
        return twist

    def _saturate(self, u: np.ndarray, th: float) -> tuple[np.ndarray, bool, bool]:
        body, sat_t, sat_r = super()._saturate(u, th)
        limited = np.asarray(self.limiter(body[None], self.prev_twist[None], self._pose[None], self.dt),
                             dtype=float)[0]
        changed = np.abs(limited - body) > 1e-12 * (1.0 + np.abs(body))  # rounding of an untouched row
        return limited, sat_t or bool(changed[0] or changed[1]), sat_r or bool(changed[2])


@dataclass(frozen=True)
class ReferenceDemand:
    """What one reference asks of the wheels, per control period (the open-loop twist sequence).

    peak_speed [m/s], peak_accel [m/s²] (world-frame translation), peak_yaw_rate [rad/s],
    peak_yaw_accel [rad/s²]; utilisation: the largest share of the limiter's set any period's twist
    change asks for (≤ 1: feasible); steady_utilisation: the largest share the motion alone asks for
    ("moving" mode at zero acceleration; 0 in "static" mode).
    """

    peak_speed: float
    peak_accel: float
    peak_yaw_rate: float
    peak_yaw_accel: float
    utilisation: float
    steady_utilisation: float


def reference_demand(cfg: EnvConfig, limiter: TractionLimiter, seed: int) -> ReferenceDemand:
    """:class:`ReferenceDemand` of the reference an environment with config ``cfg`` draws from ``seed``.

    The reference is drawn by :func:`omni_gym.envs.references.draw_reference` from
    ``numpy.random.default_rng(seed)`` (the same distribution as the environments' resets) over the
    episode, and turned into body twists as the open-loop policy does (world velocity rotated by the
    mid-period reference heading).
    """
    from omni_gym.envs.references import draw_reference

    dt = cfg.control_dt
    pose, vel = draw_reference(cfg, np.random.default_rng(seed), cfg.episode_steps + 1)
    use = reference_use(limiter, pose, vel, dt)
    world_acc = np.diff(np.vstack([np.zeros((1, 3)), vel]), axis=0) / dt
    return ReferenceDemand(
        peak_speed=float(np.max(np.hypot(vel[:, 0], vel[:, 1]))),
        peak_accel=float(np.max(np.hypot(world_acc[:, 0], world_acc[:, 1]))),
        peak_yaw_rate=float(np.max(np.abs(vel[:, 2]))),
        peak_yaw_accel=float(np.max(np.abs(world_acc[:, 2]))),
        utilisation=use.peak,
        steady_utilisation=use.steady,
    )
