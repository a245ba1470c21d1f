"""Compiled per-robot kernels of the batched estimation stack (:mod:`agents.batched`).

One call of :func:`ekf_process` runs one control period of :class:`agents.ekf.OmniEKF.process` (with the
slip detector of :mod:`agents.slip_detector`) for every active robot of a batch, in a plain loop over
robots. The arithmetic is that of the single-robot classes, step for step: the same products in the
same order, the same gates, re-acquisition, Joseph form and heading wrap. Two things differ and make
results agree to rounding, not bit for bit: matrix products are explicit loops (numpy hands them to
BLAS, whose kernels sum in another order and use fused multiply-adds), and inverses, determinants and
solves of the small symmetric positive-definite matrices go through a Cholesky factorisation (numpy:
LU). Both change the last bits of a result (relative 1e-16 per operation).

Why numba and a loop over robots rather than numpy over a robot axis: the work per robot is many
tiny products (7×7, 10×10) and, in the detector, 2ⁿ small factorisations (16 of 4×4 for four wheels);
numpy spends microseconds of call overhead per operation whatever the batch size, and its batched
``linalg.inv``/``slogdet`` on (N·16, 4, 4) stacks alone costs about as much as this whole kernel.
Measured (``benchmarks/batched_stack.py``): see ``benchmarks/results/batched_stack.md``.

Matrices are small, so products are written as loops into scratch arrays allocated once per call
(allocating a small array costs about as much as multiplying two 7×7 matrices); everything is float64.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from agents.motion import BG, NX, OM, TH, VX, VY, X, Y
from agents.motion import motion_into as _motion  # the single filter's motion model, the same compiled kernel
from omni_gym.angles import wrap_angle_nb as _wrap

# Indices into the float parameter vector ``fp`` of ekf_process.
F_DT = 0
F_ACCEL_PSD = 1
F_YAW_PSD = 2
F_BIAS_PSD = 3
F_R_WHEEL = 4  # σ_w² [rad²/s²]
F_R_GYRO = 5
F_R_COMPASS = 6
F_R_CAM_POS = 7
F_R_CAM_HEAD = 8
F_R_ACCEL = 9
F_GATE_WHEELS = 10
F_GATE_GYRO = 11
F_GATE_COMPASS = 12
F_GATE_CAMERA = 13
F_GATE_ACCEL = 14
F_ACCEL_LIMIT = 15
F_SIGMA_F2 = 16  # detector fault variance σ_f² [rad²/s²]
F_P_ON = 17  # detector Markov onset probability per period
F_P_OFF = 18  # detector Markov recovery probability per period
F_EXCLUDE = 19
F_INCLUDE = 20
N_FP = 21
# Indices into the integer parameter vector ``ip``.
I_USE_ACCEL = 0
I_USE_COMPASS = 1
I_USE_CAMERA = 2
I_USE_DETECTOR = 3
I_REACQUIRE = 4
I_INCLUDE_STEPS = 5
N_IP = 6
# Columns of the rejection counters.
REJ_GYRO, REJ_COMPASS, REJ_CAMERA = 0, 1, 2



MAXD = 16  # largest matrix side in the scratch space: 10 augmented states, up to 16 wheels
N_WS = 12  # scratch matrices
N_WV = 8  # scratch vectors


@numba.njit(cache=True)
def _mm(A, B, out):
    """out = A @ B."""
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            out[i, j] = 0.0
        for k in range(A.shape[1]):
            a = A[i, k]
            if a != 0.0:
                for j in range(B.shape[1]):
                    out[i, j] += a * B[k, j]


@numba.njit(cache=True)
def _mmt(A, B, out):
    """out = A @ B.T."""
    for i in range(A.shape[0]):
        for j in range(B.shape[0]):
            s = 0.0
            for k in range(A.shape[1]):
                s += A[i, k] * B[j, k]
            out[i, j] = s


@numba.njit(cache=True)
def _symmetrise_into(P, M):
    """P[:] = 0.5·(M + Mᵀ) (P and M distinct)."""
    m = M.shape[0]
    for i in range(m):
        for j in range(m):
            P[i, j] = 0.5 * (M[i, j] + M[j, i])


@numba.njit(cache=True)
def _cholesky(S, L):
    """L = lower Cholesky factor of a symmetric positive-definite S (NaN on the diagonal if it is not)."""
    m = S.shape[0]
    for j in range(m):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        d = math.sqrt(d) if d > 0.0 else math.nan
        L[j, j] = d
        for i in range(j + 1, m):
            s = S[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
        for i in range(j):
            L[i, j] = 0.0


@numba.njit(cache=True)
def _forward(L, b, y):
    """y with L·y = b."""
    m = L.shape[0]
    for i in range(m):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]


@numba.njit(cache=True)
def _nis(nu, S, ws, wv):
    """νᵀ S⁻¹ ν (scalar division for one dimension, as the single filter)."""
    m = S.shape[0]
    if m == 1:
        return nu[0] * nu[0] / S[0, 0]
    L = ws[10, :m, :m]
    y = wv[7, :m]
    _cholesky(S, L)
    _forward(L, nu, y)
    q = 0.0
    for i in range(m):
        q += y[i] * y[i]
    return q


@numba.njit(cache=True)
def _inv(S, out, ws, wv):
    """out = S⁻¹ of a symmetric positive-definite S (m ≥ 2) through its Cholesky factor."""
    m = S.shape[0]
    L = ws[10, :m, :m]
    Li = ws[11, :m, :m]
    e = wv[6, :m]
    y = wv[7, :m]
    _cholesky(S, L)
    for j in range(m):
        e[:] = 0.0
        e[j] = 1.0
        _forward(L, e, y)
        for i in range(m):
            Li[i, j] = y[i]
    for i in range(m):  # L⁻ᵀ L⁻¹
        for j in range(m):
            s = 0.0
            for k in range(max(i, j), m):
                s += Li[k, i] * Li[k, j]
            out[i, j] = s


@numba.njit(cache=True)
def _joseph(x, P, nu, H, R, S, ws, wv):
    """In place: x += Kν (heading wrapped), P = (I − KH)P(I − KH)ᵀ + KRKᵀ symmetrised (agents.ekf._joseph).

    The products are regrouped to cost O(nx²·m) instead of O(nx³): with A = I − KH,
    A·P = P − K·(HP) and (AP)·Aᵀ = AP − (AP·Hᵀ)·Kᵀ. Mathematically the same; the rounding differs.
    """
    nx = x.shape[0]
    m = nu.shape[0]
    PHt = ws[0, :nx, :m]
    K = ws[1, :nx, :m]
    _mm_sparse_bt(P, H, PHt)
    if m == 1:
        for i in range(nx):
            K[i, 0] = PHt[i, 0] / S[0, 0]
    else:
        Sinv = ws[2, :m, :m]
        _inv(S, Sinv, ws, wv)
        _mm(PHt, Sinv, K)
    for i in range(nx):
        s = 0.0
        for j in range(m):
            s += K[i, j] * nu[j]
        x[i] = x[i] + s
    x[TH] = _wrap(x[TH])
    HP = ws[3, :m, :nx]
    _mm(H, P, HP)
    AP = ws[4, :nx, :nx]
    for i in range(nx):
        for j in range(nx):
            s = P[i, j]
            for k in range(m):
                s -= K[i, k] * HP[k, j]
            AP[i, j] = s
    APHt = ws[5, :nx, :m]
    _mm_sparse_bt(AP, H, APHt)
    KR = ws[6, :nx, :m]
    _mm(K, R, KR)
    for k in range(m):  # APHt − KR
        for i in range(nx):
            APHt[i, k] -= KR[i, k]
    M = ws[7, :nx, :nx]
    for i in range(nx):
        for j in range(nx):
            s = AP[i, j]
            for k in range(m):
                s -= APHt[i, k] * K[j, k]
            M[i, j] = s
    _symmetrise_into(P, M)


@numba.njit(cache=True)
def _mm_sparse_bt(A, B, out):
    """out = A @ B.T, skipping the zeros of B (F is mostly identity, measurement matrices are sparse).

    Each entry is still summed over k in increasing order; a skipped term is an exact zero."""
    for i in range(A.shape[0]):
        for j in range(B.shape[0]):
            out[i, j] = 0.0
    for j in range(B.shape[0]):
        for k in range(B.shape[1]):
            b = B[j, k]
            if b != 0.0:
                for i in range(A.shape[0]):
                    out[i, j] += A[i, k] * b


@numba.njit(cache=True)
def _propagate(P, F, fp, out, ws):
    """out = F P Fᵀ + Q, Q = G·diag(q)·Δt·Gᵀ symmetrised + q_b·Δt on the bias (agents.ekf.process_noise)."""
    dt = fp[F_DT]
    q0, q2 = fp[F_ACCEL_PSD], fp[F_YAW_PSD]
    Gq = ws[8, :NX, :3]
    for i in range(NX):
        Gq[i, 0] = F[i, VX] * q0 * dt
        Gq[i, 1] = F[i, VY] * q0 * dt
        Gq[i, 2] = F[i, OM] * q2 * dt
    M = ws[9, :NX, :NX]
    for i in range(NX):  # Gq @ Gᵀ
        for j in range(NX):
            M[i, j] = Gq[i, 0] * F[j, VX] + Gq[i, 1] * F[j, VY] + Gq[i, 2] * F[j, OM]
    FP = ws[4, :NX, :NX]
    _mm(F, P, FP)
    _mm_sparse_bt(FP, F, out)
    for i in range(NX):
        for j in range(NX):
            q = 0.5 * (M[i, j] + M[j, i])
            if i == BG and j == BG:
                q += fp[F_BIAS_PSD] * dt
            out[i, j] += q


@numba.njit(cache=True)
def _predict(x, P, fp, ws, wv):
    """In place: constant-velocity prediction over Δt (agents.ekf.OmniEKF.predict)."""
    xn = wv[0, :NX]
    F = ws[0, :NX, :NX]
    _motion(x, fp[F_DT], xn, F)
    M = ws[1, :NX, :NX]
    _propagate(P, F, fp, M, ws)
    _symmetrise_into(P, M)
    x[:] = xn


@numba.njit(cache=True)
def _predict_accel(x, P, a0, a1, fp, ws, wv, Pa, xa, F, H2, R2, S2, nu2):
    """In place: prediction with (θ, vx, vy) cloned and the gated accelerometer update
    (agents.ekf.OmniEKF.predict_and_update_accel). Returns the NIS."""
    dt = fp[F_DT]
    c0, c1, c2 = TH, VX, VY
    for i in range(NX):
        Pa[i, NX] = P[i, c0]
        Pa[i, NX + 1] = P[i, c1]
        Pa[i, NX + 2] = P[i, c2]
    xa[NX], xa[NX + 1], xa[NX + 2] = x[c0], x[c1], x[c2]
    xn = wv[0, :NX]
    _motion(x, dt, xn, F)
    xa[:NX] = xn
    M = ws[1, :NX, :NX]
    _propagate(P, F, fp, M, ws)
    Pa[:NX, :NX] = M
    cross = ws[2, :NX, :3]
    _mm(F, Pa[:NX, NX:], cross)
    for i in range(NX):
        for j in range(3):
            Pa[i, NX + j] = cross[i, j]
            Pa[NX + j, i] = cross[i, j]
    for i in range(3):
        for j in range(3):
            Pa[NX + i, NX + j] = P[(c0, c1, c2)[i], (c0, c1, c2)[j]]
    # Accelerometer model h = (v − R(θc − θ)·v_c)/Δt (agents.ekf.accel_model).
    d = xa[NX] - xa[TH]
    c, sn = math.cos(d), math.sin(d)
    vc0, vc1 = xa[NX + 1], xa[NX + 2]
    rv0, rv1 = c * vc0 - sn * vc1, sn * vc0 + c * vc1
    drv0, drv1 = -sn * vc0 - c * vc1, c * vc0 - sn * vc1
    H2[:, :] = 0.0
    H2[0, VX] = H2[1, VY] = 1.0 / dt
    H2[0, TH] = drv0 / dt
    H2[1, TH] = drv1 / dt
    H2[0, NX] = -drv0 / dt
    H2[1, NX] = -drv1 / dt
    H2[0, NX + 1] = -c / dt
    H2[0, NX + 2] = sn / dt
    H2[1, NX + 1] = -sn / dt
    H2[1, NX + 2] = -c / dt
    nu2[0] = a0 - (xa[VX] - rv0) / dt
    nu2[1] = a1 - (xa[VY] - rv1) / dt
    HP = ws[3, :2, :NX + 3]
    _mm(H2, Pa, HP)
    _mm_sparse_bt(HP, H2, S2)
    S2[0, 0] += R2[0, 0]
    S2[1, 1] += R2[1, 1]
    nis = _nis(nu2, S2, ws, wv)
    if nis <= fp[F_GATE_ACCEL]:
        _joseph(xa, Pa, nu2, H2, R2, S2, ws, wv)
    x[:] = xa[:NX]
    _symmetrise_into(P, Pa[:NX, :NX])
    return nis


@numba.njit(cache=True)
def _scalar_gated(x, P, nu1, col_a, col_b, r, gate, rej, k, reacquire, ws, wv, H1, R1, S1):
    """χ²-gated scalar update, h = x[col_a] (+ x[col_b] if col_b ≥ 0), with re-acquisition by widening
    P[col_a, col_a] by ν². Returns the NIS."""
    H1[0, :] = 0.0
    H1[0, col_a] = 1.0
    if col_b >= 0:
        H1[0, col_b] = 1.0
    R1[0, 0] = r
    HP = ws[8, :1, :NX]
    _mm(H1, P, HP)
    _mm_sparse_bt(HP, H1, S1)
    S1[0, 0] += r
    nis = nu1[0] * nu1[0] / S1[0, 0]
    if nis > gate:
        rej[k] += 1
        if rej[k] < reacquire:
            return nis
        P[col_a, col_a] += nu1[0] * nu1[0]
        _mm(H1, P, HP)
        _mm_sparse_bt(HP, H1, S1)
        S1[0, 0] += r
    rej[k] = 0
    _joseph(x, P, nu1, H1, R1, S1, ws, wv)
    return nis


@numba.njit(cache=True)
def detector_step(nu, S, belief, ok, agree, hyp, fp, include_steps, ws, wv, logpost):
    """In place: one period of agents.slip_detector.SlipDetector.step (beliefs and hysteresis) for one robot.

    ``nu`` (n,) and ``S`` (n, n) are the wheel innovation and its covariance; ``hyp`` (H, n) the fault sets;
    ``logpost`` (H,) scratch.
    """
    n = nu.shape[0]
    p_on, p_off, sf2 = fp[F_P_ON], fp[F_P_OFF], fp[F_SIGMA_F2]
    logp = wv[2, :n]
    log1m = wv[3, :n]
    y = wv[4, :n]
    for j in range(n):
        prior = belief[j] * (1.0 - p_off) + (1.0 - belief[j]) * p_on
        logp[j] = math.log(prior)
        log1m[j] = math.log1p(-prior)
    C = ws[8, :n, :n]
    L = ws[9, :n, :n]
    D = wv[5, :n]
    nh = hyp.shape[0]
    for h in range(nh):
        for a in range(n):
            for b in range(a + 1):
                C[a, b] = S[a, b]
            if hyp[h, a]:
                C[a, a] += sf2
        # C = L·diag(D)·Lᵀ (unit L): log det C = log ΠD (one log), νᵀC⁻¹ν = Σ y²/D with L·y = ν.
        det = 1.0
        quad = 0.0
        for j in range(n):
            d = C[j, j]
            for k in range(j):
                d -= L[j, k] * L[j, k] * D[k]
            D[j] = d
            det *= d
            for i in range(j + 1, n):
                v = C[i, j]
                for k in range(j):
                    v -= L[i, k] * L[j, k] * D[k]
                L[i, j] = v / d
            v = nu[j]
            for k in range(j):
                v -= L[j, k] * y[k]
            y[j] = v
            quad += v * v / d
        lp = 0.0
        for j in range(n):
            lp += logp[j] if hyp[h, j] else log1m[j]
        logpost[h] = -0.5 * (quad + math.log(det)) + lp
    top = logpost.max()
    total = 0.0
    for h in range(nh):
        logpost[h] = math.exp(logpost[h] - top)
        total += logpost[h]
    for j in range(n):
        b = 0.0
        for h in range(nh):
            if hyp[h, j]:
                b += logpost[h] / total
        belief[j] = min(max(b, 0.0), 1.0)
    for j in range(n):
        if ok[j] and belief[j] > fp[F_EXCLUDE]:
            ok[j] = False
        agreeing = (not ok[j]) and belief[j] < fp[F_INCLUDE]
        agree[j] = agree[j] + 1 if agreeing else 0
        if agreeing and agree[j] >= include_steps:
            ok[j] = True
            agree[j] = 0


@numba.njit(cache=True)
def detector_batch(nu, S, belief, ok, agree, hyp, fp, include_steps, active):
    """:func:`detector_step` for every active robot: nu (N, n), S (N, n, n), state arrays (N, n)."""
    ws = np.zeros((N_WS, MAXD, MAXD))
    wv = np.zeros((N_WV, MAXD))
    logpost = np.empty(hyp.shape[0])
    for i in range(nu.shape[0]):
        if active[i]:
            detector_step(nu[i], S[i], belief[i], ok[i], agree[i], hyp, fp, include_steps, ws, wv, logpost)


@numba.njit(cache=True)
def ekf_process(xs, Ps, rej, since_cam, belief, ok, agree, wheel_ok, wheel_belief, wheels_used, nis_out,
                enc, gyro, compass, accel, camera, fix_age, W, hyp, fp, ip, active):
    """One control period of OmniEKF.process for every robot i with ``active[i]``; arrays over robots, in place.

    nis_out (N, 5): NIS of accel, gyro, compass, camera and the joint wheel NIS this period (NaN: not run).
    """
    _process_range(0, xs.shape[0], xs, Ps, rej, since_cam, belief, ok, agree, wheel_ok, wheel_belief, wheels_used,
                   nis_out, enc, gyro, compass, accel, camera, fix_age, W, hyp, fp, ip, active)


@numba.njit(cache=True, parallel=True)
def ekf_process_threaded(xs, Ps, rej, since_cam, belief, ok, agree, wheel_ok, wheel_belief, wheels_used, nis_out,
                         enc, gyro, compass, accel, camera, fix_age, W, hyp, fp, ip, active, chunks):
    """:func:`ekf_process` with the robots split into ``chunks`` contiguous blocks run on numba's threads.

    Robots are independent, so the result does not depend on the number of threads or chunks.
    """
    N = xs.shape[0]
    for c in numba.prange(chunks):
        lo = (N * c) // chunks
        hi = (N * (c + 1)) // chunks
        _process_range(lo, hi, xs, Ps, rej, since_cam, belief, ok, agree, wheel_ok, wheel_belief, wheels_used,
                       nis_out, enc, gyro, compass, accel, camera, fix_age, W, hyp, fp, ip, active)


@numba.njit(cache=True)
def _process_range(lo, hi, xs, Ps, rej, since_cam, belief, ok, agree, wheel_ok, wheel_belief, wheels_used, nis_out,
                   enc, gyro, compass, accel, camera, fix_age, W, hyp, fp, ip, active):
    """The body of :func:`ekf_process` for robots lo…hi−1, with its own scratch space."""
    n = W.shape[0]
    dt = fp[F_DT]
    ws = np.zeros((N_WS, MAXD, MAXD))
    wv = np.zeros((N_WV, MAXD))
    logpost = np.empty(hyp.shape[0])
    Hw = np.zeros((n, NX))
    Hw[:, VX:OM + 1] = W
    Hcam = np.zeros((3, NX))
    Hcam[0, X] = Hcam[1, Y] = Hcam[2, TH] = 1.0
    Rcam = np.zeros((3, 3))
    Rcam[0, 0] = Rcam[1, 1] = fp[F_R_CAM_POS]
    Rcam[2, 2] = fp[F_R_CAM_HEAD]
    Rw = np.zeros((n, n))
    for j in range(n):
        Rw[j, j] = fp[F_R_WHEEL]
    Pa = np.zeros((NX + 3, NX + 3))
    xa = np.zeros(NX + 3)
    F = np.zeros((NX, NX))
    H2 = np.zeros((2, NX + 3))
    R2 = np.zeros((2, 2))
    R2[0, 0] = R2[1, 1] = fp[F_R_ACCEL]
    S2 = np.zeros((2, 2))
    nu2 = np.zeros(2)
    H1 = np.zeros((1, NX))
    R1 = np.zeros((1, 1))
    S1 = np.zeros((1, 1))
    nu1 = np.zeros(1)
    nu = np.zeros(n)
    S = np.zeros((n, n))
    HwP = np.zeros((n, NX))
    idx = np.zeros(n, dtype=np.int64)
    nus = np.zeros(n)
    Hs = np.zeros((n, NX))
    Ss = np.zeros((n, n))
    Rs = np.zeros((n, n))
    nuc = np.zeros(3)
    S3 = np.zeros((3, 3))
    HcP = np.zeros((3, NX))
    reacquire = ip[I_REACQUIRE]
    lim = fp[F_ACCEL_LIMIT]
    for i in range(lo, hi):
        if not active[i]:
            continue
        x, P = xs[i], Ps[i]
        nis_out[i, :] = math.nan
        # Clone and predict; accelerometer (skipped at the observation clip).
        since_cam[i] += dt
        if ip[I_USE_ACCEL] and abs(accel[i, 0]) < lim and abs(accel[i, 1]) < lim:
            nis_out[i, 0] = _predict_accel(x, P, accel[i, 0], accel[i, 1], fp, ws, wv, Pa, xa, F, H2, R2, S2, nu2)
        else:
            _predict(x, P, fp, ws, wv)
        # Gyro z = ω + b_g.
        nu1[0] = gyro[i] - (x[OM] + x[BG])
        nis_out[i, 1] = _scalar_gated(x, P, nu1, OM, BG, fp[F_R_GYRO], fp[F_GATE_GYRO], rej[i], REJ_GYRO,
                                      reacquire, ws, wv, H1, R1, S1)
        # Wheel innovation against this prior: detector, then the wheels in use.
        for j in range(n):
            s = 0.0
            for k in range(3):
                s += W[j, k] * x[VX + k]
            nu[j] = enc[i, j] - s
        _mm(Hw, P, HwP)
        _mm_sparse_bt(HwP, Hw, S)
        for j in range(n):
            S[j, j] += fp[F_R_WHEEL]
        if ip[I_USE_DETECTOR]:
            detector_step(nu, S, belief[i], ok[i], agree[i], hyp, fp, ip[I_INCLUDE_STEPS], ws, wv, logpost)
            wheel_ok[i, :] = ok[i]
            wheel_belief[i, :] = belief[i]
        nis_out[i, 4] = _nis(nu, S, ws, wv)
        m = 0
        for j in range(n):
            use = wheel_ok[i, j] and nu[j] * nu[j] / S[j, j] <= fp[F_GATE_WHEELS]
            wheels_used[i, j] = use
            if use:
                idx[m] = j
                m += 1
        if m == n:
            _joseph(x, P, nu, Hw, Rw, S, ws, wv)
        elif m > 0:
            for a in range(m):
                nus[a] = nu[idx[a]]
                Hs[a] = Hw[idx[a]]
                for b in range(m):
                    Ss[a, b] = S[idx[a], idx[b]]
                    Rs[a, b] = Rw[idx[a], idx[b]]
            _joseph(x, P, nus[:m], Hs[:m], Rs[:m, :m], Ss[:m, :m], ws, wv)
        # Compass z = θ (innovation wrapped).
        if ip[I_USE_COMPASS]:
            nu1[0] = _wrap(compass[i] - x[TH])
            nis_out[i, 2] = _scalar_gated(x, P, nu1, TH, -1, fp[F_R_COMPASS], fp[F_GATE_COMPASS], rej[i],
                                          REJ_COMPASS, reacquire, ws, wv, H1, R1, S1)
        # Camera fix z = (x, y, θ) when it arrived this period.
        if ip[I_USE_CAMERA] and fix_age[i] == 0.0:
            nuc[0] = camera[i, 0] - x[X]
            nuc[1] = camera[i, 1] - x[Y]
            nuc[2] = _wrap(camera[i, 2] - x[TH])
            _mm(Hcam, P, HcP)
            _mm_sparse_bt(HcP, Hcam, S3)
            for j in range(3):
                S3[j, j] += Rcam[j, j]
            nis = _nis(nuc, S3, ws, wv)
            nis_out[i, 3] = nis
            apply = True
            if nis > fp[F_GATE_CAMERA]:
                rej[i, REJ_CAMERA] += 1
                if rej[i, REJ_CAMERA] < reacquire:
                    apply = False
                else:
                    # Widen: pose variance += ν²; body velocity += δv δvᵀ, δv = R(θ)ᵀ ν_xy / time since the last fix.
                    P[X, X] += nuc[0] * nuc[0]
                    P[Y, Y] += nuc[1] * nuc[1]
                    P[TH, TH] += nuc[2] * nuc[2]
                    c, sn = math.cos(x[TH]), math.sin(x[TH])
                    span = max(since_cam[i], 1e-3)
                    dv0 = (c * nuc[0] + sn * nuc[1]) / span
                    dv1 = (-sn * nuc[0] + c * nuc[1]) / span
                    P[VX, VX] += dv0 * dv0
                    P[VX, VY] += dv0 * dv1
                    P[VY, VX] += dv1 * dv0
                    P[VY, VY] += dv1 * dv1
                    _mm(Hcam, P, HcP)
                    _mm_sparse_bt(HcP, Hcam, S3)
                    for j in range(3):
                        S3[j, j] += Rcam[j, j]
            if apply:
                rej[i, REJ_CAMERA] = 0
                _joseph(x, P, nuc, Hcam, Rcam, S3, ws, wv)
                since_cam[i] = 0.0
