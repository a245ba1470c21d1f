"""Extended Kalman filter over the planar pose, body twist and gyro bias of an omnidirectional robot.

State x (7,) = [x, y, θ, vx, vy, ω, b_g]: world position [m] of the geometric centre and heading θ
[rad], body-frame velocity (vx, vy) [m/s] of the geometric centre and yaw rate ω [rad/s] (the body
twist of ``docs/conventions.md``), and the gyro bias b_g [rad/s]. The state heading is kept wrapped to
(−π, π] (the compass's range) after every predict and update; every heading innovation is wrapped too,
so a reading of +π − ε against an estimate of −π + ε is an innovation of −2ε, not 2π − 2ε. Callers
that need a continuous heading unwrap ``pose[2]`` themselves.

Process model: constant velocity, the body twist a random walk with acceleration spectral densities
``accel_psd`` [(m/s²)²·s] per body axis and ``yaw_accel_psd`` [(rad/s²)²·s], discretised at the control
rate as a zero-order hold: at the start of each period the twist jumps by w ~ N(0, diag(q_v, q_v,
q_ω)·Δt) and is then held, and the pose moves along the exact arc of that twist,
Δp = R(θ + ωΔt/2)·v·Δt·sinc(ωΔt/2), Δθ = ωΔt. The environments are built this way (wheel-speed
commands held over the control period; on a gripping floor the body follows within milliseconds), so
the heading change over a period is exactly ω·Δt with the ω the gyro reads at its end. (A
continuous-time white-acceleration discretisation adds heading noise the gyro cannot see; the
accelerometer update then turns its bias into heading drift, ≈0.02 rad in 3 s in our runs.) The gyro
bias is a random walk, ``gyro_bias_walk_std``² [rad²/s³]. Q = G·diag(q_v, q_v, q_ω)·Δt·Gᵀ + q_b·Δt with
G = ∂f/∂(vx, vy, ω).

Measurements, all of the state at the end of control period k:

* wheel encoders: z_i = (W·[vx, vy, ω])_i for the wheels in ``wheel_ok``. The environments report the
  change of the quantised wheel angle over the period divided by Δt, the *mean* wheel speed over the
  period; under the zero-order-hold model the twist is constant over the period, so the mean and the
  end-of-period twist coincide (we use the state at the end). A body still accelerating after a
  command step (a few milliseconds on 'grip', longer on carpet while the wheels slip) makes the
  mean lag; the wheel slip it implies is what the detector looks for. Noise: the quantisation error
  of a difference of two quantised angles, std q/(Δt·√6), q = 2π/counts_per_rev (0.125 rad/s at 2048
  counts/rev and 100 Hz), treated as white (it is in fact negatively correlated from period to period,
  lag-1 correlation −1/2, which makes the wheel NIS somewhat larger than nominal in the environments).
* gyro: z = ω + b_g, std ``gyro_noise_std``.
* compass: z = θ, std ``compass_noise_std``.
* camera: z = (x, y, θ) when ``fix_age`` == 0 (a fix taken this period), std ``camera_*_std``.
* accelerometer, as a weak update: the environments' accelerometer reads the change of the geometric
  centre's world velocity over the period, in the body frame,
  a = R(θ_k)ᵀ·(R(θ_k)·v_k − R(θ_{k−1})·v_{k−1})/Δt = (v_k − R(θ_{k−1} − θ_k)·v_{k−1})/Δt.
  It involves the previous state, so :meth:`process` clones (θ, vx, vy) before predicting (stochastic
  cloning), updates the 10-state augmented system and drops the clone. The accelerometer bias (0.02
  m/s² per axis, constant over an episode) is not a state (the state is fixed at seven); the update
  uses an inflated noise ``accel_noise_std`` = 2·√(noise² + bias²) = 0.108 m/s². Measured trade-off (1× is
  the bias treated as white noise): Monte Carlo with a biased accelerometer and quantised encoders,
  average NEES 7.7 (1×) and 5.3 (2×) for 7 states; 'grip' environment runs, NEES 6.4 / 3.9 under
  smooth commands and 11.0 / 8.4 under step commands; on the default carpet environment the
  detector flags 6.5 % / 1.4 % of the wheel-periods that do not slip. Its purpose is
  the slip detector: it tells a genuine change of the body's motion (all wheels agree with the
  accelerometer) from slip or lift-off (the wheels disagree with it), and it tells which of two
  opposite wheels of a four-wheel robot slips (the wheels alone cannot). Readings at the observation
  clip (|a| ≥ ``accel_limit``) are skipped.

Every update uses the Joseph form P = (I − KH)P(I − KH)ᵀ + KRKᵀ and a χ² gate on its normalised
innovation squared NIS = νᵀS⁻¹ν at probability ``gate_probability`` = 0.9999: a correct measurement is
rejected once in ten thousand (thresholds 15.14, 18.42, 21.11 for one, two, three degrees of
freedom). Wheels are gated one by one on their own NIS ν_i²/S_ii. Why not 0.999: the gates reject a
correct measurement exactly when the prior is far off (a manoeuvre the random walk finds unlikely),
which leaves that error to the next sensor; at 0.999 this raised the average wheel NIS by 2–3 % in the
Monte Carlo, outside its 95 % band, at 0.9999 by 0.1 %. After ``reacquire_after`` consecutive
rejections of the gyro, compass or camera the filter takes itself, not the sensor, to be wrong: it adds
ν² to the variance of the measured fast state (ω for the gyro, θ for the compass, the pose for the
camera, plus (R(θ)ᵀ·ν_xy / time since the last fix)² on the body velocity) and applies the reading.

Order inside :meth:`process` (one control period): clone and predict; accelerometer; gyro; slip
detector (:mod:`agents.slip_detector`) on the wheel innovations against this prior; wheels in use;
compass; camera.
"""

