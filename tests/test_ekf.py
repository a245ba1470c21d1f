"""The pose/twist EKF (agents/ekf.py) and its slip and lift-off detector (agents/slip_detector.py).

Every test can fail for a real defect: wrong Jacobians or process noise, heading arithmetic that is not
wrapped, a filter that is not the Kalman filter on a linear model, a filter that is inconsistent with
its own noise model, slips or lift-offs that reach the odometry, and a filter that does not track the
simulated robot. Tolerances and statistical bounds are justified where they are set.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from scipy.stats import chi2

import omni_gym  # noqa: F401  (registers the environments)
from agents.ekf import BG, OM, TH, VX, VY, EKFConfig, OmniEKF, accel_model, motion_model, process_noise
from agents.slip_detector import SlipDetector
from omni_gym.angles import wrap_angle as wrap
from omni_gym.envs.observations import SensorObs, SensorObsDecoder
from omni_gym.physics.robot import phunopas2018

DT = 0.01
ROBOT = phunopas2018()
W = ROBOT.wheel_matrix()
PHUNOPAS = "OmniPathFollow-Phunopas-v0"
MECANUM = "OmniPathFollow-Mecanum-v0"  # optiodom_omni4: four mecanum wheels (rollers at ±45°, r = 3 cm)


def obs(enc, gyro, compass, accel, camera=(0.0, 0.0, 0.0), age=0.05) -> SensorObs:
    """A decoded sensors observation; the reference fields are unused by the filter."""
    return SensorObs(np.asarray(enc, dtype=float), float(gyro), float(wrap(compass)), np.asarray(accel, dtype=float),
                     np.array([camera[0], camera[1], wrap(camera[2])]), float(age), np.zeros(3), np.zeros(3),
                     np.zeros((3, 3)), np.zeros(3))


def numeric_jacobian(fun, x: np.ndarray, h: float = 1e-6, angle_rows=()) -> np.ndarray:
    """Central differences; rows listed in ``angle_rows`` are heading outputs compared modulo 2π."""
    cols = []
    for j in range(len(x)):
        e = np.zeros(len(x))
        e[j] = h
        d = np.asarray(fun(x + e), dtype=float) - np.asarray(fun(x - e), dtype=float)
        for r in angle_rows:
            d[r] = wrap(d[r])
        cols.append(d / (2 * h))
    return np.column_stack(cols)


# States for the Jacobian checks: ordinary motion, heading just below +π, a yaw rate small enough for the
# sinc series branch (|ωΔt/2| < 1e-4), fast spin, and standing still.
STATES = [
    np.array([0.3, -0.2, 0.7, 0.4, -0.1, 0.8, 0.01]),
    np.array([-1.0, 2.0, math.pi - 1e-3, -0.2, 0.3, 2.5, -0.02]),
    np.array([0.0, 0.0, -2.0, 0.5, 0.2, 5e-3, 0.0]),
    np.array([0.1, 0.1, 1.0, 0.6, -0.6, -3.0, 0.005]),
    np.zeros(7),
]


# --- model: process ---------------------------------------------------------------------------------


@pytest.mark.parametrize("x", STATES)
def test_motion_model_is_the_exact_arc(x):
    """f(x) moves the pose along the arc of the held twist: compare with 20 000 RK4 steps of ṗ = R(θ)v, θ̇ = ω.

    RK4 with h = 5e-7 s is exact to ~1e-20 here; 1e-12 m/rad leaves room only for rounding.
    """
    out, _ = motion_model(x, DT)
    th, vx, vy, om = x[TH], x[VX], x[VY], x[OM]

    def deriv(s):
        c, sn = math.cos(s[2]), math.sin(s[2])
        return np.array([c * vx - sn * vy, sn * vx + c * vy, om])

    s = x[0:3].copy()
    h = DT / 20000
    for _ in range(20000):
        k1 = deriv(s)
        k2 = deriv(s + 0.5 * h * k1)
        k3 = deriv(s + 0.5 * h * k2)
        k4 = deriv(s + h * k3)
        s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert np.allclose(out[0:2], s[0:2], atol=1e-12, rtol=0)
    assert abs(wrap(out[TH] - s[2])) < 1e-12
    assert -math.pi < out[TH] <= math.pi
    assert np.array_equal(out[VX:], x[VX:]), "the twist and the bias are constant over a period"
    assert th == x[TH]  # the input is not modified


@pytest.mark.parametrize("x", STATES)
def test_process_jacobian_matches_finite_differences(x):
    """F = ∂f/∂x. Central differences with h = 1e-6: truncation ~h²·|f'''| < 1e-12, rounding ~1e-16/h = 1e-10."""
    _, F = motion_model(x, DT)
    num = numeric_jacobian(lambda z: motion_model(z, DT)[0], x, angle_rows=(TH,))
    assert np.allclose(F, num, atol=1e-8, rtol=0), f"\n{F}\n{num}"


@pytest.mark.parametrize("x", STATES[:4])
def test_process_noise_is_the_covariance_of_a_twist_jump(x):
    """Q is the covariance of f(x) when the twist jumps by w ~ N(0, diag(q_v, q_v, q_ω)·Δt) at the period start.

    200 000 samples: each entry of the sample covariance has a relative standard error of about
    √(2/200 000) = 0.3 % (correlation-normalised: |Ĉ_ij − Q_ij| / √(Q_ii Q_jj) ~ 0.2 %); the bound 1.5 %
    is five standard errors. The non-linearity of f in the jump (relative φ² ≈ 1e-5) is far below that.
    """
    qv, qw, qb = 1.0, 100.0, 1e-8
    Q = process_noise(x, DT, qv, qw, qb)
    eig = np.linalg.eigvalsh(Q)
    assert np.array_equal(Q, Q.T) and eig.min() > -1e-14 * eig.max(), "symmetric, positive semi-definite (rank 4)"
    rng = np.random.default_rng(1)
    n = 200_000
    jumps = rng.standard_normal((n, 3)) * np.sqrt(np.array([qv, qv, qw]) * DT)
    out = np.empty((n, 7))
    # f with the twist replaced by twist + jump, vectorised (the exact arc, as in test_motion_model_is_the_exact_arc).
    v = x[VX:OM + 1] + jumps
    phi = 0.5 * v[:, 2] * DT
    small = np.abs(phi) < 1e-4
    s = np.where(small, 1 - phi**2 / 6, np.sin(phi) / np.where(small, 1.0, phi))
    c, sn = np.cos(x[TH] + phi), np.sin(x[TH] + phi)
    out[:, 0] = x[0] + (c * v[:, 0] - sn * v[:, 1]) * DT * s
    out[:, 1] = x[1] + (sn * v[:, 0] + c * v[:, 1]) * DT * s
    out[:, 2] = x[TH] + v[:, 2] * DT
    out[:, 3:6] = v
    out[:, 6] = x[BG] + rng.standard_normal(n) * math.sqrt(qb * DT)
    C = np.cov(out, rowvar=False)
    scale = np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    assert np.all(np.abs(C - Q) <= 0.015 * scale + 1e-30), f"\n{(C - Q) / scale}"
    # Zero-order hold: the heading change over the period is exactly ω·Δt with the new ω.
    g = np.zeros(7)
    g[TH], g[OM] = 1.0, -DT
    assert g @ Q @ g <= 1e-12 * Q[TH, TH]


# --- model: measurements --------------------------------------------------------------------------


@pytest.mark.parametrize("x", STATES)
@pytest.mark.parametrize("name", ["wheels", "gyro", "compass", "camera"])
def test_measurement_jacobians_match_finite_differences(x, name):
    """H = ∂h/∂x for each sensor, against central differences (the models are linear: exact to rounding)."""
    ekf = OmniEKF(ROBOT)
    _, H = ekf.measurement_model(name, x)
    num = numeric_jacobian(lambda z: ekf.measurement_model(name, z)[0], x)
    assert np.allclose(H, num, atol=1e-8, rtol=0), f"{name}\n{H}\n{num}"


@pytest.mark.parametrize("x", STATES)
def test_accelerometer_jacobians_match_finite_differences(x):
    """The accelerometer model h = (v − R(θc − θ)·v_c)/Δt w.r.t. the state and the clone (θc, vxc, vyc).

    h scales like 1/Δt = 100, so the absolute tolerance is 100× the others'.
    """
    clone = np.array([x[TH] - 0.013, x[VX] - 0.02, x[VY] + 0.03])
    _, Hx, Hc = accel_model(x, clone, DT)
    assert np.allclose(Hx, numeric_jacobian(lambda z: accel_model(z, clone, DT)[0], x), atol=1e-6, rtol=0)
    assert np.allclose(Hc, numeric_jacobian(lambda c: accel_model(x, c, DT)[0], clone), atol=1e-6, rtol=0)
    # A body moving at constant world velocity while it turns reads zero.
    theta_c, theta = 0.4, 0.4 + 0.02
    v_world = np.array([0.3, -0.2])
    body = lambda th: np.array([[math.cos(th), math.sin(th)], [-math.sin(th), math.cos(th)]]) @ v_world  # noqa: E731
    x2 = np.zeros(7)
    x2[TH], x2[VX:VY + 1] = theta, body(theta)
    h, _, _ = accel_model(x2, np.concatenate([[theta_c], body(theta_c)]), DT)
    assert np.allclose(h, 0.0, atol=1e-12)


# --- heading wrap -------------------------------------------------------------------------------------


def test_compass_and_camera_innovations_wrap_at_pi():
    """A reading of +π − ε against an estimate of −π + ε is an innovation of −2ε, not 2π − 2ε.

    Unwrapped, the NIS would be (2π − 0.02)²/(0.02² + 0.05²) ≈ 1.3e4 and the reading would be gated out.
    """
    eps = 0.01
    ekf = OmniEKF(ROBOT)
    ekf.reset(np.array([0.0, 0.0, -math.pi + eps]), pose_std=(0.01, 0.01, 0.1))  # gain 0.8: the update crosses −π
    P_th = ekf.P[TH, TH]
    nis, accepted = ekf.update_compass(math.pi - eps)
    R = ekf.config.compass_noise_std**2
    assert accepted
    assert nis == pytest.approx((2 * eps) ** 2 / (P_th + R), rel=1e-9)
    expected = -math.pi + eps - 2 * eps * P_th / (P_th + R)  # below −π: must come back as just under +π
    assert -math.pi < ekf.x[TH] <= math.pi
    assert abs(wrap(ekf.x[TH] - expected)) < 1e-12
    assert ekf.x[TH] > 3.0, "the estimate crossed −π and is stored wrapped near +π"

    ekf.reset(np.array([1.0, 2.0, math.pi - eps]), pose_std=(0.01, 0.01, 0.02))
    nis, accepted = ekf.update_camera(np.array([1.0, 2.0, -math.pi + eps]))
    assert accepted and nis < 1.0
    assert -math.pi < ekf.x[TH] <= math.pi and abs(wrap(ekf.x[TH] - math.pi)) < 2 * eps


def test_predicted_heading_stays_wrapped_and_continuous():
    """Turning through +π: the stored heading jumps to −π (wrapped) while the motion stays continuous."""
    ekf = OmniEKF(ROBOT, EKFConfig(use_accel=False, use_camera=False))
    ekf.reset(np.array([0.0, 0.0, math.pi - 0.02]))
    ekf.x[OM] = 1.0
    unwrapped = ekf.x[TH]
    for _ in range(5):
        before = ekf.x[TH]
        ekf.predict(DT)
        unwrapped += wrap(ekf.x[TH] - before)
        assert -math.pi < ekf.x[TH] <= math.pi
    assert unwrapped == pytest.approx(math.pi - 0.02 + 0.05, abs=1e-12)
    assert ekf.x[TH] < -3.0
    # A compass reading of the true (wrapped) heading leaves a tiny innovation after the crossing.
    nis, accepted = ekf.update_compass(wrap(math.pi + 0.03))
    assert accepted and nis < 0.1


# --- linear special case ------------------------------------------------------------------------------


def test_reduces_to_the_linear_kalman_filter():
    """With θ ≡ 0 and ω ≡ 0 (zero variance, no yaw process noise) the EKF is a linear Kalman filter on
    (x, y, vx, vy): F = [[I, Δt I], [0, I]], Q = q_v Δt [[Δt² I, Δt I], [Δt I, I]] (twist jump held over
    the period), wheels z = W[:, :2]·v, camera z = (x, y). Gates off (gate_probability = 1) so both
    filters use every measurement. Agreement to 1e-9 relative: only rounding separates the Joseph form
    from the textbook P = (I − KH)P.
    """
    q = 0.3
    cfg = EKFConfig(accel_psd=q, yaw_accel_psd=0.0, gyro_bias_walk_std=0.0, gate_probability=1.0, use_detector=False)
    ekf = OmniEKF(ROBOT, cfg)
    ekf.reset(np.array([0.5, -0.5, 0.0]))
    P0 = np.diag([1e-4, 2e-4, 0.0, 0.01, 0.02, 0.0, 0.0])
    ekf.P = P0.copy()
    ekf.x[VX:VY + 1] = [0.1, -0.05]

    F = np.block([[np.eye(2), DT * np.eye(2)], [np.zeros((2, 2)), np.eye(2)]])
    Q = q * DT * np.block([[DT**2 * np.eye(2), DT * np.eye(2)], [DT * np.eye(2), np.eye(2)]])
    Hw = np.hstack([np.zeros((4, 2)), W[:, :2]])
    Rw = cfg.wheel_rate_std**2 * np.eye(4)
    Hc = np.hstack([np.eye(2), np.zeros((2, 2))])
    Rc = cfg.camera_position_std**2 * np.eye(2)
    idx = [0, 1, VX, VY]
    s = ekf.x[idx].copy()
    P = P0[np.ix_(idx, idx)].copy()

    def kf_update(s, P, z, H, R):
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        return s + K @ (z - H @ s), (np.eye(4) - K @ H) @ P

    rng = np.random.default_rng(3)
    truth = np.array([0.5, -0.5, 0.2, 0.0])
    for k in range(1, 201):
        truth[2:] += rng.standard_normal(2) * math.sqrt(q * DT)
        truth[:2] += truth[2:] * DT
        z = W[:, :2] @ truth[2:] + cfg.wheel_rate_std * rng.standard_normal(4)
        ekf.predict(DT)
        ekf.update_wheels(z)
        s, P = F @ s, F @ P @ F.T + Q
        s, P = kf_update(s, P, z, Hw, Rw)
        if k % 10 == 0:
            zc = truth[:2] + cfg.camera_position_std * rng.standard_normal(2)
            ekf.update_camera(np.array([zc[0], zc[1], 0.0]))
            s, P = kf_update(s, P, zc, Hc, Rc)
        assert np.allclose(ekf.x[idx], s, rtol=1e-9, atol=1e-12), k
        assert np.allclose(ekf.P[np.ix_(idx, idx)], P, rtol=1e-9, atol=1e-15), k
        assert ekf.x[TH] == 0.0 and ekf.x[OM] == 0.0


# --- Monte Carlo consistency --------------------------------------------------------------------------


def simulate_own_model(cfg: EKFConfig, runs: int, steps: int, rng: np.random.Generator, camera_every: int = 10):
    """Truth from the filter's own model (zero-order-hold twist random walk, exact arcs, bias walk) and
    every sensor with the configured white noise. Returns truth (steps+1, runs, 7), initial estimates and
    per-step readings."""
    n = W.shape[0]
    x = np.zeros((runs, 7))
    x[:, 0:2] = rng.uniform(-1.0, 1.0, (runs, 2))
    x[:, TH] = rng.uniform(-math.pi, math.pi, runs)
    x[:, VX:OM + 1] = rng.normal(0.0, cfg.rest_speed_std, (runs, 3))
    x[:, BG] = rng.normal(0.0, cfg.gyro_bias_std, runs)
    pose_std = np.array([0.01, 0.01, 0.02])
    start = x[:, 0:3] + pose_std * rng.standard_normal((runs, 3))
    truth = np.empty((steps + 1, runs, 7))
    truth[0] = x
    jump = np.sqrt(np.array([cfg.accel_psd, cfg.accel_psd, cfg.yaw_accel_psd]) * DT)
    readings = []
    for k in range(1, steps + 1):
        prev = x.copy()
        x[:, VX:OM + 1] += jump * rng.standard_normal((runs, 3))
        x[:, BG] += cfg.gyro_bias_walk_std * math.sqrt(DT) * rng.standard_normal(runs)
        for j in range(runs):
            x[j] = motion_model(x[j], DT)[0]
        truth[k] = x
        d = prev[:, TH] - x[:, TH]
        c, s = np.cos(d), np.sin(d)
        turned = np.column_stack([c * prev[:, VX] - s * prev[:, VY], s * prev[:, VX] + c * prev[:, VY]])
        acc = (x[:, VX:VY + 1] - turned) / DT + cfg.accel_noise_std * rng.standard_normal((runs, 2))
        readings.append(dict(
            enc=x[:, VX:OM + 1] @ W.T + cfg.wheel_rate_std * rng.standard_normal((runs, n)),
            gyro=x[:, OM] + x[:, BG] + cfg.gyro_noise_std * rng.standard_normal(runs),
            compass=x[:, TH] + cfg.compass_noise_std * rng.standard_normal(runs),
            accel=acc,
            camera=x[:, 0:3] + np.array([cfg.camera_position_std, cfg.camera_position_std, cfg.camera_heading_std])
            * rng.standard_normal((runs, 3)),
            age=0.0 if k % camera_every == 0 else (k % camera_every) * DT,
        ))
    return truth, start, pose_std, readings


def test_monte_carlo_consistency():
    """NEES and NIS over 50 Monte Carlo runs of 3 s with known truth from the filter's own model.

    The full filter runs (process(): cloning + accelerometer, gyro, slip detector, gated wheels,
    compass, camera at 10 Hz). The random-walk intensities are set to q_v = 0.05 (m/s²)²·s and
    q_ω = 0.5 (rad/s²)²·s so the simulated robot stays in its envelope (rms speed 0.58 m/s, rms yaw
    rate 1.1 rad/s after 3 s); with the environment defaults (1 and 100) the random walk would reach
    2.4 m/s and 17 rad/s rms, far outside what the robot does. Consistency is a property of the implementation given
    matching noises; the noise levels are the defaults (SensorConfig at 100 Hz).

    Statistics, each with its two-sided 95 % χ² band:
    * NEES averaged over the N = 50 runs at one instant: N·NEES ~ χ²(N·7); 95 % band
      χ²_{0.025, 0.975}(350)/50 = [6.00, 8.07]; checked at the end (t = 3 s). The run-averaged NEES is
      correlated in time, so the whole trajectory is summarised by the share of instants inside that
      band, expected 0.95, required ≥ 0.85.
    * NIS per sensor averaged over all runs and periods: innovations of a consistent filter are white, so
      the m samples are independent and m·NIS ~ χ²(m·d): wheels (the joint NIS of all four, d = 4,
      m = 15 000, band [3.955, 4.045]), gyro and compass (d = 1, m = 15 000, [0.977, 1.023]),
      accelerometer (d = 2, m = 15 000, [1.968, 2.032]), camera (d = 3, m = 1 500, [2.877, 3.125]).
    Six statistics each tested at 95 % would fail a perfect filter for one seed in four; the assertions
    therefore use the family-wise 95 % bands (Bonferroni: each at 1 − 0.05/6, e.g. NEES [5.68, 8.48]),
    and the assertion messages give the plain 95 % bands. Measured with this seed: NEES at 3 s 6.85
    (0.95 of the instants inside [6.00, 8.07]), wheels 4.044, gyro 1.025 (+2.2 standard errors: the only
    one outside its plain 95 % band), compass 0.987, accelerometer 2.027, camera 2.911. Over 8 other
    seeds (20 runs × 3 s each) the averages were NEES 6.91, wheels 3.99, gyro 0.989, compass 0.999,
    camera 3.007, accelerometer 1.999.
    A defect (wrong Q, R, H or wrap) moves these averages far outside either band.
    """
    cfg = EKFConfig(accel_psd=0.05, yaw_accel_psd=0.5)
    runs, steps = 50, 300
    truth, start, pose_std, readings = simulate_own_model(cfg, runs, steps, np.random.default_rng(0))
    nees = np.empty((steps + 1, runs))
    nis = {"wheels_joint": [], "gyro": [], "compass": [], "accel": [], "camera": []}
    for j in range(runs):
        ekf = OmniEKF(ROBOT, cfg)
        ekf.reset(start[j], pose_std)
        for k in range(steps + 1):
            if k > 0:
                r = readings[k - 1]
                ekf.process(obs(r["enc"][j], r["gyro"][j], r["compass"][j], r["accel"][j], r["camera"][j], r["age"]),
                            DT)
                for key in nis:
                    if key in ekf.step_nis:
                        nis[key].append(ekf.step_nis[key])
            e = truth[k, j] - ekf.x
            e[TH] = wrap(e[TH])
            nees[k, j] = e @ np.linalg.solve(ekf.P, e)
    avg = nees.mean(axis=1)
    n_stats = 6
    tails = [0.025 / n_stats, 1 - 0.025 / n_stats]
    lo95, hi95 = chi2.ppf([0.025, 0.975], runs * 7) / runs
    lo, hi = chi2.ppf(tails, runs * 7) / runs
    assert lo < avg[-1] < hi, f"NEES at 3 s {avg[-1]:.2f} outside [{lo:.2f}, {hi:.2f}] (95 %: [{lo95:.2f}, {hi95:.2f}])"
    inside = np.mean((avg[1:] > lo95) & (avg[1:] < hi95))
    assert inside >= 0.85, f"only {inside:.2f} of the instants inside the NEES band; time-mean {avg[1:].mean():.2f}"
    dof = {"wheels_joint": 4, "gyro": 1, "compass": 1, "accel": 2, "camera": 3}
    for key, values in nis.items():
        m = len(values)
        assert m >= (runs * steps // 10 if key == "camera" else runs * steps * 0.99), (key, m)
        lo_k, hi_k = chi2.ppf(tails, m * dof[key]) / m
        lo95_k, hi95_k = chi2.ppf([0.025, 0.975], m * dof[key]) / m
        mean = float(np.mean(values))
        assert lo_k < mean < hi_k, (f"{key}: average NIS {mean:.4f} outside [{lo_k:.4f}, {hi_k:.4f}] "
                                    f"(95 %: [{lo95_k:.4f}, {hi95_k:.4f}], m = {m})")


# --- slip and lift-off --------------------------------------------------------------------------------


def constant_twist_run(fault, twist=(0.3, 0.1, 0.5), steps=300, seed=5):
    """Odometry-only filter (no camera, no compass) on a robot holding ``twist``; ``fault(k)`` is added
    to the encoder rates. The same noise for every call, so runs differ only by the fault."""
    cfg = EKFConfig(use_camera=False, use_compass=False)
    ekf = OmniEKF(ROBOT, cfg)
    rng = np.random.default_rng(seed)
    x = np.zeros(7)
    x[VX:OM + 1] = twist
    x[BG] = 0.004
    ekf.reset(np.zeros(3))
    ekf.x[VX:OM + 1] = twist
    history = []
    for k in range(1, steps + 1):
        x = motion_model(x, DT)[0]
        enc = W @ x[VX:OM + 1] + cfg.wheel_rate_std * rng.standard_normal(4) + fault(k)
        gyro = x[OM] + x[BG] + cfg.gyro_noise_std * rng.standard_normal()
        c, s = math.cos(x[OM] * DT), math.sin(x[OM] * DT)  # body velocity held, world velocity turning
        accel = np.array([(1 - c) * x[VX] - s * x[VY], s * x[VX] + (1 - c) * x[VY]]) / DT
        accel += 0.05 * rng.standard_normal(2)
        ekf.process(obs(enc, gyro, 0.0, accel), DT)
        history.append(dict(nis=ekf.last_nis["wheels"].copy(), used=ekf.wheels_used.copy(), ok=ekf.wheel_ok.copy(),
                            belief=ekf.wheel_belief.copy(), pose=ekf.pose, twist=ekf.body_twist, truth=x.copy()))
    return history


def test_injected_encoder_slip_is_gated_out_and_flagged():
    """Wheel 1's encoder reads 5 rad/s too fast from period 100 to 249 (a slipping wheel).

    * At the first faulty period its NIS (≈ 25/0.0175 ≈ 1400) is far above the gate (15.1) and it is not
      applied; the detector drops it in that same period and keeps it out while the fault lasts; the
      other wheels stay trusted.
    * The pose then differs from the fault-free run (same noise) by less than 3 mm after 1.5 s
      (measured 0.2 mm). Had the faulty wheel been used, the least-squares velocity would be off by
      |(W⁺)_v·(5 rad/s on wheel 1)| = 0.125 m/s, ~0.19 m in 1.5 s: the bound is 60× tighter.
    * After the fault ends the wheel is back within 10 periods (belief below 0.2 for 3 periods).
    """
    fault = np.array([5.0, 0.0, 0.0, 0.0])
    bad = constant_twist_run(lambda k: fault if 100 <= k < 250 else 0.0)
    good = constant_twist_run(lambda k: 0.0)
    gate = EKFConfig().gate(1)
    first = bad[99]  # period k = 100
    assert first["nis"][0] > 50 * gate
    assert not first["used"][0] and first["used"][1:].all()
    for h in bad[99:249]:
        assert not h["ok"][0] and not h["used"][0] and h["belief"][0] > 0.99
        assert np.all(h["belief"][1:] < 0.5)
    pose_diff = np.linalg.norm(bad[248]["pose"][0:2] - good[248]["pose"][0:2])
    assert pose_diff < 3e-3, pose_diff
    would_be = np.linalg.norm((np.linalg.pinv(W) @ fault)[0:2])  # velocity error [m/s] had the wheel been used
    assert would_be * 1.5 > 60 * 3e-3
    back = next(k for k in range(249, 300) if bad[k]["ok"][0])
    assert back - 249 < 10, back - 249
    assert np.all([h["belief"].max() < 0.5 for h in good]), "no false alarm in the fault-free run"


def test_lifted_wheel_spinning_while_robot_stands_still():
    """A lifted wheel spins at 5 rad/s while the robot stands still (the other wheels read zero).

    Flagged in its first period and kept out. Against the fault-free run with the same noise the velocity
    estimate differs by less than 5 mm/s at every period (the three standing wheels now carry the
    estimate: their noise alone moves it by a few mm/s) and the position by less than 1 mm after 1 s;
    used, the spinning wheel would put 0.125 m/s into the velocity and 0.12 m into the position.
    """
    spin = np.array([0.0, 5.0, 0.0, 0.0])
    hist = constant_twist_run(lambda k: spin if k >= 50 else 0.0, twist=(0.0, 0.0, 0.0), steps=150)
    clean = constant_twist_run(lambda k: 0.0, twist=(0.0, 0.0, 0.0), steps=150)
    assert not hist[49]["ok"][1] and not hist[49]["used"][1]
    for h, c in zip(hist[49:], clean[49:], strict=True):
        assert not h["ok"][1] and np.all(h["ok"][[0, 2, 3]])
        assert np.linalg.norm(h["twist"][0:2] - c["twist"][0:2]) < 5e-3
    assert np.linalg.norm(hist[-1]["pose"][0:2] - clean[-1]["pose"][0:2]) < 1e-3
    assert np.linalg.norm((np.linalg.pinv(W) @ spin)[0:2]) > 0.12


def test_detector_diagnostics():
    """Consistency residual (I − W W⁺)z and the encoder yaw rate on known rates."""
    sigma = EKFConfig().wheel_rate_std
    det = SlipDetector(W, ROBOT.wheel_radius, sigma)
    q = np.array([0.2, -0.1, 0.7])
    S = W @ (1e-4 * np.eye(3)) @ W.T + sigma**2 * np.eye(4)
    det.step(W @ q, np.zeros(4), S, yaw_pred=0.7, yaw_var=1e-4, dt=DT)
    assert np.allclose(det.residual, 0.0, atol=1e-12) and det.residual_nis < 1e-20
    assert det.yaw_rate_encoders == pytest.approx(0.7, abs=1e-12)
    z = W @ q + np.array([2.0, 0.0, 0.0, 0.0])
    det.step(z, z - W @ q, S, yaw_pred=0.7, yaw_var=1e-4, dt=DT)
    P_perp = np.eye(4) - W @ np.linalg.pinv(W)
    assert np.allclose(det.residual, 2.0 * P_perp[:, 0], atol=1e-12)
    assert det.residual_nis == pytest.approx(4.0 * P_perp[0, 0] / sigma**2, rel=1e-9)
    assert det.belief[0] > 0.99 and np.all(det.belief[1:] < 0.01) and not det.ok[0]


# --- real environment ---------------------------------------------------------------------------------


def test_config_for_env_matches_sensor_config():
    """The defaults are SensorConfig's at 100 Hz; sensor_noise scales them; zero noise falls back to floors."""
    env = gym.make(PHUNOPAS, obs_mode="sensors")
    assert EKFConfig.for_env(env) == EKFConfig()
    env = gym.make(PHUNOPAS, obs_mode="sensors", sensor_noise=0.5, control_hz=50.0)
    c = EKFConfig.for_env(env)
    assert c.gyro_noise_std == pytest.approx(0.0025) and c.camera_position_std == pytest.approx(0.0025)
    assert c.wheel_rate_std == pytest.approx(2 * math.pi / 2048 / (0.02 * math.sqrt(6)))
    c0 = EKFConfig.for_env(gym.make(PHUNOPAS, obs_mode="sensors", sensor_noise=0.0))
    assert c0.gyro_noise_std > 0 and c0.compass_noise_std > 0 and c0.accel_noise_std > 0 and c0.camera_heading_std > 0


def make_env(env_id=PHUNOPAS, **kw):
    base = dict(obs_mode="sensors", surface="grip", friction="initial", lift_rate=0.0, lost_distance=100.0,
                arena_half_size=5.0)
    return gym.make(env_id, **{**base, **kw})


# The same bounds hold on the mecanum robot: its filter and detector see only the wheel matrix.
@pytest.mark.parametrize("env_id", [PHUNOPAS, MECANUM])
@pytest.mark.parametrize("wheel", [0, 1])
def test_env_lifted_wheel_detection_delay(wheel, env_id):
    """The real environment, 'grip' floor, wheel commands, robot driving (0.2, 0.1) m/s while turning 0.5 rad/s.

    1. 0–1 s: all wheels down. 2. 1–1.5 s: wheel lifted with `set_contact`, still commanded consistently:
       it spins exactly as the rigid motion needs and the other three drive the body, so no sensor can
       tell (belief stays < 0.5) and nothing is lost. 3. 1.5–2 s: the lifted wheel is commanded 2 rad/s
       faster (a free wheel whose speed no longer matches the body). Measured: flagged and dropped in the
       first period (delay 1 period = 10 ms, every wheel, offsets 0.7–5 rad/s; 0.5 rad/s takes 2
       periods, 0.3 rad/s is below the encoder resolution of ~0.3 rad/s per period). Required: ≤ 2
       periods. The other wheels are not flagged. 4. 2–2.5 s: wheel down, consistent command again:
       back in use after 4–5 periods (measured), required ≤ 10.
    The pose error stays below 1.5 cm throughout (camera at 10 Hz, 5 mm).
    """
    env = make_env(env_id, action_mode="wheels")
    o, info = env.reset(seed=0)
    dec = SensorObsDecoder.for_env(env)
    core = env.unwrapped.core
    ekf = OmniEKF(core.robot, EKFConfig.for_env(env))
    ekf.reset(dec(o).camera_fix)
    cmd = core.W @ np.array([0.2, 0.1, 0.5])
    lifted = np.ones(4, dtype=bool)
    lifted[wheel] = False
    detect = recover = None
    for k in range(250):
        c = cmd.copy()
        if k == 100:
            core.world.set_contact(0, lifted)
        if 150 <= k < 200:
            c[wheel] += 2.0
        if k == 200:
            core.world.set_contact(0, np.ones(4, dtype=bool))
        o, _, _, _, info = env.step(c / core.wheel_scale)
        ekf.process(dec(o), DT)
        if 100 <= k < 150:
            assert not info["contact"][wheel]
            assert ekf.wheel_belief[wheel] < 0.5 and ekf.wheel_ok.all()
        if 150 <= k < 200:
            if detect is None and not ekf.wheel_ok[wheel]:
                detect = k - 150 + 1
            assert np.all(np.delete(ekf.wheel_belief, wheel) < 0.5)
        if k >= 200 and recover is None and ekf.wheel_ok[wheel]:
            recover = k - 200 + 1
        err = info["pose"] - ekf.pose
        assert np.hypot(err[0], err[1]) < 0.015, k
    assert detect is not None and detect <= 2, detect
    assert recover is not None and recover <= 10, recover


@pytest.mark.parametrize("env_id", [PHUNOPAS, MECANUM])
@pytest.mark.parametrize("noise, use, pos_tol, head_tol", [
    (0.1, {}, 0.01, 0.02),
    (0.1, {"use_camera": False, "use_compass": False}, 0.01, 0.02),
    (1.0, {}, 0.02, 0.05),
])
def test_env_grip_feedforward_pose_within_cm(noise, use, pos_tol, head_tol, env_id):
    """Feed-forward twist on the 'grip' floor (no slip, no lift-off) for 5 s: the EKF pose follows info["pose"].

    Twist: vx = 0.25 sin(1.3 t), vy = 0.2 cos(0.9 t) m/s, ω = 1.2 sin(0.7 t) rad/s, ramped in over 0.3 s.
    Measured maximum errors per axis over seeds 0–2: sensor_noise 0.1, all sensors ≤ 1.0 mm and 0.011
    rad (the initial camera heading); odometry, gyro and accelerometer only (no camera, no compass)
    ≤ 2.2 mm and 0.003 rad; default noise ≤ 8.1 mm and 0.036 rad (again the initial camera heading,
    0.02 rad std, corrected by the compass and camera within about a second). The bounds
    (1–2 cm, 0.02–0.05 rad) are 'a few cm' with room for other seeds; a wrong wheel matrix, frame or
    sign drifts by decimetres in 5 s.
    """
    for seed in (0, 1):
        env = make_env(env_id, sensor_noise=noise)
        o, info = env.reset(seed=seed)
        dec = SensorObsDecoder.for_env(env)
        ekf = OmniEKF(env.unwrapped.core.robot, EKFConfig.for_env(env, **use))
        ekf.reset(dec(o).camera_fix)
        scale = np.array([env.unwrapped.cfg.max_speed, env.unwrapped.cfg.max_speed, env.unwrapped.cfg.max_yaw_rate])
        for k in range(500):
            t = k * DT
            twist = np.array([0.25 * math.sin(1.3 * t), 0.2 * math.cos(0.9 * t), 1.2 * math.sin(0.7 * t)])
            o, _, terminated, truncated, info = env.step(twist * min(1.0, t / 0.3) / scale)
            assert not (terminated or truncated)
            ekf.process(dec(o), DT)
            err = info["pose"] - ekf.pose
            assert np.hypot(err[0], err[1]) < pos_tol, (seed, k, err)
            assert abs(wrap(err[2])) < head_tol, (seed, k, err)


def test_noise_levels_carry_the_sensor_names_and_the_old_names_still_work():
    """EKFConfig's noise levels are named as omni_gym.sensors.SensorConfig's; the old keyword and attribute
    names map onto them with a DeprecationWarning, and giving both is refused."""
    from agents.ekf import RENAMED_NOISE
    from omni_gym.sensors import SensorConfig

    new_names = set(RENAMED_NOISE.values())
    assert new_names <= set(SensorConfig.__dataclass_fields__) and new_names <= set(EKFConfig.__dataclass_fields__)
    for old, new in RENAMED_NOISE.items():
        with pytest.warns(DeprecationWarning, match=f"{old} is now called {new}"):
            cfg = EKFConfig(**{old: 0.123})
        assert getattr(cfg, new) == 0.123
        with pytest.warns(DeprecationWarning, match=new):
            assert getattr(cfg, old) == 0.123
        with pytest.warns(DeprecationWarning):
            assert getattr(EKFConfig().with_changes(**{old: 0.5}), new) == 0.5
        with pytest.raises(TypeError, match=f"give {new} only"):
            EKFConfig(**{old: 0.1, new: 0.2})
