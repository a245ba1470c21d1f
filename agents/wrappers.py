"""Observation and action wrappers that let SB3 agents use only what a real robot has.

* :class:`EKFFeatures` (``residual-ekf-pid`` / ``ekf-features``): runs the ``ekf-pid`` baseline
  (:class:`agents.policies.EKFPIDPolicy`: the EKF, its slip/lift-off detector and the PID) inside the
  environment and gives the agent, instead of the raw sensor vector, what the filter knows:

  ====================  ===========================================================  ============
  features              quantity                                                     scale
  ====================  ===========================================================  ============
  0–1                   reference − estimated position, estimated body frame           / 0.05 m
  2                     heading error wrap(θ_ref − θ̂)                                  / 0.1 rad
  3–5                   estimated body twist vx, vy, ω                                 / max_speed, / max_yaw_rate
  6–8                   reference world velocity in the estimated body frame, ω_ref    / max_speed, / max_yaw_rate
  9–17                  reference at +0.25, +0.5, +1.0 s: body-frame offset, heading   / 0.5 m, / π
  18–20                 EKF standard deviation of x, y, θ                              / 0.01 m, / 0.02 rad
  21…20+n               detector belief that wheel i slips or is lifted                0…1
  21+n…20+2n            wheels the filter used this step (1) or rejected (0)           0/1
  21+2n…20+3n           encoder rate − W·(estimated twist) per wheel                    / w_max
  21+3n…23+3n           the PID's body twist (the baseline's action)                   / action scale
  24+3n…26+3n           the PID's integral terms in the estimated body frame            / their limits
  27+3n…29+3n           the agent's previous action                                    [−1, 1]
  ====================  ===========================================================  ============

  Every feature is clipped to ±10. The estimate frame is the filter's, never the truth.

  With ``residual_scale`` = s > 0 (``residual-ekf-pid``), the agent's action a ∈ [−1, 1]³ is a
  *residual*: the environment receives clip(a_PID + s·a, −1, 1), so a = 0 is exactly ``ekf-pid``
  and the agent can move the twist by at most s of its range. With ``residual_scale`` = 0
  (``ekf-features``) the agent's action is the whole twist and the PID only supplies features.

  Reward (``reward``): "env" keeps the environment's; "tracking" and "squared" replace it with a
  function of the true tracking error and the agent's action (:mod:`agents.rewards`; "squared" is the
  benchmark metric per step). The reward is a training signal only: the policy never sees the error.

* :class:`VectorEKFFeatures`: the same features, residual action and rewards for a native vector
  environment (N robots at once, the batched EKF of :mod:`agents.batched`); both autoreset modes.

* :class:`SensorNoiseRandomizer`: draws a sensor-noise scale from U(lo, hi) at every reset (the
  environments fix ``sensor_noise`` at construction; this domain randomisation sits outside them).
  The draw comes from a generator seeded by the reset seed (and continued by unseeded resets), so a
  seed still fixes the episode.

Both need ``obs_mode="sensors"`` and ``action_mode="twist"``.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorWrapper
from gymnasium.vector.utils import batch_space

from agents.registry import Registry
from agents.rewards import (
    TrackingReward,
    VectorTrackingReward,
    check_reward,
    step_errors,
    step_headings,
    tracking_reward,
)
from omni_gym.angles import wrap_angle

# The wrappers by name (``--wrapper``, ``meta.json``'s ``wrapper``), each with what the agent then sees and does.
WRAPPERS: Registry[str] = Registry("wrapper", [
    ("none", "the environment's own observation and action (the privileged agent)"),
    ("residual-ekf-pid", "EKF features; the action is a bounded residual on the ekf-pid twist"),
    ("ekf-features", "EKF features; the action is the whole twist"),
    ("feedforward", "the environment's state; the action corrects the reference twist (privileged)"),
])
POS_SCALE = 0.05  # m: tracking errors of a few cm are what the agent must act on
HEAD_SCALE = 0.1  # rad
LOOK_SCALE = 0.5  # m
STD_POS_SCALE = 0.01  # m: the EKF's position std is a few mm with camera fixes
STD_HEAD_SCALE = 0.02  # rad
CLIP = 10.0


def pid_twist_columns(dim: int) -> slice:
    """The columns of the EKF feature vector (length ``dim`` = 30 + 3n) that hold the PID's body twist in
    action units: ekf-pid's action before clipping to [−1, 1] (the table in the module doc)."""
    n, rest = divmod(dim - 30, 3)
    if rest or n < 3:
        raise ValueError(f"not an EKF feature vector: length {dim} (expected 30 + 3·wheels)")
    return slice(21 + 3 * n, 24 + 3 * n)


