"""Robot descriptions: wheel layout, mass properties and wheel geometry.

Frames and conventions (see ``docs/conventions.md``):

* Body frame: origin at the robot's geometric centre, x forward, y to the left, z up.
* Every wheel *i* has a centre ``position`` p_i [m] and a unit ``drive`` direction d_i in the body
  frame. A positive wheel speed w_i [rad/s] moves the wheel centre along +d_i at r·w_i without slip.
* The ``axle`` direction is a_i = z × d_i = (-d_y, d_x): the transverse (roller) direction.
* ``com`` [m] is the centre of mass in the body frame; the yaw ``inertia`` [kg·m²] is about it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from omni_gym.bounds import wheel_count

GRAVITY = 9.81  # m/s², standard gravity


@dataclass(frozen=True)
class Wheel:
    """One omni wheel: centre ``position`` [m] and unit ``drive`` direction, both in the body frame."""

    position: tuple[float, float]
    drive: tuple[float, float]

    @property
    def axle(self) -> tuple[float, float]:
        """Unit transverse direction z × drive (the roller axis direction's normal in the plane)."""
        return (-self.drive[1], self.drive[0])


@dataclass(frozen=True)
class RobotSpec:
    """Geometry and mass properties of an omnidirectional robot.

    Attributes:
        name: preset or user name.
        wheels: the omni wheels, body frame.
        wheel_radius: rolling radius r [m].
        mass: total mass m [kg].
        inertia: yaw moment of inertia about the centre of mass [kg·m²].
        com: centre of mass [m], body frame (default the geometric centre).
        rollers: rollers per wheel (sets the roller/rigid-material pitch 2π/rollers).
        roller_fraction: share of each pitch covered by roller (the rest is rigid material).
        body_radius: radius of the collision disc [m] used by the world.
        assumptions: parameter name → why its value was chosen where no source gives it.
    """

    name: str
    wheels: tuple[Wheel, ...]
    wheel_radius: float
    mass: float
    inertia: float
    com: tuple[float, float] = (0.0, 0.0)
    rollers: int = 8
    roller_fraction: float = 0.9
    body_radius: float = 0.1
    assumptions: dict[str, str] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        lo, hi = wheel_count()
        if not lo <= len(self.wheels) <= hi:
            raise ValueError(f"robot {self.name!r}: needs {lo} to {hi} wheels, got {len(self.wheels)}")
        for i, w in enumerate(self.wheels):
            norm = math.hypot(*w.drive)
            if not math.isfinite(norm) or abs(norm - 1.0) > 1e-6:
                raise ValueError(f"robot {self.name!r}: wheel {i + 1} drive direction must be a unit vector")
            if not all(math.isfinite(c) for c in w.position):
                raise ValueError(f"robot {self.name!r}: wheel {i + 1} position is not finite")
        for attr in ("wheel_radius", "mass", "inertia", "body_radius"):
            value = getattr(self, attr)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"robot {self.name!r}: {attr} must be a positive number, got {value}")
        if not all(math.isfinite(c) for c in self.com):
            raise ValueError(f"robot {self.name!r}: com is not finite")
        if int(self.rollers) != self.rollers or self.rollers < 1:
            raise ValueError(f"robot {self.name!r}: rollers must be a positive integer, got {self.rollers}")
        if not 0.0 < self.roller_fraction <= 1.0:
            raise ValueError(f"robot {self.name!r}: roller_fraction must be in (0, 1], got {self.roller_fraction}")
        if np.linalg.matrix_rank(self.wheel_matrix()) < 3:
            raise ValueError(f"robot {self.name!r}: wheel layout cannot produce every body twist (rank < 3)")

    @property
    def n_wheels(self) -> int:
        return len(self.wheels)

    def positions(self) -> np.ndarray:
        """Wheel centres p_i, shape (n, 2) [m], body frame."""
        return np.array([w.position for w in self.wheels], dtype=float)

    def drives(self) -> np.ndarray:
        """Drive directions d_i, shape (n, 2), body frame."""
        return np.array([w.drive for w in self.wheels], dtype=float)

    def axles(self) -> np.ndarray:
        """Transverse directions a_i = z × d_i, shape (n, 2), body frame."""
        d = self.drives()
        return np.stack([-d[:, 1], d[:, 0]], axis=1)

    def wheel_matrix(self) -> np.ndarray:
        """W (n×3): body twist (vx, vy, ω) of the geometric centre → no-slip wheel speeds [rad/s].

        Row i is (d_i · [1, 0], d_i · [0, 1], d_i · (z × p_i)) / r, from the wheel-centre velocity
        V + ω z × p_i projected on d_i.
        """
        p, d = self.positions(), self.drives()
        lever = d[:, 1] * p[:, 0] - d[:, 0] * p[:, 1]  # d · (z × p) = p_x d_y − p_y d_x
        return np.column_stack([d[:, 0], d[:, 1], lever]) / self.wheel_radius

    def with_changes(self, **changes) -> RobotSpec:
        """A copy with some attributes replaced (validated again)."""
        return replace(self, **changes)


def tangential_wheels(radius: float, angles: list[float]) -> tuple[Wheel, ...]:
    """Wheels on a circle of ``radius`` [m] at body-frame ``angles`` [rad], driving counter-clockwise.

    Wheel i sits at radius·(cos α_i, sin α_i) with drive (−sin α_i, cos α_i): all wheels turning
    forward spin the robot counter-clockwise (positive yaw).
    """
    return tuple(
        Wheel(
            position=(radius * math.cos(a), radius * math.sin(a)),
            drive=(-math.sin(a), math.cos(a)),
        )
        for a in angles
    )


