"""Normal loads on the wheels, for any contact mask.

Default (centre of mass at the geometric centre): the weight is shared equally by the wheels in
contact, N_i = m·g / n_contact: the assumption of Williams et al. (2002), "the vehicle weight is
equally distributed on each wheel", even where the wheel layout is not symmetric.

With a centre-of-mass offset the loads follow from static balance:

With the centre of mass at c (body frame) and wheel centres p_i, the loads N_i ≥ 0 of the wheels in
contact satisfy   Σ N_i = m·g   and   Σ N_i (p_i − c) = 0   (no tipping moment about c).
For three wheels in contact that is one solution; for more it is the least-norm solution (the
flattest load spread, what a compliant chassis on a flat floor tends to); for fewer it is the
least-squares one. Loads that come out negative (the centre of mass outside the support polygon,
where a real robot would tip) are clipped to zero and the rest rescaled to carry m·g: the robot is
assumed to stay upright, as in Phunopas & Inoue (2018), whose lifted wheels never topple it.
"""

from __future__ import annotations

import numpy as np


def wheel_loads(positions: np.ndarray, com: np.ndarray, mass: float, gravity: float,
                contact: np.ndarray | None = None) -> np.ndarray:
    """Normal load [N] per wheel: equal shares when ``com`` is (0, 0), else :func:`static_loads`."""
    p = np.asarray(positions, dtype=float)
    if np.any(np.asarray(com, dtype=float) != 0.0):
        return static_loads(p, com, mass, gravity, contact)
    mask = np.ones(p.shape[0], dtype=bool) if contact is None else np.asarray(contact, dtype=bool)
    return np.where(mask, mass * gravity / max(int(mask.sum()), 1), 0.0)


def static_loads(positions: np.ndarray, com: np.ndarray, mass: float, gravity: float,
                 contact: np.ndarray | None = None) -> np.ndarray:
    """Normal load [N] on each wheel from static balance (zero for wheels not in contact).

    Args:
        positions: wheel centres p_i [m], shape (n, 2), body frame.
        com: centre of mass [m], shape (2,), body frame.
        mass: robot mass [kg]; gravity: [m/s²].
        contact: bool (n,), True where the wheel touches the floor (default all).
    """
    p = np.asarray(positions, dtype=float)
    n = p.shape[0]
    mask = np.ones(n, dtype=bool) if contact is None else np.asarray(contact, dtype=bool)
    loads = np.zeros(n)
    if not mask.any():
        return loads
    sol = np.clip(balance_loads(p[mask], com, mass * gravity), 0.0, None)
    total = sol.sum()
    # All-negative solutions cannot happen for a positive weight; guard anyway: share equally.
    sol = sol * (mass * gravity / total) if total > 0 else np.full(sol.shape, mass * gravity / sol.size)
    loads[mask] = sol
    return loads


def balance_loads(positions: np.ndarray, com: np.ndarray, weight: float) -> np.ndarray:
    """Least-norm (or least-squares) loads [N], unclipped, with Σ N_i = weight and Σ N_i (p_i − com) = 0.

    positions (k, 2) [m] and com (2,) [m] in the body frame; weight = m·g [N]. A negative entry
    means the centre of mass lies outside the support polygon of these wheels.
    """
    rel = np.asarray(positions, dtype=float) - np.asarray(com, dtype=float)
    A = np.vstack([np.ones(len(rel)), rel[:, 0], rel[:, 1]])
    return np.linalg.lstsq(A, np.array([weight, 0.0, 0.0]), rcond=None)[0]
