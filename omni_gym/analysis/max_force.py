"""Maximum external force before sliding, Williams et al. (2002), Sec. IV-B (their Fig. 8).

The robot stands still on the floor. A horizontal force of magnitude F [N] pushes on its centre of
mass along a world direction u. Each wheel contact can resist with a friction force

    f_i = F_W,i · d_i + F_T,i · a_i        (world frame: d_i, a_i rotated by the orientation θ)

inside the paper's "dominion" box |F_W,i| ≤ μ_W·N_i, |F_T,i| ≤ μ_T·N_i, where N_i [N] is the wheel's
normal load. Roller contact uses μ_W = μ'_W (``mu_drive``) and μ_T = μ'_T (``mu_transverse``); a wheel
standing on the rigid material between rollers uses μ'' (``mu_gap``) in both directions.

The robot does not slide as long as some set of contact forces in the boxes balances the push:

    Σ f_i + F·u = 0                  (planar force balance)
    Σ ρ_i × f_i = 0                  (yaw moment about the centre of mass; F acts at the com)

with ρ_i = R(θ)(p_i − com) the contact point relative to the centre of mass. The largest such F is a
linear program in (F, F_W,1..n, F_T,1..n), solved here with ``scipy.optimize.linprog`` (HiGHS).

Only the planar problem is modelled: the loads N_i are inputs (equal, m·g/n, by default) and do not
shift with the push, and the contact point of wheel i is taken directly below its centre p_i.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from scipy.optimize import linprog

from omni_gym.physics.friction import Surface
from omni_gym.physics.loads import balance_loads
from omni_gym.physics.robot import GRAVITY, RobotSpec

__all__ = ["max_static_force", "max_force_curve", "static_loads"]


def _rotation(theta: float) -> np.ndarray:
    """R(θ): body-frame vectors → world frame (θ = robot yaw [rad], counter-clockwise)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z-component of the planar cross product a × b, row-wise for (n, 2) arrays."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _unit_direction(direction: Sequence[float]) -> np.ndarray:
    u = np.asarray(direction, dtype=float)
    if u.shape != (2,):
        raise ValueError(f"direction must be a 2-vector (x, y) in the world frame, got shape {u.shape}")
    norm = float(np.hypot(u[0], u[1]))
    if not (math.isfinite(norm) and norm > 0.0):
        raise ValueError(f"direction must be a finite, non-zero 2-vector, got {tuple(u.tolist())}")
    return u / norm  # only the direction matters; accept any length


def _wheel_flags(on_gap, n: int) -> np.ndarray:
    if on_gap is None:
        return np.zeros(n, dtype=bool)
    flags = np.asarray(on_gap)
    if flags.shape != (n,):
        raise ValueError(f"on_gap must be a boolean array with one entry per wheel ({n}), got shape {flags.shape}")
    if flags.dtype != bool:
        # Accept 0/1 integers, but not e.g. 0.5, which would hint at a misunderstanding.
        if not np.all((flags == 0) | (flags == 1)):
            raise ValueError(f"on_gap must hold booleans (or 0/1), got {flags.tolist()}")
        flags = flags.astype(bool)
    return flags


def _wheel_loads(loads, robot: RobotSpec, gravity: float) -> np.ndarray:
    n = robot.n_wheels
    if loads is None:
        if not (math.isfinite(gravity) and gravity > 0):
            raise ValueError(f"gravity must be a positive number [m/s²], got {gravity}")
        # The paper's assumption: the weight is shared equally by the wheels.
        return np.full(n, robot.mass * gravity / n)
    N = np.asarray(loads, dtype=float)
    if N.shape != (n,):
        raise ValueError(f"loads must be an array with one normal load [N] per wheel ({n}), got shape {N.shape}")
    if not np.all(np.isfinite(N)) or np.any(N < 0):
        raise ValueError(f"loads must be finite and >= 0 [N] (the floor can only push), got {N.tolist()}")
    return N


