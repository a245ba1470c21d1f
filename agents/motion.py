"""The EKF's state layout and motion model: one compiled kernel for the single filter and the batch.

State x (7,) = [x, y, θ, vx, vy, ω, b_g] (:mod:`agents.ekf`): world position [m] and heading θ [rad] of
the geometric centre, body-frame velocity (vx, vy) [m/s], yaw rate ω [rad/s] and gyro bias b_g [rad/s].
Over a period Δt [s] the body twist is held and the pose moves along its exact arc,
Δp = R(θ + ωΔt/2)·v·Δt·sinc(ωΔt/2), Δθ = ωΔt, the heading wrapped to (−π, π].

:func:`motion_into` is the one implementation: :class:`agents.ekf.OmniEKF` calls it through
:func:`motion_model`, and the batched kernels (:mod:`agents.batched.kernels`) call it for each robot.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from omni_gym.angles import wrap_angle_nb as _wrap

X, Y, TH, VX, VY, OM, BG = range(7)
NX = 7


@numba.njit(cache=True)
def sinc(phi):
    """sin(φ)/φ and its derivative (series below |φ| = 1e-4)."""
    if abs(phi) < 1e-4:
        return 1.0 - phi * phi / 6.0, -phi / 3.0
    s, c = math.sin(phi), math.cos(phi)
    return s / phi, (phi * c - s) / (phi * phi)


@numba.njit(cache=True)
def motion_into(x, dt, out, F):
    """out (7,) = f(x) over ``dt`` [s], F (7, 7) its Jacobian ∂f/∂x: the exact arc for the twist held."""
    th, vx, vy, om = x[TH], x[VX], x[VY], x[OM]
    phi = 0.5 * om * dt
    s, ds = sinc(phi)
    c, sn = math.cos(th + phi), math.sin(th + phi)
    rvx, rvy = c * vx - sn * vy, sn * vx + c * vy  # R(θm)·v
    dvx, dvy = -sn * vx - c * vy, c * vx - sn * vy  # R'(θm)·v
    for i in range(NX):
        out[i] = x[i]
        for j in range(NX):
            F[i, j] = 1.0 if i == j else 0.0
    out[X] += rvx * dt * s
    out[Y] += rvy * dt * s
    out[TH] = _wrap(th + om * dt)
    F[X, TH], F[Y, TH] = dvx * dt * s, dvy * dt * s
    F[X, VX], F[X, VY] = c * dt * s, -sn * dt * s
    F[Y, VX], F[Y, VY] = sn * dt * s, c * dt * s
    half = 0.5 * dt * dt
    F[X, OM] = (dvx * s + rvx * ds) * half
    F[Y, OM] = (dvy * s + rvy * ds) * half
    F[TH, OM] = dt


def motion_model(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """f(x) (7,) and its Jacobian F (7×7) over ``dt`` [s] (:func:`motion_into`), as new arrays."""
    out = np.empty(NX)
    F = np.empty((NX, NX))
    motion_into(np.ascontiguousarray(x, dtype=np.float64), float(dt), out, F)
    return out, F
