"""Seeded sensor models: wheel encoders, gyroscope, compass, accelerometer and a camera/tracker.

Frames and units (see :mod:`omni_gym.physics.robot`):

* World frame: fixed, x/y in the floor plane, z up; pose (x, y, θ) in [m, m, rad].
* Body frame: x forward, y left, z up; the heading θ is the angle from world x to body x.
* Wheel angles [rad] and wheel speeds [rad/s] use the sign convention of :mod:`omni_gym.physics.robot`.

Randomness: every random draw comes from a ``numpy.random.Generator`` handed to the sensor (in its
constructor or in ``reset``), never from the global numpy RNG, so a seed fixes every reading.
:class:`SensorSuite` derives one independent child generator per noisy sensor from the generator it
is given, so switching one sensor's noise off does not change another sensor's noise sequence.

All noise levels are standard deviations of zero-mean Gaussian noise, drawn once per call of
``measure`` (i.e. per sample, whatever the sample period).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.checks import finite_array, finite_scalar, nonnegative, positive

TWO_PI = 2.0 * math.pi


# --- validation helpers ---------------------------------------------------------------------------


def _check_rng(rng: np.random.Generator) -> np.random.Generator:
    """``rng`` itself; ValueError unless it is a ``numpy.random.Generator`` (not the global RNG)."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got {rng!r}")
    return rng


def _child_rngs(rng: np.random.Generator, n: int) -> list[np.random.Generator]:
    """``n`` independent generators seeded from ``rng`` (deterministic given ``rng``'s state)."""
    seeds = _check_rng(rng).integers(0, 2**63, size=n)
    return [np.random.default_rng(int(s)) for s in seeds]




def specific_force_body(acc_world: np.ndarray, theta: float | np.ndarray) -> np.ndarray:
    """Rotate a world-frame planar acceleration (a_x, a_y) [m/s²] into the body frame at heading θ [rad].

    For a planar robot gravity is along z, so it does not enter the x/y components: the body-frame
    x/y specific force an ideal accelerometer reads equals R(θ)ᵀ·a_world. ``acc_world`` may be (..., 2)
    with θ broadcasting against its leading dimensions. The caller supplies the acceleration of the
    sensor's own location (for an offset sensor include the ω² and α lever-arm terms).
    """
    a = np.asarray(acc_world, dtype=float)
    if a.shape[-1:] != (2,):
        raise ValueError(f"acc_world must have shape (..., 2), got shape {a.shape}")
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * a[..., 0] + s * a[..., 1], -s * a[..., 0] + c * a[..., 1]], axis=-1)


# --- configuration -------------------------------------------------------------------------------


