"""The per-substep wheel-force kernel, compiled with numba and batched over robots.

For every robot and wheel it (1) advances the wheel speed and angle by the actuation model,
(2) takes the share of the substep the wheel spends on rigid material between rollers, (3) computes
the slip velocities along the roller axis e = cos γ d + sin γ (z × d) and the free direction
f = z × e (drive and axle for an omni wheel, γ = 0) and the regularised-Coulomb friction forces
along them, and (4) returns the *effective*
generalised force that makes one linearly-implicit (Rosenbrock–Euler) velocity step:

    (M + dt·A) Δq = dt·Q(q),     A = −∂Q/∂q  (symmetric, positive semi-definite),

with q = (V_x, V_y, ω) the centre-of-mass velocity (world frame) and yaw rate and M = diag(m, m, I).
Applying F_eff = M·Δq/dt through pymunk reproduces that step exactly, while pymunk still handles
collisions. The implicit treatment keeps the stiff friction law (k = 1000 s/m) stable at any step
and friction level; see ``docs/model.md``.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from omni_gym.physics.layout import (
    C_EACH_BODY,
    C_FORCES,
    C_GET_INT_NUM,
    C_GET_ITER,
    C_GET_NUM,
    C_GET_REQ,
    C_N_SET,
    C_SET_ITER,
    C_SET_NUM,
    C_SET_REQ,
    C_SPACE,
    C_STATES,
    C_STEP,
    N_SP,
    N_WH,
    N_WP,
    SP_CX,
    SP_CY,
    SP_GAP,
    SP_INERTIA,
    SP_JW,
    SP_K,
    SP_KI,
    SP_KIN_RATIO,
    SP_KP,
    SP_MASS,
    SP_MODE,
    SP_PITCH,
    SP_TAU,
    SP_TMAX,
    SP_VS,
    WH_ANGLE,
    WH_CMD,
    WH_GAP_AT,
    WH_GAP_MEASURE,
    WH_INT,
    WH_LOAD,
    WH_SPEED,
    WP_COSG,
    WP_DX,
    WP_DY,
    WP_GAPT,
    WP_GAPW,
    WP_MUT,
    WP_MUW,
    WP_PHASE,
    WP_PX,
    WP_PY,
    WP_R,
    WP_SING,
)

TWO_OVER_PI = 2.0 / math.pi


@numba.njit(cache=True, inline="always")
def friction_coefficient(v, mu_s, k, kin_ratio, v_s):
    """(μ(v), dμ/dv) of the regularised law, with optional kinetic-below-static shaping.

    μ(v) = (2/π)·atan(k·v)·[μ_k + (μ_s − μ_k)·exp(−(v/v_s)²)],  μ_k = kin_ratio·μ_s.
    kin_ratio = 1 gives the paper's law μ_s·(2/π)·atan(k·v).
    """
    shape = TWO_OVER_PI * math.atan(k * v)
    dshape = TWO_OVER_PI * k / (1.0 + (k * v) * (k * v))
    if kin_ratio == 1.0:
        return mu_s * shape, mu_s * dshape
    mu_k = kin_ratio * mu_s
    x = v / v_s
    g = math.exp(-x * x)
    level = mu_k + (mu_s - mu_k) * g
    dlevel = (mu_s - mu_k) * g * (-2.0 * x / v_s)
    return shape * level, dshape * level + shape * dlevel


@numba.njit(cache=True, inline="always")
def gap_measure(angle, pitch, gap):
    """Wheel angle [rad] spent on rigid material between 0 and ``angle`` (rigid sector centred at p/2)."""
    n = math.floor(angle / pitch)
    within = angle - n * pitch - 0.5 * (pitch - gap)
    if within < 0.0:
        within = 0.0
    elif within > gap:
        within = gap
    return n * gap + within


@numba.njit(cache=True, inline="always")
def gap_fraction(theta0, theta1, pitch, gap):
    """Share of the wheel-angle interval [θ0, θ1] on rigid material (exact for linear θ(t))."""
    if gap <= 0.0:
        return 0.0
    d = theta1 - theta0
    if abs(d) < 1e-12:
        m = theta0 - math.floor(theta0 / pitch) * pitch
        return 1.0 if abs(m - 0.5 * pitch) < 0.5 * gap else 0.0
    return (gap_measure(theta1, pitch, gap) - gap_measure(theta0, pitch, gap)) / d


@numba.njit(cache=True, inline="always")
def gap_fraction_memo(theta0, theta1, pitch, gap, memo_at, memo_measure):
    """:func:`gap_fraction` given a memo (angle, gap_measure at that angle); returns the fraction and
    gap_measure(θ1) (NaN where it was not computed). Bit-identical to :func:`gap_fraction`: the memo is
    used only for the very same θ0, and the same operations follow."""
    if gap <= 0.0:
        return 0.0, math.nan
    d = theta1 - theta0
    if abs(d) < 1e-12:
        m = theta0 - math.floor(theta0 / pitch) * pitch
        return (1.0 if abs(m - 0.5 * pitch) < 0.5 * gap else 0.0), math.nan
    m0 = memo_measure if theta0 == memo_at else gap_measure(theta0, pitch, gap)
    m1 = gap_measure(theta1, pitch, gap)
    return (m1 - m0) / d, m1


@numba.njit(cache=True, inline="always")
def _robot_substep(b, dt, state, wheels, sp, wp, ext, out_force, out_slip):
    """One robot's part of :func:`substep` (shared by the serial and the parallel loop)."""
    n_wheels = wheels.shape[1]
    c = math.cos(state[b, 2])
    s = math.sin(state[b, 2])
    vx = state[b, 3]
    vy = state[b, 4]
    om = state[b, 5]
    cx = sp[b, SP_CX]
    cy = sp[b, SP_CY]
    k = sp[b, SP_K]
    kin = sp[b, SP_KIN_RATIO]
    v_s = sp[b, SP_VS]
    pitch = sp[b, SP_PITCH]
    gap = sp[b, SP_GAP]
    tau = sp[b, SP_TAU]
    servo = sp[b, SP_MODE] == 1.0
    q0 = ext[b, 0]
    q1 = ext[b, 1]
    q2 = ext[b, 2]
    a00 = 0.0
    a01 = 0.0
    a02 = 0.0
    a11 = 0.0
    a12 = 0.0
    a22 = 0.0
    for i in range(n_wheels):
        # Geometry in the world frame: lever arm from the centre of mass, the roller axis e (the
        # constrained direction) and the free direction f = z × e. For an omni wheel (sin γ = 0)
        # e = d (drive) and f = a (axle), and the arithmetic below is exactly the omni law's.
        rx0 = wp[b, i, WP_PX] - cx
        ry0 = wp[b, i, WP_PY] - cy
        rho_x = c * rx0 - s * ry0
        rho_y = s * rx0 + c * ry0
        dx = c * wp[b, i, WP_DX] - s * wp[b, i, WP_DY]
        dy = s * wp[b, i, WP_DX] + c * wp[b, i, WP_DY]
        ux = vx - om * rho_y
        uy = vy + om * rho_x
        r = wp[b, i, WP_R]
        sg = wp[b, i, WP_SING]
        mecanum = sg != 0.0
        if mecanum:
            cg = wp[b, i, WP_COSG]
            ex = cg * dx - sg * dy  # e = cos γ d + sin γ (z × d)
            ey = cg * dy + sg * dx
            rc = r * cg  # rim speed share along e: v_e = u·e − r w cos γ
            rs = r * sg  # along f: v_f = u·f − r w (d·f) = u·f + r w sin γ
        else:
            cg = 1.0
            ex = dx
            ey = dy
            rc = r
            rs = 0.0
        ax = -ey
        ay = ex
        load = wheels[b, i, WH_LOAD]
        phase = wp[b, i, WP_PHASE]
        w0 = wheels[b, i, WH_SPEED]
        cmd = wheels[b, i, WH_CMD]
        th0 = wheels[b, i, WH_ANGLE]
        # 1) Actuation: wheel speed at the end of the substep and the angle turned.
        if servo:
            f0, _ = gap_fraction_memo(th0 + phase, th0 + phase + w0 * dt, pitch, gap, wheels[b, i, WH_GAP_AT],
                                      wheels[b, i, WH_GAP_MEASURE])
            mu_w_max = (1.0 - f0) * wp[b, i, WP_MUW] + f0 * wp[b, i, WP_GAPW]
            mu, dmu = friction_coefficient(ux * ex + uy * ey - rc * w0, mu_w_max, k, kin, v_s)
            f_drive = -load * mu  # force on the robot along the drive direction
            if mecanum:
                # F·d = −N (μ_e cos γ − μ_f sin γ); ∂(−r F·d)/∂w = −N r² (μ'_e cos²γ + μ'_f sin²γ).
                mu_t_max = (1.0 - f0) * wp[b, i, WP_MUT] + f0 * wp[b, i, WP_GAPT]
                mu_f, dmu_f = friction_coefficient(ux * ax + uy * ay + rs * w0, mu_t_max, k, kin, v_s)
                f_drive = -load * (mu * cg - mu_f * sg)
                dmu = dmu * cg * cg + dmu_f * sg * sg
            err = cmd - w0
            torque = sp[b, SP_KP] * err + sp[b, SP_KI] * wheels[b, i, WH_INT]
            kp_eff = sp[b, SP_KP]
            tmax = sp[b, SP_TMAX]
            if torque > tmax:
                torque = tmax
                kp_eff = 0.0
            elif torque < -tmax:
                torque = -tmax
                kp_eff = 0.0
            else:
                wheels[b, i, WH_INT] += err * dt  # anti-windup: integrate only when unsaturated
            # Wheel: J dw/dt = torque − r·f_drive, with the friction and P terms taken implicitly
            # (the wheel mode is far stiffer than the body's).
            jw = sp[b, SP_JW]
            dw = dt * (torque - r * f_drive) / (jw + dt * (r * r * load * dmu + kp_eff))
            w1 = w0 + dw
            dth = 0.5 * (w0 + w1) * dt
        elif tau > 0.0:
            e = math.exp(-dt / tau)
            w1 = cmd + (w0 - cmd) * e
            dth = cmd * dt + (w0 - cmd) * tau * (1.0 - e)
        else:
            w1 = cmd
            dth = cmd * dt
        th1 = th0 + dth
        wheels[b, i, WH_SPEED] = w1
        wheels[b, i, WH_ANGLE] = th1
        # 2) Rigid-material share of this substep (the start's measure from the last substep's end),
        # 3) coefficients and slip.
        a1 = th1 + phase
        f, m1 = gap_fraction_memo(th0 + phase, a1, pitch, gap, wheels[b, i, WH_GAP_AT], wheels[b, i, WH_GAP_MEASURE])
        wheels[b, i, WH_GAP_AT] = a1 if m1 == m1 else math.nan  # NaN m1: nothing to remember
        wheels[b, i, WH_GAP_MEASURE] = m1
        mu_w_max = (1.0 - f) * wp[b, i, WP_MUW] + f * wp[b, i, WP_GAPW]
        mu_t_max = (1.0 - f) * wp[b, i, WP_MUT] + f * wp[b, i, WP_GAPT]
        v_w = ux * ex + uy * ey - rc * w1
        v_t = ux * ax + uy * ay
        if mecanum:
            v_t += rs * w1
        out_slip[b, i, 0] = v_w
        out_slip[b, i, 1] = v_t
        if load <= 0.0:
            continue
        mu_w, dmu_w = friction_coefficient(v_w, mu_w_max, k, kin, v_s)
        mu_t, dmu_t = friction_coefficient(v_t, mu_t_max, k, kin, v_s)
        fx = -load * (mu_w * ex + mu_t * ax)
        fy = -load * (mu_w * ey + mu_t * ay)
        q0 += fx
        q1 += fy
        q2 += rho_x * fy - rho_y * fx
        # 4) A = Σ Gᵀ K G with K = N(μ'_W e eᵀ + μ'_T f fᵀ) and G = [[1, 0, −ρ_y], [0, 1, ρ_x]].
        kw = load * dmu_w
        kt = load * dmu_t
        k11 = kw * ex * ex + kt * ax * ax
        k12 = kw * ex * ey + kt * ax * ay
        k22 = kw * ey * ey + kt * ay * ay
        a00 += k11
        a01 += k12
        a11 += k22
        a02 += -k11 * rho_y + k12 * rho_x
        a12 += -k12 * rho_y + k22 * rho_x
        a22 += k11 * rho_y * rho_y - 2.0 * k12 * rho_x * rho_y + k22 * rho_x * rho_x
    m = sp[b, SP_MASS]
    inertia = sp[b, SP_INERTIA]
    # Solve (M + dt A) Δq = dt Q by the symmetric 3×3 adjugate.
    m00 = m + dt * a00
    m01 = dt * a01
    m02 = dt * a02
    m11 = m + dt * a11
    m12 = dt * a12
    m22 = inertia + dt * a22
    c00 = m11 * m22 - m12 * m12
    c01 = m02 * m12 - m01 * m22
    c02 = m01 * m12 - m02 * m11
    c11 = m00 * m22 - m02 * m02
    c12 = m01 * m02 - m00 * m12
    c22 = m00 * m11 - m01 * m01
    det = m00 * c00 + m01 * c01 + m02 * c02
    r0 = dt * q0
    r1 = dt * q1
    r2 = dt * q2
    inv = 1.0 / det  # one division instead of three: divisions dominate this kernel's arithmetic
    inv_dt = 1.0 / dt
    out_force[b, 0] = m * ((c00 * r0 + c01 * r1 + c02 * r2) * inv) * inv_dt
    out_force[b, 1] = m * ((c01 * r0 + c11 * r1 + c12 * r2) * inv) * inv_dt
    out_force[b, 2] = inertia * ((c02 * r0 + c12 * r1 + c22 * r2) * inv) * inv_dt


