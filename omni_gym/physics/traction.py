"""The wrench the wheels can transmit, and the limiter that keeps a body twist's change inside it.

Source: Williams et al. (2002), Sec. IV-B, the largest force static friction can hold (the linear
program of ``omni_gym.analysis.max_force``). Here the same friction boxes bound the whole planar
wrench (force and yaw moment about the centre of mass), not only a push through the centre of mass.

**The feasible wrench set.** Wheel i with normal load N_i [N] transmits a friction force
f_i = F_W,i·e_i + F_T,i·f_i with |F_W,i| ≤ μ_W·N_i and |F_T,i| ≤ μ_T·N_i (body frame, e_i the roller axis
``RobotSpec.roller_axes()``, the direction the wheel constrains, and f_i = z × e_i the direction its floor
roller rolls freely, ``RobotSpec.free_directions()``; ρ_i = p_i − com its lever arm about the centre of
mass). For an omni wheel (roller angle γ_i = 0) e_i is the drive direction d_i and f_i the axle a_i; for
a mecanum wheel both are turned by γ_i (``docs/model.md``, the law for any roller angle). The wrenches
(F_x, F_y, M_z) the wheels can exert together form the zonotope

    Z = { Σ_j t_j·g_j : |t_j| ≤ 1 },  g = μ_W,i·N_i·(e_i, ρ_i × e_i)  and  μ_T,i·N_i·(f_i, ρ_i × f_i)

(2n generators in 3-D). Its facets are known in closed form: for every pair of generators (j, k) with
normal n = g_j × g_k ≠ 0, |n·w| ≤ h = Σ_l |n·g_l|. With the moment set to zero this is exactly the LP
of ``max_static_force`` (``tests/test_traction.py`` checks both against each other).

**Orientation.** Every vector above is in the body frame, so the set does not depend on the robot's
orientation θ as long as the loads do not (they do not: they follow from the body-frame geometry). The
facets are computed once at construction; a step costs one (N, 3)·(3, K) product, K ≤ n(2n − 1).

**From twist change to wrench.** A twist (vx, vy, ω) held over a period dt moves the geometric centre
along an arc; its world velocity at mid-period is R(θ_mid)·(vx, vy). Relative to the heading θ at the
period boundary, the previous twist had its mid-period heading at θ − ω_prev·dt/2 and the new one at
θ + ω_new·dt/2, so the inertial acceleration of the geometric centre over the boundary, in the body
frame at θ, is

    a = (Rot(ω_new·dt/2)·v_new − Rot(−ω_prev·dt/2)·v_prev) / dt,      α = (ω_new − ω_prev) / dt.

This includes the ω × v term: a robot that turns while moving straight keeps its world velocity and
needs no force. The wrench is w = (m·(a + α·z × c), I·α) with c the centre of mass (body frame); the
centripetal −ω²·c term of an offset centre of mass is left out (ω²·|c| is below 0.01 m/s² for 1 rad/s
and 1 cm). The limiter scales (a, α) by the largest λ ∈ [0, 1] that keeps w in ``margin``·Z, keeping
its direction, and solves back for the twist.

**Speed.** The friction law μ(v) = μ_max·(2/π)·atan(k·v) saturates above a few mm/s of slip and does not
depend on speed beyond that: whether steady motion is possible in a direction depends on the
direction only, not on the speed. The limiter therefore bounds accelerations, never speeds.

**Assumptions (conservative where it matters).** Every wheel on a roller (μ'_W, μ'_T): the rigid
material between rollers has the larger μ'' in both directions, so roller contact gives the smaller
set. Loads as the physics computes them (:func:`omni_gym.physics.loads.wheel_loads`, all wheels
down). With ``contact_cases`` the set is the intersection over the given contact masks (e.g. the
lift-off process's cases: the policy does not know which wheel is lifted).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from omni_gym.physics.friction import Surface
from omni_gym.physics.loads import wheel_loads
from omni_gym.physics.robot import GRAVITY, RobotSpec

__all__ = ["TRACTION_MODES", "ReferenceUse", "TractionLimiter", "body_twists", "reference_use", "reference_use_arrays",
           "wrench_facets", "wrench_generators"]


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z-component of the planar cross product, row-wise."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def wrench_generators(robot: RobotSpec, surface: Surface, loads: np.ndarray,
                      com: Sequence[float] | None = None) -> np.ndarray:
    """Generators (2n, 3) of the wrench zonotope [N, N, N·m], body frame, about the centre of mass.

    Rows 0..n−1: roller axes e_i (omni wheel: the drive direction) scaled by μ'_W·N_i; rows n..2n−1: free
    rolling directions f_i = z × e_i (omni wheel: the axle) scaled by μ'_T·N_i.
    """
    c = np.asarray(robot.com if com is None else com, dtype=float)
    rho = robot.positions() - c
    d, a = robot.roller_axes(), robot.free_directions()
    N = np.asarray(loads, dtype=float)
    gd = np.column_stack([d, _cross2(rho, d)]) * (surface.mu_drive * N)[:, None]
    ga = np.column_stack([a, _cross2(rho, a)]) * (surface.mu_transverse * N)[:, None]
    return np.vstack([gd, ga])


def wrench_facets(generators: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """H-representation (normals (K, 3), offsets (K,)) of the zonotope {Σ t_j g_j : |t_j| ≤ 1}.

    A point w lies in the zonotope iff |normals·w| ≤ offsets row-wise. Raises ValueError if the
    generators do not span 3-D (the wheels could not transmit some wrench at all).
    """
    g = np.asarray(generators, dtype=float)
    scale = float(np.max(np.abs(g))) if g.size else 0.0
    g = g[np.linalg.norm(g, axis=1) > 1e-12 * max(scale, 1e-300)]
    if g.shape[0] < 3 or np.linalg.matrix_rank(g, tol=1e-9 * scale) < 3:
        raise ValueError("the wheels cannot transmit every planar wrench (friction generators span < 3 dimensions)")
    normals = []
    for j in range(len(g)):
        for k in range(j + 1, len(g)):
            n = np.cross(g[j], g[k])
            norm = float(np.linalg.norm(n))
            if norm > 1e-9 * float(np.linalg.norm(g[j]) * np.linalg.norm(g[k])):
                normals.append(n / norm)
    normals = np.array(normals)
    offsets = np.abs(normals @ g.T).sum(axis=1)
    return normals, offsets


# The limiter's modes (see TractionLimiter's ``mode``), each with the friction set it bounds the twist by.
TRACTION_MODES = {
    "static": "the LP's set Z: every wheel's transverse force free within its friction limit",
    "moving": "the drive boxes only, once the rollers turn",
}


class TractionLimiter:
    """Limit a body twist's change per period to the accelerations the wheels' friction can produce.

    Args:
        robot: layout, mass m [kg], yaw inertia I [kg·m²] about ``com`` (body frame).
        surface: friction coefficients; roller contact (μ'_W, μ'_T) is used (the conservative case).
        mode: ``"static"``: the LP's set Z (module docstring); ``"moving"``: the drive boxes only, around
            the transverse friction wrench that the current motion already draws (see below).
        margin: share of the friction set the commands may use, in (0, 1] (1: the bound itself).
        com: centre of mass [m], body frame (default ``robot.com``; pass ``SimModel.com()`` for a model
            with a ``com_offset`` effect).
        contact_cases: optional contact masks (each a bool per wheel, True = down); the limit is the
            intersection of their sets. Default: all wheels down.
        gravity: g [m/s²].

    ``"moving"``: once a wheel's rollers turn, its transverse force is not free to help: it is the
    friction law's value at the rollers' rolling speed, F_T,i = −μ'_T·N_i·(2/π)·atan(k·v_T,i) along f_i, a
    resistance the drive forces must overcome before anything is left to accelerate the robot. The set
    is then {w_T(v) + Σ t_i·g_W,i : |t_i| ≤ 1}, the drive generators around the transverse wrench of the
    previous twist v. If w_T alone is outside the drive set, steady motion along v is not possible
    without slip and the limiter holds the previous twist (λ = 0). The rolling speed is the one of a
    wheel turning without slip along e_i: with the wheel-centre velocity u_i, v_T,i = u_i·f_i + r·w_i·sin γ_i
    and r·w_i·cos γ_i = u_i·e_i, so v_T,i = (u_i·a_i)/cos γ_i (a_i the axle; u_i·a_i for an omni wheel).

    Call it as the limiter hook ``limiter(twist, prev_twist, estimate, dt) -> twist`` with (N, 3)
    arrays of body twists (vx, vy [m/s], ω [rad/s]) and pose estimates (x, y [m], θ [rad]); dt [s].
    """

    def __init__(self, robot: RobotSpec, surface: Surface, mode: str = "static", margin: float = 1.0,
                 com: Sequence[float] | None = None, contact_cases: Sequence[Sequence[bool]] | None = None,
                 gravity: float = GRAVITY) -> None:
        if mode not in TRACTION_MODES:
            raise ValueError(f"unknown traction mode {mode!r} (known: {', '.join(TRACTION_MODES)})")
        if not (isinstance(margin, (int, float)) and math.isfinite(margin) and 0.0 < margin <= 1.0):
            raise ValueError(f"margin must be a number in (0, 1], got {margin!r}")
        self.robot = robot
        self.surface = surface
        self.mode = mode
        self.margin = float(margin)
        self.com = np.asarray(robot.com if com is None else com, dtype=float)
        n = robot.n_wheels
        cases = [np.ones(n, dtype=bool)] if contact_cases is None else [np.asarray(c, dtype=bool)
                                                                          for c in contact_cases]
        for c in cases:
            if c.shape != (n,):
                raise ValueError(f"each contact case needs one flag per wheel ({n}), got shape {c.shape}")
        m, inertia = robot.mass, robot.inertia
        cx, cy = self.com
        # Wrench = A·(a_x, a_y, α) for the geometric centre's acceleration a and the yaw acceleration α.
        self.wrench_matrix = np.array([[m, 0.0, -m * cy], [0.0, m, m * cx], [0.0, 0.0, inertia]])
        self._positions = robot.positions()
        # Rolling speed of a no-slip wheel along f_i: (u·a_i)/cos γ_i (class docstring), so the axle over cos γ.
        self._rolling = robot.axles() / np.cos(robot.roller_angles())[:, None]
        normals, offsets, transverse = [], [], []
        for c in cases:
            loads = wheel_loads(self._positions, self.com, m, gravity, c)
            g = wrench_generators(robot, surface, loads, self.com)
            nw, hw = wrench_facets(g if mode == "static" else g[:n])
            normals.append(nw @ self.wrench_matrix)  # n·(A x) = (Aᵀ n)·x: facets in acceleration space
            offsets.append(hw * self.margin)
            transverse.append(g[n:] @ nw.T)  # (n, K): facet projections of each wheel's full transverse force
        self.normals = np.vstack(normals)  # (K, 3), acceleration space (a_x, a_y [m/s²], α [rad/s²])
        self.offsets = np.concatenate(offsets)  # (K,)
        self._transverse = np.hstack(transverse)  # (n, K)

    def _shift(self, twist: np.ndarray) -> np.ndarray:
        """Facet projections (N, K) of the transverse friction wrench drawn by body twists (N, 3) ("moving")."""
        if self.mode == "static":
            return np.zeros((twist.shape[0], self.offsets.shape[0]))
        # Rolling speed (u_i·a_i)/cos γ_i of the wheel-centre velocity u_i = v + ω z × p_i (class docstring).
        px, py = self._positions[:, 0], self._positions[:, 1]
        ux = twist[:, :1] - twist[:, 2:3] * py
        uy = twist[:, 1:2] + twist[:, 2:3] * px
        vt = ux * self._rolling[:, 0] + uy * self._rolling[:, 1]  # (N, n) [m/s]
        share = (2.0 / math.pi) * np.arctan(self.surface.k * vt)  # of μ'_T·N_i, opposing the motion
        return -share @ self._transverse

    def utilisation(self, accel: np.ndarray, twist: np.ndarray | None = None) -> np.ndarray:
        """Share of the (margin-scaled) friction set that body accelerations (N, 3) ask for, (N,).

        accel rows are (a_x, a_y [m/s²], α [rad/s²]) of the geometric centre, body frame; ``twist`` (N, 3)
        the motion during it ("moving" mode; default at rest). ≤ 1 is feasible.
        """
        x = np.atleast_2d(np.asarray(accel, dtype=float))
        v = np.zeros_like(x) if twist is None else np.atleast_2d(np.asarray(twist, dtype=float))
        return np.max(np.abs(x @ self.normals.T - self._shift(v)) / self.offsets, axis=1)

    def max_acceleration(self, direction: Sequence[float]) -> float:
        """Largest |a| [m/s²] of the geometric centre along a body-frame direction (α = 0), from rest."""
        u = np.array([direction[0], direction[1], 0.0], dtype=float)
        u /= math.hypot(u[0], u[1])
        return float(1.0 / self.utilisation(u)[0])

    @staticmethod
    def accelerations(twist: np.ndarray, prev_twist: np.ndarray, dt: float) -> np.ndarray:
        """Body-frame accelerations (N, 3) implied by changing ``prev_twist`` to ``twist`` over a boundary."""
        v, p = np.asarray(twist, dtype=float), np.asarray(prev_twist, dtype=float)
        hn, hp = 0.5 * dt * v[:, 2], -0.5 * dt * p[:, 2]
        out = np.empty_like(v)
        out[:, 0] = (np.cos(hn) * v[:, 0] - np.sin(hn) * v[:, 1] - np.cos(hp) * p[:, 0] + np.sin(hp) * p[:, 1]) / dt
        out[:, 1] = (np.sin(hn) * v[:, 0] + np.cos(hn) * v[:, 1] - np.sin(hp) * p[:, 0] - np.cos(hp) * p[:, 1]) / dt
        out[:, 2] = (v[:, 2] - p[:, 2]) / dt
        return out

    def scale(self, accel: np.ndarray, prev_twist: np.ndarray) -> np.ndarray:
        """Largest λ ∈ [0, 1] (N,) with λ·accel inside the set (around ``prev_twist``'s transverse wrench)."""
        s = accel @ self.normals.T  # (N, K)
        b = self._shift(prev_twist)
        h = self.offsets
        # −h ≤ λ·s − b ≤ h: each facet bounds λ from above by (h + b)/s (s > 0) or (h − b)/|s| (s < 0).
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = np.where(s > 0, (h + b) / s, np.where(s < 0, (h - b) / -s, np.inf))
        return np.clip(np.min(bound, axis=1), 0.0, 1.0)

    def limit(self, twist: np.ndarray, prev_twist: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(limited twists (N, 3), scale λ (N,) applied to each row's acceleration; 1 = untouched)."""
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite number > 0 [s], got {dt!r}")
        v = np.atleast_2d(np.asarray(twist, dtype=float))
        p = np.atleast_2d(np.asarray(prev_twist, dtype=float))
        acc = self.accelerations(v, p, dt)
        lam = self.scale(acc, p)
        out = v.copy()
        rows = lam < 1.0
        if np.any(rows):
            a = acc[rows] * lam[rows, None]
            pr = p[rows]
            om = pr[:, 2] + a[:, 2] * dt
            hp = -0.5 * dt * pr[:, 2]
            # Velocity after the boundary in the body frame at θ, then rotated back by the new half-turn.
            wx = np.cos(hp) * pr[:, 0] - np.sin(hp) * pr[:, 1] + a[:, 0] * dt
            wy = np.sin(hp) * pr[:, 0] + np.cos(hp) * pr[:, 1] + a[:, 1] * dt
            hn = 0.5 * dt * om
            out[rows, 0] = np.cos(hn) * wx + np.sin(hn) * wy
            out[rows, 1] = -np.sin(hn) * wx + np.cos(hn) * wy
            out[rows, 2] = om
        return out, lam

    def __call__(self, twist: np.ndarray, prev_twist: np.ndarray, estimate: np.ndarray, dt: float) -> np.ndarray:
        """Limiter hook: limited twists (N, 3). ``estimate`` (N, 3) is accepted for the hook's signature and
        not used: in the body frame the friction set does not depend on the pose (module docstring)."""
        return self.limit(twist, prev_twist, dt)[0]


def body_twists(pose: np.ndarray, velocity: np.ndarray, dt: float) -> np.ndarray:
    """Open-loop body twists (K, 3) of a reference sampled every ``dt`` [s]: pose (K, 3) and world velocity
    (K, 3) rotated by the mid-period reference heading (as the open-loop policy commands them)."""
    mid = pose[:, 2] + 0.5 * velocity[:, 2] * dt
    c, s = np.cos(mid), np.sin(mid)
    return np.column_stack([c * velocity[:, 0] + s * velocity[:, 1], -s * velocity[:, 0] + c * velocity[:, 1],
                            velocity[:, 2]])


@dataclass(frozen=True)
class ReferenceUse:
    """The share of a limiter's friction set a reference asks for: ``peak`` over its periods (accelerations
    and motion together; ≤ 1 feasible), and ``steady``, the share the motion alone asks for ("moving" mode at
    zero acceleration; 0 in "static" mode), which no slowing down can lower."""

    peak: float
    steady: float


def reference_use(limiter: TractionLimiter, pose: np.ndarray, velocity: np.ndarray, dt: float) -> ReferenceUse:
    """:class:`ReferenceUse` of a reference sampled every ``dt`` [s] from rest (pose, world velocity (K, 3)).

    One compiled pass over the samples (every environment reset measures its reference: the array version,
    :func:`reference_use_arrays`, took 80 % of a reset); the same formulas, equal to it within rounding."""
    pose = np.ascontiguousarray(pose, dtype=float)
    velocity = np.ascontiguousarray(velocity, dtype=float)
    if pose.ndim != 2 or pose.shape[1] != 3 or velocity.shape != pose.shape:
        raise ValueError(f"pose and velocity must both have shape (K, 3), got {pose.shape} and {velocity.shape}")
    peak, steady = _reference_use_kernel(pose, velocity, float(dt), limiter.normals, limiter.offsets,
                                         limiter._transverse, limiter._positions, limiter._rolling,
                                         float(limiter.surface.k), limiter.mode == "moving")
    return ReferenceUse(peak=peak, steady=steady)


def reference_use_arrays(limiter: TractionLimiter, pose: np.ndarray, velocity: np.ndarray,
                         dt: float) -> ReferenceUse:
    """:func:`reference_use` written with the limiter's own array methods (its reference in the tests)."""
    twist = body_twists(pose, velocity, dt)
    prev = np.vstack([np.zeros((1, 3)), twist[:-1]])  # the reference starts at rest
    acc = limiter.accelerations(twist, prev, dt)
    steady = limiter.utilisation(np.zeros_like(twist), twist) if limiter.mode == "moving" else np.zeros(1)
    return ReferenceUse(peak=float(np.max(limiter.utilisation(acc, prev))), steady=float(np.max(steady)))


@numba.njit(cache=True)
def _reference_use_kernel(pose, velocity, dt, normals, offsets, transverse, positions, rolling, k, moving):
    """(peak, steady) of :func:`reference_use_arrays`, sample by sample: body twist at the mid-period heading,
    the boundary's acceleration from the previous twist (rest before the first), the facet shares around the
    previous twist's rolling resistance ("moving"), and the resistance of each twist alone (steady)."""
    n_facets, n_wheels = normals.shape[0], positions.shape[0]
    shift_prev = np.zeros(n_facets)  # the previous twist's transverse wrench on each facet (rest: none)
    shift_now = np.zeros(n_facets)
    pvx, pvy, pw = 0.0, 0.0, 0.0
    peak, steady = 0.0, 0.0
    for i in range(pose.shape[0]):
        mid = pose[i, 2] + 0.5 * velocity[i, 2] * dt
        c, s = math.cos(mid), math.sin(mid)
        vx = c * velocity[i, 0] + s * velocity[i, 1]
        vy = -s * velocity[i, 0] + c * velocity[i, 1]
        w = velocity[i, 2]
        hn, hp = 0.5 * dt * w, -0.5 * dt * pw
        ax = (math.cos(hn) * vx - math.sin(hn) * vy - math.cos(hp) * pvx + math.sin(hp) * pvy) / dt
        ay = (math.sin(hn) * vx + math.cos(hn) * vy - math.sin(hp) * pvx - math.cos(hp) * pvy) / dt
        al = (w - pw) / dt
        for f in range(n_facets):
            u = abs(ax * normals[f, 0] + ay * normals[f, 1] + al * normals[f, 2] - shift_prev[f]) / offsets[f]
            peak = max(peak, u)
        if moving:
            shift_now[:] = 0.0
            for j in range(n_wheels):
                ux = vx - w * positions[j, 1]
                uy = vy + w * positions[j, 0]
                share = (2.0 / math.pi) * math.atan(k * (ux * rolling[j, 0] + uy * rolling[j, 1]))
                for f in range(n_facets):
                    shift_now[f] -= share * transverse[j, f]
            for f in range(n_facets):
                steady = max(steady, abs(shift_now[f]) / offsets[f])
            shift_prev[:] = shift_now
        pvx, pvy, pw = vx, vy, w
    return peak, steady
