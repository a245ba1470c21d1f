"""The one angle wrap: angles [rad] to the half-open interval (−π, π], in Python and compiled for numba.

A utility (it imports nothing else of the package): the sensors, references, trajectories, the
environments' kernels, the estimators and the discrepancy residuals all wrap headings with it.
"""

from __future__ import annotations

import math

import numba
import numpy as np

TWO_PI = 2.0 * math.pi


def _wrap_scalar(angle: float) -> float:
    """One angle [rad] wrapped to (−π, π]: the single definition of the interval (see :func:`wrap_angle`)."""
    wrapped = (angle + math.pi) % TWO_PI - math.pi
    return math.pi if wrapped == -math.pi else wrapped


# The same function compiled for the numba kernels (omni_gym.envs.core): one expression, one interval.
wrap_angle_nb = numba.njit(cache=True, inline="always")(_wrap_scalar)


def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """Angle(s) [rad] wrapped to the half-open interval (−π, π]; works element-wise on arrays.

    Computed as (a + π) mod 2π − π, with −π mapped to π. An angle already inside the interval may
    move by one rounding step of π (about 4e-16 rad) through the +π/−π; the copies this function
    replaced used the same arithmetic, so results stay bit-identical to theirs (an exact −π, where
    the old copies returned −π, is the only value that differs).
    """
    if isinstance(angle, (float, int)) and not isinstance(angle, bool):  # fast path: no array round trip
        return _wrap_scalar(float(angle))
    a = np.asarray(angle, dtype=float)
    wrapped = (a + math.pi) % TWO_PI - math.pi
    wrapped = np.where(wrapped == -math.pi, math.pi, wrapped)
    return float(wrapped) if wrapped.ndim == 0 else wrapped