@numba.njit(cache=True)
def substep(dt, state, wheels, sp, wp, ext, out_force, out_slip):
    """Advance wheel states by dt [s] and write the effective force for one pymunk step.

    Arrays (B robots, n wheels); few arguments on purpose, as each costs dispatch time:
        state (B, 6): body x, y [m] (world), heading θ [rad], centre-of-mass velocity V_x, V_y [m/s]
            (world) and yaw rate ω [rad/s], as pymunk's batch API lays them out.
        wheels (B, n, N_WH): per wheel the integrated angle [rad] and speed [rad/s] (both updated), the
            commanded speed [rad/s], the PI integrator state [rad] (servo only; updated), the
            normal load N_i [N] (zero for a lifted wheel) and the rigid-material memo (updated);
            layout WH_* in :mod:`omni_gym.physics.layout`.
        sp (B, N_SP), wp (B, n, N_WP): parameters, layouts in :mod:`omni_gym.physics.layout`.
        ext (B, 3): extra generalised force (F_x, F_y [N], torque [N·m] about the centre of mass).
        out_force (B, 3): effective F_x, F_y [N] at the centre of mass and torque [N·m]; written.
        out_slip (B, n, 2): slip along the roller axis v_W = u·e − r w cos γ and along the free direction
            v_T = u·f + r w sin γ [m/s] (omni wheel: drive slip and transverse velocity); written.
    """
    for b in range(wheels.shape[0]):
        _robot_substep(b, dt, state, wheels, sp, wp, ext, out_force, out_slip)


