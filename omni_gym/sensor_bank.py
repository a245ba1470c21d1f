"""The sensors of B robots, measured together: the batched counterpart of :class:`omni_gym.sensors.SensorSuite`.

Same sensors, same noise distributions and the same camera schedule as the single-robot classes of
:mod:`omni_gym.sensors` (see :class:`~omni_gym.sensors.SensorConfig` for every level): encoders quantised
to whole counts, a gyro with a reset bias and a random-walk bias, a compass wrapped to (−π, π], a
planar accelerometer with a reset bias, a camera fix due every 1/rate s from the robot's reset. One
compiled call measures every robot.

Random draws: robot j owns one generator (handed to :meth:`SensorBank.reset`). At reset it draws the
biases (gyro, then accelerometer x, y), then a block of standard normals for the next
:data:`BLOCK_STEPS` samples, :data:`NOISE_SLOTS` per sample, in the order of :data:`SLOT_NAMES`; a block
is refilled from the same generator when used up. Every sample uses its slots whether or not a camera
fix is due, so robot j's readings depend only on its generator and its own true states, never on how
many robots share the bank or on when the others reset. A Gaussian draw N(0, σ²) is σ·z with z a
standard normal, as ``Generator.normal`` computes it.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from omni_gym.angles import wrap_angle_nb as _wrap  # (−π, π], compiled
from omni_gym.checks import nonnegative
from omni_gym.sensors import SensorConfig

SLOT_NAMES = ("gyro_bias_walk", "gyro", "compass", "accel_x", "accel_y", "camera_x", "camera_y", "camera_heading")
NOISE_SLOTS = len(SLOT_NAMES)  # standard normals per robot and sample
BLOCK_STEPS = 32  # samples per pre-drawn block: one generator call per robot every 32 samples
# Columns of SensorBank.std (per robot, after noise scaling).
STD_GYRO, STD_GYRO_WALK, STD_COMPASS, STD_ACCEL, STD_CAM_POS, STD_CAM_HEAD = range(6)
CAMERA_TOLERANCE = 1e-9  # in camera periods, as omni_gym.sensors.CameraTracker: absorbs rounding of step times


@numba.njit(cache=True)
def measure_all(robots, t, dt, wheel_angles, pose, yaw_rate, acc_body, std, quantum, period, noise, cursor,
                gyro_bias, accel_bias, camera_k, out_enc, out_gyro, out_compass, out_accel, out_fix, out_has_fix):
    """One sample of every sensor of the robots with indices ``robots`` (see the module docstring for the draws).

    t (B,) [s] each robot's time since its reset; dt [s] since the previous sample (bias walk);
    wheel_angles (B, n) [rad]; pose (B, 3) world x, y [m], θ [rad]; yaw_rate (B,) [rad/s]; acc_body
    (B, 2) [m/s²] body frame. std (B, 6) columns STD_*; quantum (B,) encoder count [rad]; period (B,)
    camera period [s]. State updated: cursor (B,) next unused slot of noise (B, L), gyro_bias (B,),
    camera_k (B,) index of the next due fix. Outputs: encoder angles [rad], gyro [rad/s], compass
    [rad], accelerometer [m/s²], camera fix (x, y, θ) and whether a fix was due this sample.
    """
    root_dt = math.sqrt(dt)
    for b in robots:
        q = quantum[b]
        for i in range(wheel_angles.shape[1]):
            out_enc[b, i] = math.floor(wheel_angles[b, i] / q) * q
        z = noise[b, cursor[b]:cursor[b] + NOISE_SLOTS]
        cursor[b] += NOISE_SLOTS
        gyro_bias[b] += (std[b, STD_GYRO_WALK] * root_dt) * z[0]
        out_gyro[b] = yaw_rate[b] + gyro_bias[b] + std[b, STD_GYRO] * z[1]
        out_compass[b] = _wrap(pose[b, 2] + std[b, STD_COMPASS] * z[2])
        out_accel[b, 0] = acc_body[b, 0] + accel_bias[b, 0] + std[b, STD_ACCEL] * z[3]
        out_accel[b, 1] = acc_body[b, 1] + accel_bias[b, 1] + std[b, STD_ACCEL] * z[4]
        elapsed = t[b] / period[b]
        if elapsed < camera_k[b] - CAMERA_TOLERANCE:
            out_has_fix[b] = False
            continue
        camera_k[b] = math.floor(elapsed + CAMERA_TOLERANCE) + 1
        out_has_fix[b] = True
        out_fix[b, 0] = pose[b, 0] + std[b, STD_CAM_POS] * z[5]
        out_fix[b, 1] = pose[b, 1] + std[b, STD_CAM_POS] * z[6]
        out_fix[b, 2] = _wrap(pose[b, 2] + std[b, STD_CAM_HEAD] * z[7])


class SensorBank:
    """Sensors of ``n_robots`` robots with ``n_wheels`` wheels; robot j is set up by :meth:`reset`.

    After :meth:`measure` the readings are in ``wheel_angles`` (B, n) [rad], ``gyro`` (B,) [rad/s],
    ``compass`` (B,) [rad], ``accel`` (B, 2) [m/s², body frame], ``fix`` (B, 3) [m, m, rad, world
    frame] and ``has_fix`` (B,) (``fix`` holds a fresh value only where ``has_fix``).
    """

    def __init__(self, n_robots: int, n_wheels: int) -> None:
        B = self.n_robots = int(n_robots)
        self.n_wheels = int(n_wheels)
        self.std = np.zeros((B, 6))
        self.quantum = np.ones(B)
        self.period = np.ones(B)
        self.noise = np.zeros((B, BLOCK_STEPS * NOISE_SLOTS))
        self.cursor = np.full(B, BLOCK_STEPS * NOISE_SLOTS, dtype=np.int64)
        self.gyro_bias = np.zeros(B)
        self.accel_bias = np.zeros((B, 2))
        self.camera_k = np.zeros(B, dtype=np.int64)
        self.rngs: list[np.random.Generator | None] = [None] * B
        self.wheel_angles = np.zeros((B, self.n_wheels))
        self.gyro = np.zeros(B)
        self.compass = np.zeros(B)
        self.accel = np.zeros((B, 2))
        self.fix = np.zeros((B, 3))
        self.has_fix = np.zeros(B, dtype=bool)
        self._all = np.arange(B)

    def reset(self, j: int, rng: np.random.Generator, config: SensorConfig, noise_scale: float = 1.0) -> None:
        """New sensors for robot j from ``config`` with every noise std × ``noise_scale`` (≥ 0); every
        draw of robot j from now on comes from ``rng``. The first camera fix is due at t = 0."""
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator, got {rng!r}")
        s = nonnegative("noise_scale", noise_scale)
        c = config
        self.std[j] = (c.gyro_noise_std * s, c.gyro_bias_walk_std * s, c.compass_noise_std * s,
                       c.accel_noise_std * s, c.camera_position_std * s, c.camera_heading_std * s)
        self.quantum[j] = 2.0 * math.pi / c.counts_per_rev
        self.period[j] = 1.0 / c.camera_rate_hz
        bias = rng.standard_normal(3)
        self.gyro_bias[j] = (c.gyro_bias_std * s) * bias[0]
        self.accel_bias[j] = (c.accel_bias_std * s) * bias[1:3]
        self.camera_k[j] = 0
        self.rngs[j] = rng
        self._refill(j)

    def _refill(self, j: int) -> None:
        self.rngs[j].standard_normal(out=self.noise[j])
        self.cursor[j] = 0

    def measure(self, t: np.ndarray, dt: float, wheel_angles: np.ndarray, pose: np.ndarray, yaw_rate: np.ndarray,
                acc_body: np.ndarray, robots: np.ndarray | None = None) -> None:
        """Sample the sensors of ``robots`` (indices; default all), each of which must have been :meth:`reset`.

        Arrays are over all B robots as in :func:`measure_all`; only the rows of ``robots`` are read and
        written. Non-finite true states give non-finite readings (not checked here).
        """
        idx = self._all if robots is None else np.asarray(robots, dtype=np.int64)
        for j in idx[self.cursor[idx] >= self.noise.shape[1]]:  # blocks used up: every BLOCK_STEPS samples
            self._refill(int(j))
        measure_all(idx, t, dt, wheel_angles, pose, yaw_rate, acc_body, self.std, self.quantum, self.period, self.noise,
                    self.cursor, self.gyro_bias, self.accel_bias, self.camera_k, self.wheel_angles, self.gyro,
                    self.compass, self.accel, self.fix, self.has_fix)
