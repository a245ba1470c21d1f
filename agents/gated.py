"""One controller for grip and slip: ``ekf-pid`` until its own estimate says the robot has left the path, then a
student for the rest of the episode.

The students distilled from the oracle (:mod:`agents.distillation`) track far better than ``ekf-pid`` where the
wheels slip and worse where they grip; a user who does not know the floor cannot pick. The gate decides from what
the robot itself knows: the EKF's estimate of the tracking error, |e_xy| [m] of ``ekf-pid``'s PID (estimate
against reference, the path's frame), smoothed by an exponential moving average

    m_k = (1 − α)·m_{k−1} + α·|e_xy,k|,   α = :data:`GATE_ALPHA` per control period (10 ms: a time constant of 0.5 s)

and the student takes over for good once m_k exceeds the threshold (``threshold_m``). Where the wheels grip,
``ekf-pid`` keeps its estimate within about 1 mm of the path and the gate stays shut: the controller *is*
``ekf-pid``. Where they slip enough to matter, the estimate leaves the path and the student drives. What the gate
cannot see: a slip the EKF does not notice (its estimate stays on the path while the robot drifts), as on the
mecanum robot's carpet without lift-off; there the controller stays ``ekf-pid``.

A gated controller is a model directory with a ``meta.json`` of ``{"kind": "gated", "student": NAME,
"threshold_m": G, "env_id": ID}``; NAME is a sibling directory (the student's own model directory, next to the
gated one). ``omni-gym evaluate --policy DIR`` runs it (:class:`agents.loaders.GatedLoader`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.rollout import TrainedPolicy
from agents.sb3_policy import META
from omni_gym.io import read_json

KIND = "gated"
GATE_ALPHA = 0.02  # per 10 ms control period: the average forgets in about 0.5 s (50 periods)


@dataclass(frozen=True)
class GateSpec:
    """A gated controller's ``meta.json``: the student's directory and the threshold [m] of the smoothed estimated
    tracking error at which it takes over."""

    student: Path
    threshold_m: float
    env_id: str | None


def is_gated(path: str | Path) -> bool:
    """True if ``path`` is a directory whose ``meta.json`` says ``"kind": "gated"`` (read at most once, bounded)."""
    f = Path(path) / META
    if not f.is_file():
        return False
    try:
        meta = read_json(f)
    except ValueError:
        return False
    return isinstance(meta, dict) and meta.get("kind") == KIND


def read_gate(path: str | Path) -> GateSpec:
    """The :class:`GateSpec` of a gated model directory; ValueError (one line naming the file) if malformed."""
    d = Path(path)
    f = d / META
    meta = read_json(f)
    if not isinstance(meta, dict) or meta.get("kind") != KIND:
        raise ValueError(f"{f}: not a gated controller (expected \"kind\": \"{KIND}\")")
    name = meta.get("student")
    if not isinstance(name, str) or not name or "/" in name or "\\" in name or name in (".", ".."):
        raise ValueError(f"{f}: key 'student' must name a sibling model directory, got {name!r}")
    g = meta.get("threshold_m")
    if isinstance(g, bool) or not isinstance(g, (int, float)) or not math.isfinite(g) or not 0 < g < 1:
        raise ValueError(f"{f}: key 'threshold_m' must be a number in (0, 1) [m], got {g!r}")
    student = d.resolve().parent / name
    if not (student / META).is_file():
        raise ValueError(f"{f}: its student {name!r} is not a model directory beside it ({student})")
    env_id = meta.get("env_id")
    return GateSpec(student, float(g), env_id if isinstance(env_id, str) else None)


class GateState:
    """The smoothed estimated error m [m] and the latch of N robots (the module docstring's gate)."""

    def __init__(self, num: int, threshold_m: float) -> None:
        self.threshold_m = float(threshold_m)
        self.mean_error = np.zeros(num)
        self.latched = np.zeros(num, dtype=bool)

    def reset(self, mask: np.ndarray | None = None) -> None:
        m = slice(None) if mask is None else np.asarray(mask, dtype=bool)
        self.mean_error[m] = 0.0
        self.latched[m] = False

    def update(self, error_xy: np.ndarray) -> np.ndarray:
        """Fold in this period's estimated position errors (N, 2) [m]; the robots the student drives (N,) bool."""
        e = np.hypot(error_xy[:, 0], error_xy[:, 1])
        self.mean_error = (1.0 - GATE_ALPHA) * self.mean_error + GATE_ALPHA * e
        self.latched |= self.mean_error > self.threshold_m
        return self.latched


def _features_wrapper(env):
    """The :class:`agents.wrappers.EKFFeatures` inside ``env``'s wrapper chain (the student's observation)."""
    from agents.wrappers import EKFFeatures

    e = env
    while not isinstance(e, EKFFeatures):
        if not hasattr(e, "env"):
            raise ValueError("a gated controller's student must read the EKF features (wrapper 'ekf-features')")
        e = e.env
    if e.residual_scale != 0.0:
        raise ValueError("a gated controller's student must give the whole action (residual_scale 0), got "
                         f"{e.residual_scale}")
    return e


class GatedPolicy(TrainedPolicy):
    """``ekf-pid`` until the gate opens, then the student (module docstring); one environment.

    Args:
        student: the student (:class:`agents.sb3_policy.SB3Policy`) on its EKF-feature environment ``env``.
        env: that environment; its :class:`agents.wrappers.EKFFeatures` holds ``ekf-pid`` (whose action and PID
            error the gate reads).
        threshold_m: the gate's threshold [m].
    """

    name = "gated"

    def __init__(self, student, env, threshold_m: float) -> None:
        super().__init__(env)
        self.student = student
        self.features = _features_wrapper(env)
        self.gate = GateState(1, threshold_m)

    def reset(self, obs: np.ndarray) -> None:
        self.gate.reset()
        self.student.reset(obs)

    @property
    def student_driving(self) -> bool:
        """True once the gate has opened in this episode."""
        return bool(self.gate.latched[0])

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.gate.update(self.features.base.pid.error[None, :2])[0]:
            return self.student.act(obs)
        return self.features.base_action.astype(np.float32).reshape(self.features.action_space.shape)


class VectorGatedPolicy(TrainedPolicy):
    """:class:`GatedPolicy` for the N robots of a :class:`agents.wrappers.VectorEKFFeatures` vector env."""

    name = "gated"

    def __init__(self, student, venv, threshold_m: float) -> None:
        super().__init__(venv)
        from agents.wrappers import VectorEKFFeatures

        if not isinstance(venv, VectorEKFFeatures) or venv.residual_scale != 0.0:
            raise ValueError("a gated controller's student must read the EKF features and give the whole action")
        self.student = student
        self.gate = GateState(venv.num, threshold_m)

    def reset(self, obs: np.ndarray, mask: np.ndarray | None = None) -> None:
        self.gate.reset(mask)

    def act(self, obs: np.ndarray) -> np.ndarray:
        venv = self.env
        driving = self.gate.update(venv.base.pid.error[:, :2])
        out = venv.base_action.astype(np.float32)  # a copy
        if driving.any():
            out[driving] = np.asarray(self.student.act(obs), dtype=np.float32).reshape(out.shape)[driving]
        return out


def build(path: str | Path, env_id: str | None = None, env_kwargs: dict | None = None, options=None):
    """(wrapped env, :class:`GatedPolicy`) for the gated controller in ``path``."""
    from agents.sb3_policy import build as build_student

    spec = read_gate(path)
    env, student = build_student(spec.student, env_id or spec.env_id, env_kwargs, options)
    try:
        return env, GatedPolicy(student, env, spec.threshold_m)
    except BaseException:
        env.close()
        raise


def build_vector(path: str | Path, num: int, env_id: str | None = None, env_kwargs: dict | None = None,
                 options=None):
    """(vector env, :class:`VectorGatedPolicy`): :func:`build` for ``num`` robots at once."""
    from agents.sb3_policy import build_vector as build_student

    spec = read_gate(path)
    venv, student = build_student(spec.student, num, env_id or spec.env_id, env_kwargs, options)
    try:
        return venv, VectorGatedPolicy(student, venv, spec.threshold_m)
    except BaseException:
        venv.close()
        raise
