"""A linear wheel-to-twist map: the best a purely kinematic description of the robot can do.

The kinematic calibration (:mod:`~omni_gym.discrepancy.fit.kinematic_calibration`) keeps the wheel layout
and fits n + 1 sizes. A linear map drops the layout: the body displacement per control cycle is
Δq = A·Δφ with A a free 3 × n matrix [m/rad, m/rad, rad/rad] (9 numbers for three wheels, 12 for four),
fitted by the same whole-run least squares (dead-reckoned poses against the tracker, the heading weighted
by the robot's reach). It can express what the calibration cannot: a tracked frame rotated from the wheel
frame, a skew or a coupling of the axes (y moving with x), a yaw rate that depends on the direction of
travel. It is a baseline, not a model: it predicts a run from its wheel encoders alone, with no dynamics,
so a physical model that does not beat it on runs it never saw has not yet explained what a matrix can.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.data.dataset import Run
from omni_gym.discrepancy.fit.kinematic_calibration import (
    Geometry,
    integrate_twist,
    nominal_geometry,
    prepare_runs,
    wheel_travel,
)
from omni_gym.discrepancy.replay.simulate import pose_residual
from omni_gym.physics.model import SimModel


@dataclass(frozen=True)
class LinearMap:
    """A fitted wheel-to-twist map: ``matrix`` (3, n): body displacement (x, y [m], heading [rad]) per
    radian of each wheel's travel; ``runs`` and ``rows`` fitted; ``train_position_rms`` [m] on them, and
    ``start_position_rms`` [m] of the map it started from (the nominal kinematics)."""

    matrix: np.ndarray
    runs: int
    rows: int
    train_position_rms: float
    start_position_rms: float

    def predict(self, run: Run) -> np.ndarray:
        """Poses (K, 3) [m, m, rad], world frame, of ``run`` dead-reckoned with the map from its start pose."""
        if run.enc is not None and run.enc.shape[1] != self.matrix.shape[1]:
            raise ValueError(f"run {run.name}: {run.enc.shape[1]} encoder columns, the linear map has "
                             f"{self.matrix.shape[1]} wheels")
        return integrate_twist(wheel_travel(run) @ self.matrix.T, run.start_pose)

    def to_json(self) -> dict:
        return {"matrix": self.matrix.tolist(), "runs": self.runs, "rows": self.rows,
                "train_position_rms": self.train_position_rms, "start_position_rms": self.start_position_rms}


def fit_linear_map(runs: list[Run], nominal: SimModel | Geometry, lever: float | None = None) -> LinearMap:
    """Fit the 3 × n map to ``runs`` (every observed row after each start), starting from the nominal
    kinematics (the pseudo-inverse of ``nominal``'s wheel matrix). ``lever`` [m] weighs the heading as
    :func:`~omni_gym.discrepancy.fit.kinematic_calibration.calibrate` does (default: the robot's reach).
    ValueError (naming the run) for a run without encoder columns or without an observed row."""
    from scipy.optimize import least_squares

    if not runs:
        raise ValueError("linear map: no training runs")
    g0 = nominal if isinstance(nominal, Geometry) else nominal_geometry(nominal)
    lever = g0.reach if lever is None else float(lever)
    a0 = np.linalg.pinv(g0.wheel_matrix())  # (3, n)
    n = a0.shape[1]
    prepared = prepare_runs(runs, n, "fit")
    scale = np.maximum(np.abs(a0), np.max(np.abs(a0)) * 1e-2).ravel()  # entries near 0 still move

    def residuals(x: np.ndarray) -> np.ndarray:
        a = x.reshape(3, n)
        return np.concatenate([pose_residual(meas, integrate_twist(dphi @ a.T, start)[obs], lever).ravel()
                               for dphi, start, meas, obs in prepared])

    def pos_rms(a: np.ndarray) -> float:
        r = residuals(a.ravel()).reshape(-1, 3)
        return float(math.sqrt(np.mean(np.sum(r[:, :2] ** 2, axis=1))))

    fit = least_squares(residuals, a0.ravel(), x_scale=scale, xtol=1e-12, ftol=1e-12)
    if not fit.success:
        raise ValueError(f"linear map fit did not converge: {fit.message}")
    a = fit.x.reshape(3, n)
    return LinearMap(matrix=a, runs=len(runs), rows=sum(int(p[3].sum()) for p in prepared),
                     train_position_rms=pos_rms(a), start_position_rms=pos_rms(a0))

