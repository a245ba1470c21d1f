"""How much a whole run's replay trusts its tracked start pose against its first tracked rows.

A replay from rest starts at the run's tracked start pose (:attr:`~omni_gym.discrepancy.data.dataset.Run.start_pose`).
If that pose carries tracker noise, a heading error of a few mrad turns the whole replay and reads as a model
error; the mean offset of the replay from the tracked rows over the first ``window`` seconds
(:func:`~omni_gym.discrepancy.replay.measurement.align_to_start_window`) estimates that error with a row's noise
/ sqrt(rows). If the start pose is exact (a generator that writes the true first pose, or a run with a long rest
before it moves), moving the replay by that noisy mean adds error instead: with 3 mm and 20 mrad of tracker
noise, 20 rows leave about 4.5 mrad of heading error, several mm over a 2.5 s run, enough to hide a 3 %
wheel-size error (measured: the recovery sweeps named ``wheel_liftoff`` or ``unexplained`` instead).

Neither case can be told from one run, but the runs of a dataset share their tracker. Over the runs, the
window offsets d_r of the model's replays from the start pose satisfy E[d_r²] = s² + σ²/n_r (s² the start pose's
error variance, σ² a row's tracker noise variance, n_r the window's tracked rows), so

    ŝ² = max(0, mean_r(d_r² − σ²/n_r)),   w_r = ŝ² / (ŝ² + σ²/n_r),

and the replay moves by w_r·d_r: the minimum-variance combination of the two estimates of the start (a
shrinkage, as in empirical Bayes). Noisy first rows give w ≈ n/(n+1) (the whole offset); exact ones w ≈ 0.
Position (x and y pooled) and heading get their own ŝ² and weights. σ² per channel comes from the residuals'
second differences (:func:`~omni_gym.discrepancy.replay.residuals.channel_noise`), which an offset or a slow
drift does not touch.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.discrepancy.data.dataset import Dataset
from omni_gym.discrepancy.replay.measurement import start_window_rows
from omni_gym.discrepancy.replay.residuals import channel_noise
from omni_gym.discrepancy.replay.simulate import FIT_DT, Job, pose_residual, simulate_poses


@dataclass(frozen=True)
class StartTrust:
    """The dataset's start-pose error and the per-run alignment weights (module docstring).

    ``start_position`` [m]: ŝ of the start pose's position (per axis); ``start_heading`` [rad]: ŝ of its heading;
    ``row_position`` [m], ``row_heading`` [rad]: a tracked row's noise σ; ``weights``: run name → (position,
    heading) share of the window offset its replay is moved by (0-1)."""

    window: float
    start_position: float
    start_heading: float
    row_position: float
    row_heading: float
    weights: dict[str, tuple[float, float]]

    def to_json(self) -> dict:
        w = np.array(list(self.weights.values()))  # never empty: estimate_start_trust returns None instead
        return {"window_s": self.window, "start_position_m": self.start_position,
                "start_heading_rad": self.start_heading, "row_position_m": self.row_position,
                "row_heading_rad": self.row_heading,
                "weight_position_mean": float(w[:, 0].mean()), "weight_heading_mean": float(w[:, 1].mean()),
                "note": "each whole-run replay is moved by weight x its mean offset from the tracked rows over the "
                        "first window_s: weight = s^2 / (s^2 + row^2 / rows), s the start pose's error estimated "
                        "over the runs (replay.start_trust)"}


def _shrink(d2: np.ndarray, noise_var: np.ndarray) -> tuple[float, np.ndarray]:
    """ŝ² from the squared window offsets ``d2`` and their noise variances ``noise_var`` (per run), and the
    per-run weights ŝ² / (ŝ² + noise_var)."""
    s2 = max(0.0, float(np.mean(d2 - noise_var)))
    return s2, s2 / np.maximum(s2 + noise_var, 1e-300)


def estimate_start_trust(ds: Dataset, window: float, dt: float = FIT_DT) -> StartTrust | None:
    """The start trust of ``ds``'s whole runs from rest, replayed by the dataset's model (one simulation per
    run). None when the tracker noise cannot be estimated or no run has two tracked rows in the window (the
    replays are then aligned in full, as without this estimate)."""
    runs = [r for r in ds.runs if r.state0 is None]
    if not runs:
        return None
    poses = simulate_poses([Job(ds.model, r) for r in runs], dt=dt, start_window=None)
    lever = ds.model.robot.lever()
    ch = channel_noise([pose_residual(r.pose, p, lever) for r, p in zip(runs, poses, strict=True)],
                       [r.t for r in runs])
    if ch is None:
        return None
    var_pos = float(ch[0] + ch[1]) / 2.0  # m², per axis
    var_head = float(ch[2]) / lever**2  # rad²
    names, n, dpos2, dhead2 = [], [], [], []
    for r, p in zip(runs, poses, strict=True):
        rows = start_window_rows(r.t, r.pose, window)
        if rows is None:
            continue
        names.append(r.name)
        n.append(int(np.count_nonzero(rows)))
        dpos2.append(float(np.mean(np.mean(r.pose[rows, :2] - p[rows, :2], axis=0) ** 2)))
        dhead2.append(float(np.mean(wrap_angle(r.pose[rows, 2] - p[rows, 2]))) ** 2)
    if not names:
        return None
    n_arr = np.array(n, dtype=float)
    s2_pos, w_pos = _shrink(np.array(dpos2), var_pos / n_arr)
    s2_head, w_head = _shrink(np.array(dhead2), var_head / n_arr)
    weights = {name: (float(a), float(b)) for name, a, b in zip(names, w_pos, w_head, strict=True)}
    return StartTrust(window, float(np.sqrt(s2_pos)), float(np.sqrt(s2_head)), float(np.sqrt(var_pos)),
                      float(np.sqrt(var_head)), weights)


def with_start_trust(ds: Dataset, trust: StartTrust | None) -> Dataset:
    """``ds`` with each run's :attr:`~omni_gym.discrepancy.data.dataset.Run.start_weight` from ``trust`` (runs it
    has no weight for, and every run when ``trust`` is None, keep theirs)."""
    if trust is None:
        return ds
    runs = [replace(r, start_weight=trust.weights[r.name]) if r.name in trust.weights else r for r in ds.runs]
    return replace(ds, runs=runs)
