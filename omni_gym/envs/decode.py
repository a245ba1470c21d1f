"""Decode a ``sensors`` observation back into physical units (the layout in ``docs/environments.md``).

Controllers that only use what a real robot has (the scripted baselines in ``agents/``) read the
observation through :func:`decode_sensor_obs` rather than indexing it themselves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.envs.core import ACC_SCALE, LOOKAHEAD_SECONDS


@dataclass(frozen=True)
class SensorObs:
    """One decoded ``sensors`` observation (SI units, world frame unless stated)."""

    encoder_rates: np.ndarray  # (n,) rad/s: change of the quantised wheel angles over the control period
    gyro: float  # rad/s, yaw rate (noise and bias)
    compass: float  # rad, heading in (−π, π]
    accel: np.ndarray  # (2,) m/s², body frame
    camera: np.ndarray  # (3,) last camera fix x, y [m], θ [rad]
    camera_age: float  # s since that fix (0: it arrived this step; capped at 1)
    ref_pose: np.ndarray  # (3,) reference x, y, θ now (θ wrapped)
    ref_velocity: np.ndarray  # (3,) reference world velocity ẋ, ẏ, θ̇ now
    lookahead: np.ndarray  # (K, 3) reference x, y, θ at LOOKAHEAD_SECONDS ahead
    prev_action: np.ndarray  # previous clipped action


class SensorObsDecoder:
    """Turns ``sensors`` observations of one environment configuration into :class:`SensorObs`.

    Args: the environment's config (``env.unwrapped.cfg``), its wheel count, its wheel-speed scale
    (``env.unwrapped.core.wheel_scale``) and its action dimension.
    """

    def __init__(self, cfg, n_wheels: int, wheel_scale: float, action_dim: int) -> None:
        if cfg.obs_mode != "sensors":
            raise ValueError(f"decoding needs obs_mode='sensors', got {cfg.obs_mode!r}")
        self.cfg = cfg
        self.n = n_wheels
        self.wheel_scale = wheel_scale
        self.action_dim = action_dim
        self.dim = n_wheels + 5 + 5 + 7 + 4 * len(LOOKAHEAD_SECONDS) + action_dim

    def __call__(self, obs: np.ndarray) -> SensorObs:
        o = np.asarray(obs, dtype=float)
        if o.shape != (self.dim,):
            raise ValueError(f"sensors observation must have shape ({self.dim},), got {o.shape}")
        cfg, n, h = self.cfg, self.n, self.cfg.arena_half_size
        k = n
        enc = o[0:n] * self.wheel_scale
        gyro = o[k] * cfg.max_yaw_rate
        compass = math.atan2(o[k + 1], o[k + 2])
        accel = o[k + 3:k + 5] * ACC_SCALE
        cam = o[k + 5:k + 10]
        camera = np.array([cam[0] * h, cam[1] * h, math.atan2(cam[2], cam[3])])
        ref = o[k + 10:k + 17]
        ref_pose = np.array([ref[0] * h, ref[1] * h, math.atan2(ref[2], ref[3])])
        ref_vel = np.array([ref[4] * cfg.max_speed, ref[5] * cfg.max_speed, ref[6] * cfg.max_yaw_rate])
        look = o[k + 17:k + 17 + 4 * len(LOOKAHEAD_SECONDS)].reshape(-1, 4)
        lookahead = np.column_stack([look[:, 0] * h, look[:, 1] * h, np.arctan2(look[:, 2], look[:, 3])])
        return SensorObs(enc, float(gyro), float(compass), accel, camera, float(cam[4]), ref_pose, ref_vel,
                         lookahead, o[self.dim - self.action_dim:])

    @classmethod
    def for_env(cls, env) -> SensorObsDecoder:
        """Decoder for a (possibly wrapped) omni-gym environment."""
        u = env.unwrapped
        return cls(u.cfg, u.core.n_wheels, u.core.wheel_scale, u.core.action_dim)
