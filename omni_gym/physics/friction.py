"""The regularised Coulomb friction law of Williams et al. (2002) and the surfaces of their Table I.

μ(v) = μ_max · (2/π) · atan(k·v): odd in the slip speed v [m/s], saturating at ±μ_max.
The friction force on wheel i (world frame) is

    F_i = −N_i · [μ_W(v_W,i) · d_i + μ_T(v_T,i) · a_i]

with v_W the slip along the drive direction d_i and v_T the velocity along the axle direction a_i.

Friction models (which coefficients apply):

* ``initial``: roller coefficients μ'_W, μ'_T at every wheel angle (the paper's first model).
* ``roller_gap``: the rigid material between rollers touches the floor for part of each roller
  pitch; while it does, the rigid-material coefficient μ'' applies in both directions (the paper's
  improved model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEFAULT_K = 1000.0  # s/m, steepness of the regularised law (the paper's choice)
FRICTION_MODELS = ("initial", "roller_gap")


@dataclass(frozen=True)
class Surface:
    """Friction coefficients of one floor (dimensionless) and the law's steepness k [s/m].

    mu_drive: μ'_W, roller contact, along the wheel's drive direction.
    mu_transverse: μ'_T, roller contact, along the axle.
    mu_gap: μ'', rigid material between rollers, both directions.
    """

    name: str
    mu_drive: float
    mu_transverse: float
    mu_gap: float
    k: float = DEFAULT_K

    def __post_init__(self) -> None:
        for attr in ("mu_drive", "mu_transverse", "mu_gap", "k"):
            value = getattr(self, attr)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"surface {self.name!r}: {attr} must be a finite number >= 0, got {value!r}")
        if self.k <= 0:
            raise ValueError(f"surface {self.name!r}: k must be > 0, got {self.k}")

    def to_json(self) -> dict:
        return {"name": self.name, "mu_drive": self.mu_drive, "mu_transverse": self.mu_transverse,
                "mu_gap": self.mu_gap, "k": self.k}


# Williams et al. (2002), Table I; "grip" is ours: an idealised floor on which the wheels do not slip
# along their drive direction (μ'_W = 2, far above any force the robots need) and the rollers turn
# freely (μ'_T = 0), for no-slip baselines. Stiffer than the others: N·μ·(2/π)·k/m ≈ 3000 /s.
SURFACES = {
    "paper": Surface("paper", mu_drive=0.26, mu_transverse=0.09, mu_gap=0.47),
    "carpet": Surface("carpet", mu_drive=0.25, mu_transverse=0.15, mu_gap=0.56),
    "grip": Surface("grip", mu_drive=2.0, mu_transverse=0.0, mu_gap=2.0),
}


def surface_preset(name: str) -> Surface:
    if name not in SURFACES:
        raise ValueError(f"unknown surface {name!r}; choose one of {sorted(SURFACES)}")
    return SURFACES[name]


def check_friction_model(name: str) -> str:
    if name not in FRICTION_MODELS:
        raise ValueError(f"unknown friction model {name!r}; choose one of {list(FRICTION_MODELS)}")
    return name


def regularised_coulomb(v: np.ndarray | float, mu_max: np.ndarray | float, k: float = DEFAULT_K):
    """μ(v) = μ_max·(2/π)·atan(k·v) for slip speed v [m/s]."""
    return mu_max * (2.0 / np.pi) * np.arctan(k * np.asarray(v, dtype=float))


def gap_measure(angle: np.ndarray | float, pitch: float, gap_width: float):
    """Total wheel angle [rad] spent on rigid material between 0 and ``angle`` (any sign).

    Within each pitch p the rigid sector is [p/2 − g/2, p/2 + g/2], so angle 0 is mid-roller.
    The measure is odd-symmetric about 0, which makes it valid for negative angles too.
    """
    a = np.asarray(angle, dtype=float)
    n = np.floor(a / pitch)
    within = a - n * pitch
    return n * gap_width + np.clip(within - (pitch - gap_width) / 2.0, 0.0, gap_width)


def on_gap(angle: np.ndarray | float, pitch: float, gap_width: float):
    """True where the wheel touches with rigid material: |(θ mod p) − p/2| < g/2."""
    a = np.asarray(angle, dtype=float)
    return np.abs(np.mod(a, pitch) - pitch / 2.0) < gap_width / 2.0
