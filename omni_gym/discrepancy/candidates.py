"""The effect library as fit candidates: each effect's fitted dimensions, their bounds and the null point.

A candidate's parameters live in the unit cube [0, 1]^p: :meth:`Dim.value` maps a coordinate to the
parameter's bounds (log-spaced or linear; periodic dimensions wrap). :func:`null_point` is the point at
which an effect changes nothing (a fit that includes it is never worse than nominal on its training runs).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from omni_gym.physics.model import SimModel


@dataclass(frozen=True)
class Dim:
    """One fitted parameter: bounds [lo, hi] (log-spaced if ``log``; ``periodic`` wraps)."""

    name: str
    lo: float
    hi: float
    log: bool = False
    periodic: bool = False

    def value(self, u: float) -> float:
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))


@dataclass(frozen=True)
class Candidate:
    """A library effect with its fitted dimensions and how they map to the effect's parameters."""

    name: str
    dims: tuple[Dim, ...]
    build: Callable[[list[float]], dict]
    stochastic: bool = False

    @property
    def n_params(self) -> int:
        return len(self.dims)

    def params(self, u: np.ndarray) -> dict:
        return self.build([d.value(float(x)) for d, x in zip(self.dims, u, strict=True)])


def candidates(model: SimModel) -> list[Candidate]:
    """The effect library as fit candidates for ``model`` (bounds wide enough for real robots)."""
    n = model.n_wheels
    pitch = 2 * math.pi / model.robot.rollers
    lever = float(np.max(np.hypot(*model.robot.positions().T)))
    c = 0.4 * lever  # the centre of mass well inside the support polygon
    return [
        Candidate("roller_gap", (Dim("mu_gap", 0.05, 1.5), Dim("roller_fraction", 0.6, 1.0),
                                 *[Dim(f"phase{i + 1}", 0.0, pitch, periodic=True) for i in range(n)]),
                  lambda v: {"mu_gap": v[0], "roller_fraction": v[1], "phase": list(v[2:])}),
        Candidate("kinetic_friction", (Dim("ratio", 0.2, 1.0), Dim("v_s", 0.002, 0.3, log=True)),
                  lambda v: {"ratio": v[0], "v_s": v[1]}),
        Candidate("com_offset", (Dim("cx", -c, c), Dim("cy", -c, c)), lambda v: {"com": [v[0], v[1]]}),
        Candidate("wheel_radius", tuple(Dim(f"scale{i + 1}", 0.85, 1.15) for i in range(n)),
                  lambda v: {"scale": list(v)}),
        Candidate("motor_lag", (Dim("tau", 0.001, 0.5, log=True),), lambda v: {"tau": v[0]}),
        Candidate("wheel_liftoff", (Dim("lift_rate", 0.05, 5.0, log=True), Dim("recover_rate", 0.5, 50.0, log=True)),
                  lambda v: {"lift_rate": v[0], "recover_rate": v[1]}, stochastic=True),
    ]


def null_point(cand: Candidate, nominal: SimModel) -> np.ndarray | None:
    """Unit-cube point at which the effect changes nothing (None when the family has none)."""
    lo = {d.name: d.lo for d in cand.dims}
    hi = {d.name: d.hi for d in cand.dims}
    if cand.name == "kinetic_friction":
        null = {"ratio": 1.0}
    elif cand.name == "roller_gap":
        null = {"roller_fraction": 1.0}  # no rigid material: the initial model
    elif cand.name == "com_offset":
        null = {"cx": float(nominal.com[0]), "cy": float(nominal.com[1])}
    elif cand.name == "motor_lag":
        null = {"tau": lo["tau"]}
    elif cand.name == "wheel_liftoff":
        null = {"lift_rate": lo["lift_rate"], "recover_rate": hi["recover_rate"]}
    elif cand.name == "wheel_radius":
        null = {d.name: 1.0 for d in cand.dims}
    else:
        null = None
    if null is None:
        return None
    u = np.full(cand.n_params, 0.5)
    for j, d in enumerate(cand.dims):
        if d.name in null:
            v = null[d.name]
            u[j] = ((math.log(v) - math.log(d.lo)) / (math.log(d.hi) - math.log(d.lo)) if d.log
                    else (v - d.lo) / (d.hi - d.lo))
    if cand.name == "kinetic_friction":
        u[1] = 0.5  # v_s is irrelevant at ratio 1
    return np.clip(u, 0.0, 1.0)


def to_cube(cand: Candidate, u: np.ndarray) -> np.ndarray:
    """``u`` moved into the unit cube: periodic dimensions wrapped, the others clipped (a copy)."""
    out = u.copy()
    for j, d in enumerate(cand.dims):
        out[j] = np.mod(out[j], 1.0) if d.periodic else np.clip(out[j], 0.0, 1.0)
    return out