@numba.njit(cache=True, parallel=True)
def substep_parallel(dt, state, wheels, sp, wp, ext, out_force, out_slip):
    """:func:`substep` with the robots shared among threads.

    Each robot's arithmetic is the same code as in the serial loop and touches only its own rows,
    so results are bit-identical to :func:`substep` (``tests/test_world.py`` checks it).
    """
    for b in numba.prange(wheels.shape[0]):
        _robot_substep(b, dt, state, wheels, sp, wp, ext, out_force, out_slip)


# Below this many robots, waking threads costs more than it saves (measured: 1024 robots, 2 cores:
# 128 µs parallel vs 245 µs serial per substep).
PARALLEL_MIN_ROBOTS = 256


def warm_up(kernel=substep) -> None:
    """Compile (or load from cache) ``kernel`` on tiny inputs, so the first real step is not slow.

    For :func:`substep_parallel` this first call may also start numba's OpenMP threads, which wait
    passively (``OMP_WAIT_POLICY``, set when ``omni_gym`` is imported: see ``omni_gym/__init__.py``).
    """
    z = np.zeros
    sp = z((2, N_SP))
    sp[:, SP_MASS] = sp[:, SP_INERTIA] = sp[:, SP_K] = sp[:, SP_KIN_RATIO] = sp[:, SP_VS] = sp[:, SP_PITCH] = 1.0
    kernel(1e-3, z((2, 6)), z((2, 3, N_WH)), sp, z((2, 3, N_WP)), z((2, 3)), z((2, 3)), z((2, 3, 2)))