from __future__ import annotations

import inspect
import math
import warnings
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import chi2

# The state layout and the motion model f, F: one compiled kernel shared with the batched filter.
from agents.motion import BG, NX, OM, TH, VX, VY, X, Y, motion_model  # noqa: F401  (re-exported)
from agents.slip_detector import DetectorConfig, SlipDetector
from omni_gym.angles import wrap_angle
from omni_gym.physics.kinematics import WheelKinematics
from omni_gym.physics.robot import RobotSpec
from omni_gym.sensors import SensorConfig

_CLONE = [TH, VX, VY]  # states cloned for the accelerometer update
TWO_PI = 2.0 * math.pi

# Noise floors used when the environment's sensor noise is scaled to zero (sensor_noise=0): the
# observation is float32 and a zero measurement variance would make S singular.
GYRO_FLOOR = 1e-4  # rad/s
COMPASS_FLOOR = 1e-3  # rad
CAMERA_POSITION_FLOOR = 1e-4  # m
CAMERA_HEADING_FLOOR = 1e-3  # rad
ACCEL_FLOOR = 0.02  # m/s²
BIAS_FLOOR = 1e-4  # rad/s, initial gyro-bias std
BIAS_WALK_FLOOR = 1e-6  # rad/s/√s
ACCEL_INFLATION = 2.0  # accel_noise_std = ACCEL_INFLATION·√(noise² + bias²): a weak update (module docstring)
# EKFConfig's noise levels carry omni_gym.sensors.SensorConfig's names; the old names still work for a
# while (a DeprecationWarning), as keywords and as attributes.
RENAMED_NOISE = {"gyro_std": "gyro_noise_std", "gyro_bias_walk": "gyro_bias_walk_std",
                 "compass_std": "compass_noise_std", "accel_std": "accel_noise_std"}
_SENSORS = SensorConfig()  # the defaults of EKFConfig's noise levels
OBS_ACCEL_LIMIT = 49.9  # m/s²: the sensors observation clips the accelerometer at ±10 × 5 m/s²


