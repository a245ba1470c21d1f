"""A second, separately written integrator of the wheel-floor model, with event handling.

Written from the documented equations only (``docs/model.md``, ``docs/conventions.md``, the effect
tables of ``docs/discrepancy.md``), not from the world, its kernel or the first reference integrator
(:mod:`omni_gym.analysis.reference`). It reads the robot's numbers from a
:class:`~omni_gym.physics.model.SimModel` (mass, inertia, wheels, surface, the effects' parameters) and
implements every physics effect itself. Used by :mod:`omni_gym.analysis.second_generator` to write
validation datasets that the discrepancy workflow did not fit with.

Equations (world frame, SI)
---------------------------
State y = (X, Y, θ, Vx, Vy, ω, φ_1 … φ_n[, w_1 … w_n]): the centre of mass (COM) position and
velocity, the heading, the yaw rate, the wheel angles φ_i and, with ``motor_lag``, the wheel speeds.

    m dV/dt = Σ F_i − c·V            I dω/dt = Σ ρ_i × F_i − c_rot·ω
    ρ_i = R(θ)(p_i − com),  u_i = V + ω z × ρ_i,  e_i = R(θ)(cos γ_i d_i + sin γ_i a_i),  f_i = z × e_i
    v_W = u_i·e_i − r_i w_i cos γ_i,  v_T = u_i·f_i + r_i w_i sin γ_i
    F_i = −N_i [μ_W(v_W) e_i + μ_T(v_T) f_i],  μ(v) = μ_max (2/π) atan(k v)

(c, c_rot: the ``drag`` effect outside the library, 0 otherwise; the ``slope`` effect, also outside the
library, adds the downhill acceleration g·sin α·(cos β, sin β) to dV/dt and carries the weight's normal
share cos α on the wheels). The tracked pose is the geometric
centre's: (X, Y) − R(θ)·com.

Choices where the documents leave room (each one a place where this integrator may differ from the
world, on purpose written down):

* **Loads.** Equal shares m·g/n_contact over the wheels in contact when the COM is exactly the
  geometric centre (``docs/model.md``: "the paper's assumption"; note that for the ``williams2002``
  layout static balance would *not* give equal shares). Otherwise static balance Σ N_i = m g,
  Σ N_i (p_i − com) = 0 over the wheels in contact, least-norm (pseudo-inverse) for more than three;
  a negative load is clipped by an active set: the wheel is dropped and the balance re-solved on the
  others (a careful reading of "clipped at zero" that keeps Σ N = m g). The loads use the wheel
  positions after ``wheel_geometry``, body frame, independent of the motion (no load transfer).
* **Roller/rigid material.** Wheel i touches rigid material while
  \\|((φ_i + phase_i) mod p) − p/2\\| < (1 − roller_fraction)·p/2, p = 2π/rollers; there μ'' replaces
  both μ'_W and μ'_T (the same law, k unchanged). The boundaries are located by ``solve_ivp`` event
  functions on the integrated wheel angle (so they are exact for the lagged wheel too); a wheel
  exactly at a boundary at the start is put on the side it moves to.
* **Kinetic friction** shapes every coefficient (μ'_W, μ'_T and μ''), each with its own slip.
* **mecanum_lateral**: r_i ← r_i·2/(1 + ratio) and tan γ_i ← tan γ_i / ratio, after ``wheel_radius``
  scaled r_i; ``wheel_geometry`` scales the wheel position by ``distance`` and yaws d_i (and with it
  e_i, f_i) by ``mount``.
* **Actuation.** Ideal velocity source: φ̇_i = command_i; ``motor_lag``: ẇ_i = (command_i − w_i)/τ,
  φ̇_i = w_i, w_i = 0 at the start (the robot starts at rest), integrated by the solver with the body.
  Encoders read φ_i.
* **Commands** are piecewise constant, row j held on [t_j, t_{j+1}) exactly (no rounding to a substep);
  past the last row the last command is held (needed only for a negative tracker delay).
* **Lift-off.** A lifted wheel carries no load (no force); its angle still follows its speed. The
  schedule is a list of (time, lifted mask) switches, applied exactly at their times.
  :func:`draw_lift_schedule` draws it from the documented contact process: from all-down a lift
  after Exp(1/lift_rate) into a case chosen uniformly among "one wheel up" (n cases) and "a diagonal
  pair up" (for an even n: wheel i with the wheel nearest to −p_i; a three-wheeled robot has no
  diagonal pair, and two of its three wheels up would tip it over), back to all-down after
  Exp(1/recover_rate).

Event handling: the run is split at every command change and every lift-off switch; within a piece,
``solve_ivp`` (LSODA by default, rtol 1e-8; Radau on request) integrates with two terminal,
directional events per gap-switching wheel, the two boundaries of the roller/rigid interval its angle
is in. At an event the wheel's region index is stepped (with it any wheel within 1e-9 rad of its own
boundary and moving across it: equal wheels of a turn in place cross together), its angle put onto
the boundary (a correction at the solver's root tolerance; 1e-12 rad past it, on the new side) and
the integration restarted, so no step straddles a friction discontinuity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from omni_gym.physics.model import SimModel

TRACKER_EFFECTS = ("tracker_offset", "time_offset")
PHYSICS_EFFECTS = ("com_offset", "wheel_radius", "wheel_geometry", "motor_lag", "kinetic_friction",
                   "roller_gap", "wheel_liftoff", "mecanum_lateral")
EXTRA_EFFECTS = ("drag", "slope")


@dataclass(frozen=True)
class Plant:
    """The robot as this integrator sees it, every physics effect applied (body frame, SI).

    positions (n, 2) [m] and drives (n, 2) (unit) of the wheels from the geometric centre; gammas (n,)
    roller angles [rad]; radii (n,) rolling radii [m]; mu_w, mu_t, mu_gap friction coefficients; k
    [s/m]; gap: whether rigid material between rollers is modelled; pitch [rad] and gap_half [rad] its
    geometry, phases (n,) [rad]; kinetic (ratio, v_s [m/s]) or None; tau [s] motor lag or None; drag
    c [N·s/m] and c_rot [N·m·s].
    """

    mass: float
    inertia: float
    gravity: float
    com: np.ndarray
    positions: np.ndarray
    drives: np.ndarray
    gammas: np.ndarray
    radii: np.ndarray
    mu_w: float
    mu_t: float
    mu_gap: float
    k: float
    gap: bool
    pitch: float
    gap_half: float
    phases: np.ndarray
    kinetic: tuple[float, float] | None = None
    tau: float | None = None
    drag: float = 0.0
    drag_rot: float = 0.0
    lift: tuple[float, float] | None = None  # (lift_rate, recover_rate) [1/s] of wheel_liftoff
    slope: tuple[float, float] = (0.0, 0.0)  # downhill acceleration g·sin α (cos β, sin β) [m/s²], world frame
    normal_scale: float = 1.0  # cos α: the share of the weight the tilted floor carries

    @property
    def n(self) -> int:
        return len(self.radii)

    def loads(self, lifted: np.ndarray) -> np.ndarray:
        """(n,) normal loads [N] with the wheels of ``lifted`` (n,) bool off the floor."""
        weight = self.mass * self.gravity * self.normal_scale
        contact = ~np.asarray(lifted, dtype=bool)
        loads = np.zeros(self.n)
        if not contact.any():
            return loads
        if not np.any(self.com):
            loads[contact] = weight / contact.sum()
            return loads
        active = contact.copy()
        while active.any():
            idx = np.flatnonzero(active)
            rel = self.positions[idx] - self.com
            a = np.vstack([np.ones(len(idx)), rel[:, 0], rel[:, 1]])
            sol = np.linalg.pinv(a) @ np.array([weight, 0.0, 0.0])
            if np.all(sol >= 0.0):
                loads[idx] = sol
                return loads
            active[idx[np.argmin(sol)]] = False
        return loads


def _finite(value, where: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{where}: NaN or infinity in {value!r}")
    return arr


def _per_wheel(params: dict, key: str, effect: str, n: int) -> np.ndarray:
    if key not in params:
        raise ValueError(f"effect {effect!r}: missing parameter {key!r}")
    arr = _finite(params[key], f"effect {effect!r} parameter {key!r}")
    if arr.shape != (n,):
        raise ValueError(f"effect {effect!r} parameter {key!r}: expected {n} values (one per wheel), "
                         f"got {arr.size}")
    return arr


def _scalar(params: dict, key: str, effect: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    if key not in params:
        raise ValueError(f"effect {effect!r}: missing parameter {key!r}")
    arr = _finite(params[key], f"effect {effect!r} parameter {key!r}")
    if arr.shape != ():
        raise ValueError(f"effect {effect!r} parameter {key!r}: expected one number, got {params[key]!r}")
    value = float(arr)
    if not lo <= value <= hi:
        raise ValueError(f"effect {effect!r} parameter {key!r}: {value} outside [{lo}, {hi}]")
    return value


def drag_params(value) -> tuple[float, float]:
    """(c [N·s/m], c_rot [N·m·s]) of the ``drag`` effect: a number c, or {"c": c, "c_rot": c_rot}."""
    if isinstance(value, dict):
        unknown = set(value) - {"c", "c_rot"}
        if unknown:
            raise ValueError(f"effect 'drag': unknown parameter {sorted(unknown)[0]!r} (allowed: c, c_rot)")
        c = _scalar(value, "c", "drag", 0.0, 1e3)
        c_rot = _scalar(value, "c_rot", "drag", 0.0, 1e3) if "c_rot" in value else 0.0
        return c, c_rot
    return _scalar({"c": value}, "c", "drag", 0.0, 1e3), 0.0


def slope_params(value) -> tuple[float, float]:
    """(α [rad], β [rad]) of the ``slope`` effect {"angle": α, "direction": β}: the floor tilted by α (at most
    0.2 rad, 11°) so that downhill points along the world direction β."""
    if not isinstance(value, dict):
        raise ValueError(f"effect 'slope': parameters must be an object {{angle, direction}}, got {value!r}")
    unknown = set(value) - {"angle", "direction"}
    if unknown:
        raise ValueError(f"effect 'slope': unknown parameter {sorted(unknown)[0]!r} (allowed: angle, direction)")
    return _scalar(value, "angle", "slope", 0.0, 0.2), _scalar(value, "direction", "slope", -10.0, 10.0)


def check_effects(effects: dict, model: SimModel) -> None:
    """Raise a one-line ValueError naming the first effect or parameter that does not fit ``model``."""
    if not isinstance(effects, dict):
        raise ValueError(f"hidden effects must be an object {{name: params}}, got {effects!r}")
    known = PHYSICS_EFFECTS + TRACKER_EFFECTS + EXTRA_EFFECTS
    n = model.n_wheels
    mecanum = bool(np.any([w.roller_angle != 0.0 for w in model.robot.wheels]))
    for name, params in effects.items():
        if name not in known:
            raise ValueError(f"unknown effect {name!r} (known: {', '.join(known)})")
        if name == "drag":
            drag_params(params)
            continue
        if name == "slope":
            slope_params(params)
            continue
        if not isinstance(params, dict):
            raise ValueError(f"effect {name!r}: parameters must be an object, got {params!r}")
        for key, value in params.items():
            _finite(value, f"effect {name!r} parameter {key!r}")
        if name == "mecanum_lateral" and not mecanum:
            raise ValueError("effect 'mecanum_lateral' applies to mecanum wheels only; this robot has omni wheels")
        if name == "roller_gap" and mecanum:
            raise ValueError("effect 'roller_gap' applies to omni wheels only; this robot has mecanum wheels")
        if name in ("wheel_radius",):
            _per_wheel(params, "scale", name, n)
        if name == "wheel_geometry":
            _per_wheel(params, "distance", name, n)
            _per_wheel(params, "mount", name, n)
        if name == "roller_gap":
            _per_wheel(params, "phase", name, n)
            _scalar(params, "mu_gap", name, 0.0, 10.0)
            _scalar(params, "roller_fraction", name, 0.0, 1.0)
        if name == "com_offset":
            com = _finite(params.get("com"), "effect 'com_offset' parameter 'com'")
            if com.shape != (2,):
                raise ValueError(f"effect 'com_offset' parameter 'com': expected [x, y], got {params.get('com')!r}")
        if name == "motor_lag":
            _scalar(params, "tau", name, 0.0, 10.0)
        if name == "kinetic_friction":
            _scalar(params, "ratio", name, 0.0, 1.0)
            _scalar(params, "v_s", name, 1e-9, 10.0)
        if name == "wheel_liftoff":
            _scalar(params, "lift_rate", name, 0.0, 1000.0)
            _scalar(params, "recover_rate", name, 0.0, 1000.0)
        if name == "mecanum_lateral":
            _scalar(params, "ratio", name, 0.5, 2.0)
        if name == "tracker_offset":
            off = _finite(params.get("offset"), "effect 'tracker_offset' parameter 'offset'")
            if off.shape != (2,):
                raise ValueError(f"effect 'tracker_offset' parameter 'offset': expected [x, y], "
                                 f"got {params.get('offset')!r}")
            _scalar(params, "yaw", name)
        if name == "time_offset":
            _scalar(params, "delay", name, -1.0, 1.0)


def build_plant(model: SimModel, extra: dict | None = None) -> Plant:
    """The plant of ``model`` (its own ``effects``) with the effects of ``extra`` {name: params} on top.

    Tracker effects are ignored here (they change the measurement, not the motion).
    """
    effects = dict(model.effects)
    effects.update(extra or {})
    check_effects(effects, model)
    robot = model.robot
    n = robot.n_wheels
    positions = np.array([w.position for w in robot.wheels], dtype=float)
    drives = np.array([w.drive for w in robot.wheels], dtype=float)
    drives /= np.linalg.norm(drives, axis=1)[:, None]
    gammas = np.array([w.roller_angle for w in robot.wheels], dtype=float)
    radii = np.full(n, float(robot.wheel_radius))
    com = np.array(robot.com, dtype=float)
    surface = model.surface
    gap = model.friction == "roller_gap"
    pitch = 2.0 * math.pi / robot.rollers
    fraction = float(robot.roller_fraction)
    mu_gap = float(surface.mu_gap)
    phases = np.zeros(n)
    kinetic = tau = lift = None
    c = c_rot = 0.0
    slope, normal_scale = (0.0, 0.0), 1.0
    if "com_offset" in effects:
        com = np.array(effects["com_offset"]["com"], dtype=float)
    if "wheel_radius" in effects:
        radii = radii * np.asarray(effects["wheel_radius"]["scale"], dtype=float)
    if "wheel_geometry" in effects:
        p = effects["wheel_geometry"]
        positions = positions * np.asarray(p["distance"], dtype=float)[:, None]
        mount = np.asarray(p["mount"], dtype=float)
        cm, sm = np.cos(mount), np.sin(mount)
        drives = np.column_stack([cm * drives[:, 0] - sm * drives[:, 1], sm * drives[:, 0] + cm * drives[:, 1]])
    if "mecanum_lateral" in effects:
        ratio = float(effects["mecanum_lateral"]["ratio"])
        radii = radii * 2.0 / (1.0 + ratio)
        gammas = np.arctan(np.tan(gammas) / ratio)
    if "motor_lag" in effects:
        t = float(effects["motor_lag"]["tau"])
        tau = t if t > 0.0 else None
    if "kinetic_friction" in effects:
        p = effects["kinetic_friction"]
        kinetic = (float(p["ratio"]), float(p["v_s"]))
    if "roller_gap" in effects:
        p = effects["roller_gap"]
        gap, mu_gap, fraction = True, float(p["mu_gap"]), float(p["roller_fraction"])
        phases = np.asarray(p["phase"], dtype=float)
    if "wheel_liftoff" in effects:
        p = effects["wheel_liftoff"]
        lift = (float(p["lift_rate"]), float(p["recover_rate"]))
    if "drag" in effects:
        c, c_rot = drag_params(effects["drag"])
    if "slope" in effects:
        alpha, beta = slope_params(effects["slope"])
        g_along = float(model.gravity) * math.sin(alpha)
        slope, normal_scale = (g_along * math.cos(beta), g_along * math.sin(beta)), math.cos(alpha)
    gap_half = (1.0 - fraction) * pitch / 2.0
    return Plant(mass=float(robot.mass), inertia=float(robot.inertia), gravity=float(model.gravity), com=com,
                 positions=positions, drives=drives, gammas=gammas, radii=radii,
                 mu_w=float(surface.mu_drive), mu_t=float(surface.mu_transverse), mu_gap=mu_gap,
                 k=float(surface.k), gap=gap and gap_half > 0.0, pitch=pitch, gap_half=gap_half,
                 phases=phases, kinetic=kinetic, tau=tau, drag=c, drag_rot=c_rot, lift=lift, slope=slope,
                 normal_scale=normal_scale)


def draw_lift_schedule(plant: Plant, duration: float, rng: np.random.Generator) -> list[tuple[float, np.ndarray]]:
    """Lift-off switches [(time [s], lifted (n,) bool)] over [0, duration] from the contact process.

    All wheels start down. Holding times are Exp(1/rate) draws from ``rng``; a rate of 0 never switches.
    """
    if plant.lift is None:
        return []
    lift_rate, recover_rate = plant.lift
    cases = [np.eye(plant.n, dtype=bool)[i] for i in range(plant.n)]
    if plant.n % 2 == 0:
        pairs = set()
        for i in range(plant.n):
            j = int(np.argmin(np.linalg.norm(plant.positions + plant.positions[i], axis=1)))
            if j != i:
                pairs.add((min(i, j), max(i, j)))
        for i, j in sorted(pairs):
            mask = np.zeros(plant.n, dtype=bool)
            mask[[i, j]] = True
            cases.append(mask)
    schedule: list[tuple[float, np.ndarray]] = []
    t, down = 0.0, True
    while True:
        rate = lift_rate if down else recover_rate
        if rate <= 0.0:
            break
        t += rng.exponential(1.0 / rate)
        if not t < duration:
            break
        if down:
            mask = cases[int(rng.integers(len(cases)))].copy()
        else:
            mask = np.zeros(plant.n, dtype=bool)
        schedule.append((t, mask))
        down = not down
    return schedule


@dataclass
class Trajectory:
    """Samples of an integration: times (K,) [s]; pose (K, 3) of the geometric centre (x, y [m], θ [rad],
    world frame); velocity (K, 3) of the geometric centre (ẋ, ẏ [m/s], ω [rad/s], world frame); angles
    (K, n) wheel angles [rad]; events: gap switches and restarts counted."""

    t: np.ndarray
    pose: np.ndarray
    velocity: np.ndarray
    angles: np.ndarray
    events: dict = field(default_factory=dict)


class _Rhs:
    """The right-hand side for one piece (fixed commands, loads and roller/gap state)."""

    def __init__(self, plant: Plant, cmd: np.ndarray, loads: np.ndarray, on_gap: np.ndarray):
        self.p = plant
        self.cmd = cmd
        self.loads = loads
        self.on_gap = on_gap
        n = plant.n
        d, g = plant.drives, plant.gammas
        a = np.column_stack([-d[:, 1], d[:, 0]])
        self.e_body = np.cos(g)[:, None] * d + np.sin(g)[:, None] * a
        self.rel = plant.positions - plant.com
        self.mu_w = np.where(on_gap, plant.mu_gap, plant.mu_w)
        self.mu_t = np.where(on_gap, plant.mu_gap, plant.mu_t)
        self.rcos = plant.radii * np.cos(g)
        self.rsin = plant.radii * np.sin(g)
        self.n = n

    def law(self, v: np.ndarray, mu: np.ndarray) -> np.ndarray:
        p = self.p
        shape = (2.0 / math.pi) * np.arctan(p.k * v)
        if p.kinetic is None:
            return mu * shape
        ratio, v_s = p.kinetic
        return mu * shape * (ratio + (1.0 - ratio) * np.exp(-(v / v_s) ** 2))

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        p, n = self.p, self.n
        th, vx, vy, om = y[2], y[3], y[4], y[5]
        c, s = math.cos(th), math.sin(th)
        rho_x = c * self.rel[:, 0] - s * self.rel[:, 1]
        rho_y = s * self.rel[:, 0] + c * self.rel[:, 1]
        ex = c * self.e_body[:, 0] - s * self.e_body[:, 1]
        ey = s * self.e_body[:, 0] + c * self.e_body[:, 1]
        fx, fy = -ey, ex
        ux = vx - om * rho_y
        uy = vy + om * rho_x
        w = y[6 + n:6 + 2 * n] if p.tau is not None else self.cmd
        v_w = ux * ex + uy * ey - self.rcos * w
        v_t = ux * fx + uy * fy + self.rsin * w
        mw = self.law(v_w, self.mu_w)
        mt = self.law(v_t, self.mu_t)
        fxs = -self.loads * (mw * ex + mt * fx)
        fys = -self.loads * (mw * ey + mt * fy)
        dy = np.empty_like(y)
        dy[0], dy[1], dy[2] = vx, vy, om
        dy[3] = (fxs.sum() - p.drag * vx) / p.mass + p.slope[0]
        dy[4] = (fys.sum() - p.drag * vy) / p.mass + p.slope[1]
        dy[5] = (np.sum(rho_x * fys - rho_y * fxs) - p.drag_rot * om) / p.inertia
        dy[6:6 + n] = w
        if p.tau is not None:
            dy[6 + n:6 + 2 * n] = (self.cmd - w) / p.tau
        return dy


def _boundary(plant: Plant, j: int) -> float:
    """Angle (φ + phase) of region boundary j: 2m → start of pitch m's rigid sector, 2m+1 → its end."""
    m, odd = divmod(j, 2)
    centre = m * plant.pitch + plant.pitch / 2.0
    return centre + (plant.gap_half if odd else -plant.gap_half)


