"""The one owner of both observation layouts: sizes, named slices, scales, encoding and decoding.

Two layouts (float32 ``Box(-OBS_CLIP, OBS_CLIP)``; ``docs/environments.md``):

* ``state`` (privileged): tracking error and heading error in the body frame, body velocity, the
  reference velocity in the body frame, the reference at the look-ahead times (body frame), last action.
* ``sensors``: what a real robot has: encoder rates, gyro, compass, accelerometer, the last camera fix
  and its age, the reference (world frame) now and at the look-ahead times, last action.

Everything that writes or reads an observation goes through the names here: the numba kernels
``observe_state`` and ``encode_sensor_obs`` (``omni_gym.envs.core``) take their offsets as an argument,
from :func:`state_offsets` and :func:`sensor_offsets` (not as module globals: numba's on-disk cache
would keep stale values of another module's constants), :func:`encode_sensors` writes one sensors
observation by name (the reference the batched kernel is tested against), and
:class:`StateObsDecoder` / :class:`SensorObsDecoder` read by name.
:meth:`ObservationLayout.table` renders the layout as the Markdown table the environment docstrings
and ``docs/environments.md`` show (``tests/test_env_docs.py`` keeps them equal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np

LOOKAHEAD_SECONDS = (0.25, 0.5, 1.0)  # s ahead of "now" at which the reference is shown
POS_SCALE = 0.25  # m, tracking-error scale in the state observation
LOOK_SCALE = 0.5  # m, look-ahead offset scale in the state observation
ACC_SCALE = 5.0  # m/s², accelerometer scale in the sensors observation
OBS_CLIP = 10.0  # every observation value is clipped to [−OBS_CLIP, OBS_CLIP]

# State layout offsets: state_layout() is built from these; the numba kernel gets them through
# state_offsets(), read back from the layout.
ST_ERR = 0  # tracking error body x, y (2), heading error (1)
ST_BODY_VEL = 3  # body vx, vy, ω
ST_REF_VEL = 6  # reference velocity in the body frame, reference yaw rate
ST_LOOK = 9  # first look-ahead block
ST_LOOK_STRIDE = 3  # per look-ahead time: body-frame offset x, y, heading error


@dataclass(frozen=True)
class ObsField:
    """One named block of an observation: indices ``start:stop`` and what they hold.

    ``quantity`` says what is measured and in which frame, ``scale`` what it is divided by (empty: not
    scaled), ``unit`` the physical unit before scaling, ``range`` the values after scaling and clipping.
    """

    name: str
    start: int
    stop: int
    quantity: str
    unit: str
    scale: str
    range: str

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)


@dataclass(frozen=True)
class ObservationLayout:
    """The fields of one observation mode, in order, covering ``0:size`` without gaps."""

    mode: str
    fields: tuple[ObsField, ...]

    @property
    def size(self) -> int:
        return self.fields[-1].stop

    @cached_property
    def _by_name(self) -> dict[str, ObsField]:
        return {f.name: f for f in self.fields}

    @cached_property
    def _slices(self) -> dict[str, slice]:
        return {f.name: f.slice for f in self.fields}  # looked up every step by the sensors encoder

    @cached_property
    def starts(self) -> dict[str, int]:
        """First index of every field, by name."""
        return {f.name: f.start for f in self.fields}

    def field(self, name: str) -> ObsField:
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"no field {name!r} in the {self.mode} observation; fields: "
                           f"{', '.join(self._by_name)}") from None

    def __getitem__(self, name: str) -> slice:
        """The slice of field ``name`` (e.g. ``obs[layout["gyro"]]``)."""
        try:
            return self._slices[name]
        except KeyError:
            self.field(name)  # raises the KeyError that lists the fields
            raise

    def names(self) -> list[str]:
        return [f.name for f in self.fields]

    def table(self) -> str:
        """The layout as a Markdown table with symbolic index ranges (n wheels, A action values).

        Offsets are linear in n and A, so each bound is rendered from three evaluations of the layout.
        """
        at = {(nw, na): build_layout(self.mode, nw, na) for nw, na in ((3, 3), (4, 3), (3, 4))}
        lines = ["| index | name | quantity | unit | scale | range |", "|---|---|---|---|---|---|"]
        for i, f in enumerate(self.fields):
            first = _symbolic([at[k].fields[i].start for k in at])
            last = _symbolic([at[k].fields[i].stop - 1 for k in at])
            index = first if first == last else f"{first}…{last}"
            lines.append(f"| {index} | `{f.name}` | {f.quantity} | {f.unit} | {f.scale} | {f.range} |")
        return "\n".join(lines)


def _symbolic(values: list[int]) -> str:
    """``a·n + c + b·A`` from the values at (n, A) = (3, 3), (4, 3), (3, 4), written like ``n+3`` or ``17+A``."""
    a = values[1] - values[0]
    b = values[2] - values[0]
    c = values[0] - 3 * a - 3 * b
    text = "" if a == 0 else ("n" if a == 1 else f"{a}n")
    if c or not text:
        text += f"{c:+d}".replace("-", "−") if text else str(c)
    if b:
        text += "+" + ("A" if b == 1 else f"{b}A")
    return text


def state_layout(action_dim: int, n_look: int = len(LOOKAHEAD_SECONDS)) -> ObservationLayout:
    """The privileged ``state`` layout for ``action_dim`` action values and ``n_look`` look-ahead times."""
    speed = "/ v_max, v_max, ω_max"
    fields = [
        ObsField("tracking_error_body", ST_ERR, ST_ERR + 2, "reference − robot position, body frame",
                 "m", f"/ {POS_SCALE:g} m", "±10"),
        ObsField("heading_error", ST_ERR + 2, ST_BODY_VEL, "wrap(θ_ref − θ)", "rad", "/ π", "±1"),
        ObsField("body_velocity", ST_BODY_VEL, ST_REF_VEL, "robot vx, vy (body frame), ω",
                 "m/s, m/s, rad/s", speed, "±10"),
        ObsField("reference_velocity", ST_REF_VEL, ST_LOOK, "reference vx, vy (body frame), ω",
                 "m/s, m/s, rad/s", speed, "±10"),
    ]
    for i in range(n_look):
        start = ST_LOOK + ST_LOOK_STRIDE * i
        ahead = f"+{LOOKAHEAD_SECONDS[i]:g} s" if i < len(LOOKAHEAD_SECONDS) else f"look-ahead {i}"
        fields.append(ObsField(f"lookahead[{i}]", start, start + ST_LOOK_STRIDE,
                               f"reference at {ahead}: offset x, y (body frame), heading error",
                               "m, m, rad", f"/ {LOOK_SCALE:g} m, / π", "±10"))
    base = ST_LOOK + ST_LOOK_STRIDE * n_look
    fields.append(ObsField("last_action", base, base + action_dim, "previous (clipped) action", "", "",
                           "±1"))
    return ObservationLayout("state", tuple(fields))


def state_offsets(layout: ObservationLayout) -> np.ndarray:
    """int64 offsets for the numba kernel ``observe_state``: tracking error, body velocity, reference
    velocity, first look-ahead block, look-ahead stride, last action (from the layout's named slices)."""
    if layout.mode != "state":
        raise ValueError(f"state_offsets needs the state layout, got {layout.mode!r}")
    look0 = layout.field("lookahead[0]")
    return np.array([layout.field("tracking_error_body").start, layout.field("body_velocity").start,
                     layout.field("reference_velocity").start, look0.start, look0.stop - look0.start,
                     layout.field("last_action").start], dtype=np.int64)


def sensor_layout(n_wheels: int, action_dim: int, n_look: int = len(LOOKAHEAD_SECONDS)) -> ObservationLayout:
    """The ``sensors`` layout for ``n_wheels`` wheels, ``action_dim`` action values, ``n_look`` look-ahead times."""
    n = n_wheels
    fields = [
        ObsField("encoder_rates", 0, n, "change of the quantised wheel angles over the control period",
                 "rad/s", "/ w_max", "±10"),
        ObsField("gyro", n, n + 1, "yaw rate (noise, bias, bias walk)", "rad/s", "/ ω_max", "±10"),
        ObsField("compass_sin_cos", n + 1, n + 3, "compass heading (noise) as sin, cos", "", "", "±1"),
        ObsField("accelerometer", n + 3, n + 5, "acceleration, body frame (noise, bias)", "m/s²",
                 f"/ {ACC_SCALE:g} m/s²", "±10"),
        ObsField("camera_fix", n + 5, n + 9, "last camera fix (10 Hz): x, y (world frame), sin θ, cos θ", "m, m, –, –",
                 "/ h (x, y)", "±10"),
        ObsField("fix_age", n + 9, n + 10, "time since that fix, capped at 1 s", "s", "", "[0, 1]"),
        ObsField("reference_now", n + 10, n + 14, "reference now: x, y (world frame), sin θ, cos θ",
                 "m, m, –, –", "/ h (x, y)", "±10"),
        ObsField("reference_velocity", n + 14, n + 17, "reference velocity now: ẋ, ẏ (world frame), θ̇",
                 "m/s, m/s, rad/s", "/ v_max, v_max, ω_max", "±10"),
    ]
    for i in range(n_look):
        start = n + 17 + 4 * i
        ahead = f"+{LOOKAHEAD_SECONDS[i]:g} s" if i < len(LOOKAHEAD_SECONDS) else f"look-ahead {i}"
        fields.append(ObsField(f"reference_lookahead[{i}]", start, start + 4,
                               f"reference at {ahead}: x, y (world frame), sin θ, cos θ", "m, m, –, –",
                               "/ h (x, y)", "±10"))
    base = n + 17 + 4 * n_look
    fields.append(ObsField("last_action", base, base + action_dim, "previous (clipped) action", "", "",
                           "±1"))
    return ObservationLayout("sensors", tuple(fields))


def sensor_offsets(layout: ObservationLayout) -> np.ndarray:
    """int64 offsets for the numba kernel ``encode_sensor_obs`` (``omni_gym.envs.core``): encoder rates,
    gyro, compass, accelerometer, camera fix, fix age, reference now, reference velocity, first
    look-ahead block, look-ahead stride, last action (from the layout's named slices)."""
    if layout.mode != "sensors":
        raise ValueError(f"sensor_offsets needs the sensors layout, got {layout.mode!r}")
    start = layout.starts
    look0 = layout.field("reference_lookahead[0]")
    return np.array([start["encoder_rates"], start["gyro"], start["compass_sin_cos"], start["accelerometer"],
                     start["camera_fix"], start["fix_age"], start["reference_now"], start["reference_velocity"],
                     look0.start, look0.stop - look0.start, start["last_action"]], dtype=np.int64)


def build_layout(obs_mode: str, n_wheels: int, action_dim: int) -> ObservationLayout:
    """The layout of ``obs_mode`` ("state" or "sensors") for a robot with ``n_wheels`` and ``action_dim``."""
    if obs_mode == "state":
        return state_layout(action_dim)
    if obs_mode == "sensors":
        return sensor_layout(n_wheels, action_dim)
    raise ValueError(f"invalid obs_mode={obs_mode!r}; allowed: 'state', 'sensors'")


@dataclass(frozen=True)
class ObsScales:
    """What observations are divided by: wheel speed w_max [rad/s] at wheel action ±1, twist limits
    max_speed [m/s] and max_yaw_rate [rad/s], arena_half_size [m]."""

    wheel_scale: float
    max_speed: float
    max_yaw_rate: float
    arena_half_size: float


# --- sensors: encode --------------------------------------------------------------------------


def encode_sensors(layout: ObservationLayout, scales: ObsScales, out: np.ndarray, *, encoder_rates: np.ndarray,
                   gyro: float, compass: float, accel: np.ndarray, fix: np.ndarray, fix_age: float,
                   ref_now: np.ndarray, ref_velocity: np.ndarray, ref_lookahead: np.ndarray,
                   last_action: np.ndarray) -> None:
    """Write one ``sensors`` observation into ``out`` (float64, ``layout.size``), clipped to ±OBS_CLIP.

    SI units, world frame unless stated: encoder_rates (n,) rad/s; gyro rad/s; compass rad; accel (2,)
    m/s² body frame; fix (3,) camera x, y, θ; fix_age s; ref_now (3,) reference pose now;
    ref_velocity (3,) reference world velocity now; ref_lookahead (K, 3) reference poses ahead.
    """
    h = scales.arena_half_size
    start = layout.starts
    out[layout["encoder_rates"]] = encoder_rates / scales.wheel_scale
    out[start["gyro"]] = gyro / scales.max_yaw_rate
    i = start["compass_sin_cos"]
    out[i] = math.sin(compass)
    out[i + 1] = math.cos(compass)
    out[layout["accelerometer"]] = accel / ACC_SCALE
    _put_pose_sin_cos(out, start["camera_fix"], fix, h)
    out[start["fix_age"]] = fix_age
    _put_pose_sin_cos(out, start["reference_now"], ref_now, h)
    i = start["reference_velocity"]
    out[i] = ref_velocity[0] / scales.max_speed
    out[i + 1] = ref_velocity[1] / scales.max_speed
    out[i + 2] = ref_velocity[2] / scales.max_yaw_rate
    for j, pose in enumerate(ref_lookahead):
        _put_pose_sin_cos(out, start[f"reference_lookahead[{j}]"], pose, h)
    out[layout["last_action"]] = last_action
    np.clip(out, -OBS_CLIP, OBS_CLIP, out=out)


def _put_pose_sin_cos(out: np.ndarray, i: int, pose, h: float) -> None:
    """out[i:i + 4] = x/h, y/h, sin θ, cos θ of a pose (x, y [m], θ [rad]); scalar writes (fast per step)."""
    out[i] = pose[0] / h
    out[i + 1] = pose[1] / h
    out[i + 2] = math.sin(pose[2])
    out[i + 3] = math.cos(pose[2])


def _angle(sin_cos: np.ndarray) -> float:
    return math.atan2(sin_cos[0], sin_cos[1])


# --- decode -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class SensorObs:
    """One decoded ``sensors`` observation (SI units, world frame unless stated)."""

    encoder_rates: np.ndarray  # (n,) rad/s: change of the quantised wheel angles over the control period
    gyro: float  # rad/s, yaw rate (noise and bias)
    compass: float  # rad, heading in (−π, π]
    accel: np.ndarray  # (2,) m/s², body frame
    camera_fix: np.ndarray  # (3,) last camera fix x, y [m], θ [rad]
    fix_age: float  # s since that fix (0: it arrived this step; capped at 1)
    ref_pose: np.ndarray  # (3,) reference x, y, θ now (θ wrapped)
    ref_velocity: np.ndarray  # (3,) reference world velocity ẋ, ẏ, θ̇ now
    lookahead: np.ndarray  # (K, 3) reference x, y, θ at LOOKAHEAD_SECONDS ahead
    last_action: np.ndarray  # previous clipped action


class _ObsDecoder:
    """What both decoders share: the layout of one observation mode, its scales, the number of
    look-ahead points, the shape check and the construction from an environment."""

    mode: ClassVar[str]  # the obs_mode this decoder reads
    lookahead_prefix: ClassVar[str]  # field-name prefix of the look-ahead points in the layout

    def __init__(self, layout: ObservationLayout, scales: ObsScales) -> None:
        if layout.mode != self.mode:
            raise ValueError(f"decoding needs obs_mode={self.mode!r}, got {layout.mode!r}")
        self.layout = layout
        self.scales = scales
        self.dim = layout.size
        self.n_look = sum(f.name.startswith(self.lookahead_prefix) for f in layout.fields)

    def _array(self, obs: np.ndarray) -> np.ndarray:
        """``obs`` as a float array of the layout's size (ValueError otherwise)."""
        o = np.asarray(obs, dtype=float)
        if o.shape != (self.dim,):
            raise ValueError(f"{self.mode} observation must have shape ({self.dim},), got {o.shape}")
        return o

    @classmethod
    def for_env(cls, env):
        """Decoder for a (possibly wrapped) omni-gym environment (its ``observation_layout`` and ``obs_scales``)."""
        u = env.unwrapped
        return cls(u.observation_layout, u.obs_scales)


class SensorObsDecoder(_ObsDecoder):
    """Turns ``sensors`` observations of one layout and set of scales into :class:`SensorObs`."""

    mode = "sensors"
    lookahead_prefix = "reference_lookahead["

    def __call__(self, obs: np.ndarray) -> SensorObs:
        o = self._array(obs)
        L, sc = self.layout, self.scales
        h = sc.arena_half_size
        gyro = o[L["gyro"]][0] * sc.max_yaw_rate
        cam = o[L["camera_fix"]]
        camera = np.array([cam[0] * h, cam[1] * h, _angle(cam[2:4])])
        ref = o[L["reference_now"]]
        ref_pose = np.array([ref[0] * h, ref[1] * h, _angle(ref[2:4])])
        rv = o[L["reference_velocity"]]
        ref_vel = np.array([rv[0] * sc.max_speed, rv[1] * sc.max_speed, rv[2] * sc.max_yaw_rate])
        look = np.array([o[L[f"reference_lookahead[{i}]"]] for i in range(self.n_look)]).reshape(-1, 4)
        lookahead = np.column_stack([look[:, 0] * h, look[:, 1] * h, np.arctan2(look[:, 2], look[:, 3])])
        return SensorObs(o[L["encoder_rates"]] * sc.wheel_scale, float(gyro), _angle(o[L["compass_sin_cos"]]),
                         o[L["accelerometer"]] * ACC_SCALE, camera, float(o[L["fix_age"]][0]), ref_pose, ref_vel,
                         lookahead, o[L["last_action"]])


@dataclass(frozen=True)
class BatchSensorObs:
    """Decoded ``sensors`` observations of N robots: the fields of :class:`SensorObs` with a leading robot axis."""

    encoder_rates: np.ndarray  # (N, n) rad/s
    gyro: np.ndarray  # (N,) rad/s
    compass: np.ndarray  # (N,) rad, in (−π, π]
    accel: np.ndarray  # (N, 2) m/s², body frame
    camera_fix: np.ndarray  # (N, 3) last camera fix x, y [m], θ [rad]
    fix_age: np.ndarray  # (N,) s since that fix
    ref_pose: np.ndarray  # (N, 3) reference x, y, θ now
    ref_velocity: np.ndarray  # (N, 3) reference world velocity ẋ, ẏ, θ̇ now
    lookahead: np.ndarray  # (N, K, 3) reference x, y, θ at LOOKAHEAD_SECONDS ahead
    last_action: np.ndarray  # (N, A) previous clipped action


class BatchSensorObsDecoder(SensorObsDecoder):
    """:class:`SensorObsDecoder` for a batch: (N, D) observations (a vector environment's) → :class:`BatchSensorObs`.

    Row i decodes to what :class:`SensorObsDecoder` gives for row i, with the same arithmetic element by
    element (angles through ``numpy.arctan2`` instead of ``math.atan2``).
    """

    def _batch(self, obs: np.ndarray) -> np.ndarray:
        o = np.asarray(obs, dtype=float)
        if o.ndim != 2 or o.shape[1] != self.dim:
            raise ValueError(f"batched sensors observations must have shape (N, {self.dim}), got {o.shape}")
        return o

    def __call__(self, obs: np.ndarray) -> BatchSensorObs:  # type: ignore[override]
        o = self._batch(obs)
        L, sc = self.layout, self.scales
        h = sc.arena_half_size
        st = L.starts

        def pose(i: int) -> np.ndarray:
            return np.column_stack([o[:, i] * h, o[:, i + 1] * h, np.arctan2(o[:, i + 2], o[:, i + 3])])

        c = st["compass_sin_cos"]
        rv = st["reference_velocity"]
        look = np.stack([pose(st[f"reference_lookahead[{j}]"]) for j in range(self.n_look)], axis=1)
        ref_vel = np.column_stack([o[:, rv] * sc.max_speed, o[:, rv + 1] * sc.max_speed,
                                   o[:, rv + 2] * sc.max_yaw_rate])
        return BatchSensorObs(o[:, L["encoder_rates"]] * sc.wheel_scale, o[:, st["gyro"]] * sc.max_yaw_rate,
                              np.arctan2(o[:, c], o[:, c + 1]), o[:, L["accelerometer"]] * ACC_SCALE,
                              pose(st["camera_fix"]), o[:, st["fix_age"]].copy(), pose(st["reference_now"]),
                              ref_vel, look, o[:, L["last_action"]])


@dataclass(frozen=True)
class StateObs:
    """One decoded ``state`` observation (SI units; body frame of the robot now)."""

    tracking_error_body: np.ndarray  # (2,) m, reference position − robot position
    heading_error: float  # rad, wrap(θ_ref − θ)
    body_velocity: np.ndarray  # (3,) vx, vy [m/s], ω [rad/s]
    reference_velocity: np.ndarray  # (3,) reference velocity vx, vy [m/s] and yaw rate [rad/s]
    lookahead: np.ndarray  # (K, 3) reference offset x, y [m] and heading error [rad] at LOOKAHEAD_SECONDS
    last_action: np.ndarray  # previous clipped action


class StateObsDecoder(_ObsDecoder):
    """Turns ``state`` observations into :class:`StateObs` (values clipped at ±OBS_CLIP stay clipped)."""

    mode = "state"
    lookahead_prefix = "lookahead["

    def __call__(self, obs: np.ndarray) -> StateObs:
        o = self._array(obs)
        L, sc = self.layout, self.scales
        twist = np.array([sc.max_speed, sc.max_speed, sc.max_yaw_rate])
        look = np.array([o[L[f"lookahead[{i}]"]] for i in range(self.n_look)]).reshape(-1, 3)
        return StateObs(o[L["tracking_error_body"]] * POS_SCALE, float(o[L["heading_error"]][0] * math.pi),
                        o[L["body_velocity"]] * twist, o[L["reference_velocity"]] * twist,
                        look * np.array([LOOK_SCALE, LOOK_SCALE, math.pi]), o[L["last_action"]])
