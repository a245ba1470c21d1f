"""Validation reference: a slow, high-accuracy integration of the omni/mecanum-robot slip model.

This module is written independently of the world and its force kernel (it shares only the robot,
surface, model and static-load definitions), so the tests can use it as ground truth for the
pymunk world. It is not meant for simulation at scale: one robot, up to ~1 s of CPU per simulated second.

Model (SI units). State: geometric-centre pose (x, y, θ) in the world frame, centre-of-mass world
velocity V and yaw rate ω. With the centre of mass at c (body frame) and q = R(θ) c,

    ẋ = V_x + ω q_y,   ẏ = V_y − ω q_x,   θ̇ = ω,
    m V̇ = Σ F_i,       I ω̇ = Σ ρ_i × F_i,      ρ_i = R(p_i − c),
    F_i = −N_i [μ_W(v_W,i) e_i + μ_T(v_T,i) f_i]    (e_i, f_i rotated to the world),
    v_W,i = u_i · e_i − r w_i cos γ_i,   v_T,i = u_i · f_i + r w_i sin γ_i,   u_i = V + ω z × ρ_i,
    μ(v) = μ_max (2/π) atan(k v),

where γ_i is wheel i's roller angle, e_i = cos γ_i d_i + sin γ_i a_i the axis of its floor roller
(the direction it constrains) and f_i = z × e_i the direction the roller rolls freely (a_i = z × d_i).
The floor roller's material moves at u_i − r w_i d_i plus its free roll along f_i; v_W is that
velocity along e_i, v_T the roll velocity the rollers' rolling friction opposes, and d_i · e_i =
cos γ_i, d_i · f_i = −sin γ_i. An omni wheel (γ = 0: e = d, f = a) gives Williams et al.'s law.

Wheels are ideal velocity sources: wheel i turns at its commanded speed w_i (piecewise constant)
and its angle φ_i = ∫ w_i dt is piecewise linear. With the ``motor_lag`` effect (time constant τ,
``docs/model.md``, Actuation) the wheel speed is a first-order lag of the command, τ ẇ_i = c_i − w_i,
from rest at t = 0; between two command changes that is solved exactly, w_i(t) = c_i + (w_a − c_i)
e^{−(t−t_a)/τ} and φ_i(t) = φ_a + c_i (t − t_a) + (w_a − c_i) τ (1 − e^{−(t−t_a)/τ}), so the wheel
speed enters the right-hand side as a known function of time, not as extra states.

With the ``kinetic_friction`` effect (``docs/model.md``, Model effects) every coefficient falls from
μ_s to μ_k = ratio·μ_s above the Stribeck speed v_s: μ(v) = (2/π) atan(k v) [μ_k + (μ_s − μ_k)
e^{−(v/v_s)²}], along e and f alike (and for mu_gap).

With the ``wheel_liftoff`` effect the contact process is random in the world; here its realisation
is given as a deterministic list of lift events (t_start, t_end, contact mask), e.g. drawn by
:func:`omni_gym.discrepancy.synthetic.reference_data.lift_schedule`, and the loads switch exactly at the event
times (the event times are interval boundaries, like the roller/gap switches).

In the ``roller_gap`` friction model the wheel rests on rigid material while |(φ_i mod p) − p/2| <
g/2 (p = 2π/rollers, g = (1 − roller_fraction) p) and then both coefficients are mu_gap; otherwise
(and always in the ``initial`` model) they are mu_drive and mu_transverse. The ``roller_gap`` effect
turns that model on with its own μ'' (``mu_gap``), roller share and a phase per wheel, as
``docs/discrepancy.md`` states it: wheel i is on rigid material while |((φ_i + phase_i) mod p) − p/2| <
(1 − roller_fraction)·p/2.

The normal loads N_i come from :func:`omni_gym.physics.loads.wheel_loads`: equal shares
m·g/n_contact with the centre of mass at the geometric centre (the paper's assumption), static
balance with a centre-of-mass offset. That load law is shared on purpose: it is the documented law
of ``docs/model.md`` (Normal loads and lift-off) that both implementations take as given, so a lifted
wheel redistributes the loads here exactly as the law says, whatever the world does with it.

Accuracy: the coefficient switches and the command changes are discontinuities of the right-hand
side. Because every wheel angle is piecewise linear (ideal wheels), every switching time is computed
exactly in advance (lift events are given times; the roller/gap switching of a lagged wheel is not
supported), and the (stiff, k = 1000 s/m) ODE is integrated with an implicit solver separately on each
interval between consecutive switching times, restarting at each boundary with the state reached.
Within an interval the right-hand side is smooth (atan), so the solver's error control holds.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from omni_gym.physics.loads import wheel_loads
from omni_gym.physics.model import SimModel

# Effects this integrator implements itself (written from the effects' documented equations, not their
# kernel code): the centre of mass, per-wheel rolling radius, per-wheel placement and mounting yaw,
# the mecanum wheels' lateral / longitudinal radius ratio, the first-order motor lag, the Stribeck drop of
# friction, lift-off (as a given event schedule) and the rigid material between the rollers with its own
# μ'', roller share and per-wheel phase.
SUPPORTED_EFFECTS = ("com_offset", "wheel_radius", "wheel_geometry", "mecanum_lateral", "motor_lag",
                     "kinetic_friction", "wheel_liftoff", "roller_gap")
_TWO_OVER_PI = 2.0 / math.pi


def _wheel_angles(t: float, times: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """Angle φ_i(t) [rad] of every wheel: the integral of the piecewise-constant commands from 0."""
    ends = np.append(times[1:], np.inf)
    span = np.clip(np.minimum(ends, t) - times, 0.0, None)
    return span @ commands


class WheelMotion:
    """Speed and angle of every wheel under piecewise-constant commands, with an optional first-order lag.

    Args:
        times: (K,) command switch times [s], ``times[0] == 0``; commands: (K, n) commands [rad/s].
        tau: lag time constant [s] (0: ideal wheels, speed = command).
        w0: (n,) wheel speeds [rad/s] at t = 0 (used only with a lag; default at rest).
    """

    def __init__(self, times: np.ndarray, commands: np.ndarray, tau: float = 0.0,
                 w0: np.ndarray | None = None) -> None:
        self.times, self.commands, self.tau = times, commands, float(tau)
        n = commands.shape[1]
        speed = np.zeros(n) if w0 is None else np.asarray(w0, dtype=float).copy()
        angle = np.zeros(n)
        self.start_speed = np.empty_like(commands)
        self.start_angle = np.empty_like(commands)
        for j in range(len(times)):
            self.start_speed[j], self.start_angle[j] = speed, angle
            if j + 1 < len(times):
                speed, angle = self._in_segment(j, times[j + 1])

    def _row(self, t: float) -> int:
        return max(int(np.searchsorted(self.times, t, side="right")) - 1, 0)

    def _in_segment(self, j: int, t: float) -> tuple[np.ndarray, np.ndarray]:
        c, w_a, phi_a, h = self.commands[j], self.start_speed[j], self.start_angle[j], t - self.times[j]
        if self.tau <= 0.0:
            return c.copy(), phi_a + c * h
        e = math.exp(-h / self.tau)
        return c + (w_a - c) * e, phi_a + c * h + (w_a - c) * self.tau * (1.0 - e)

    def speed(self, t: float, row: int | None = None) -> np.ndarray:
        """(n,) wheel speeds [rad/s] at time t (in command segment ``row`` if given)."""
        return self._in_segment(self._row(t) if row is None else row, t)[0]

    def angle(self, t: float) -> np.ndarray:
        """(n,) wheel angles [rad] at time t, 0 at t = 0."""
        return self._in_segment(self._row(t), t)[1]


def _switch_times(times: np.ndarray, commands: np.ndarray, t_end: float, pitch: float, gap: float,
                  use_gap: bool, phase: np.ndarray | None = None) -> np.ndarray:
    """Sorted times in (0, t_end) where a command changes or a wheel enters / leaves rigid material
    (wheel i on it while |((φ_i + phase_i) mod pitch) − pitch/2| < gap/2; phase default 0)."""
    out = [t for t in times[1:] if 0.0 < t < t_end]
    if use_gap and gap > 0.0:
        starts = np.concatenate([times, [t_end]])
        for j in range(len(times)):
            ta, tb = starts[j], min(starts[j + 1], t_end)
            if tb <= ta:
                continue
            phi0 = _wheel_angles(ta, times, commands)
            if phase is not None:
                phi0 = phi0 + phase
            for i, w in enumerate(commands[j]):
                if w == 0.0:
                    continue
                lo, hi = sorted((phi0[i], phi0[i] + w * (tb - ta)))
                for edge in (0.5 * (pitch - gap), 0.5 * (pitch + gap)):
                    # boundaries edge + k·p inside [lo, hi]
                    k0 = math.ceil((lo - edge) / pitch)
                    k1 = math.floor((hi - edge) / pitch)
                    for k in range(k0, k1 + 1):
                        ts = ta + (edge + k * pitch - phi0[i]) / w
                        if ta < ts < tb:
                            out.append(ts)
    out = np.unique(np.asarray(out, dtype=float))
    # Merge switches closer than any meaningful solver step (they come from the same instant).
    if out.size:
        keep = np.concatenate([[True], np.diff(out) > 1e-13])
        out = out[keep]
    return out


def reference_trajectory(model: SimModel, times: np.ndarray, commands: np.ndarray, t_eval: np.ndarray,
                         contact: np.ndarray | None = None, rtol: float = 1e-10, atol: float = 1e-12,
                         initial_velocity: np.ndarray | None = None, method: str = "LSODA",
                         drag: float = 0.0, lift_events: list[tuple[float, float, np.ndarray]] | None = None,
                         initial_wheel_speed: np.ndarray | None = None) -> dict:
    """Integrate the slip model for one robot starting at the origin (pose (0, 0, 0)).

    This is the validation reference (slow; switching times handled exactly), not a simulator.

    Args:
        model: the model; only the effects of :data:`SUPPORTED_EFFECTS` are supported (others raise
            NotImplementedError): ``com_offset`` moves c, ``wheel_radius`` scales r per wheel,
            ``wheel_geometry`` moves wheel i to distance_i·p_i and yaws d_i by mount_i, ``motor_lag``
            lags the wheel speeds (not with rigid material between the rollers), ``kinetic_friction``
            shapes every coefficient, ``wheel_liftoff`` needs ``lift_events`` (its realisation),
            ``roller_gap`` turns the gap model on with its mu_gap, roller_fraction and phases.
        times: (K,) command switch times [s], ``times[0] == 0``, increasing. Row j of ``commands``
            holds on [times[j], times[j+1]); the last row holds until ``t_eval[-1]``.
        commands: (K, n) commanded wheel speeds [rad/s].
        t_eval: (M,) increasing sample times [s] in [0, ∞).
        contact: bool (n,), True where the wheel is on the floor (default all); lifted wheels carry
            no load and so exert no force.
        rtol, atol: solver tolerances (state in m, rad, m/s, rad/s).
        initial_velocity: (3,) initial world velocity of the geometric centre and yaw rate
            (default at rest).
        method: scipy stiff method, ``"LSODA"`` (default: automatic stiff/non-stiff switching, several
            times faster here) or ``"Radau"``; the two agree to ~1e-10 m on 2 s manoeuvres.
        drag: a viscous force −drag·V [N·s/m] on the centre of mass (not a library effect: independent
            data the library cannot explain).
        lift_events: (t_start, t_end, mask) per lift [s, s, bool (n,), True = on the floor], not
            overlapping: the wheels off in ``mask`` carry no load on [t_start, t_end) (and, with
            ``contact``, the mask is and-ed with it). Required (possibly empty) with ``wheel_liftoff``.
        initial_wheel_speed: (n,) wheel speeds [rad/s] at t = 0 with ``motor_lag`` (default at rest).

    Returns:
        dict with
        ``pose`` (M, 3): geometric centre x, y [m] and heading θ [rad];
        ``velocity`` (M, 3): world velocity of the geometric centre [m/s] and ω [rad/s];
        ``wheel_speed`` (M, n): w_i [rad/s];
        ``slip`` (M, n, 2): slip v_W along the roller axis and roll velocity v_T along the free direction
        [m/s] per wheel (omni wheel: drive slip and transverse velocity);
        ``wheel_angle`` (M, n): φ_i [rad];
        ``switch_times``: the interval boundaries used.
    """
    unsupported = sorted(set(model.effects) - set(SUPPORTED_EFFECTS))
    if unsupported:
        raise NotImplementedError(f"reference: model effects {unsupported} are not supported")
    tau = float(model.effects.get("motor_lag", {"tau": 0.0})["tau"])
    if "wheel_liftoff" in model.effects and lift_events is None:
        raise ValueError("reference: the model has wheel_liftoff; give its realisation as lift_events")
    kin = model.effects.get("kinetic_friction")
    ratio, v_s = (1.0, 1.0) if kin is None else (float(kin["ratio"]), float(kin["v_s"]))
    robot, surf = model.robot, model.surface
    n = robot.n_wheels
    times = np.asarray(times, dtype=float)
    commands = np.asarray(commands, dtype=float).reshape(len(times), n)
    t_eval = np.asarray(t_eval, dtype=float)
    if times.ndim != 1 or times[0] != 0.0 or np.any(np.diff(times) <= 0):
        raise ValueError("times must start at 0 and increase strictly")
    if t_eval.ndim != 1 or np.any(np.diff(t_eval) < 0) or t_eval[0] < 0:
        raise ValueError("t_eval must be non-negative and non-decreasing")

    c = np.asarray(model.com, dtype=float)
    positions = robot.positions()
    drive = robot.drives()
    r = np.full(n, robot.wheel_radius)
    if "wheel_radius" in model.effects:
        r = r * np.asarray(model.effects["wheel_radius"]["scale"], dtype=float)
    if "wheel_geometry" in model.effects:
        geo = model.effects["wheel_geometry"]
        positions = positions * np.asarray(geo["distance"], dtype=float)[:, None]
        yaw = np.asarray(geo["mount"], dtype=float)
        drive = np.column_stack([np.cos(yaw) * drive[:, 0] - np.sin(yaw) * drive[:, 1],
                                 np.sin(yaw) * drive[:, 0] + np.cos(yaw) * drive[:, 1]])
    p_rel = positions - c  # wheel centres relative to the centre of mass, body frame
    gamma = np.array([w.roller_angle for w in robot.wheels], dtype=float)
    if "mecanum_lateral" in model.effects:
        # docs/model.md: r_lon = r·2/(1 + ratio) and tan γ' = tan γ / ratio on every angled wheel
        ratio = float(model.effects["mecanum_lateral"]["ratio"])
        angled = gamma != 0.0
        r = np.where(angled, r * 2.0 / (1.0 + ratio), r)
        gamma = np.where(angled, np.arctan(np.tan(gamma) / ratio), gamma)
    axle = np.column_stack([-drive[:, 1], drive[:, 0]])
    d_b = np.cos(gamma)[:, None] * drive + np.sin(gamma)[:, None] * axle  # roller axis e_i (body frame)
    a_b = np.column_stack([-d_b[:, 1], d_b[:, 0]])  # free direction f_i = z × e_i
    r_cos = r * np.cos(gamma)  # v_W = u·e − r w cos γ
    r_sin = r * np.sin(gamma)  # v_T = u·f + r w sin γ
    m, inertia = robot.mass, robot.inertia
    k = surf.k
    base_contact = np.ones(n, dtype=bool) if contact is None else np.asarray(contact, dtype=bool)
    events = sorted(((float(a), float(b), np.asarray(msk, dtype=bool)) for a, b, msk in (lift_events or [])),
                    key=lambda ev: ev[:2])
    for (_a0, b0, _), (a1, _b1, _) in zip(events[:-1], events[1:], strict=True):
        if a1 < b0:
            raise ValueError(f"reference: lift events overlap at {a1} s")

    def contact_at(t: float) -> np.ndarray:
        for a, b, msk in events:
            if a <= t < b:
                return base_contact & msk
        return base_contact

    pitch = 2.0 * math.pi / robot.rollers
    gap = (1.0 - robot.roller_fraction) * pitch
    use_gap = model.friction == "roller_gap"
    mu_gap, phase = surf.mu_gap, None
    if "roller_gap" in model.effects:
        rg = model.effects["roller_gap"]
        use_gap, mu_gap = True, float(rg["mu_gap"])
        gap = (1.0 - float(rg["roller_fraction"])) * pitch
        phase = np.asarray(rg["phase"], dtype=float)
    if tau > 0.0 and use_gap:
        raise NotImplementedError("reference: motor_lag with rigid material between the rollers (roller_gap) is "
                                  "not supported (the gap switching times of a lagged wheel are not piecewise "
                                  "linear)")
    wheels = WheelMotion(times, commands, tau, initial_wheel_speed)

    t_end = float(t_eval[-1])
    lift_times = [t for a, b, _ in events for t in (a, b) if 0.0 < t < t_end]
    inner = np.unique(np.concatenate([_switch_times(times, commands, t_end, pitch, gap, use_gap, phase),
                                     lift_times]))
    bounds = np.concatenate([[0.0], inner, [t_end]])

    def frame(theta):
        cs, sn = math.cos(theta), math.sin(theta)
        rho = np.column_stack([cs * p_rel[:, 0] - sn * p_rel[:, 1], sn * p_rel[:, 0] + cs * p_rel[:, 1]])
        dw = np.column_stack([cs * d_b[:, 0] - sn * d_b[:, 1], sn * d_b[:, 0] + cs * d_b[:, 1]])
        aw = np.column_stack([cs * a_b[:, 0] - sn * a_b[:, 1], sn * a_b[:, 0] + cs * a_b[:, 1]])  # = z × dw
        q = np.array([cs * c[0] - sn * c[1], sn * c[0] + cs * c[1]])
        return rho, dw, aw, q

    def slips(s, w):
        rho, dw, aw, q = frame(s[2])
        ux = s[3] - s[5] * rho[:, 1]
        uy = s[4] + s[5] * rho[:, 0]
        v_w = ux * dw[:, 0] + uy * dw[:, 1] - r_cos * w
        v_t = ux * aw[:, 0] + uy * aw[:, 1] + r_sin * w
        return rho, dw, aw, q, ux, uy, v_w, v_t

    def law(v):
        """(atan(k v)·g(v), its derivative in v; None without kinetic_friction): the shape the force is
        N μ_s (2/π) times."""
        base = np.arctan(k * v)
        if kin is None:
            return base, None
        dbase = k / (1.0 + (k * v) ** 2)
        drop = (1.0 - ratio) * np.exp(-((v / v_s) ** 2))
        g = ratio + drop
        return base * g, dbase * g + base * drop * (-2.0 * v / v_s**2)

    def make_rhs(row, mu_w, mu_t, loads):
        nw = loads * mu_w * _TWO_OVER_PI  # N_i μ_W,max (2/π)
        nt = loads * mu_t * _TWO_OVER_PI

        def rhs(t, s):
            rho, dw, aw, q, _ux, _uy, v_w, v_t = slips(s, wheels.speed(t, row))
            fw = nw * law(v_w)[0]
            ft = nt * law(v_t)[0]
            fx = -(fw * dw[:, 0] + ft * aw[:, 0])
            fy = -(fw * dw[:, 1] + ft * aw[:, 1])
            tau = np.sum(rho[:, 0] * fy - rho[:, 1] * fx)
            return np.array([s[3] + s[5] * q[1], s[4] - s[5] * q[0], s[5], (fx.sum() - drag * s[3]) / m,
                             (fy.sum() - drag * s[4]) / m, tau / inertia])

        def jac(t, s):
            rho, dw, aw, q, ux, uy, v_w, v_t = slips(s, wheels.speed(t, row))
            om = s[5]
            shape_w, dshape_w = law(v_w)
            shape_t, dshape_t = law(v_t)
            fw = nw * shape_w
            ft = nt * shape_t
            if kin is None:  # the plain law's derivative, in the arithmetic order the reference always used
                gw = nw * k / (1.0 + (k * v_w) ** 2)  # d(N μ_W)/d v_W
                gt = nt * k / (1.0 + (k * v_t) ** 2)
            else:
                gw = nw * dshape_w
                gt = nt * dshape_t
            # per-wheel derivatives of v_W, v_T w.r.t. (θ, Vx, Vy, ω)
            rho_x_dw = rho[:, 0] * dw[:, 1] - rho[:, 1] * dw[:, 0]
            rho_x_aw = rho[:, 0] * aw[:, 1] - rho[:, 1] * aw[:, 0]
            rho_dot_dw = rho[:, 0] * dw[:, 0] + rho[:, 1] * dw[:, 1]
            rho_dot_aw = rho[:, 0] * aw[:, 0] + rho[:, 1] * aw[:, 1]
            u_dot_dw = ux * dw[:, 0] + uy * dw[:, 1]
            u_dot_aw = ux * aw[:, 0] + uy * aw[:, 1]
            # ∂(u·e)/∂θ = −ω ρ·e + u·f (∂u/∂θ = −ω ρ, ∂e/∂θ = f); ∂(u·f)/∂θ = −ω ρ·f − u·e.
            dvw = np.stack([u_dot_aw - om * rho_dot_dw, dw[:, 0], dw[:, 1], rho_x_dw], axis=1)  # (n, 4)
            dvt = np.stack([-om * rho_dot_aw - u_dot_dw, aw[:, 0], aw[:, 1], rho_x_aw], axis=1)
            # F_i = −(fw e + ft f);  ∂e/∂θ = f,  ∂f/∂θ = −e
            dfx = -(gw[:, None] * dvw * dw[:, 0:1] + gt[:, None] * dvt * aw[:, 0:1])
            dfy = -(gw[:, None] * dvw * dw[:, 1:2] + gt[:, None] * dvt * aw[:, 1:2])
            dfx[:, 0] += -(fw * aw[:, 0] - ft * dw[:, 0])
            dfy[:, 0] += -(fw * aw[:, 1] - ft * dw[:, 1])
            fx = -(fw * dw[:, 0] + ft * aw[:, 0])
            fy = -(fw * dw[:, 1] + ft * aw[:, 1])
            dtau = rho[:, 0:1] * dfy - rho[:, 1:2] * dfx
            # ∂ρ/∂θ = z × ρ, and (z × ρ) × F = −ρ · F
            dtau[:, 0] += -(rho[:, 0] * fx + rho[:, 1] * fy)
            J = np.zeros((6, 6))
            J[0, 2], J[0, 3], J[0, 5] = om * q[0], 1.0, q[1]
            J[1, 2], J[1, 4], J[1, 5] = om * q[1], 1.0, -q[0]
            J[2, 5] = 1.0
            cols = [2, 3, 4, 5]
            J[3, cols] = dfx.sum(axis=0) / m
            J[4, cols] = dfy.sum(axis=0) / m
            J[3, 3] -= drag / m
            J[4, 4] -= drag / m
            J[5, cols] = dtau.sum(axis=0) / inertia
            return J

        return rhs, jac

    # initial state: pose 0, COM velocity from the geometric-centre velocity
    s0 = np.zeros(6)
    if initial_velocity is not None:
        v0 = np.asarray(initial_velocity, dtype=float)
        # V = v_gc + ω z × (R c) at θ = 0
        s0[3:] = [v0[0] - v0[2] * c[1], v0[1] + v0[2] * c[0], v0[2]]

    states = np.empty((len(t_eval), 6))
    done = np.zeros(len(t_eval), dtype=bool)
    at_zero = t_eval == 0.0
    states[at_zero] = s0
    done |= at_zero
    s = s0
    for ta, tb in zip(bounds[:-1], bounds[1:], strict=True):
        if tb <= ta:
            continue
        tm = 0.5 * (ta + tb)
        row = int(np.searchsorted(times, tm, side="right")) - 1
        loads = wheel_loads(positions, c, m, model.gravity, contact_at(tm))
        if use_gap and gap > 0.0:
            phi = _wheel_angles(tm, times, commands)
            if phase is not None:
                phi = phi + phase
            on_rigid = np.abs(np.mod(phi, pitch) - 0.5 * pitch) < 0.5 * gap
            mu_w = np.where(on_rigid, mu_gap, surf.mu_drive)
            mu_t = np.where(on_rigid, mu_gap, surf.mu_transverse)
        else:
            mu_w = np.full(n, surf.mu_drive)
            mu_t = np.full(n, surf.mu_transverse)
        rhs, jac = make_rhs(row, mu_w, mu_t, loads)
        sel = (~done) & (t_eval >= ta) & (t_eval <= tb)
        pts = np.unique(np.append(t_eval[sel], tb))  # sorted, distinct, ends at tb
        sol = solve_ivp(rhs, (ta, tb), s, method=method, t_eval=pts, rtol=rtol, atol=atol, jac=jac)
        if not sol.success:
            raise RuntimeError(f"reference: solver failed on [{ta}, {tb}]: {sol.message}")
        states[sel] = sol.y[:, np.searchsorted(pts, t_eval[sel])].T
        done |= sel
        s = sol.y[:, -1]

    pose = states[:, :3].copy()
    velocity = np.empty((len(t_eval), 3))
    slip = np.empty((len(t_eval), n, 2))
    angles = np.empty((len(t_eval), n))
    speeds = np.empty((len(t_eval), n))
    for j, t in enumerate(t_eval):
        st = states[j]
        speeds[j] = wheels.speed(t)
        *_, q, _ux, _uy, v_w, v_t = slips(st, speeds[j])
        velocity[j] = [st[3] + st[5] * q[1], st[4] - st[5] * q[0], st[5]]
        slip[j, :, 0], slip[j, :, 1] = v_w, v_t
        angles[j] = wheels.angle(t) if tau > 0.0 else _wheel_angles(t, times, commands)
    return {"pose": pose, "velocity": velocity, "wheel_speed": speeds, "slip": slip, "wheel_angle": angles,
            "switch_times": bounds[1:-1]}