def _region(plant: Plant, shifted: float) -> int:
    """Region j with boundary(j) ≤ shifted < boundary(j+1); even j: on rigid material."""
    m = math.floor(shifted / plant.pitch)
    local = shifted - m * plant.pitch
    if local < plant.pitch / 2.0 - plant.gap_half:
        j = 2 * m - 1
    elif local < plant.pitch / 2.0 + plant.gap_half:
        j = 2 * m
    else:
        j = 2 * m + 1
    # Floating-point guard: keep the documented strict inequality exactly at a boundary.
    while shifted < _boundary(plant, j):
        j -= 1
    while shifted >= _boundary(plant, j + 1):
        j += 1
    return j


def _on_gap_of(plant: Plant, regions: np.ndarray) -> np.ndarray:
    """(n,) bool: the wheels whose region is a rigid-material one (even index).

    The region index, not the angle, is the authority: after an event the angle sits exactly on the
    boundary just crossed, and the direction of the crossing says which side the wheel is on.
    """
    if not plant.gap:
        return np.zeros(plant.n, dtype=bool)
    return np.asarray(regions) % 2 == 0


def start_state(plant: Plant, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(state y at rest with the geometric centre at ``start`` (x, y, θ), the wheels' roller/rigid region
    indices) from which :func:`integrate` and the closed-loop plant run."""
    n = plant.n
    state = np.zeros(6 + n + (n if plant.tau is not None else 0))
    c0, s0 = math.cos(start[2]), math.sin(start[2])
    state[0] = start[0] + c0 * plant.com[0] - s0 * plant.com[1]
    state[1] = start[1] + s0 * plant.com[0] + c0 * plant.com[1]
    state[2] = start[2]
    regions = np.array([_region(plant, plant.phases[i]) for i in range(n)]) if plant.gap else np.zeros(n, int)
    return state, regions


def integrate(plant: Plant, times: np.ndarray, commands: np.ndarray, sample_times: np.ndarray,
              start_pose=(0.0, 0.0, 0.0), lift_schedule=(), method: str = "LSODA",
              rtol: float = 1e-8, atol: float = 1e-10) -> Trajectory:
    """Integrate the run from rest at ``start_pose`` and sample it at ``sample_times`` [s] (≥ 0).

    ``times`` (K,) [s] strictly increasing from 0, ``commands`` (K, n) [rad/s]: row j holds on
    [times[j], times[j+1]); the last row's command holds after the last time. ``lift_schedule``: a
    list of (time [s], lifted (n,) bool) switches. Raises ValueError on NaN or inconsistent shapes.
    """
    times = _finite(times, "command times")
    commands = _finite(commands, "commands")
    samples = _finite(sample_times, "sample times")
    start = _finite(start_pose, "start pose")
    n = plant.n
    if commands.ndim != 2 or commands.shape != (len(times), n):
        raise ValueError(f"commands: expected shape ({len(times)}, {n}), got {commands.shape}")
    if times[0] != 0.0 or np.any(np.diff(times) <= 0):
        raise ValueError("command times must start at 0 and increase strictly")
    if np.any(samples < 0) or np.any(np.diff(samples) < 0):
        raise ValueError("sample times must be >= 0 and sorted")
    end = float(max(times[-1], samples[-1] if len(samples) else 0.0))
    # Piece boundaries: command changes and lift switches.
    switches = sorted((float(t), np.asarray(m, dtype=bool)) for t, m in lift_schedule)
    cuts = sorted(set([float(t) for t in times if t < end] + [t for t, _ in switches if t < end]))
    cuts.append(end)
    state, regions = start_state(plant, start)
    lifted = np.zeros(n, dtype=bool)
    out = np.zeros((len(samples), len(state)))
    filled = np.zeros(len(samples), dtype=bool)
    counts = {"pieces": 0, "gap_switches": 0}
    sw = 0
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        while sw < len(switches) and switches[sw][0] <= a:
            lifted = switches[sw][1]
            sw += 1
        row = int(np.searchsorted(times, a, side="right") - 1)
        cmd = commands[row]
        loads = plant.loads(lifted)

        def keep(sol, t, t_end, b=b):
            mask = (~filled) & (samples >= t) & ((samples <= t_end) if t_end >= b else (samples < t_end))
            if mask.any():
                out[mask] = sol.sol(samples[mask]).T
                filled[mask] = True

        state = run_piece(plant, state, regions, cmd, loads, a, b, counts, method, rtol, atol, keep)
    if not filled.all():  # samples exactly at the last cut
        out[~filled] = state
    th = out[:, 2]
    c, s = np.cos(th), np.sin(th)
    cx, cy = plant.com
    pose = np.column_stack([out[:, 0] - (c * cx - s * cy), out[:, 1] - (s * cx + c * cy), th])
    om = out[:, 5]
    # velocity of the geometric centre = V + ω z × (−R com)
    rx, ry = -(c * cx - s * cy), -(s * cx + c * cy)
    vel = np.column_stack([out[:, 3] - om * ry, out[:, 4] + om * rx, om])
    return Trajectory(t=samples, pose=pose, velocity=vel, angles=out[:, 6:6 + n].copy(), events=counts)


def run_piece(plant: Plant, state: np.ndarray, regions: np.ndarray, cmd: np.ndarray, loads: np.ndarray, a: float,
              b: float, counts: dict, method: str = "LSODA", rtol: float = 1e-8, atol: float = 1e-10,
              keep=None) -> np.ndarray:
    """Integrate one piece [a, b] of fixed commands ``cmd`` and loads from ``state``; return the state at b.

    ``regions`` (n,) is stepped in place at every roller/rigid event; ``counts`` gathers the pieces and
    switches; ``keep(sol, t, t_end)``, if given, sees every solver segment (dense output on [t, t_end]).
    """
    n = plant.n
    t = a
    while t < b:
        on_gap = _on_gap_of(plant, regions)
        rhs = _Rhs(plant, cmd, loads, on_gap)
        events = []
        owners = []
        if plant.gap:
            for i in range(n):
                lo = _boundary(plant, int(regions[i])) - plant.phases[i]
                hi = _boundary(plant, int(regions[i]) + 1) - plant.phases[i]
                ev_lo = _angle_event(6 + i, lo, -1.0)
                ev_hi = _angle_event(6 + i, hi, +1.0)
                events += [ev_lo, ev_hi]
                owners += [(i, -1, lo), (i, +1, hi)]
        try:
            sol = solve_ivp(rhs, (t, b), state, method=method, rtol=rtol, atol=atol, dense_output=True,
                            events=events or None)
        except ValueError:
            # The event root search brackets on the step's interpolant; should it disagree in sign
            # with the step's end values (seen with LSODA's interpolant), Radau's collocation
            # polynomial passes through them.
            sol = solve_ivp(rhs, (t, b), state, method="Radau", rtol=rtol, atol=atol, dense_output=True,
                            events=events or None)
            counts["radau_retries"] = counts.get("radau_retries", 0) + 1
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed at t = {t:.6f} s: {sol.message}")
        counts["pieces"] += 1
        t_end = float(sol.t[-1])
        if keep is not None:
            keep(sol, t, t_end)
        state = sol.y[:, -1].copy()
        if sol.status == 1:  # an event: step the wheel's region, snap its angle onto the boundary
            hit = [k for k, te in enumerate(sol.t_events) if len(te)]
            k = min(hit, key=lambda q: sol.t_events[q][0])
            i, step, angle = owners[k]
            _cross(plant, regions, state, i, step, angle)
            counts["gap_switches"] += 1
            # Wheels at the same angle (a turn in place with equal phases) cross together.
            for i2, step2, angle2 in owners:
                speed = state[6 + n + i2] if plant.tau is not None else cmd[i2]
                if i2 != i and abs(state[6 + i2] - angle2) < SIMULTANEOUS and step2 * speed > 0:
                    _cross(plant, regions, state, i2, step2, angle2)
                    counts["gap_switches"] += 1
        t = t_end
    return state


SIMULTANEOUS = 1e-9  # rad: wheels this close to their boundary at another wheel's event cross with it


def _cross(plant: Plant, regions: np.ndarray, state: np.ndarray, i: int, step: int, angle: float) -> None:
    """Step wheel i's region by ``step`` (±1) and put its angle just past ``angle``, on the new side.

    1e-12 rad past the boundary: the new region's event function then starts strictly non-zero, so a
    wheel that stops there does not re-trigger it.
    """
    regions[i] += step
    state[6 + i] = angle + step * max(1e-12, 8 * math.ulp(angle))


def _angle_event(index: int, boundary: float, direction: float):
    def event(t, y):
        return y[index] - boundary
    event.terminal = True
    event.direction = direction
    return event