def encoder_rate_std(counts_per_rev: int, dt: float) -> float:
    """Std [rad/s] of (⌊θ_k/q⌋ − ⌊θ_{k−1}/q⌋)·q/Δt − (θ_k − θ_{k−1})/Δt for uniform errors: q/(Δt·√6)."""
    return (TWO_PI / counts_per_rev) / (dt * math.sqrt(6.0))


def process_noise(x: np.ndarray, dt: float, accel_psd: float, yaw_accel_psd: float, bias_psd: float,
                  F: np.ndarray | None = None) -> np.ndarray:
    """Q (7×7) of one period: the twist jumps by w ~ N(0, diag(q_v, q_v, q_ω)·Δt) at the period start.

    The pose then integrates the new twist over the period, so Q = G·diag(q_v, q_v, q_ω)·Δt·Gᵀ with
    G = ∂f/∂(vx, vy, ω) (the twist columns of F; pass ``F`` from :func:`motion_model` to reuse it),
    plus q_b·Δt on the gyro bias.
    """
    if F is None:
        _, F = motion_model(x, dt)
    G = F[:, VX:OM + 1]
    Q = (G * np.array([accel_psd, accel_psd, yaw_accel_psd]) * dt) @ G.T
    Q = 0.5 * (Q + Q.T)
    Q[BG, BG] += bias_psd * dt
    return Q


