"""The state a run's own data imply at each row: smoothed pose and rate from the tracker, wheel angles.

Where a replay starts from the *measured* state instead of the run's start (a multiple-shooting window of
:mod:`omni_gym.discrepancy.replay.localise` and :mod:`omni_gym.discrepancy.replay.residuals`, a segment of
:mod:`omni_gym.discrepancy.data.segments`), the state comes from here: pose [m, m, rad] and world-frame rate
[m/s, m/s, rad/s] by local quadratic fits to the tracked poses, wheel angles [rad] from the encoders or,
without them, the integrated commands. Data only: nothing is simulated.
"""

from __future__ import annotations

import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.discrepancy.data.dataset import Run


def pose_rate(run: Run, half: int = 5) -> np.ndarray:
    """(K, 3) world-frame rate of the tracked pose [m/s, m/s, rad/s] by local quadratic fits (NaN if too few rows)."""
    return local_pose_fit(run, half)[1]


def local_pose_fit(run: Run, half: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Local quadratic fits to the tracked pose over ±``half`` rows: (K, 3) smoothed pose [m, m, rad]
    (heading wrapped) and (K, 3) world-frame rate [m/s, m/s, rad/s]; NaN where fewer than 4 rows are observed.

    The smoothed pose has about a fifth of the tracker-noise variance of one row (11 rows, quadratic).
    """
    K = len(run.t)
    obs = run.observed
    theta = np.unwrap(np.where(obs, run.pose[:, 2], 0.0))
    pose = np.column_stack([run.pose[:, 0], run.pose[:, 1], theta])
    value = np.full((K, 3), np.nan)
    rate = np.full((K, 3), np.nan)
    for k in range(K):
        lo, hi = max(0, k - half), min(K, k + half + 1)
        idx = np.arange(lo, hi)[obs[lo:hi]]
        if idx.size < 4:
            continue
        tt = run.t[idx] - run.t[k]
        A = np.column_stack([np.ones_like(tt), tt, tt * tt])
        coef = np.linalg.lstsq(A, pose[idx], rcond=None)[0]
        value[k], rate[k] = coef[0], coef[1]
    value[:, 2] = wrap_angle(value[:, 2])
    return value, rate


def wheel_angles(run: Run) -> np.ndarray:
    """(K, n) wheel angles [rad]: encoders if present, else the integrated commands."""
    if run.enc is not None and np.all(np.isfinite(run.enc)):
        return run.enc
    dt = np.diff(run.t)
    return np.vstack([np.zeros(run.cmd.shape[1]), np.cumsum(run.cmd[:-1] * dt[:, None], axis=0)])