@dataclass(frozen=True)
class SensorConfig:
    """Sensor parameters; the defaults are typical of a small (RoboCup-size) wheeled robot.

    Attributes:
        counts_per_rev: encoder counts per wheel revolution (quantum 2π/counts_per_rev rad). 2048:
            a 512-line quadrature encoder on the wheel shaft.
        gyro_noise_std: gyroscope white noise per sample [rad/s]. 0.005 rad/s ≈ 0.3 °/s: a consumer
            MEMS gyro (≈0.01 °/s/√Hz) sampled at ~100 Hz plus motor vibration.
        gyro_bias_std: std of the constant gyro bias drawn at reset [rad/s]. 0.01 rad/s ≈ 0.6 °/s:
            residual turn-on bias of a MEMS gyro after a simple static calibration.
        gyro_bias_walk_std: bias random walk [rad/s per √s]. 1e-4: slow thermal drift of a MEMS gyro.
        compass_noise_std: heading noise [rad]. 0.05 rad ≈ 3°: a magnetometer indoors near motors.
        accel_noise_std: accelerometer white noise per sample and axis [m/s²]. 0.05 m/s² ≈ 5 mg:
            a consumer MEMS accelerometer (≈400 µg/√Hz) at ~100 Hz.
        accel_bias_std: std of the constant accelerometer bias per axis drawn at reset [m/s²].
            0.02 m/s²: residual bias after a static calibration.
        camera_rate_hz: camera/tracker fix rate [Hz]. 10 Hz: a webcam-based overhead tracker.
        camera_position_std: tracker position noise per axis [m]. 0.005 m: overhead camera over a
            few-metre arena (RoboCup SSL-vision grade).
        camera_heading_std: tracker heading noise [rad]. 0.02 rad ≈ 1°.
    """

    counts_per_rev: int = 2048
    gyro_noise_std: float = 0.005
    gyro_bias_std: float = 0.01
    gyro_bias_walk_std: float = 1e-4
    compass_noise_std: float = 0.05
    accel_noise_std: float = 0.05
    accel_bias_std: float = 0.02
    camera_rate_hz: float = 10.0
    camera_position_std: float = 0.005
    camera_heading_std: float = 0.02

    def __post_init__(self) -> None:
        cpr = self.counts_per_rev
        if isinstance(cpr, bool) or not isinstance(cpr, (int, np.integer)) or cpr < 1:
            raise ValueError(f"counts_per_rev must be a positive integer, got {cpr!r}")
        positive("camera_rate_hz", self.camera_rate_hz)
        for f in fields(self):
            if f.name.endswith("_std"):
                nonnegative(f.name, getattr(self, f.name))

    @classmethod
    def noiseless(cls, **overrides: float) -> SensorConfig:
        """A config with every noise and bias std zero (encoder quantisation and camera rate kept)."""
        zeros = {f.name: 0.0 for f in fields(cls) if f.name.endswith("_std")}
        return replace(cls(), **{**zeros, **overrides})


# --- sensors -------------------------------------------------------------------------------------


class WheelEncoders:
    """Incremental wheel encoders: true wheel angles [rad] → angles quantised to whole counts.

    The reading is ⌊θ/q⌋·q with quantum q = 2π/counts_per_rev, so the error θ − reading lies in [0, q).
    Deterministic: no random draws.
    """

    def __init__(self, n_wheels: int, counts_per_rev: int = 2048) -> None:
        if isinstance(n_wheels, bool) or not isinstance(n_wheels, (int, np.integer)) or n_wheels < 1:
            raise ValueError(f"n_wheels must be a positive integer, got {n_wheels!r}")
        if isinstance(counts_per_rev, bool) or not isinstance(counts_per_rev, (int, np.integer)) \
                or counts_per_rev < 1:
            raise ValueError(f"counts_per_rev must be a positive integer, got {counts_per_rev!r}")
        self.n_wheels = int(n_wheels)
        self.counts_per_rev = int(counts_per_rev)

    @property
    def quantum(self) -> float:
        """Angle of one count [rad]."""
        return TWO_PI / self.counts_per_rev

    def counts(self, wheel_angles: np.ndarray) -> np.ndarray:
        """Integer counts ⌊θ_i/q⌋ for true wheel angles θ_i [rad], shape (n_wheels,)."""
        angles = finite_array("wheel_angles", wheel_angles, (self.n_wheels,))
        return np.floor(angles / self.quantum).astype(np.int64)

    def measure(self, wheel_angles: np.ndarray) -> np.ndarray:
        """Quantised wheel angles [rad], shape (n_wheels,)."""
        return self.counts(wheel_angles) * self.quantum


class Gyroscope:
    """Yaw-rate gyro: true yaw rate [rad/s] → rate + bias + white noise [rad/s].

    The bias is drawn at reset from N(0, bias_std²) and, if ``bias_walk_std`` > 0, random-walks by
    N(0, bias_walk_std²·dt) before each sample (``dt`` [s] is then required by ``measure``).
    """

    def __init__(self, rng: np.random.Generator, noise_std: float = 0.005, bias_std: float = 0.01,
                 bias_walk_std: float = 1e-4) -> None:
        self.noise_std = nonnegative("noise_std", noise_std)
        self.bias_std = nonnegative("bias_std", bias_std)
        self.bias_walk_std = nonnegative("bias_walk_std", bias_walk_std)
        self.bias = 0.0
        self.reset(rng)

    def reset(self, rng: np.random.Generator) -> None:
        """Take ``rng`` as the noise source and draw a new bias [rad/s]."""
        self._rng = _check_rng(rng)
        self.bias = float(self._rng.normal(0.0, self.bias_std))

    def measure(self, yaw_rate: float, dt: float | None = None) -> float:
        """One gyro reading [rad/s] of the true yaw rate ``yaw_rate`` [rad/s]; ``dt`` [s] since the last."""
        rate = finite_scalar("yaw_rate", yaw_rate)
        if self.bias_walk_std > 0:
            if dt is None:
                raise ValueError("dt is required when bias_walk_std > 0")
            step = positive("dt", dt)
            self.bias += float(self._rng.normal(0.0, self.bias_walk_std * math.sqrt(step)))
        return rate + self.bias + float(self._rng.normal(0.0, self.noise_std))


