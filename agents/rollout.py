"""Rollout: build an omni-gym environment for a policy and run one episode of it.

The layer below evaluation (:mod:`agents.evaluate`: statistics over episodes) and training
(:mod:`agents.train`: validation episodes), and the one both use, so neither imports the other.
Scripted policies (:mod:`agents.policies`) and trained models (:class:`agents.sb3_policy.SB3Policy`)
both follow :class:`Policy`.

Per-episode metrics come from the ground truth in ``info`` (the policies never see it); see
:mod:`agents.evaluate` for their definitions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


class Policy(Protocol):
    """What :func:`run_episode` needs of a policy.

    ``reset(obs)`` starts an episode from its first observation; ``act(obs)`` returns the action for an
    observation (the environment's action space, e.g. a body twist [m/s, m/s, rad/s] for the scripted
    policies). Optional attribute ``estimate``: the policy's pose estimate (x [m], y [m], θ [rad], world
    frame) after its last ``act``, or None (open loop); a policy without it counts as open loop.
    """

    def reset(self, obs: np.ndarray) -> None: ...

    def act(self, obs: np.ndarray) -> np.ndarray: ...


class TrainedPolicy:
    """Base of the trained-model adapters (:class:`agents.sb3_policy.SB3Policy`,
    :class:`agents.rllib.policy.RLlibPolicy`): a network acting on each observation alone.

    It keeps the environment it acts on and exposes that environment's ``estimate`` (the EKF wrappers'
    pose estimate, x [m], y [m], θ [rad], world frame; None without one) as its own. ``reset`` has nothing
    to reset: any filter state lives in the wrapper, which restarts it with the environment. Subclasses
    give ``act``.
    """

    name = "trained"

    def __init__(self, env=None) -> None:
        self.env = env

    @property
    def estimate(self) -> np.ndarray | None:
        return getattr(self.env, "estimate", None)

    def reset(self, obs: np.ndarray) -> None:
        """Nothing to reset: the network acts on each observation alone (a wrapper keeps any filter state)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError


@dataclass
class Episode:
    """One evaluated episode; the trajectories are filled only with ``record=True``."""

    seed: int
    tracking_rmse: float
    final_position_error: float
    final_heading_error: float
    success: bool
    terminated: bool
    steps: int
    episode_return: float = math.nan  # sum of the environment's own reward (the id's, not a wrapper's)
    # The share of the wheels' friction set the episode's reference asks for (> 1: beyond the robot's traction;
    # NaN where the environment cannot tell), info["reference_traction"] at reset.
    reference_traction: float = math.nan
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pose: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # true pose (x, y, θ)
    reference: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    estimate: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # NaN where the policy has none
    contact: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))

    def metrics(self) -> dict:
        return {"seed": self.seed, "tracking_rmse": self.tracking_rmse,
                "final_position_error": self.final_position_error, "final_heading_error": self.final_heading_error,
                "success": self.success, "terminated": self.terminated, "steps": self.steps,
                "episode_return": self.episode_return,
                "reference_traction": known_or_none(self.reference_traction)}


def known_or_none(value: float | None) -> float | None:
    """``value``, or None where it is not known (None or NaN): what a JSON record holds."""
    return None if value is None or math.isnan(value) else float(value)


def run_episode(env, policy: Policy, seed: int, record: bool = False) -> Episode:
    """Run one episode of ``policy`` (a scripted policy object) on ``env`` from ``env.reset(seed=seed)``.

    With ``record`` the episode keeps, at every step k = 0…K, the time, true pose, reference pose, the
    policy's estimate after acting on observation k (NaN for open-loop) and the wheel contacts.
    """
    obs, info = env.reset(seed=seed)
    traction = float(info.get("reference_traction", math.nan))
    policy.reset(obs)
    dt = env.unwrapped.cfg.control_dt
    core = env.unwrapped.core  # the environment's own reward, also under a wrapper that replaces it
    sq_sum, steps, ret = 0.0, 0, 0.0
    rows = []

    def keep(info_) -> None:
        est = getattr(policy, "estimate", None)
        est = est if est is not None else np.full(3, np.nan)
        rows.append((steps * dt, info_["pose"], info_["reference_pose"], np.array(est, dtype=float),
                     info_["contact"]))

    while True:
        action = policy.act(obs)
        if record:
            keep(info)
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        sq_sum += info["tracking_error"] ** 2
        ret += float(core.reward[0])
        if terminated or truncated:
            break
    if record:  # the estimate of the last pose: one more (unused) action updates it
        policy.act(obs)
        keep(info)
    ep = Episode(seed=int(seed), tracking_rmse=math.sqrt(sq_sum / steps),
                 final_position_error=float(info["tracking_error"]),
                 final_heading_error=abs(float(info["heading_error"])),
                 success=bool(info["is_success"]) and not terminated, terminated=bool(terminated), steps=steps,
                 episode_return=ret, reference_traction=traction)
    if record:
        ep.t = np.array([r[0] for r in rows])
        ep.pose = np.array([r[1] for r in rows])
        ep.reference = np.array([r[2] for r in rows])
        ep.estimate = np.array([r[3] for r in rows])
        ep.contact = np.array([r[4] for r in rows])
    return ep