def static_loads(robot: RobotSpec, gravity: float = GRAVITY) -> np.ndarray:
    """Normal loads N_i [N] that hold the robot's weight with no roll/pitch moment about its com.

    Solves Σ N_i = m·g and Σ N_i·(p_i − com) = 0 (body frame). Three wheels not on one line give a
    unique answer; with more wheels the problem is statically indeterminate and the minimum-norm
    (most even) solution is returned. Raises ValueError if a load would be negative, i.e. the centre
    of mass lies outside the wheels' support polygon.

    This is an alternative to the equal loads m·g/n that ``max_static_force`` uses by default: equal
    loads are only consistent with the weight when the com is the wheels' centroid.
    """
    if not (math.isfinite(gravity) and gravity > 0):
        raise ValueError(f"gravity must be a positive number [m/s²], got {gravity}")
    weight = robot.mass * gravity
    N = balance_loads(robot.positions(), robot.com, weight)
    rel = robot.positions() - np.asarray(robot.com, dtype=float)
    if not np.allclose([N.sum(), N @ rel[:, 0], N @ rel[:, 1]], [weight, 0.0, 0.0], rtol=1e-9, atol=1e-9 * weight):
        raise ValueError(f"robot {robot.name!r}: wheels cannot carry the weight without a moment (collinear?)")
    if np.any(N < -1e-9 * robot.mass * gravity):
        raise ValueError(f"robot {robot.name!r}: com lies outside the support polygon (loads {N.tolist()})")
    return np.clip(N, 0.0, None)


def max_static_force(
    robot: RobotSpec,
    surface: Surface,
    theta: float,
    direction: Sequence[float] = (1.0, 0.0),
    on_gap: Sequence[bool] | np.ndarray | None = None,
    loads: Sequence[float] | np.ndarray | None = None,
    gravity: float = GRAVITY,
) -> float:
    """Largest force F_max [N] at the centre of mass along ``direction`` that friction can hold.

    Args:
        robot: layout; wheel positions, drive/axle directions and ``com`` are in the body frame.
        surface: friction coefficients (μ'_W = ``mu_drive``, μ'_T = ``mu_transverse``, μ'' = ``mu_gap``).
        theta: robot orientation [rad], the yaw that rotates the body frame into the world frame.
        direction: world-frame direction u of the push; normalised here, must be finite and non-zero.
        on_gap: optional boolean per wheel; True → that wheel touches the floor with the rigid material
            between rollers and has μ'' in both directions. Default: every wheel on a roller.
        loads: optional normal load per wheel [N], each >= 0. Default: m·g/n on every wheel.
        gravity: g [m/s²], used only for the default loads.

    Returns:
        F_max >= 0 [N]. The robot stays put for any push along u with magnitude <= F_max.
    """
    if not math.isfinite(theta):
        raise ValueError(f"theta must be a finite angle [rad], got {theta}")
    u = _unit_direction(direction)
    n = robot.n_wheels
    gap = _wheel_flags(on_gap, n)
    N = _wheel_loads(loads, robot, gravity)

    R = _rotation(theta)
    d = robot.roller_axes() @ R.T  # (n, 2) world-frame constrained directions (omni wheel: drive)
    a = robot.free_directions() @ R.T  # (n, 2) world-frame free directions (omni wheel: axle)
    rho = (robot.positions() - np.asarray(robot.com, dtype=float)) @ R.T  # contact points about the com

    mu_w = np.where(gap, surface.mu_gap, surface.mu_drive)
    mu_t = np.where(gap, surface.mu_gap, surface.mu_transverse)

    # Variables x = [F, F_W,1..n, F_T,1..n]; equality rows: force x, force y, yaw moment.
    A_eq = np.zeros((3, 1 + 2 * n))
    A_eq[:2, 0] = u
    A_eq[:2, 1:1 + n] = d.T
    A_eq[:2, 1 + n:] = a.T
    A_eq[2, 1:1 + n] = _cross(rho, d)
    A_eq[2, 1 + n:] = _cross(rho, a)
    b_eq = np.zeros(3)

    # F >= 0 with no upper bound: the friction boxes already bound it (|Σ f_i| is finite).
    bounds = [(0.0, None)]
    bounds += [(-m, m) for m in mu_w * N]
    bounds += [(-m, m) for m in mu_t * N]
    cost = np.zeros(1 + 2 * n)
    cost[0] = -1.0  # maximise F

    res = linprog(cost, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method="highs")
    if res.status != 0:  # x = 0 is always feasible and F is bounded, so this means a solver failure
        raise RuntimeError(f"max_static_force: linprog failed ({res.status}): {res.message}")
    return max(float(res.x[0]), 0.0)


def max_force_curve(robot: RobotSpec, surface: Surface, thetas: Iterable[float], **kw) -> np.ndarray:
    """F_max [N] at each robot orientation in ``thetas`` [rad]; ``kw`` as for ``max_static_force``."""
    th = np.asarray(list(thetas) if not isinstance(thetas, np.ndarray) else thetas, dtype=float)
    if th.ndim != 1:
        raise ValueError(f"thetas must be a 1-D sequence of angles [rad], got shape {th.shape}")
    return np.array([max_static_force(robot, surface, float(t), **kw) for t in th])
