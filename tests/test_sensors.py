"""Behavioural tests of omni_gym.sensors.

Statistical tolerances: for N independent Gaussian samples of std σ, the sample mean has standard
error σ/√N and the sample std has standard error ≈ σ/√(2N). We allow 5 standard errors, so a
correct model fails with probability < 1e-6 per check (and the seeds are fixed, so the tests are
deterministic anyway), while a wrong std (e.g. variance used as std, or a factor √2) is off by far
more than 5 SE at these N.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_gym.angles import wrap_angle
from omni_gym.physics.kinematics import rotation
from omni_gym.sensors import (
    Accelerometer,
    CameraTracker,
    Compass,
    Gyroscope,
    SensorConfig,
    SensorSuite,
    WheelEncoders,
    specific_force_body,
)

N = 20_000  # samples for noise statistics
SE_LIMIT = 5.0  # allowed deviation in standard errors (see module docstring)


def assert_std(samples: np.ndarray, sigma: float) -> None:
    """Sample std within SE_LIMIT standard errors (σ/√(2N)) of σ."""
    n = samples.size
    assert abs(np.std(samples, ddof=1) - sigma) < SE_LIMIT * sigma / math.sqrt(2 * n)


def assert_mean(samples: np.ndarray, mean: float, sigma: float) -> None:
    """Sample mean within SE_LIMIT standard errors (σ/√N) of ``mean``."""
    assert abs(np.mean(samples) - mean) < SE_LIMIT * sigma / math.sqrt(samples.size)


def run_suite(seed: int, config: SensorConfig | None = None, steps: int = 300) -> list:
    """Readings of a 3-wheel suite along a simple deterministic motion."""
    suite = SensorSuite(3, np.random.default_rng(seed), config)
    dt, out = 0.01, []
    for k in range(steps):
        t = k * dt
        angles = np.array([1.0, -2.0, 0.5]) * t
        pose = np.array([0.1 * t, 0.0, 0.3 * t])
        out.append(suite.measure(t, dt, angles, pose, 0.3, np.array([0.0, 0.1])))
    return out


def flatten(readings: list) -> np.ndarray:
    """Every numeric value of a run as one vector (camera absent → NaN placeholders)."""
    rows = []
    for r in readings:
        cam = r.camera if r.camera is not None else np.full(3, np.nan)
        rows.append(np.concatenate([r.wheel_angles, [r.gyro, r.compass], r.accel, cam]))
    return np.array(rows)


# --- determinism ---------------------------------------------------------------------------------


def test_same_seed_same_readings_different_seed_different() -> None:
    a, b, c = flatten(run_suite(7)), flatten(run_suite(7)), flatten(run_suite(8))
    np.testing.assert_array_equal(a, b)  # bit-identical: every draw comes from the seeded generator
    assert not np.allclose(a[:, 3:], c[:, 3:], equal_nan=True)  # noisy channels differ with the seed


def test_reset_with_same_seed_replays_the_noise() -> None:
    suite = SensorSuite(3, np.random.default_rng(1))
    first = [suite.gyro.measure(0.0, 0.01) for _ in range(50)]
    suite.reset(np.random.default_rng(1))
    assert [suite.gyro.measure(0.0, 0.01) for _ in range(50)] == first


def test_global_numpy_rng_is_not_used() -> None:
    # Deliberately reseeds the legacy global RNG: readings must not depend on it.
    np.random.seed(0)  # noqa: NPY002
    a = flatten(run_suite(3))
    np.random.seed(12345)  # noqa: NPY002
    b = flatten(run_suite(3))
    np.testing.assert_array_equal(a, b)


def test_sensor_streams_are_independent_of_other_sensors_noise() -> None:
    # Switching the compass noise off must not shift the gyro's random sequence.
    base = run_suite(5)
    quiet_compass = run_suite(5, SensorConfig(compass_noise_std=0.0))
    assert [r.gyro for r in base] == [r.gyro for r in quiet_compass]


# --- encoders ------------------------------------------------------------------------------------


def test_encoder_quantisation_error_in_zero_to_quantum() -> None:
    enc = WheelEncoders(4, counts_per_rev=2048)
    q = 2 * math.pi / 2048
    assert enc.quantum == pytest.approx(q, rel=1e-15)
    angles = np.random.default_rng(0).uniform(-50.0, 50.0, size=(2000, 4))  # both signs, many turns
    for a in angles:
        err = a - enc.measure(a)
        assert np.all(err >= 0.0) and np.all(err < q)
        np.testing.assert_allclose(enc.measure(a) / q, np.round(enc.measure(a) / q), atol=1e-6)


def test_encoder_counts_are_floor() -> None:
    enc = WheelEncoders(3, counts_per_rev=4)  # quantum π/2
    np.testing.assert_array_equal(enc.counts([0.1, math.pi / 2 + 0.1, -0.1]), [0, 1, -1])


# --- gyroscope -----------------------------------------------------------------------------------


def test_gyro_noise_statistics() -> None:
    gyro = Gyroscope(np.random.default_rng(0), noise_std=0.01, bias_std=0.0, bias_walk_std=0.0)
    readings = np.array([gyro.measure(0.5) for _ in range(N)])
    assert_mean(readings, 0.5, 0.01)
    assert_std(readings, 0.01)


def test_gyro_bias_is_constant_and_distributed_as_configured() -> None:
    gyro = Gyroscope(np.random.default_rng(0), noise_std=0.0, bias_std=0.02, bias_walk_std=0.0)
    readings = [gyro.measure(1.0) for _ in range(10)]
    assert readings == [1.0 + gyro.bias] * 10  # no noise, no walk: the bias alone
    rng = np.random.default_rng(1)
    biases = np.array([Gyroscope(rng, 0.0, 0.02, 0.0).bias for _ in range(4000)])
    assert_mean(biases, 0.0, 0.02)
    assert_std(biases, 0.02)


def test_gyro_bias_walk_grows_with_sqrt_time() -> None:
    # After k steps of dt the walked bias has std σ_w·√(k·dt); checked across 4000 independent gyros.
    sigma_w, dt, k = 0.01, 0.05, 100
    rng = np.random.default_rng(2)
    finals = []
    for _ in range(4000):
        gyro = Gyroscope(rng, noise_std=0.0, bias_std=0.0, bias_walk_std=sigma_w)
        for _ in range(k):
            reading = gyro.measure(0.0, dt)
        finals.append(reading)
    assert_std(np.array(finals), sigma_w * math.sqrt(k * dt))


def test_gyro_walk_needs_dt() -> None:
    gyro = Gyroscope(np.random.default_rng(0), bias_walk_std=1e-3)
    with pytest.raises(ValueError, match="dt"):
        gyro.measure(0.0)
    with pytest.raises(ValueError, match="dt"):
        gyro.measure(0.0, -0.01)


# --- compass -------------------------------------------------------------------------------------


@pytest.mark.parametrize(("heading", "expected"), [
    (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi + 0.1, -math.pi + 0.1),
    (-0.2, -0.2), (2 * math.pi - 0.3, -0.3), (-7 * math.pi / 2, math.pi / 2),
])
def test_noiseless_compass_wraps_to_half_open_interval(heading: float, expected: float) -> None:
    compass = Compass(np.random.default_rng(0), noise_std=0.0)
    assert compass.measure(heading) == pytest.approx(expected, abs=1e-12)


def test_noisy_compass_near_pi_stays_wrapped_and_unbiased() -> None:
    # Headings at ±π: readings straddle the cut, so all must land in (−π, π] and their circular
    # error (wrapped difference to the truth) has the configured statistics.
    compass = Compass(np.random.default_rng(0), noise_std=0.05)
    readings = np.array([compass.measure(math.pi) for _ in range(N)])
    assert np.all(readings > -math.pi) and np.all(readings <= math.pi)
    assert np.any(readings < 0) and np.any(readings > 0)
    err = wrap_angle(readings - math.pi)
    assert_mean(err, 0.0, 0.05)
    assert_std(err, 0.05)


# --- accelerometer -------------------------------------------------------------------------------


def test_accelerometer_noise_and_bias() -> None:
    acc = Accelerometer(np.random.default_rng(0), noise_std=0.05, bias_std=0.1)
    true = np.array([0.3, -0.2])
    readings = np.array([acc.measure(true) for _ in range(N)])
    assert readings.shape == (N, 2)
    for axis in range(2):
        assert_mean(readings[:, axis], true[axis] + acc.bias[axis], 0.05)
        assert_std(readings[:, axis], 0.05)
    assert not np.allclose(acc.bias, 0.0)  # a bias was drawn (|b| < 1e-8 has probability ~1e-7)


def test_specific_force_body_rotates_world_into_body() -> None:
    # Heading π/2: world +x is body −y.
    np.testing.assert_allclose(specific_force_body([1.0, 0.0], math.pi / 2), [0.0, -1.0], atol=1e-15)
    rng = np.random.default_rng(0)
    a_world, theta = rng.normal(size=(50, 2)), rng.uniform(-4, 4, size=50)
    body = specific_force_body(a_world, theta)
    back = np.array([rotation(th) @ b for th, b in zip(theta, body, strict=True)])
    np.testing.assert_allclose(back, a_world, atol=1e-12)  # R(θ)·(R(θ)ᵀ a) = a up to rounding


# --- camera --------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [0.01, 0.003, 0.02])
def test_camera_fix_rate(dt: float) -> None:
    # Time accumulated by repeated addition (as a simulator does); fixes are due at 0, 0.1, ..., 9.9
    # in [0, 10), and every 0.1 s window holds at least one sample since dt < 0.1, so exactly 100.
    cam = CameraTracker(np.random.default_rng(0), rate_hz=10.0)
    t, fixes = 0.0, 0
    while t < 10.0 - 1e-9:
        fixes += cam.measure(t, np.zeros(3)) is not None
        t += dt
    assert fixes == 100


def test_camera_first_fix_at_t0_then_spacing() -> None:
    cam = CameraTracker(np.random.default_rng(0), rate_hz=4.0, t0=1.0)
    times = np.arange(0.0, 3.0, 0.05)
    fix_times = [t for t in times if cam.measure(t, np.zeros(3)) is not None]
    np.testing.assert_allclose(fix_times, [1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5, 2.75], atol=1e-9)


def test_camera_coarse_steps_give_at_most_one_fix_per_call() -> None:
    cam = CameraTracker(np.random.default_rng(0), rate_hz=10.0)
    results = [cam.measure(0.25 * k, np.zeros(3)) for k in range(40)]
    assert all(r is not None for r in results)  # every call is past a due time
    assert cam.next_due == pytest.approx(9.8, abs=1e-9)  # first due time after t = 9.75


def test_camera_noise_statistics_and_heading_wrap() -> None:
    cam = CameraTracker(np.random.default_rng(0), rate_hz=10.0, position_std=0.01, heading_std=0.03)
    pose = np.array([1.0, -2.0, math.pi])
    fixes = np.array([cam.measure(0.1 * k, pose) for k in range(N)])
    for axis, sigma in ((0, 0.01), (1, 0.01)):
        assert_mean(fixes[:, axis], pose[axis], sigma)
        assert_std(fixes[:, axis], sigma)
    assert np.all(fixes[:, 2] > -math.pi) and np.all(fixes[:, 2] <= math.pi)
    assert_std(wrap_angle(fixes[:, 2] - math.pi), 0.03)


# --- config and suite ----------------------------------------------------------------------------


def test_noiseless_config_gives_exact_readings_up_to_quantisation() -> None:
    cfg = SensorConfig.noiseless()
    assert cfg.counts_per_rev == SensorConfig().counts_per_rev
    assert cfg.camera_rate_hz == SensorConfig().camera_rate_hz
    suite = SensorSuite(3, np.random.default_rng(0), cfg)
    angles, pose = np.array([0.5, -1.0, 7.0]), np.array([0.2, 0.3, 4.0])
    r = suite.measure(0.0, 0.01, angles, pose, 0.7, np.array([0.1, -0.2]))
    assert r.gyro == 0.7
    assert r.compass == pytest.approx(4.0 - 2 * math.pi, abs=1e-12)
    np.testing.assert_array_equal(r.accel, [0.1, -0.2])
    np.testing.assert_allclose(r.camera, [0.2, 0.3, 4.0 - 2 * math.pi], atol=1e-12)
    q = suite.encoders.quantum
    assert np.all((angles - r.wheel_angles >= 0) & (angles - r.wheel_angles < q))


def test_default_config_is_noisy() -> None:
    cfg = SensorConfig()
    assert cfg.counts_per_rev == 2048 and cfg.camera_rate_hz == 10.0
    assert all(getattr(cfg, name) > 0 for name in ("gyro_noise_std", "compass_noise_std", "accel_noise_std",
                                                   "camera_position_std", "camera_heading_std"))


# --- bad inputs ----------------------------------------------------------------------------------


@pytest.mark.parametrize(("kwargs", "name"), [
    ({"gyro_noise_std": -0.1}, "gyro_noise_std"),
    ({"compass_noise_std": float("nan")}, "compass_noise_std"),
    ({"camera_rate_hz": 0.0}, "camera_rate_hz"),
    ({"counts_per_rev": 0}, "counts_per_rev"),
    ({"counts_per_rev": 10.5}, "counts_per_rev"),
])
def test_bad_config_raises_naming_the_field(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        SensorConfig(**kwargs)


def test_bad_measure_inputs_raise_naming_the_argument() -> None:
    suite = SensorSuite(3, np.random.default_rng(0))
    good = {"t": 0.0, "dt": 0.01, "wheel_angles": np.zeros(3), "pose": np.zeros(3), "yaw_rate": 0.0,
            "acc_body": np.zeros(2)}
    for name, bad in [("wheel_angles", np.zeros(4)), ("pose", [0.0, np.nan, 0.0]), ("yaw_rate", np.inf),
                      ("acc_body", np.zeros(3)), ("t", np.nan)]:
        with pytest.raises(ValueError, match=name):
            suite.measure(**{**good, name: bad})


@pytest.mark.parametrize("bad_rng", [np.random, 42, None])
def test_rng_must_be_a_generator(bad_rng: object) -> None:
    with pytest.raises(ValueError, match="rng"):
        Gyroscope(bad_rng)
    with pytest.raises(ValueError, match="rng"):
        SensorSuite(3, bad_rng)


def test_negative_sensor_noise_raises() -> None:
    with pytest.raises(ValueError, match="noise_std"):
        Compass(np.random.default_rng(0), noise_std=-1.0)
    with pytest.raises(ValueError, match="position_std"):
        CameraTracker(np.random.default_rng(0), position_std=-1e-3)
    with pytest.raises(ValueError, match="n_wheels"):
        WheelEncoders(0)