def check_env_id(env_id, where: str | None = None, registered: bool = True) -> str:
    """``env_id`` if it is an omni-gym id, bare (``OmniPathFollow-Phunopas-v0``) or with gym's module prefix
    ``omni_gym:``; ValueError (one line, starting with ``where`` if given) otherwise. ``registered``: the id must
    also be one of :func:`omni_gym.envs.all_ids` (or a renamed one, whose own error names the new id).

    ``gym.make("MODULE:ID")`` imports MODULE, so an id read from a model folder (``meta.json``, an RL Zoo
    ``args.yml``) would import whatever module the folder names, without ``--trust-pickle``. No other module is
    ever imported, trusted model or not: the environment must be an omni-gym one, which omni_gym registers.
    """
    from omni_gym.envs import RENAMED, all_ids
    from omni_gym.io import excerpt

    at = f"{where}: " if where else ""
    if not isinstance(env_id, str) or not env_id:
        raise ValueError(f"{at}an environment id must be a non-empty string, got {excerpt(repr(env_id))}")
    module, colon, bare = env_id.rpartition(":")
    if colon and module != "omni_gym":
        raise ValueError(f"{at}environment id {excerpt(ascii(env_id))} names a module to import "
                         f"({excerpt(ascii(module))}); omni-gym imports none: give a registered id "
                         f"({', '.join(all_ids())})")
    if registered and bare not in all_ids() and bare not in RENAMED:
        raise ValueError(f"{at}unknown environment id {excerpt(ascii(env_id))}; omni-gym ids: "
                         f"{', '.join(all_ids())}")
    return env_id


def make_env(env_id: str, env_kwargs: dict | None = None, obs_mode: str = "sensors"):
    """``gym.make(env_id, obs_mode=obs_mode, action_mode="twist", **env_kwargs)`` with clear ValueErrors.

    ``obs_mode`` is "sensors" for the scripted policies; an SB3 model trained on ``"state"`` (a privileged
    upper bound) asks for that.
    """
    import gymnasium as gym

    import omni_gym  # noqa: F401  (registers the ids)
    from omni_gym.envs import all_ids

    if not isinstance(env_kwargs or {}, dict):
        raise ValueError(f"env_kwargs must be a dict (a JSON object), got {env_kwargs!r}")
    kwargs = dict(env_kwargs or {})
    for key, need in (("obs_mode", obs_mode), ("action_mode", "twist")):
        if kwargs.get(key, need) != need:
            raise ValueError(f"this policy runs with {key}={need!r}; got {key}={kwargs[key]!r} in env_kwargs")
        kwargs[key] = need
    check_env_id(env_id, registered=False)  # never "MODULE:ID" of another module: gym.make would import it
    bare_id = env_id.rpartition(":")[2]
    try:
        spec = gym.spec(bare_id)
    except (gym.error.Error, ImportError) as exc:
        raise ValueError(f"unknown environment id {env_id!r} ({exc}); omni-gym ids: {', '.join(all_ids())}") from None
    if not str(spec.entry_point).startswith("omni_gym."):
        raise ValueError(f"environment {env_id!r} is not an omni-gym environment; omni-gym ids: "
                         f"{', '.join(all_ids())}")
    try:
        env = gym.make(env_id, **kwargs)
    except TypeError as exc:
        raise ValueError(f"bad env_kwargs for {env_id}: {exc}") from None
    # The registered TimeLimit (e.g. 800 steps for OmniGoToPose-v0) would cut a longer episode_seconds
    # short; the environment truncates at the end of its reference by itself, so match the two.
    steps = env.unwrapped.cfg.episode_steps
    if env.spec is not None and env.spec.max_episode_steps != steps:
        env.close()
        env = gym.make(env_id, max_episode_steps=steps, **kwargs)
    return env