class Compass:
    """Heading sensor: true heading θ [rad] → θ + N(0, noise_std²), wrapped to (−π, π]."""

    def __init__(self, rng: np.random.Generator, noise_std: float = 0.05) -> None:
        self.noise_std = nonnegative("noise_std", noise_std)
        self.reset(rng)

    def reset(self, rng: np.random.Generator) -> None:
        """Take ``rng`` as the noise source."""
        self._rng = _check_rng(rng)

    def measure(self, heading: float) -> float:
        """One heading reading [rad] in (−π, π] (world frame, from world x to body x)."""
        theta = finite_scalar("heading", heading)
        return wrap_angle(theta + float(self._rng.normal(0.0, self.noise_std)))


class Accelerometer:
    """Planar accelerometer: true body-frame acceleration (a_x, a_y) [m/s²] → + bias + white noise.

    The caller gives the sensor's acceleration in the body frame (see :func:`specific_force_body`).
    The bias (one value per axis) is drawn at reset from N(0, bias_std²).
    """

    def __init__(self, rng: np.random.Generator, noise_std: float = 0.05, bias_std: float = 0.0) -> None:
        self.noise_std = nonnegative("noise_std", noise_std)
        self.bias_std = nonnegative("bias_std", bias_std)
        self.bias = np.zeros(2)
        self.reset(rng)

    def reset(self, rng: np.random.Generator) -> None:
        """Take ``rng`` as the noise source and draw a new bias [m/s²], shape (2,)."""
        self._rng = _check_rng(rng)
        self.bias = self._rng.normal(0.0, self.bias_std, size=2)

    def measure(self, acc_body: np.ndarray) -> np.ndarray:
        """One reading [m/s²], body frame, shape (2,)."""
        acc = finite_array("acc_body", acc_body, (2,))
        return acc + self.bias + self._rng.normal(0.0, self.noise_std, size=2)


class CameraTracker:
    """External camera/tracker: true world pose (x, y, θ) → noisy pose fix at ``rate_hz``.

    Fixes are due at t0, t0 + 1/rate, t0 + 2/rate, ... [s]. ``measure(t, pose)`` returns a fix when
    t ≥ next_due (with a 1e-9-period tolerance for floating-point time steps) and None otherwise.
    After a fix, next_due becomes the first due time after t, so a caller stepping more coarsely
    than 1/rate gets at most one fix per call (missed fixes are dropped, not queued). No latency.
    """

    _TOLERANCE = 1e-9  # in periods: absorbs rounding of accumulated simulation time

    def __init__(self, rng: np.random.Generator, rate_hz: float = 10.0, position_std: float = 0.005,
                 heading_std: float = 0.02, t0: float = 0.0) -> None:
        self.rate_hz = positive("rate_hz", rate_hz)
        self.position_std = nonnegative("position_std", position_std)
        self.heading_std = nonnegative("heading_std", heading_std)
        self.reset(rng, t0)

    @property
    def period(self) -> float:
        """Time between fixes [s]."""
        return 1.0 / self.rate_hz

    @property
    def next_due(self) -> float:
        """Time [s] of the next fix."""
        return self._t0 + self._k * self.period

    def reset(self, rng: np.random.Generator, t0: float = 0.0) -> None:
        """Take ``rng`` as the noise source; the first fix is due at ``t0`` [s]."""
        self._rng = _check_rng(rng)
        self._t0 = finite_scalar("t0", t0)
        self._k = 0

    def measure(self, t: float, pose: np.ndarray) -> np.ndarray | None:
        """A noisy fix (x, y, θ) [m, m, rad] (θ wrapped to (−π, π]) if one is due at ``t`` [s], else None."""
        now = finite_scalar("t", t)
        true_pose = finite_array("pose", pose, (3,))
        elapsed = (now - self._t0) / self.period
        if elapsed < self._k - self._TOLERANCE:
            return None
        self._k = math.floor(elapsed + self._TOLERANCE) + 1
        noise = self._rng.normal(0.0, [self.position_std, self.position_std, self.heading_std])
        fix = true_pose + noise
        fix[2] = wrap_angle(fix[2])
        return fix