def accel_model(x: np.ndarray, clone: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Accelerometer h = (v − R(θc − θ)·v_c)/Δt and its Jacobians w.r.t. x (2×7) and clone (θc, vxc, vyc) (2×3)."""
    d = clone[0] - x[TH]
    c, sn = math.cos(d), math.sin(d)
    vc = clone[1:3]
    rv = np.array([c * vc[0] - sn * vc[1], sn * vc[0] + c * vc[1]])  # R(d)·v_c
    drv = np.array([-sn * vc[0] - c * vc[1], c * vc[0] - sn * vc[1]])  # R'(d)·v_c
    h = (x[VX:VY + 1] - rv) / dt
    Hx = np.zeros((2, NX))
    Hx[0, VX] = Hx[1, VY] = 1.0 / dt
    Hx[:, TH] = drv / dt  # ∂/∂θ of −R(θc − θ)v_c = +R'(d)v_c
    Hc = np.zeros((2, 3))
    Hc[:, 0] = -drv / dt
    Hc[:, 1:3] = -np.array([[c, -sn], [sn, c]]) / dt
    return h, Hx, Hc


@dataclass(frozen=True)
class EKFConfig:
    """Noise levels (standard deviations), process noise, gates and switches of :class:`OmniEKF`.

    The defaults match ``omni_gym.sensors.SensorConfig()`` at 100 Hz (what :meth:`for_env` returns for
    a default environment).

    Attributes:
        wheel_rate_std: encoder-rate noise [rad/s]; quantisation q/(Δt·√6), 0.125 at 2048 counts, 100 Hz.
        gyro_noise_std: gyro white noise [rad/s].
        gyro_bias_std: initial gyro-bias std [rad/s] (the sensor's turn-on bias spread).
        gyro_bias_walk_std: gyro-bias random walk [rad/s/√s].
        compass_noise_std: compass noise [rad].
        accel_noise_std: accelerometer noise assumed by the weak update [m/s²] (inflated, module docstring).
        camera_position_std, camera_heading_std: camera fix noise [m], [rad].
        accel_psd: spectral density of the body accelerations [(m/s²)²·s]: 1.0 → velocity jumps of
            std 0.1 m/s per 10 ms period, room for a controller's step commands (the accelerometer and
            the wheels measure the velocity every period, so a generous value costs little).
        yaw_accel_psd: spectral density of the yaw acceleration [(rad/s²)²·s]: 100 → yaw-rate jumps of
            std 1 rad/s per period (the twist action spans ±3 rad/s; the gyro measures ω every period).
        rest_speed_std: velocity std [m/s, rad/s] after :meth:`OmniEKF.reset` (robot at rest).
        gate_probability: χ² gate probability of every update (0.9999, module docstring; 1: no gate).
        reacquire_after: consecutive rejections of gyro, compass or camera before re-acquisition.
        accel_limit: |reading| [m/s²] at or above which the accelerometer is treated as clipped.
        use_accel, use_compass, use_camera, use_detector: switch parts of :meth:`OmniEKF.process` off.
        detector: slip-detector parameters.
    """

    # The sensors' default noise levels (their one home: omni_gym.sensors.SensorConfig) at 100 Hz.
    wheel_rate_std: float = encoder_rate_std(_SENSORS.counts_per_rev, 0.01)
    gyro_noise_std: float = _SENSORS.gyro_noise_std
    gyro_bias_std: float = _SENSORS.gyro_bias_std
    gyro_bias_walk_std: float = _SENSORS.gyro_bias_walk_std
    compass_noise_std: float = _SENSORS.compass_noise_std
    accel_noise_std: float = ACCEL_INFLATION * math.hypot(_SENSORS.accel_noise_std, _SENSORS.accel_bias_std)
    camera_position_std: float = _SENSORS.camera_position_std
    camera_heading_std: float = _SENSORS.camera_heading_std
    accel_psd: float = 1.0
    yaw_accel_psd: float = 100.0
    rest_speed_std: float = 1e-3
    gate_probability: float = 0.9999
    reacquire_after: int = 3
    accel_limit: float = OBS_ACCEL_LIMIT
    use_accel: bool = True
    use_compass: bool = True
    use_camera: bool = True
    use_detector: bool = True
    detector: DetectorConfig = DetectorConfig()

    def __post_init__(self) -> None:
        for name in ("wheel_rate_std", "gyro_noise_std", "gyro_bias_std", "compass_noise_std", "accel_noise_std",
                     "camera_position_std", "camera_heading_std", "rest_speed_std", "accel_limit"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        for name in ("gyro_bias_walk_std", "accel_psd", "yaw_accel_psd"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if not 0.0 < self.gate_probability <= 1.0:
            raise ValueError(f"gate_probability must be in (0, 1] (1: no gate), got {self.gate_probability!r}")
        if int(self.reacquire_after) != self.reacquire_after or self.reacquire_after < 1:
            raise ValueError(f"reacquire_after must be an integer >= 1, got {self.reacquire_after!r}")

    def gate(self, dof: int) -> float:
        """χ² gate threshold on the NIS for ``dof`` degrees of freedom (inf when gate_probability = 1)."""
        return math.inf if self.gate_probability >= 1.0 else float(chi2.ppf(self.gate_probability, dof))

    @classmethod
    def from_sensor_config(cls, sensor_config, control_hz: float, **overrides) -> EKFConfig:
        """Noise levels from an ``omni_gym.sensors.SensorConfig`` sampled at ``control_hz`` [Hz]."""
        sc = sensor_config
        dt = 1.0 / control_hz
        values = dict(
            wheel_rate_std=encoder_rate_std(sc.counts_per_rev, dt),
            gyro_noise_std=max(sc.gyro_noise_std, GYRO_FLOOR),
            gyro_bias_std=max(sc.gyro_bias_std, BIAS_FLOOR),
            gyro_bias_walk_std=max(sc.gyro_bias_walk_std, BIAS_WALK_FLOOR),
            compass_noise_std=max(sc.compass_noise_std, COMPASS_FLOOR),
            accel_noise_std=max(ACCEL_INFLATION * math.hypot(sc.accel_noise_std, sc.accel_bias_std), ACCEL_FLOOR),
            camera_position_std=max(sc.camera_position_std, CAMERA_POSITION_FLOOR),
            camera_heading_std=max(sc.camera_heading_std, CAMERA_HEADING_FLOOR),
        )
        return cls(**{**values, **_new_names(overrides, 3)})

    @classmethod
    def for_env(cls, env, **overrides) -> EKFConfig:
        """Config for a (possibly wrapped) omni-gym environment: reads ``env.unwrapped.cfg``."""
        cfg = env.unwrapped.cfg
        return cls.from_sensor_config(cfg.sensor_config(), cfg.control_hz, **overrides)

    def with_changes(self, **changes) -> EKFConfig:
        return replace(self, **_new_names(changes, 3))

    # The old names of the renamed noise levels, readable for a while (RENAMED_NOISE).
    gyro_std = property(lambda self: _old_name(self, "gyro_std"))
    gyro_bias_walk = property(lambda self: _old_name(self, "gyro_bias_walk"))
    compass_std = property(lambda self: _old_name(self, "compass_std"))
    accel_std = property(lambda self: _old_name(self, "accel_std"))


def _new_names(values: dict, stacklevel: int) -> dict:
    """``values`` with the old noise names (:data:`RENAMED_NOISE`) replaced by the new ones, warning once each."""
    out = dict(values)
    for old, new in RENAMED_NOISE.items():
        if old in out:
            if new in out:
                raise TypeError(f"EKFConfig: give {new} only ({old} is its old name)")
            warnings.warn(f"EKFConfig's {old} is now called {new}", DeprecationWarning, stacklevel=stacklevel)
            out[new] = out.pop(old)
    return out


def _old_name(config: EKFConfig, old: str) -> float:
    warnings.warn(f"EKFConfig's {old} is now called {RENAMED_NOISE[old]}", DeprecationWarning, stacklevel=3)
    return getattr(config, RENAMED_NOISE[old])


_dataclass_init = EKFConfig.__init__


def _init_with_old_names(self, *args, **kwargs) -> None:
    _dataclass_init(self, *args, **_new_names(kwargs, 3))


_init_with_old_names.__doc__ = _dataclass_init.__doc__
_init_with_old_names.__signature__ = inspect.signature(_dataclass_init)  # help() shows the fields
EKFConfig.__init__ = _init_with_old_names


def _joseph(x: np.ndarray, P: np.ndarray, nu: np.ndarray, H: np.ndarray, R: np.ndarray,
            S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kalman update with the Joseph-form covariance (I − KH)P(I − KH)ᵀ + KRKᵀ; heading (index 2) wrapped."""
    PHt = P @ H.T
    K = PHt / S[0, 0] if S.shape == (1, 1) else PHt @ np.linalg.inv(S)
    x = x + K @ nu
    x[TH] = wrap_angle(x[TH])
    A = -K @ H
    A.flat[:: len(x) + 1] += 1.0
    P = A @ P @ A.T + K @ R @ K.T
    return x, 0.5 * (P + P.T)


def _nis(nu: np.ndarray, S: np.ndarray) -> float:
    """νᵀS⁻¹ν."""
    if S.shape == (1, 1):
        return float(nu[0] * nu[0] / S[0, 0])
    return float(nu @ np.linalg.solve(S, nu))


class OmniEKF:
    """EKF over pose, body twist and gyro bias with slip/lift-off-aware wheel odometry.

    See the module docstring for the model. Attributes: ``x`` (7,), ``P`` (7, 7), ``wheel_belief`` (n,)
    in [0, 1], ``wheel_ok`` (n,) bool, ``wheels_used`` (n,) bool (wheels applied in the last wheel
    update), ``last_nis`` (sensor name → NIS of its last update; ``"wheels"`` per wheel,
    ``"wheels_joint"`` the NIS of the whole innovation vector), ``step_nis`` (the same, only for the
    updates of the last :meth:`process` call), ``detector`` (:class:`SlipDetector`).
    """

    def __init__(self, robot: RobotSpec | WheelKinematics, config: EKFConfig | None = None) -> None:
        # robot: its wheel matrix and wheel radius are read (a model's effective kinematics may stand in).
        self.robot = robot
        self.config = EKFConfig() if config is None else config
        self.W = robot.wheel_matrix()
        self.n = self.W.shape[0]
        self.detector = SlipDetector(self.W, robot.wheel_radius, self.config.wheel_rate_std, self.config.detector)
        c = self.config
        self._gates = {"wheels": c.gate(1), "gyro": c.gate(1), "compass": c.gate(1), "camera": c.gate(3),
                       "accel": c.gate(2)}
        self._bias_psd = c.gyro_bias_walk_std**2
        # Constant measurement matrices and noise covariances.
        self._H_wheels = np.zeros((self.n, NX))
        self._H_wheels[:, VX:OM + 1] = self.W
        self._R_wheels = c.wheel_rate_std**2 * np.eye(self.n)
        self._H_gyro = np.zeros((1, NX))
        self._H_gyro[0, OM] = self._H_gyro[0, BG] = 1.0
        self._R_gyro = np.array([[c.gyro_noise_std**2]])
        self._H_compass = np.zeros((1, NX))
        self._H_compass[0, TH] = 1.0
        self._R_compass = np.array([[c.compass_noise_std**2]])
        self._H_camera = np.zeros((3, NX))
        self._H_camera[0, X] = self._H_camera[1, Y] = self._H_camera[2, TH] = 1.0
        self._R_camera = np.diag([c.camera_position_std**2, c.camera_position_std**2, c.camera_heading_std**2])
        self._R_accel = c.accel_noise_std**2 * np.eye(2)
        self.reset(np.zeros(3))

    # --- state ---------------------------------------------------------------------------------

    def reset(self, pose: np.ndarray, pose_std=(0.01, 0.01, 0.02)) -> None:
        """Robot at rest at ``pose`` (x, y, θ) with the given std [m, m, rad]; bias 0 ± gyro_bias_std."""
        pose = np.asarray(pose, dtype=float)
        std = np.asarray(pose_std, dtype=float)
        if pose.shape != (3,) or std.shape != (3,) or not (np.all(np.isfinite(pose)) and np.all(std > 0)):
            raise ValueError(f"pose and pose_std must be 3 finite numbers (std > 0), got {pose!r}, {pose_std!r}")
        c = self.config
        self.x = np.zeros(NX)
        self.x[0:3] = pose
        self.x[TH] = wrap_angle(pose[2])
        v = c.rest_speed_std**2
        self.P = np.diag([std[0] ** 2, std[1] ** 2, std[2] ** 2, v, v, v, c.gyro_bias_std**2])
        self.detector.reset()
        self.wheel_ok = np.ones(self.n, dtype=bool)
        self.wheel_belief = np.zeros(self.n)
        self.wheels_used = np.ones(self.n, dtype=bool)
        self.last_nis: dict = {}
        self.step_nis: dict = {}
        self._rejections = {"gyro": 0, "compass": 0, "camera": 0}
        self._since_camera = 0.0  # s since the last camera fix applied (for camera re-acquisition)

    @property
    def pose(self) -> np.ndarray:
        """(x, y, θ) [m, m, rad], world frame, θ in (−π, π]."""
        return self.x[0:3].copy()

    @property
    def body_twist(self) -> np.ndarray:
        """(vx, vy, ω) [m/s, m/s, rad/s], body frame."""
        return self.x[VX:OM + 1].copy()

    # --- low-level steps -----------------------------------------------------------------------

    def process_noise(self, dt: float, F: np.ndarray | None = None) -> np.ndarray:
        c = self.config
        return process_noise(self.x, dt, c.accel_psd, c.yaw_accel_psd, self._bias_psd, F)

    def predict(self, dt: float) -> None:
        """Propagate x and P over ``dt`` [s] with the constant-velocity model."""
        x_new, F = motion_model(self.x, dt)
        Q = self.process_noise(dt, F)
        self.x = x_new
        self.P = F @ self.P @ F.T + Q
        self.P = 0.5 * (self.P + self.P.T)
        self._since_camera += dt

    def _record(self, name: str, nis) -> None:
        self.last_nis[name] = nis
        self.step_nis[name] = nis

    def _gated_update(self, name: str, nu: np.ndarray, H: np.ndarray, R: np.ndarray, widen=None) -> tuple[float, bool]:
        """χ²-gated Joseph update of (x, P). After ``reacquire_after`` consecutive rejections ``widen(nu)``
        inflates P (the filter, not the sensor, is taken to be wrong) and the measurement is applied."""
        S = H @ self.P @ H.T + R
        nis = _nis(nu, S)
        self._record(name, nis)
        if nis > self._gates[name]:
            self._rejections[name] += 1
            if widen is None or self._rejections[name] < self.config.reacquire_after:
                return nis, False
            widen(nu)
            S = H @ self.P @ H.T + R
        self._rejections[name] = 0
        self.x, self.P = _joseph(self.x, self.P, nu, H, R, S)
        return nis, True

    def _widen(self, states: list[int]):
        def widen(nu: np.ndarray) -> None:
            self.P[states, states] += nu**2
        return widen

    def _widen_camera(self, nu: np.ndarray) -> None:
        """Pose variance += ν²; body-velocity covariance += δv δvᵀ, δv = R(θ)ᵀ·ν_xy / (time since the last fix used)."""
        self.P[[X, Y, TH], [X, Y, TH]] += nu**2
        c, sn = math.cos(self.x[TH]), math.sin(self.x[TH])
        dv = np.array([c * nu[0] + sn * nu[1], -sn * nu[0] + c * nu[1]]) / max(self._since_camera, 1e-3)
        self.P[VX:VY + 1, VX:VY + 1] += np.outer(dv, dv)

    def measurement_model(self, name: str, x: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurement h(x) and its Jacobian H for ``name`` in wheels, gyro, compass, camera.

        The updates use exactly these (the accelerometer's model is :func:`accel_model`).
        """
        x = self.x if x is None else x
        if name == "wheels":
            return self.W @ x[VX:OM + 1], self._H_wheels
        if name == "gyro":
            return np.array([x[OM] + x[BG]]), self._H_gyro
        if name == "compass":
            return np.array([x[TH]]), self._H_compass
        if name == "camera":
            return np.array([x[X], x[Y], x[TH]]), self._H_camera
        raise ValueError(f"unknown measurement {name!r}; one of wheels, gyro, compass, camera")

    def wheel_innovation(self, rates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ν = z − W·(vx, vy, ω) and S = H P Hᵀ + σ_w² I against the current state."""
        z = np.asarray(rates, dtype=float)
        if z.shape != (self.n,):
            raise ValueError(f"rates must have shape ({self.n},), got {z.shape}")
        h, H = self.measurement_model("wheels")
        return z - h, H @ self.P @ H.T + self._R_wheels

    def update_wheels(self, rates: np.ndarray) -> np.ndarray:
        """Encoder-rate update with the wheels in ``wheel_ok`` whose own NIS passes the gate.

        Returns the per-wheel NIS ν_i²/S_ii (all wheels, used or not); ``wheels_used`` tells which
        were applied (jointly).
        """
        nu, S = self.wheel_innovation(rates)
        nis = nu**2 / np.diag(S)
        self._record("wheels", nis)
        self._record("wheels_joint", _nis(nu, S))
        use = self.wheel_ok & (nis <= self._gates["wheels"])
        self.wheels_used = use
        if use.all():
            self.x, self.P = _joseph(self.x, self.P, nu, self._H_wheels, self._R_wheels, S)
        elif use.any():
            idx = np.ix_(use, use)
            self.x, self.P = _joseph(self.x, self.P, nu[use], self._H_wheels[use], self._R_wheels[idx], S[idx])
        return nis

    def update_gyro(self, z: float) -> tuple[float, bool]:
        """Gyro z = ω + b_g [rad/s]; (NIS, accepted)."""
        h, H = self.measurement_model("gyro")
        nu = np.array([float(z) - h[0]])
        return self._gated_update("gyro", nu, H, self._R_gyro, widen=self._widen([OM]))

    def update_compass(self, z: float) -> tuple[float, bool]:
        """Compass z = θ [rad] (any branch; innovation wrapped to (−π, π]); (NIS, accepted)."""
        h, H = self.measurement_model("compass")
        nu = np.array([wrap_angle(float(z) - h[0])])
        return self._gated_update("compass", nu, H, self._R_compass, widen=self._widen([TH]))

    def update_camera(self, z: np.ndarray) -> tuple[float, bool]:
        """Camera fix z = (x, y, θ) [m, m, rad] (heading innovation wrapped); (NIS, accepted)."""
        z = np.asarray(z, dtype=float)
        if z.shape != (3,):
            raise ValueError(f"camera fix must have shape (3,), got {z.shape}")
        h, H = self.measurement_model("camera")
        nu = np.array([z[0] - h[0], z[1] - h[1], wrap_angle(z[2] - h[2])])
        nis, accepted = self._gated_update("camera", nu, H, self._R_camera, widen=self._widen_camera)
        if accepted:
            self._since_camera = 0.0
        return nis, accepted

    def predict_and_update_accel(self, accel: np.ndarray, dt: float) -> tuple[float, bool]:
        """Predict over ``dt`` with (θ, vx, vy) cloned, apply the accelerometer ``accel`` (2,), drop the clone."""
        a = np.asarray(accel, dtype=float)
        P = self.P
        Pa = np.empty((NX + 3, NX + 3))  # covariance of (x, clone) with clone = (θ, vx, vy) now
        Pa[:NX, :NX] = P
        Pa[:NX, NX:] = P[:, _CLONE]
        Pa[NX:, :NX] = P[_CLONE, :]
        Pa[NX:, NX:] = P[np.ix_(_CLONE, _CLONE)]
        xa = np.concatenate([self.x, self.x[_CLONE]])
        self._since_camera += dt
        xa[:NX], F = motion_model(self.x, dt)
        Q = self.process_noise(dt, F)
        Pa[:NX, :NX] = F @ P @ F.T + Q
        Pa[:NX, NX:] = F @ Pa[:NX, NX:]
        Pa[NX:, :NX] = Pa[:NX, NX:].T
        h, Hx, Hc = accel_model(xa[:NX], xa[NX:], dt)
        H = np.hstack([Hx, Hc])
        nu = a - h
        R = self._R_accel
        S = H @ Pa @ H.T + R
        nis = _nis(nu, S)
        self._record("accel", nis)
        accepted = nis <= self._gates["accel"]
        if accepted:
            xa, Pa = _joseph(xa, Pa, nu, H, R, S)
        self.x, self.P = xa[:NX].copy(), 0.5 * (Pa[:NX, :NX] + Pa[:NX, :NX].T)
        return nis, accepted

    # --- one control period --------------------------------------------------------------------

    def process(self, s, dt: float) -> None:
        """One control period from a decoded ``SensorObs``: predict over ``dt`` [s], then every update."""
        c = self.config
        self.step_nis = {}
        accel = np.asarray(s.accel, dtype=float)
        if c.use_accel and np.all(np.abs(accel) < c.accel_limit):
            self.predict_and_update_accel(accel, dt)
        else:
            self.predict(dt)
        self.update_gyro(s.gyro)
        rates = np.asarray(s.encoder_rates, dtype=float)
        if c.use_detector:
            nu, S = self.wheel_innovation(rates)
            self.wheel_ok = self.detector.step(rates, nu, S, self.x[OM], self.P[OM, OM], dt)
            self.wheel_belief = self.detector.belief.copy()
        self.update_wheels(rates)
        if c.use_compass:
            self.update_compass(s.compass)
        if c.use_camera and s.fix_age == 0.0:
            self.update_camera(s.camera_fix)
