"""The measurement model: what the pose tracker reports for a simulated motion.

The simulator moves the robot's geometric centre; the tracker reports its own body point on its own
clock. The model's tracker effects (``Effect.kind == "tracker"``: ``tracker_offset``, ``time_offset``)
say how the two differ. This module is the one place they are applied: :func:`measured` turns
simulated centre poses into the poses the tracker would report (used by
:func:`omni_gym.discrepancy.replay.simulate.simulate_jobs` for every replay, so every residual of the
workflow compares like with like), and :func:`centre_start` turns a tracked start state into the
centre's (a replay from a measured state: a run's first pose, a segment's or a window's start).
Physics effects pass through both unchanged. :func:`align_to_start_window` estimates a whole run's start pose
from its first tracked rows, not from one noisy row.
"""

from __future__ import annotations

import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.discrepancy.settings import DataSettings
from omni_gym.physics.effects import REGISTRY
from omni_gym.physics.model import SimModel


def _tracker_effects(model: SimModel) -> list[tuple]:
    return [(REGISTRY[name], params) for name, params in model.effects.items() if REGISTRY[name].kind == "tracker"]


def has_tracker_effects(model: SimModel) -> bool:
    """True when ``model`` carries a measurement effect."""
    return bool(_tracker_effects(model))


def measured(model: SimModel, t: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Tracker poses (K, 3) [m, m, rad] for centre poses ``pose`` (K, 3) at times ``t`` (K,) [s]: the time
    offset first (which instant the tracker saw), then the tracked point's offset."""
    effects = _tracker_effects(model)
    # time shift before the body offset: the offset is rigid, it moves with the pose it is attached to
    effects.sort(key=lambda e: 0 if e[0].name == "time_offset" else 1)
    for effect, params in effects:
        pose = effect.measure(params, t, pose)
    return pose


def centre_start(model: SimModel, pose: np.ndarray, velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The geometric centre's pose (3,) and velocity (3,) for a start state measured by the tracker
    (the inverse of :func:`measured`, first order in the time offset)."""
    effects = _tracker_effects(model)
    effects.sort(key=lambda e: 0 if e[0].name == "time_offset" else 1, reverse=True)
    pose, velocity = np.asarray(pose, dtype=float), np.asarray(velocity, dtype=float)
    for effect, params in effects:
        pose, velocity = effect.unmeasure(params, pose, velocity)
    return pose, velocity


def align_start(pose: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``pose`` (K, 3) moved rigidly (rotated about its first row, then translated) so that its first row
    is ``target`` (3,) [m, m, rad]. On a uniform floor the motion is equivariant under such moves."""
    d = float(target[2] - pose[0, 2])
    c, s = np.cos(d), np.sin(d)
    rel = pose[:, :2] - pose[0, :2]
    out = np.empty_like(pose)
    out[:, 0] = target[0] + c * rel[:, 0] - s * rel[:, 1]
    out[:, 1] = target[1] + s * rel[:, 0] + c * rel[:, 1]
    out[:, 2] = pose[:, 2] + d
    return out


START_WINDOW = DataSettings().start_window  # s: the default of align_to_start_window (settings.DataSettings)


def start_window_rows(run_t: np.ndarray, measured_pose: np.ndarray, window: float) -> np.ndarray | None:
    """(K,) mask of the run's tracked rows within its first ``window`` [s] (times ``run_t`` (K,), tracked poses
    ``measured_pose`` (K, 3), NaN where unobserved); None when fewer than two are tracked: too few to align to."""
    rows = np.all(np.isfinite(measured_pose), axis=1) & (run_t - run_t[0] <= window)
    return rows if np.count_nonzero(rows) >= 2 else None


def align_to_start_window(run_t: np.ndarray, measured_pose: np.ndarray, pose: np.ndarray,
                          window: float = START_WINDOW, weight: tuple[float, float] = (1.0, 1.0)) -> np.ndarray:
    """A replay ``pose`` (K, 3) of a whole run, moved rigidly so that it matches the run's tracked rows
    ``measured_pose`` (K, 3, NaN where unobserved) over the first ``window`` [s] on average: rotated about its
    first row by the mean heading difference there, then translated by the mean position difference.

    The replay starts at the tracked start pose, which carries the tracker's noise: a heading error of 2 mrad
    turns the whole replay (2 mm of drift per metre travelled), which would read as a model error. Over the
    first rows the replay has not yet drifted, so their mean difference estimates the start pose's error
    with a row's noise / sqrt(rows) (0.2 s at 100 Hz: 20 rows). On a uniform floor the motion is equivariant
    under a rigid move of its start, so moving the replay is the same as replaying from the moved start.
    ``weight`` (position, heading): the share of each mean difference applied (1: all of it; less when the start
    pose itself is more certain than the window's mean, :mod:`omni_gym.discrepancy.replay.start_trust`).
    Unchanged when fewer than two rows are observed in the window."""
    rows = start_window_rows(run_t, measured_pose, window)
    if rows is None:
        return pose
    dtheta = weight[1] * float(np.mean(wrap_angle(measured_pose[rows, 2] - pose[rows, 2])))
    turned = align_start(pose, np.array([pose[0, 0], pose[0, 1], pose[0, 2] + dtheta]))
    shift = weight[0] * np.mean(measured_pose[rows, :2] - turned[rows, :2], axis=0)
    turned[:, :2] += shift
    return turned