# --- The substep loop compiled: batched read, force kernel, batched write and pymunk step ----------
#
# World.substeps runs the substeps between two contact switches through run_substeps (or
# run_substeps_parallel, the threaded kernel; run_substeps_spaces, one pymunk space per thread). Each
# substep makes the same calls, in the same order, as a Python loop over BodyBatch.read, the kernel,
# BodyBatch.write and BodyBatch.step, so results are bit-identical; only the cost of the Python calls
# is gone (a few µs per substep, more than one robot's physics). pymunk's C functions are called
# through their addresses (BodyBatch.c_table, columns C_* of the layout; pymunk_batch is the only
# module that knows pymunk's internals) by small intrinsics that cast an integer to a function
# pointer. The loops hold the GIL, so pymunk's collision callbacks (Python, through cffi) run as
# they did from Python. They live in this file because numba's cache does not notice edits to a
# function defined in another file: a loop elsewhere would keep running a stale kernel.

_VOID_P = ir.IntType(8).as_pointer()


@intrinsic
def _each_body(typingctx, fn, space, func, data):
    """Call ``void cpSpaceEachBody(cpSpace *, void (*)(cpBody *, void *), void *)`` at address ``fn``."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.VoidType(), [_VOID_P, _VOID_P, _VOID_P])
        target = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(target, [builder.inttoptr(a, _VOID_P) for a in args[1:]])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _space_step(typingctx, fn, space, dt):
    """Call ``void cpSpaceStep(cpSpace *, double)`` at address ``fn``."""
    sig = types.void(types.int64, types.int64, types.float64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.VoidType(), [_VOID_P, ir.DoubleType()])
        target = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(target, [builder.inttoptr(args[1], _VOID_P), args[2]])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _store_int(typingctx, address, value):
    """Store ``value`` as a C ``int`` (int32) at ``address`` (the element count of a pymunk array)."""
    sig = types.void(types.int64, types.int64)

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        ptr = builder.inttoptr(args[0], i32.as_pointer())
        builder.store(builder.trunc(args[1], i32), ptr)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _float_pointer(typingctx, address):
    """The float64 pointer at integer ``address`` (for ``numba.carray`` over a pymunk buffer)."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], ir.DoubleType().as_pointer())

    return sig, codegen