# --- suite ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SensorReadings:
    """One time step of readings.

    Attributes:
        t: time [s].
        wheel_angles: quantised encoder angles [rad], shape (n_wheels,).
        gyro: yaw rate [rad/s].
        compass: heading [rad], in (−π, π].
        accel: body-frame acceleration (a_x, a_y) [m/s²], shape (2,).
        camera: world pose fix (x, y, θ) [m, m, rad], or None when no fix was due.
    """

    t: float
    wheel_angles: np.ndarray
    gyro: float
    compass: float
    accel: np.ndarray
    camera: np.ndarray | None


class SensorSuite:
    """All sensors of one robot, built from a :class:`SensorConfig` and reset from one generator.

    ``reset(rng)`` derives independent child generators (gyro, compass, accelerometer, camera, in
    that order) from ``rng``, so the readings depend only on the seed and the true states.
    """

    def __init__(self, n_wheels: int, rng: np.random.Generator, config: SensorConfig | None = None,
                 t0: float = 0.0) -> None:
        self.config = SensorConfig() if config is None else config
        if not isinstance(self.config, SensorConfig):
            raise ValueError(f"config must be a SensorConfig, got {config!r}")
        c = self.config
        gyro_rng, compass_rng, accel_rng, camera_rng = _child_rngs(rng, 4)
        self.encoders = WheelEncoders(n_wheels, c.counts_per_rev)
        self.gyro = Gyroscope(gyro_rng, c.gyro_noise_std, c.gyro_bias_std, c.gyro_bias_walk_std)
        self.compass = Compass(compass_rng, c.compass_noise_std)
        self.accelerometer = Accelerometer(accel_rng, c.accel_noise_std, c.accel_bias_std)
        self.camera = CameraTracker(camera_rng, c.camera_rate_hz, c.camera_position_std,
                                    c.camera_heading_std, t0)

    def reset(self, rng: np.random.Generator, t0: float = 0.0) -> None:
        """New noise streams and biases from ``rng``; the first camera fix is due at ``t0`` [s]."""
        gyro_rng, compass_rng, accel_rng, camera_rng = _child_rngs(rng, 4)
        self.gyro.reset(gyro_rng)
        self.compass.reset(compass_rng)
        self.accelerometer.reset(accel_rng)
        self.camera.reset(camera_rng, t0)

    def measure(self, t: float, dt: float, wheel_angles: np.ndarray, pose: np.ndarray, yaw_rate: float,
                acc_body: np.ndarray) -> SensorReadings:
        """Read every sensor at time ``t`` [s], ``dt`` [s] after the previous call.

        Args:
            wheel_angles: true wheel angles [rad], shape (n_wheels,).
            pose: true world pose (x, y, θ) [m, m, rad]; θ also feeds the compass.
            yaw_rate: true yaw rate θ̇ [rad/s].
            acc_body: true body-frame acceleration (a_x, a_y) [m/s²] at the accelerometer.
        """
        true_pose = finite_array("pose", pose, (3,))
        return SensorReadings(
            t=finite_scalar("t", t),
            wheel_angles=self.encoders.measure(wheel_angles),
            gyro=self.gyro.measure(yaw_rate, dt),
            compass=self.compass.measure(true_pose[2]),
            accel=self.accelerometer.measure(acc_body),
            camera=self.camera.measure(t, true_pose),
        )