# --- presets -------------------------------------------------------------------------------------

WILLIAMS_L = 0.09  # m, wheel-centre radius; see assumptions below
WILLIAMS_R = 0.03  # m, wheel radius
WILLIAMS_MASS = 2.0  # kg
WILLIAMS_DELTA = math.radians(14.0)  # angle of each front wheel centre from the body x axis (tuned)


def williams2002() -> RobotSpec:
    """Three-wheeled robot of Williams, Carter, Gallina & Rosati (IEEE T-RA 18(3), 2002).

    Wheel 3 (rear) sits at (0, −L) and drives along +x ("aligned with the body x axis"); the front
    pair sits at angle δ from the x axis, symmetric about the y axis (wheel 1 right-front, wheel 2
    left-front), all driving counter-clockwise. 8 rollers; roller 90 % / rigid material 10 %.
    """
    L = WILLIAMS_L
    delta = WILLIAMS_DELTA
    wheels = tangential_wheels(L, [delta, math.pi - delta, -math.pi / 2])
    return RobotSpec(
        name="williams2002",
        wheels=wheels,
        wheel_radius=WILLIAMS_R,
        mass=WILLIAMS_MASS,
        inertia=0.5 * WILLIAMS_MASS * L**2,
        rollers=8,
        roller_fraction=0.9,
        body_radius=L + 0.01,
        assumptions={
            "mass": "2.0 kg: not given in the paper; a small RoboCup F180-class base, the value of the "
            "project's time-step study (semi-implicit Euler against scipy Radau: 0.5 ms substeps meet "
            "1 mm / 2 mrad; docs/model.md, 'Integration step: measured facts').",
            "inertia": "0.5·m·L² = 0.0081 kg·m²: uniform disc of radius L, no number in the paper.",
            "wheel_centre_radius L": "0.09 m: RoboCup F180 size limit (18 cm diameter), as in the "
            "time-step study.",
            "wheel_radius": "0.03 m: small commercial omni wheel (Kornylak-type), as in the time-step study.",
            "front-wheel angle δ": "14° from the body x axis: lost from our copy of the paper, which says only "
            "that δ differs from the symmetric 30° because of RoboCup size limits. Fitted by "
            "benchmarks/tune_williams.py so the paper's maneuver reproduces the paper's own simulation "
            "results, subject to the robot staying drivable along x on carpet (best fit 14.1°, rounded).",
        },
    )


def phunopas2018() -> RobotSpec:
    """Four-wheeled robot of Phunopas & Inoue (2018): wheels at 45° + k·90°, R = 0.10 m, r = 0.05 m.

    Drive directions follow the paper's eq. (3): wheel i has w_i = (−sin α_i vx + cos α_i vy + R ω)/r.
    """
    R = 0.10
    return regular(4, radius=R, wheel_radius=0.05, mass=3.0, offset=math.pi / 4, name="phunopas2018").with_changes(
        body_radius=R + 0.02,
        assumptions={
            "mass": "3.0 kg: not given in the paper; a small indoor four-wheeled base.",
            "inertia": "0.5·m·R² = 0.015 kg·m²: uniform disc of radius R, no number in the paper.",
            "rollers, roller_fraction": "8 and 0.9: the paper gives none; the Williams wheel's values.",
        },
    )


def regular(n: int, radius: float = 0.1, wheel_radius: float = 0.03, mass: float = 2.0,
            offset: float = 0.0, name: str | None = None) -> RobotSpec:
    """``n`` wheels evenly spaced on a circle of ``radius`` [m], the first at ``offset`` [rad]."""
    lo, hi = wheel_count()
    if int(n) != n or not lo <= n <= hi:  # before anything is built: n sets the allocation
        raise ValueError(f"regular robot: n must be an integer from {lo} to {hi}, got {n}")
    angles = [offset + 2 * math.pi * k / n for k in range(int(n))]
    return RobotSpec(
        name=name or f"regular{int(n)}",
        wheels=tangential_wheels(radius, angles),
        wheel_radius=wheel_radius,
        mass=mass,
        inertia=0.5 * mass * radius**2,
        body_radius=radius + 0.01,
        assumptions={"inertia": "0.5·m·R²: uniform disc of the wheel-circle radius."},
    )


PRESETS = {
    "williams2002": williams2002,
    "phunopas2018": phunopas2018,
}


def robot_preset(name: str) -> RobotSpec:
    """A preset by name: ``williams2002``, ``phunopas2018`` or ``regularN`` (N from 3 to 16 wheels,
    ``omni_gym.bounds.wheel_count``)."""
    if name in PRESETS:
        return PRESETS[name]()
    lo, hi = wheel_count()
    digits = name[len("regular"):]
    if name.startswith("regular") and digits.isascii() and digits.isdigit():
        # The digit string is checked before int(): a 10⁵-digit N must not cost a conversion.
        if len(digits.lstrip("0")) > len(str(hi)) or not lo <= int(digits) <= hi:
            shown = digits if len(digits) <= 12 else f"{digits[:6]}…({len(digits)} digits)"
            raise ValueError(f"robot {_short(name)}: regularN takes N from {lo} to {hi} wheels, got {shown}")
        return regular(int(digits))
    raise ValueError(f"unknown robot {_short(name)}; choose one of {sorted(PRESETS)} or regularN, N from {lo} to {hi} "
                     "(e.g. regular5)")


def _short(name: str, limit: int = 40) -> str:
    """``repr(name)``, cut to ``limit`` characters with '…' (a 10⁵-character name stays one readable line)."""
    return repr(name) if len(name) <= limit else repr(name[:limit]) + "…"
