"""Robot descriptions: wheel layout, mass properties and wheel geometry.

Frames and conventions (see ``docs/conventions.md``):

* Body frame: origin at the robot's geometric centre, x forward, y to the left, z up.
* Every wheel *i* has a centre ``position`` p_i [m] and a unit ``drive`` direction d_i in the body
  frame. A positive wheel speed w_i [rad/s] moves the wheel centre along +d_i at r·w_i without slip.
* The ``axle`` direction is a_i = z × d_i = (-d_y, d_x): the transverse direction.
* Every wheel has a ``roller_angle`` γ_i [rad]: the axis of the roller touching the floor points along
  u_i = cos γ_i·d_i + sin γ_i·a_i (the direction the wheel constrains); the rollers roll freely along
  f_i = z × u_i. γ = 0 is an omni wheel (u = d, f = a), γ = ±π/4 a mecanum wheel.
* ``com`` [m] is the centre of mass in the body frame; the yaw ``inertia`` [kg·m²] is about it.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field, replace

import numpy as np

from omni_gym.bounds import ROLLER_ANGLE_MAX, ROLLER_ANGLE_REASON, wheel_count

GRAVITY = 9.81  # m/s², standard gravity


@dataclass(frozen=True)
class Wheel:
    """One wheel: centre ``position`` [m] and unit ``drive`` direction (body frame), ``roller_angle`` γ [rad].

    γ is the angle of the floor roller's axis from the drive direction, counter-clockwise seen from
    above: the axis is u = cos γ·d + sin γ·a (a = z × d). γ = 0: omni wheel (rollers in the wheel
    plane, free across it); γ = ±π/4: mecanum wheel. Without slip the wheel centre's velocity v_c
    satisfies v_c·u = r·w·cos γ (``docs/conventions.md``).
    """

    position: tuple[float, float]
    drive: tuple[float, float]
    roller_angle: float = 0.0

    @property
    def axle(self) -> tuple[float, float]:
        """Unit transverse direction a = z × drive (the wheel's axle, horizontal)."""
        return (-self.drive[1], self.drive[0])

    @property
    def roller_axis(self) -> tuple[float, float]:
        """Unit direction u = cos γ·d + sin γ·a the wheel constrains (the floor roller's axis)."""
        c, s = math.cos(self.roller_angle), math.sin(self.roller_angle)
        return (c * self.drive[0] - s * self.drive[1], c * self.drive[1] + s * self.drive[0])

    @property
    def free_direction(self) -> tuple[float, float]:
        """Unit direction f = z × u along which the floor roller rolls freely."""
        u = self.roller_axis
        return (-u[1], u[0])


@dataclass(frozen=True)
class RobotSpec:
    """Geometry and mass properties of an omnidirectional robot (omni or mecanum wheels).

    Attributes:
        name: preset or user name.
        wheels: the wheels, body frame (omni wheels, or mecanum wheels by their roller angle).
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
            if not (math.isfinite(w.roller_angle) and abs(w.roller_angle) <= ROLLER_ANGLE_MAX):
                raise ValueError(f"robot {self.name!r}: wheel {i + 1} roller_angle must be in "
                                 f"[-{ROLLER_ANGLE_MAX:.4g}, {ROLLER_ANGLE_MAX:.4g}] rad, got {w.roller_angle!r} "
                                 f"({ROLLER_ANGLE_REASON})")
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

    def lever(self) -> float:
        """The largest wheel-centre distance from the body origin [m]: the length that turns a heading error
        [rad] into a displacement [m] (pose residuals) and sizes offsets from the centre."""
        return float(np.max(np.hypot(*self.positions().T)))

    def drives(self) -> np.ndarray:
        """Drive directions d_i, shape (n, 2), body frame."""
        return np.array([w.drive for w in self.wheels], dtype=float)

    def axles(self) -> np.ndarray:
        """Transverse directions a_i = z × d_i, shape (n, 2), body frame."""
        d = self.drives()
        return np.stack([-d[:, 1], d[:, 0]], axis=1)

    def roller_angles(self) -> np.ndarray:
        """Roller angles γ_i [rad], shape (n,)."""
        return np.array([w.roller_angle for w in self.wheels], dtype=float)

    @property
    def has_angled_rollers(self) -> bool:
        """True if some wheel's rollers sit at an angle to its plane (γ ≠ 0: a mecanum wheel)."""
        return any(w.roller_angle != 0.0 for w in self.wheels)

    def roller_axes(self) -> np.ndarray:
        """Constrained directions u_i = cos γ_i d_i + sin γ_i a_i, shape (n, 2), body frame (= d_i for γ = 0)."""
        d = self.drives()
        g = self.roller_angles()
        if not np.any(g):
            return d
        a = self.axles()
        return np.cos(g)[:, None] * d + np.sin(g)[:, None] * a

    def free_directions(self) -> np.ndarray:
        """Free rolling directions f_i = z × u_i, shape (n, 2), body frame (= a_i for γ = 0)."""
        u = self.roller_axes()
        return np.stack([-u[:, 1], u[:, 0]], axis=1)

    def wheel_matrix(self) -> np.ndarray:
        """W (n×3): body twist (vx, vy, ω) of the geometric centre → no-slip wheel speeds [rad/s].

        Row i is (u_i · [1, 0], u_i · [0, 1], u_i · (z × p_i)) / (r cos γ_i): the wheel-centre velocity
        V + ω z × p_i projected on the roller axis u_i equals r·w_i·cos γ_i without slip. For an omni
        wheel (γ = 0) u_i = d_i and the row is (d_i, d_i · (z × p_i)) / r; equivalently the row is
        (d_i + tan γ_i a_i) · (…) / r.
        """
        p, u = self.positions(), self.roller_axes()
        lever = u[:, 1] * p[:, 0] - u[:, 0] * p[:, 1]  # u · (z × p) = p_x u_y − p_y u_x
        m = np.column_stack([u[:, 0], u[:, 1], lever])
        g = self.roller_angles()
        if not np.any(g):
            return m / self.wheel_radius
        return m / (self.wheel_radius * np.cos(g))[:, None]

    def with_changes(self, **changes) -> RobotSpec:
        """A copy with some attributes replaced (validated again)."""
        return replace(self, **changes)


def tangential_wheels(radius: float, angles: list[float], clockwise: bool = False) -> tuple[Wheel, ...]:
    """Wheels on a circle of ``radius`` [m] at body-frame ``angles`` [rad], driving counter-clockwise.

    Wheel i sits at radius·(cos α_i, sin α_i) with drive (−sin α_i, cos α_i): all wheels turning
    forward spin the robot counter-clockwise (positive yaw); ``clockwise``: drive (sin α_i, −cos α_i).
    """
    sign = -1.0 if clockwise else 1.0
    return tuple(
        Wheel(
            position=(radius * math.cos(a), radius * math.sin(a)),
            drive=(sign * -math.sin(a), sign * math.cos(a)),
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


OPTIODOM_MASS = 4.0  # kg; see the assumptions of optiodom_omni4


def optiodom_omni4(l1: float = 0.2, l2: float = 0.2,
                   diameters: tuple[float, float, float, float] = (0.06, 0.06, 0.06, 0.06)) -> RobotSpec:
    """The four-wheeled mecanum robot of the OptiOdom dataset (Sousa et al. 2022; kinematics of Lin et al. 2019).

    OptiOdom's omni4 odometry maps the wheel travels Δ_i [m] of one cycle to the body displacement
    dx = (Δ1 − Δ2 + Δ3 − Δ4)/4, dy = (−Δ1 − Δ2 + Δ3 + Δ4)/4, dθ = −(Δ1 + Δ2 + Δ3 + Δ4)/(2(l1 + l2)),
    the least-squares inverse of Δ1 = dx − dy − c·dθ, Δ2 = −dx − dy − c·dθ, Δ3 = dx + dy − c·dθ,
    Δ4 = −dx + dy − c·dθ with c = (l1 + l2)/2. This layout reproduces it exactly (r·W is that matrix):
    wheels at (±l1/2, ±l2/2) [m] (l1 along the body x axis, l2 along y; only l1 + l2 enters the
    matrix), the left wheels 1 (front) and 3 (rear) driving along +x and the right wheels 2 (front)
    and 4 (rear) along −x (mirror-mounted motors), rollers at γ = −45°, +45°, +45°, −45°.

    ``diameters`` D_i [m]: the model has one nominal wheel radius, so they must be equal here
    (ValueError otherwise); for per-wheel diameters use their mean and the ``wheel_radius`` effect
    with scale D_i / mean (:func:`optiodom_omni4_radius_scales`).
    """
    diameters = tuple(float(v) for v in diameters)
    if len(diameters) != 4 or not all(math.isfinite(v) and v > 0 for v in diameters):
        raise ValueError(f"optiodom_omni4: diameters must be 4 positive numbers [m], got {diameters!r}")
    if len(set(diameters)) != 1:
        raise ValueError("optiodom_omni4: the wheel diameters differ; the robot has one nominal radius: use "
                         "optiodom_omni4_radius_scales(diameters) for the mean diameter and a wheel_radius effect")
    for name, value in (("l1", l1), ("l2", l2)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"optiodom_omni4: {name} must be a positive length [m], got {value!r}")
    hx, hy = 0.5 * l1, 0.5 * l2
    q = math.pi / 4
    wheels = (
        Wheel(position=(hx, hy), drive=(1.0, 0.0), roller_angle=-q),
        Wheel(position=(hx, -hy), drive=(-1.0, 0.0), roller_angle=q),
        Wheel(position=(-hx, hy), drive=(1.0, 0.0), roller_angle=q),
        Wheel(position=(-hx, -hy), drive=(-1.0, 0.0), roller_angle=-q),
    )
    mass = OPTIODOM_MASS
    side_x, side_y = l1 + diameters[0], l2 + diameters[0]  # chassis footprint with the wheels, m
    return RobotSpec(
        name="optiodom_omni4",
        wheels=wheels,
        wheel_radius=0.5 * diameters[0],
        mass=mass,
        inertia=mass * (side_x**2 + side_y**2) / 12.0,
        rollers=9,
        roller_fraction=1.0,
        body_radius=math.hypot(hx, hy) + 0.5 * diameters[0],
        assumptions={
            "layout": "wheels at (±l1/2, ±l2/2) with l1 along x: the dataset documents only the kinematic matrix, "
            "in which only l1 + l2 enters; drive directions and roller angles are the ones that reproduce it "
            "exactly (tests/test_kinematics.py).",
            "mass": "4.0 kg: not published with the dataset; a small mecanum base with 60 mm wheels, four geared "
            "DC motors (~0.2 kg each), a battery (~0.5 kg) and an on-board computer on a ~0.25 m aluminium "
            "chassis weighs 3-5 kg (e.g. educational 60 mm mecanum kits).",
            "inertia": "m·(a² + b²)/12 with a = l1 + D, b = l2 + D: a uniform rectangular plate the size of the "
            "footprint including the wheels (0.045 kg·m² at the nominal geometry); no number is published.",
            "rollers": "9: a typical roller count of 60 mm mecanum wheels; it only sets the roller pitch, which "
            "matters to the roller_gap model, and that model does not apply to mecanum wheels.",
            "roller_fraction": "1.0: a mecanum wheel's rollers overlap seen from the side, so the wheel always "
            "touches the floor with a roller (no rigid material between rollers).",
            "surface": "not characterised with the data; any surface preset applies (model show and simulate "
            "default to carpet, the import of real runs to grip, the rolling without slip that OptiOdom's "
            "kinematic odometry assumes).",
        },
    )


OPTIODOM_OMNI3_MASS = 8.0  # kg; see the assumptions of optiodom_omni3
# omni3's wheels sit at distance L at these body-frame angles [deg] (x forward, y left) and drive clockwise
# tangentially, d_i = (sin α_i, −cos α_i): the dataset README's table, (−0.866, −0.5), (0.866, −0.5), (0, 1).
OPTIODOM_OMNI3_ANGLES_DEG = (-60.0, 60.0, 180.0)


def _exact_zero(v: float, scale: float) -> float:
    """cos(90°) and sin(180°) are 6e-17 in floating point: a written layout shows exact zeros."""
    return 0.0 if abs(v) < 1e-12 * scale else v


def optiodom_omni3(L: float = 0.195, diameter: float = 0.102) -> RobotSpec:
    """The three-wheeled omni robot of the OptiOdom dataset (Sousa et al. 2022; ``data/optiodom-omni3/README.md``).

    Wheels at distance ``L`` [m] from the centre at −60°, 60° and 180°, driving clockwise tangentially:
    equal positive wheel speeds turn the robot clockwise (yaw rate −r·w/L), as the dataset README states.
    ``diameter`` [m]: the nominal wheel diameter (the importer uses the mean of the logged ones and a
    ``wheel_radius`` effect for their differences). Mass properties and rollers are assumed (below).
    """
    for name, value in (("L", L), ("diameter", diameter)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"optiodom_omni3: {name} must be a positive length [m], got {value!r}")
    wheels = [Wheel(position=(_exact_zero(w.position[0], L), _exact_zero(w.position[1], L)),
                    drive=(_exact_zero(w.drive[0], 1.0), _exact_zero(w.drive[1], 1.0)))
              for w in tangential_wheels(L, [math.radians(deg) for deg in OPTIODOM_OMNI3_ANGLES_DEG], clockwise=True)]
    rho = max(math.hypot(*w.position) for w in wheels)  # L, up to rounding
    mass = OPTIODOM_OMNI3_MASS
    return RobotSpec(
        name="optiodom_omni3",
        wheels=tuple(wheels),
        wheel_radius=0.5 * diameter,
        mass=mass,
        inertia=0.5 * mass * rho**2,
        rollers=18,
        roller_fraction=1.0,
        body_radius=rho + 0.05,
        assumptions={
            "mass": "8 kg: not published with the dataset; a three-wheeled base about 0.45 m across (wheels at "
            "0.195 m, 102 mm wheels, geared DC motors, battery and computer on board) typically weighs this.",
            "inertia": "0.5·m·L²: a uniform disc of the wheel-centre radius (the convention of regular()); no "
            "number is published.",
            "rollers": "18: a 102 mm (4-inch class) omni wheel is most often a double-row wheel with two staggered "
            "rows of 9 rollers.",
            "roller_fraction": "1.0: the staggered rows overlap, so a roller always touches the floor (friction "
            "model initial, no roller-gap switching).",
            "body_radius": "L + 0.05 m: the wheel-centre radius and about half a wheel (the world's walls).",
            "surface": "not characterised with the data; the import of real runs uses grip, the rolling without "
            "slip that OptiOdom's kinematic odometry assumes.",
        },
    )


def optiodom_omni4_radius_scales(diameters) -> tuple[float, list[float]]:
    """(nominal wheel diameter [m] = mean of ``diameters``, per-wheel ``wheel_radius`` effect scales D_i / mean)."""
    d = [float(v) for v in diameters]
    mean = sum(d) / len(d)
    return mean, [v / mean for v in d]


PRESETS = {
    "williams2002": williams2002,
    "phunopas2018": phunopas2018,
    "optiodom_omni3": optiodom_omni3,
    "optiodom_omni4": optiodom_omni4,
}


def robot_preset(name: str) -> RobotSpec:
    """A preset by name (:data:`PRESETS`: ``williams2002``, ``phunopas2018``, ``optiodom_omni3``, ``optiodom_omni4``)
    or ``regularN`` (N from 3 to 16 wheels, ``omni_gym.bounds.wheel_count``)."""
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
    close = difflib.get_close_matches(name.replace("-", "_").lower(), PRESETS, n=1, cutoff=0.8)
    hint = f"did you mean {close[0]}? " if close else ""
    raise ValueError(f"unknown robot {_short(name)}; {hint}choose one of {sorted(PRESETS)} or regularN, N from {lo} "
                     f"to {hi} (e.g. regular5)")


def _short(name: str, limit: int = 40) -> str:
    """``repr(name)``, cut to ``limit`` characters with '…' (a 10⁵-character name stays one readable line)."""
    return repr(name) if len(name) <= limit else repr(name[:limit]) + "…"