@numba.njit(cache=True, inline="always")
def _read(c):
    _store_int(c[C_GET_NUM], 0)
    _store_int(c[C_GET_INT_NUM], 0)
    _each_body(c[C_EACH_BODY], c[C_SPACE], c[C_GET_ITER], c[C_GET_REQ])


@numba.njit(cache=True, inline="always")
def _write_and_step(c, dt):
    _store_int(c[C_SET_NUM], 0)
    _each_body(c[C_EACH_BODY], c[C_SPACE], c[C_SET_ITER], c[C_SET_REQ])
    _store_int(c[C_SET_NUM], c[C_N_SET])
    _space_step(c[C_STEP], c[C_SPACE], dt)


@numba.njit(cache=True)
def run_substeps(count, c, dt, state, wheels, sp, wp, ext, force, slip):
    """``count`` substeps of ``dt`` [s]: read the bodies into ``state``, run the serial kernel, write
    ``force`` and step the space (``c``: ``BodyBatch.c_table``; arrays as in ``kernel.substep``)."""
    for _ in range(count):
        _read(c)
        substep(dt, state, wheels, sp, wp, ext, force, slip)
        _write_and_step(c, dt)


@numba.njit(cache=True)
def run_substeps_parallel(count, c, dt, state, wheels, sp, wp, ext, force, slip):
    """:func:`run_substeps` with the threaded kernel (bit-identical results)."""
    for _ in range(count):
        _read(c)
        substep_parallel(dt, state, wheels, sp, wp, ext, force, slip)
        _write_and_step(c, dt)


@numba.njit(cache=True, parallel=True)
def run_substeps_spaces(count, tables, dt, bounds, state, wheels, sp, wp, ext, slip):
    """:func:`run_substeps` for robots split among pymunk spaces: space k (``tables[k]``, one
    ``BodyBatch.c_table`` each) holds robots ``bounds[k]`` to ``bounds[k + 1]``; each thread runs
    every substep of its spaces (read, serial kernel, write, step) with no join between substeps,
    then gathers its robots' final states into ``state`` (B, 6). Each robot's arithmetic is that of
    :func:`run_substeps`, so results are bit-identical whatever the split and the thread count."""
    for k in numba.prange(tables.shape[0]):
        c = tables[k]
        lo = bounds[k]
        hi = bounds[k + 1]
        own = numba.carray(_float_pointer(c[C_STATES]), (hi - lo, 6))
        force = numba.carray(_float_pointer(c[C_FORCES]), (hi - lo, 3))
        w, p, q, e, s = wheels[lo:hi], sp[lo:hi], wp[lo:hi], ext[lo:hi], slip[lo:hi]
        for _ in range(count):
            _read(c)
            substep(dt, own, w, p, q, e, force, s)
            _write_and_step(c, dt)
        _read(c)
        state[lo:hi] = own