NOISE_SALT = 0x5E17  # mixes the reset seed into the noise-scale generator (independent of the env's draws)


def _check_env(env: gym.Env, who: str) -> None:
    cfg = getattr(env.unwrapped, "cfg", None)
    if cfg is None:
        raise ValueError(f"{who} needs an omni-gym environment, got {type(env.unwrapped).__name__}")
    if cfg.obs_mode != "sensors" or cfg.action_mode != "twist":
        raise ValueError(f"{who} needs obs_mode='sensors' and action_mode='twist', got obs_mode={cfg.obs_mode!r}, "
                         f"action_mode={cfg.action_mode!r}")


def _check_wrapper_args(residual_scale, reward: str) -> None:
    """The EKF wrappers' keywords: a residual bound in [0, 1] and one of :data:`agents.rewards.REWARDS`."""
    if not (isinstance(residual_scale, (int, float)) and 0.0 <= residual_scale <= 1.0):
        raise ValueError(f"residual_scale must be a number in [0, 1], got {residual_scale!r}")
    check_reward(reward)


class EKFFeatures(gym.Wrapper):
    """EKF-estimate observation and (optionally) a bounded residual on the ekf-pid action; see the module doc.

    Args:
        env: an omni-gym environment with ``obs_mode="sensors"``, ``action_mode="twist"``.
        residual_scale: s in [0, 1]: the agent's action moves the PID action by at most s (0: the agent
            gives the whole action).
    """

    def __init__(self, env: gym.Env, residual_scale: float = 0.3, reward: str = "env") -> None:
        super().__init__(env)
        _check_env(env, "EKFFeatures")
        _check_wrapper_args(residual_scale, reward)
        self.reward_mode = reward
        self.lost_distance = float(env.unwrapped.cfg.lost_distance)
        self.filter = EKFFeatureFilter.for_env(env, float(residual_scale))  # what the agent sees and does
        self.residual_scale = self.filter.residual_scale
        self.n = self.base.robot.n_wheels
        self.twist_scale = self.filter.twist_scale
        self.wheel_scale = self.filter.wheel_scale
        self.dim = 30 + 3 * self.n
        self.observation_space = spaces.Box(-CLIP, CLIP, shape=(self.dim,), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self._rates = np.zeros(self.n)

    @property
    def base(self):
        """The ekf-pid baseline inside the features (:class:`agents.policies.EKFPIDPolicy`)."""
        return self.filter.base

    @property
    def base_action(self) -> np.ndarray:
        """ekf-pid's action on the latest observation, in [-1, 1]³."""
        return self.filter.base_action

    @property
    def prev_action(self) -> np.ndarray:
        """The agent's latest (clipped) action."""
        return self.filter.prev_action

    @property
    def estimate(self) -> np.ndarray:
        """The EKF's pose estimate (x, y, θ) [m, m, rad], world frame."""
        return self.base.estimate

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self.filter.reset(obs), info

    def step(self, action):
        total = self.filter.command(action)
        a = self.filter.prev_action
        obs, reward, terminated, truncated, info = self.env.step(total)
        reward = float(tracking_reward(self.reward_mode, [reward], [info["tracking_error"]], a[None], [terminated],
                                       self.lost_distance, [info["heading_error"]])[0])
        return self.filter.observe(obs), reward, terminated, truncated, info


def ekf_feature_vector(base, obs: np.ndarray, prev_action: np.ndarray, twist_scale: np.ndarray,
                       wheel_scale: float) -> np.ndarray:
    """The EKF feature vector (the module doc's table, float32, clipped to ±10) of an ``ekf-pid`` policy
    ``base`` that has just acted on the sensor observation ``obs``; ``prev_action``: the agent's previous
    action; ``twist_scale`` (max_speed, max_speed, max_yaw_rate); ``wheel_scale`` [rad/s]."""
    s = base.decode(obs)
    ekf, pid = base.ekf, base.pid
    x, y, th = ekf.pose
    c, si = math.cos(th), math.sin(th)

    def body(dx: float, dy: float) -> tuple[float, float]:
        return c * dx + si * dy, -si * dx + c * dy

    ex, ey = body(s.ref_pose[0] - x, s.ref_pose[1] - y)
    eth = wrap_angle(s.ref_pose[2] - th)
    rvx, rvy = body(s.ref_velocity[0], s.ref_velocity[1])
    look = []
    for lx, ly, lth in s.lookahead:
        bx, by = body(lx - x, ly - y)
        look += [bx / LOOK_SCALE, by / LOOK_SCALE, wrap_angle(lth - th) / math.pi]
    std = np.sqrt(np.maximum(np.diag(ekf.P)[0:3], 0.0))
    innov = (np.asarray(s.encoder_rates) - base.W @ ekf.body_twist) / wheel_scale
    ix, iy = body(pid.integral[0], pid.integral[1])
    ilim = pid._ilim
    f = np.concatenate([
        [ex / POS_SCALE, ey / POS_SCALE, eth / HEAD_SCALE],
        ekf.body_twist / twist_scale,
        [rvx / twist_scale[0], rvy / twist_scale[1], s.ref_velocity[2] / twist_scale[2]],
        look,
        [std[0] / STD_POS_SCALE, std[1] / STD_POS_SCALE, std[2] / STD_HEAD_SCALE],
        ekf.wheel_belief, ekf.wheels_used.astype(float), innov,
        base.twist / twist_scale,
        [ix / ilim[0], iy / ilim[1], pid.integral[2] / ilim[2]],
        prev_action,
    ])
    return np.clip(f, -CLIP, CLIP).astype(np.float32)

class EKFFeatureFilter:
    """The EKF features of a residual or EKF-feature agent, outside any environment: what a robot program runs.

    It holds the ``ekf-pid`` baseline (EKF, slip/lift-off detector, PID; numpy and scipy only) and turns each
    sensor observation into the agent's input, then the agent's action into the twist action the robot is
    given, exactly as :class:`EKFFeatures` does inside training and evaluation::

        feat = filt.reset(obs)                  # at the start (the robot at rest on its reference)
        while running:
            a = policy(feat)                    # e.g. the exported ONNX network
            twist = filt.command(a)             # action in [-1, 1]^3: x max_speed, max_speed, max_yaw_rate
            obs = robot.step(twist)             # the sensor observation one control period later
            feat = filt.observe(obs)

    Args:
        base: an ``ekf-pid`` policy (:func:`agents.policies.make_policy`) for the robot.
        twist_scale: (max_speed [m/s], max_speed [m/s], max_yaw_rate [rad/s]): action units.
        wheel_scale: the encoder observation scale [rad/s].
        residual_scale: s in [0, 1]: the agent's action moves ekf-pid's by at most s (0: the whole twist).
    """

    def __init__(self, base, twist_scale: np.ndarray, wheel_scale: float, residual_scale: float) -> None:
        self.base = base
        self.twist_scale = np.asarray(twist_scale, dtype=float)
        self.wheel_scale = float(wheel_scale)
        self.residual_scale = float(residual_scale)
        self.base_action = np.zeros(3)
        self.prev_action = np.zeros(3)

    @classmethod
    def for_env(cls, env, residual_scale: float) -> EKFFeatureFilter:
        """The filter of an omni-gym environment's robot, control period, scales and kinematics (sensors, twist)."""
        from agents.policies import make_policy

        _check_env(env, "EKFFeatureFilter")
        cfg = env.unwrapped.cfg
        return cls(make_policy("ekf-pid", env), np.array([cfg.max_speed, cfg.max_speed, cfg.max_yaw_rate]),
                   float(env.unwrapped.wheel_scale), residual_scale)

    def reset(self, obs: np.ndarray) -> np.ndarray:
        """Start from the first sensor observation; returns the first feature vector (float32)."""
        self.prev_action = np.zeros(3)
        self.base.reset(obs)
        return self.observe(obs)

    def observe(self, obs: np.ndarray) -> np.ndarray:
        """Advance the filter and the PID with a sensor observation; returns the feature vector (float32)."""
        self.base_action = np.asarray(self.base.act(obs), dtype=float).reshape(3)
        return ekf_feature_vector(self.base, obs, self.prev_action, self.twist_scale, self.wheel_scale)

    def command(self, action: np.ndarray) -> np.ndarray:
        """The twist action (float32, [-1, 1]^3) for the agent's ``action``: clip(ekf-pid + s·a, -1, 1) for a
        residual agent, the action itself otherwise."""
        a = np.clip(np.asarray(action, dtype=float).reshape(3), -1.0, 1.0)
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action contains NaN or infinity: {a.tolist()}")
        self.prev_action = a
        total = np.clip(self.base_action + self.residual_scale * a, -1.0, 1.0) if self.residual_scale > 0 else a
        return total.astype(np.float32)

    @property
    def estimate(self) -> np.ndarray:
        """The EKF's pose estimate (x, y, θ) [m, m, rad], world frame."""
        return self.base.estimate


class VectorEKFFeatures(VectorWrapper):
    """:class:`EKFFeatures` for a native vector environment: the same features, residual action and rewards
    per robot, with the batched ekf-pid baseline (:class:`agents.batched.policies.VectorEKFPIDPolicy`).

    Row i of every step equals what ``EKFFeatures`` over robot i's single environment gives inside a
    Gymnasium vector env of the same autoreset mode (``tests/test_batched_estimation.py``). Both
    autoreset modes of the wrapped env (``env.metadata["autoreset_mode"]``) are handled:

    * ``NEXT_STEP``: on the step after robot i ended, the env ignores its action and returns its first
      observation: the wrapper restarts robot i's filter and PID on it, its previous action is zero and
      its reward 0 (what a Gymnasium vector env does on the autoreset step), flags False.
    * ``SAME_STEP``: when robot i ends, ``obs[i]`` is its reset observation and ``info["final_obs"][i]``
      the last one of the ended episode: the wrapper advances robot i's filter with the latter, returns
      those features in its own ``info["final_obs"]`` (float32 (N, dim), valid where
      ``info["_final_obs"]``), then restarts the filter on ``obs[i]`` and returns its features. The reward
      uses the ended episode's tracking error (``info["final_info"]["tracking_error"]``).

    Args: as :class:`EKFFeatures`; ``env`` a vector environment with ``obs_mode="sensors"``,
    ``action_mode="twist"``; ``threads`` runs the batched EKF on numba's threads.
    """

    def __init__(self, env, residual_scale: float = 0.3, reward: str = "env", threads: bool = False) -> None:
        super().__init__(env)
        _check_env(env, "VectorEKFFeatures")
        _check_wrapper_args(residual_scale, reward)
        from agents.batched.policies import make_vector_policy

        self.reward_mode = reward
        self.residual_scale = float(residual_scale)
        self.base = make_vector_policy("ekf-pid", env, threads=threads)
        self.num = int(env.num_envs)
        cfg = env.unwrapped.cfg
        self.lost_distance = float(cfg.lost_distance)
        self.n = self.base.robot.n_wheels
        self.twist_scale = np.array([cfg.max_speed, cfg.max_speed, cfg.max_yaw_rate])
        self.wheel_scale = float(env.unwrapped.wheel_scale)
        self.dim = 30 + 3 * self.n
        self.single_observation_space = spaces.Box(-CLIP, CLIP, shape=(self.dim,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, self.num)
        self.same_step = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP) == AutoresetMode.SAME_STEP
        self.base_action = np.zeros((self.num, 3))
        self.prev_action = np.zeros((self.num, 3))
        self._autoreset = np.zeros(self.num, dtype=bool)

    @property
    def estimate(self) -> np.ndarray:
        """(N, 3) EKF pose estimates (x, y, θ) [m, m, rad], world frame."""
        return self.base.estimate

    def reset(self, *, seed=None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.prev_action[:] = 0.0
        self._autoreset[:] = False
        self.base.reset(obs)
        return self._observe(obs), info

    def step(self, actions):
        a = np.clip(np.asarray(actions, dtype=float).reshape(self.num, 3), -1.0, 1.0)
        if not np.all(np.isfinite(a)):
            raise ValueError("actions contain NaN or infinity")
        if self.residual_scale > 0:
            total = np.clip(self.base_action + self.residual_scale * a, -1.0, 1.0)
        else:
            total = a
        obs, reward, terminated, truncated, info = self.env.step(total.astype(np.float32))
        e, done, restart, self._autoreset = step_errors(info, terminated, truncated, self.same_step, self._autoreset)
        live = ~restart
        self.prev_action[live] = a[live]
        reward = tracking_reward(self.reward_mode, reward, e, a, terminated, self.lost_distance,
                                 step_headings(info, done))
        if restart.any():  # NEXT_STEP: obs[restart] are first observations, the actions were ignored
            self.prev_action[restart] = 0.0
            reward[restart] = 0.0
            self.base.reset(obs, restart)
        if done.any():  # SAME_STEP: finish the ended episodes on their final observations, then restart
            last = np.asarray(obs, dtype=np.float32).copy()
            final_obs = np.asarray(info["final_obs"])  # (N, D); a Gymnasium vector env's is an object array
            last[done] = np.stack(list(final_obs[done])) if final_obs.dtype == object else final_obs[done]
            features = self._observe(last)
            final = features.copy()
            self.prev_action[done] = 0.0
            self.base.reset(obs, done)
            features[done] = self._observe(obs, done)[done]
            info = dict(info)
            info["final_obs"] = final
            info["_final_obs"] = done.copy()
        else:
            features = self._observe(obs)
        return features, reward, terminated, truncated, info

    def _observe(self, obs: np.ndarray, robots=None) -> np.ndarray:
        """Advance the baseline of ``robots`` (None: all) with ``obs`` (N, D) and build the (N, dim) features."""
        base = self.base
        act = np.asarray(base.act(obs, robots), dtype=float)
        m = np.ones(self.num, dtype=bool) if robots is None else np.asarray(robots, dtype=bool)
        self.base_action[m] = act[m]
        s = base.decode(obs)
        ekf, pid = base.ekf, base.pid
        pose = ekf.pose
        x, y, th = pose[:, 0], pose[:, 1], pose[:, 2]
        c, si = np.cos(th), np.sin(th)

        def body(dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return c * dx + si * dy, -si * dx + c * dy

        ex, ey = body(s.ref_pose[:, 0] - x, s.ref_pose[:, 1] - y)
        eth = wrap_angle(s.ref_pose[:, 2] - th)
        rvx, rvy = body(s.ref_velocity[:, 0], s.ref_velocity[:, 1])
        look = []
        for j in range(s.lookahead.shape[1]):
            lx, ly, lth = s.lookahead[:, j, 0], s.lookahead[:, j, 1], s.lookahead[:, j, 2]
            bx, by = body(lx - x, ly - y)
            look += [bx / LOOK_SCALE, by / LOOK_SCALE, wrap_angle(lth - th) / math.pi]
        std = np.sqrt(np.maximum(np.diagonal(ekf.P, axis1=1, axis2=2)[:, 0:3], 0.0))
        twist = ekf.body_twist
        W = base.W
        predicted = np.stack([W[j, 0] * twist[:, 0] + W[j, 1] * twist[:, 1] + W[j, 2] * twist[:, 2]
                              for j in range(self.n)], axis=1)
        innov = (s.encoder_rates - predicted) / self.wheel_scale
        ix, iy = body(pid.integral[:, 0], pid.integral[:, 1])
        ilim = pid._ilim
        ts = self.twist_scale
        f = np.column_stack([
            ex / POS_SCALE, ey / POS_SCALE, eth / HEAD_SCALE,
            twist / ts,
            rvx / ts[0], rvy / ts[1], s.ref_velocity[:, 2] / ts[2],
            *look,
            std[:, 0] / STD_POS_SCALE, std[:, 1] / STD_POS_SCALE, std[:, 2] / STD_HEAD_SCALE,
            ekf.wheel_belief, ekf.wheels_used.astype(float), innov,
            base.twist / ts,
            ix / ilim[0], iy / ilim[1], pid.integral[:, 2] / ilim[2],
            self.prev_action,
        ])
        return np.clip(f, -CLIP, CLIP).astype(np.float32)


class SensorNoiseRandomizer(gym.Wrapper):
    """Scales every sensor noise level by U(lo, hi) at each reset (domain randomisation; see the module doc)."""

    def __init__(self, env: gym.Env, scale_range: tuple[float, float]) -> None:
        super().__init__(env)
        _check_env(env, "SensorNoiseRandomizer")
        try:
            lo, hi = (float(v) for v in scale_range)
        except (TypeError, ValueError):
            raise ValueError(f"sensor-noise range must be a (low, high) pair, got {scale_range!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo <= hi <= 10.0):
            raise ValueError(f"sensor-noise range must satisfy 0 <= low <= high <= 10, got {scale_range!r}")
        self.range = (lo, hi)
        self._nominal = env.unwrapped.sensor_config
        self._rng = np.random.default_rng(NOISE_SALT)
        self.scale = 1.0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng([NOISE_SALT, int(seed)])
        self.scale = float(self._rng.uniform(*self.range))
        nominal = self._nominal
        scaled = {f.name: getattr(nominal, f.name) * self.scale for f in fields(nominal) if f.name.endswith("_std")}
        # The environment builds its sensors from this config at every reset (its public sensor_config).
        self.env.unwrapped.sensor_config = replace(nominal, **scaled)
        return self.env.reset(seed=seed, options=options)


class FeedForwardTwist(gym.Wrapper):
    """Privileged action structure: the environment receives clip(v_ref + scale·a, −1, 1).

    v_ref is the reference's twist in the robot's body frame, read from the ``state`` observation
    (``reference_velocity``, already divided by v_max, v_max, ω_max, i.e. in action units), so action 0 is
    pure feed-forward of the reference and the agent learns only the correction, bounded by ``scale`` of the
    action range. Needs ``obs_mode="state"`` and ``action_mode="twist"``; observations pass unchanged. Not a
    residual on a controller: nothing here feeds back an error.
    """

    def __init__(self, env: gym.Env, scale: float = 0.5) -> None:
        super().__init__(env)
        layout = env.unwrapped.observation_layout
        if layout.mode != "state" or env.unwrapped.cfg.action_mode != "twist":
            raise ValueError("FeedForwardTwist needs obs_mode='state' and action_mode='twist'")
        self.ref = layout["reference_velocity"]
        self.scale = float(scale)
        self._obs = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self._obs, info = self.env.reset(seed=seed, options=options)
        return self._obs, info

    def step(self, action):
        a = np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0)
        total = np.clip(self._obs[self.ref] + self.scale * a, -1.0, 1.0).astype(np.float32)
        self._obs, reward, terminated, truncated, info = self.env.step(total)
        return self._obs, reward, terminated, truncated, info


class VectorFeedForwardTwist(VectorWrapper):
    """:class:`FeedForwardTwist` for a native vector environment (either autoreset mode: the stored
    observation is the one the robot acts on, the first observation after a same-step reset)."""

    def __init__(self, env, scale: float = 0.5) -> None:
        super().__init__(env)
        layout = env.unwrapped.observation_layout
        if layout.mode != "state":
            raise ValueError("VectorFeedForwardTwist needs obs_mode='state'")
        self.ref = layout["reference_velocity"]
        self.scale = float(scale)
        self._obs = None

    def reset(self, *, seed=None, options: dict | None = None):
        self._obs, info = self.env.reset(seed=seed, options=options)
        return self._obs, info

    def step(self, actions):
        a = np.clip(np.asarray(actions, dtype=float).reshape(self.num_envs, -1), -1.0, 1.0)
        total = np.clip(self._obs[:, self.ref] + self.scale * a, -1.0, 1.0).astype(np.float32)
        self._obs, reward, terminated, truncated, info = self.env.step(total)
        return self._obs, reward, terminated, truncated, info


def wrap_env(env: gym.Env, name: str = "none", residual_scale: float = 0.3,
             sensor_noise_range: tuple[float, float] | None = None, reward: str = "env") -> gym.Env:
    """Apply the sensor-noise randomiser (if a range is given) and the named wrapper (one of :data:`WRAPPERS`).

    ``reward``: one of :data:`agents.rewards.REWARDS`; without an EKF wrapper ("none", the privileged
    agent) a reward other than "env" is applied alone (:class:`agents.rewards.TrackingReward`).
    """
    WRAPPERS.check(name)
    if sensor_noise_range is not None:
        env = SensorNoiseRandomizer(env, sensor_noise_range)
    if name == "residual-ekf-pid":
        env = EKFFeatures(env, residual_scale, reward)
    elif name == "ekf-features":
        env = EKFFeatures(env, 0.0, reward)
    else:
        if name == "feedforward":  # privileged: reference feed-forward + the agent's correction
            env = FeedForwardTwist(env, residual_scale)
        if reward != "env":  # the privileged agent: the reward alone (on the agent's own action)
            env = TrackingReward(env, reward)
    return env


def wrap_vector_env(env, name: str = "none", residual_scale: float = 0.3, reward: str = "env"):
    """:func:`wrap_env` for a native vector environment: the named wrapper as :class:`VectorEKFFeatures`,
    or the reward alone (:class:`agents.rewards.VectorTrackingReward`). The sensor-noise randomiser has
    no vector twin: give the environment keyword ``randomize_sensor_noise`` instead."""
    WRAPPERS.check(name)
    if name == "residual-ekf-pid":
        return VectorEKFFeatures(env, residual_scale, reward)
    if name == "ekf-features":
        return VectorEKFFeatures(env, 0.0, reward)
    if name == "feedforward":
        env = VectorFeedForwardTwist(env, residual_scale)
    return env if reward == "env" else VectorTrackingReward(env, reward)
