"""Training rewards on the true tracking error: one home for the reward modes every learned agent uses.

``reward="env"`` keeps the environment's reward (docs/environments.md). The other two replace it,
computed from the true tracking error e [m] (``info["tracking_error"]``) and the agent's action
a ∈ [−1, 1]^A:

* ``"tracking"``:  r = 0.5·exp(−(e/0.05 m)²) + 0.5·exp(−e/0.1 m) − 0.02·mean(a²).
  It concentrates on e (slope at e = 4.5 cm 2.5× the environment reward's) and stays positive, so
  getting lost early never pays.
* ``"squared"``:  r = −(e/0.1 m)² − 0.01·mean(a²), and −LOST_HORIZON·(lost_distance/0.1 m)² once when
  the episode terminates (the robot got lost). This is the benchmark metric itself, per step. Under
  slip and lift-off the tracking RMSE is dominated by rare excursions of 20–30 cm, where the bounded
  rewards are flat; the squared reward weighs them as the RMSE does. The termination penalty is what
  staying lost for the discounting horizon would cost, so ending early does not pay.

* ``"gaussian"``:  r = 0.5·exp(−(e/0.01 m)²) + 0.5·exp(−(e/0.1 m)²) − 0.01·mean(a²): a tracking reward with
  scales, as in the field's tracking tasks. Near the path it resolves millimetres (its slope at e = 5 mm
  is 0.39 per cm, the squared reward's 0.01 per cm), the wide term still pulls back from 10–20 cm, and it
  is positive, so getting lost ends the income (no termination penalty needed).

* ``"pose"``:  the gaussian reward plus a heading term 0.25·exp(−(e_θ/0.02 rad)²) + 0.25·exp(−(e_θ/0.2 rad)²),
  e_θ = wrap(θ_ref − θ) [rad] (``info["heading_error"]``): the position-only rewards leave the heading free,
  and a privileged agent trained on them lets it drift by radians (docs/agents.md, "Diagnosis").

* ``"pose_fine"``: the pose reward with a third, millimetre scale: (1/3)·Σ exp(−(e/s)²) over s = 1 mm, 1 cm,
  10 cm, plus (1/6)·Σ exp(−(e_θ/s_θ)²) over s_θ = 0.002, 0.02, 0.2 rad, − 0.01·mean(a²). On a grip floor the
  true-state law tracks to 0.4–0.6 mm, where the pose reward's narrowest term (1 cm) is flat: a fine-tuned
  agent there has no signal to keep sub-millimetre precision (docs/agents.md, "Floor randomisation").

The reward is a training signal only: no policy observes e.

* :func:`tracking_reward`: the formula, for one robot or N at once; :func:`step_errors`: which error each
  robot of a native vector env is rewarded for, in either autoreset mode.
* :class:`TrackingReward` / :class:`VectorTrackingReward`: the reward alone, for agents without the
  EKF wrappers (the privileged-state agent), on a single or a native vector environment. The EKF
  wrappers (:mod:`agents.wrappers`) call :func:`tracking_reward` with their agent's action.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorWrapper

from agents.registry import Registry

LOST_HORIZON = 50  # steps: the squared reward's penalty for getting lost (≈ 1/(1 − γ) at γ = 0.98)
ERROR_SCALE = 0.1  # m: the squared reward's unit of tracking error
# The reward modes by name, each with its formula in one line, for plot labels and reports (e: true tracking
# error [m], a: the agent's action).
REWARDS: Registry[str] = Registry("reward", [
    ("env", "the environment's reward (docs/environments.md)"),
    ("tracking", "0.5·exp(−(e/0.05 m)²) + 0.5·exp(−e/0.1 m) − 0.02·mean(a²)"),
    ("squared", "−(e/0.1 m)² − 0.01·mean(a²); once when lost −50·(lost_distance/0.1 m)²"),
    ("gaussian", "0.5·exp(−(e/0.01 m)²) + 0.5·exp(−(e/0.1 m)²) − 0.01·mean(a²)"),
    ("pose", "gaussian + 0.25·exp(−(e_θ/0.02 rad)²) + 0.25·exp(−(e_θ/0.2 rad)²)"),
    ("pose_fine", "(1/3)·Σ exp(−(e/s)²), s = 1 mm, 1 cm, 10 cm + (1/6)·Σ exp(−(e_θ/s)²), s = 2, 20, 200 mrad "
                  "− 0.01·mean(a²)"),
])
GAUSSIAN_SCALES = (0.01, 0.1)  # m: the gaussian reward's narrow and wide error scales
HEADING_SCALES = (0.02, 0.2)  # rad: the pose reward's narrow and wide heading scales
FINE_SCALES = (0.001, 0.01, 0.1)  # m: pose_fine's position scales
FINE_HEADING_SCALES = (0.002, 0.02, 0.2)  # rad: pose_fine's heading scales


def check_reward(reward: str) -> None:
    """Raise ValueError unless ``reward`` is one of :data:`REWARDS`."""
    REWARDS.check(reward)


def tracking_reward(mode: str, env_reward, error, action, terminated, lost_distance: float,
                    heading=None) -> np.ndarray:
    """Reward of ``mode`` per robot: (N,) from env_reward, error [m], terminated (N,) and action (N, A).

    ``lost_distance`` [m] is the environment's termination distance (``cfg.lost_distance``); ``heading``
    (N,) the heading error [rad], needed by ``"pose"`` only.
    """
    env_reward = np.asarray(env_reward, dtype=float)
    if mode == "env":
        return env_reward.copy()
    e = np.asarray(error, dtype=float)
    a = np.asarray(action, dtype=float)
    effort = np.mean(a * a, axis=-1)
    if mode == "tracking":
        return 0.5 * np.exp(-((e / 0.05) ** 2)) + 0.5 * np.exp(-e / 0.1) - 0.02 * effort
    if mode == "squared":
        r = -((e / ERROR_SCALE) ** 2) - 0.01 * effort
        return np.where(terminated, r - LOST_HORIZON * (lost_distance / ERROR_SCALE) ** 2, r)
    if mode in ("gaussian", "pose"):
        narrow, wide = GAUSSIAN_SCALES
        r = 0.5 * np.exp(-((e / narrow) ** 2)) + 0.5 * np.exp(-((e / wide) ** 2)) - 0.01 * effort
        if mode == "pose":
            if heading is None:
                raise ValueError("the 'pose' reward needs the heading error")
            h = np.asarray(heading, dtype=float)
            r = r + 0.25 * np.exp(-((h / HEADING_SCALES[0]) ** 2)) + 0.25 * np.exp(-((h / HEADING_SCALES[1]) ** 2))
        return r
    if mode == "pose_fine":
        if heading is None:
            raise ValueError("the 'pose_fine' reward needs the heading error")
        h = np.asarray(heading, dtype=float)
        r = sum(np.exp(-((e / sc) ** 2)) for sc in FINE_SCALES) / 3.0
        r = r + sum(np.exp(-((h / sc) ** 2)) for sc in FINE_HEADING_SCALES) / 6.0
        return r - 0.01 * effort
    check_reward(mode)
    raise AssertionError("unreachable")


def step_headings(info: dict, done: np.ndarray) -> np.ndarray:
    """Per robot of a native vector env: the heading error [rad] of the step it just took (``done`` from
    :func:`step_errors`: those robots' ended episodes are in ``info["final_info"]``)."""
    h = np.asarray(info["heading_error"], dtype=float).copy()
    if done.any():
        h[done] = np.asarray(info["final_info"]["heading_error"], dtype=float)[done]
    return h


def step_errors(info: dict, terminated, truncated, same_step: bool,
                pending: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per robot of a native vector env: the tracking error [m] of the step it just took, and its autoreset.

    ``SAME_STEP``: a robot that ended this step has its ended episode's error in ``info["final_info"]``;
    ``done`` marks those robots. ``NEXT_STEP``: the robots in ``pending`` (ended on the previous step)
    were reset by this step, their actions ignored: ``restart`` marks them. Returns ``(e, done, restart,
    pending for the next step)``; the masks are (N,) booleans.
    """
    e = np.asarray(info["tracking_error"], dtype=float).copy()
    ended = np.asarray(terminated | truncated, dtype=bool)
    none = np.zeros(e.shape[0], dtype=bool)
    if same_step:
        if ended.any():
            e[ended] = np.asarray(info["final_info"]["tracking_error"], dtype=float)[ended]
        return e, ended, none, pending
    return e, none, pending.copy(), ended


def _omni_cfg(env, who: str):
    cfg = getattr(env.unwrapped, "cfg", None)
    if cfg is None:
        raise ValueError(f"{who} needs an omni-gym environment, got {type(env.unwrapped).__name__}")
    return cfg


class TrackingReward(gym.Wrapper):
    """Replace an omni-gym environment's reward with :func:`tracking_reward` (``reward`` mode).

    Observations, actions, flags and info pass through unchanged; any ``obs_mode`` / ``action_mode``.
    """

    def __init__(self, env: gym.Env, reward: str = "squared") -> None:
        super().__init__(env)
        check_reward(reward)
        self.reward_mode = reward
        self.lost_distance = float(_omni_cfg(env, "TrackingReward").lost_distance)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        a = np.clip(np.asarray(action, dtype=float).reshape(1, -1), -1.0, 1.0)
        r = tracking_reward(self.reward_mode, [reward], [info["tracking_error"]], a, [terminated], self.lost_distance,
                            [info["heading_error"]])
        return obs, float(r[0]), terminated, truncated, info


class VectorTrackingReward(VectorWrapper):
    """:class:`TrackingReward` for a native vector environment, in either autoreset mode.

    ``SAME_STEP``: an ended robot's reward uses its ended episode's error (``info["final_info"]``).
    ``NEXT_STEP``: on the step after a robot ended, its action was ignored and its reward is 0, as the
    environment's own reward is.
    """

    def __init__(self, env, reward: str = "squared") -> None:
        super().__init__(env)
        check_reward(reward)
        self.reward_mode = reward
        self.lost_distance = float(_omni_cfg(env, "VectorTrackingReward").lost_distance)
        self.same_step = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP) == AutoresetMode.SAME_STEP
        self._autoreset = np.zeros(int(env.num_envs), dtype=bool)

    def reset(self, *, seed=None, options: dict | None = None):
        self._autoreset[:] = False
        return self.env.reset(seed=seed, options=options)

    def step(self, actions):
        obs, reward, terminated, truncated, info = self.env.step(actions)
        e, done, restart, self._autoreset = step_errors(info, terminated, truncated, self.same_step, self._autoreset)
        a = np.clip(np.asarray(actions, dtype=float).reshape(self.num_envs, -1), -1.0, 1.0)
        r = tracking_reward(self.reward_mode, reward, e, a, terminated, self.lost_distance, step_headings(info, done))
        r[restart] = 0.0
        return obs, r, terminated, truncated, info
