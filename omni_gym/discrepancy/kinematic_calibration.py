"""Kinematic odometry calibration: the anchor a dynamic model has to beat (issue 15, item 5).

The classical calibration of a three-wheeled omnidirectional robot (OptiOdom and its predecessors):
dead-reckon every training run from its measured wheel angles with a purely kinematic model whose only
unknowns are the three effective wheel diameters D_i [m] and one common centre-to-wheel distance L [m],
and fit them by least squares against motion capture.

Dead reckoning (:func:`dead_reckon`), per control cycle (t_{k-1}, t_k]:

1. wheel travel Δφ_i = enc_i(t_k) − enc_i(t_{k-1}) [rad] (the dataset's ``enc`` columns);
2. body displacement Δq = (Δx_b, Δy_b, Δθ) by least squares on the wheel geometry, W⁺·Δφ, where row i of
   W is (d_i, d_i·(z × p_i)) / (D_i / 2) (:meth:`omni_gym.physics.robot.RobotSpec.wheel_matrix`), with the
   nominal drive directions d_i and the nominal wheel positions scaled to distance L;
3. exact integration of that twist held constant over the cycle (an arc), from the pose at t_{k-1}.

Every run starts at its start pose (the first row). The cost (:func:`calibrate`) is the pose residual
of :func:`omni_gym.discrepancy.simulate.pose_residual` (x, y and heading × lever [m]) on every observed
row of every training run, minimised with :func:`scipy.optimize.least_squares`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from omni_gym.discrepancy.dataset import Run
from omni_gym.discrepancy.simulate import pose_residual
from omni_gym.discrepancy.synth import pose_lever
from omni_gym.physics import effects as effect_library
from omni_gym.physics.model import SimModel
from omni_gym.physics.robot import Wheel

# Search box around the nominal values (as scales): a factor 1.5 either way is far outside any real
# calibration (a few per cent) yet keeps the model from degenerating (D or L → 0).
_LO, _HI = 1.0 / 1.5, 1.5


@dataclass(frozen=True)
class Geometry:
    """The kinematic model of one calibration: nominal wheel directions, fitted sizes.

    ``units`` (n, 2): unit vectors from the geometric centre towards the wheels (body frame);
    ``drives`` (n, 2): unit drive directions (body frame); ``diameters`` (n,) [m]; ``L`` [m]: every
    wheel sits at L·units_i.
    """

    units: np.ndarray
    drives: np.ndarray
    diameters: np.ndarray
    L: float

    def wheel_matrix(self) -> np.ndarray:
        """W (n×3): body displacement (Δx_b [m], Δy_b [m], Δθ [rad]) → wheel travel [rad]."""
        p = self.L * self.units
        d = self.drives
        lever = d[:, 1] * p[:, 0] - d[:, 0] * p[:, 1]  # d · (z × p)
        return np.column_stack([d[:, 0], d[:, 1], lever]) / (0.5 * self.diameters[:, None])


@dataclass(frozen=True)
class KinematicCalibration:
    """Result of :func:`calibrate`.

    ``diameters`` (n,) [m] effective wheel diameters and ``L`` [m] the common centre-to-wheel distance;
    ``nominal_diameters``, ``nominal_L`` the nominal model's. ``train_position_rms`` [m]: RMS over every
    observed training row of the position error (Euclidean, x and y), ``train_pose_rms`` [m]: RMS of the
    fitted cost's components (x, y, heading × ``lever``); ``nominal_*`` the same with the nominal
    geometry. ``model``: the calibrated :class:`SimModel` (:func:`to_model`); ``nominal``: the model it
    started from. ``runs`` and ``rows``: training runs and observed rows used.
    """

    diameters: np.ndarray
    L: float
    train_position_rms: float
    train_pose_rms: float
    nominal_diameters: np.ndarray
    nominal_L: float
    nominal_position_rms: float
    nominal_pose_rms: float
    lever: float
    runs: int
    rows: int
    nominal: SimModel = field(repr=False)
    model: SimModel = field(repr=False)

    @property
    def geometry(self) -> Geometry:
        """The fitted kinematic model (for :func:`dead_reckon`)."""
        g = nominal_geometry(self.nominal)
        return replace(g, diameters=np.asarray(self.diameters, dtype=float), L=float(self.L))

    def to_json(self) -> dict:
        """Plain numbers (metres) for reports."""
        return {"diameters": [float(v) for v in self.diameters], "L": float(self.L),
                "nominal_diameters": [float(v) for v in self.nominal_diameters], "nominal_L": float(self.nominal_L),
                "train_position_rms": self.train_position_rms, "train_pose_rms": self.train_pose_rms,
                "nominal_position_rms": self.nominal_position_rms, "nominal_pose_rms": self.nominal_pose_rms,
                "lever": self.lever, "runs": self.runs, "rows": self.rows}


def nominal_geometry(model: SimModel) -> Geometry:
    """The kinematic model of ``model``: its wheel directions and drives, effective diameters
    2·r·scale_i (the ``wheel_radius`` effect's scales, if any) and L the mean wheel distance [m].

    Other effects (``wheel_geometry`` included) are not read: the calibration starts from the layout.
    """
    r = model.robot
    pos = r.positions()
    dist = np.hypot(pos[:, 0], pos[:, 1])
    if np.any(dist <= 0):
        raise ValueError(f"model {r.name!r}: a wheel sits at the geometric centre; no distance L to calibrate")
    scale = np.ones(r.n_wheels)
    if "wheel_radius" in model.effects:
        scale = np.asarray(model.effects["wheel_radius"]["scale"], dtype=float)
    L = float(np.mean(dist))
    # Scaling every position by L_new / L keeps wheels that are not on one circle in proportion.
    return Geometry(units=pos / L, drives=r.drives(), diameters=2.0 * r.wheel_radius * scale, L=L)


def _wheel_travel(run: Run) -> np.ndarray:
    """(K−1, n) wheel angle increments [rad] of each cycle, from the run's ``enc`` columns."""
    if run.enc is None:
        raise ValueError(f"run {run.name}: no measured wheel angles (enc columns): kinematic calibration "
                         "dead-reckons from the encoders")
    if not np.all(np.isfinite(run.enc)):
        k = int(np.nonzero(~np.all(np.isfinite(run.enc), axis=1))[0][0])
        raise ValueError(f"run {run.name}: row {k + 2}: empty encoder cell; dead reckoning needs every wheel angle")
    return np.diff(run.enc, axis=0)


def dead_reckon(run: Run, geometry: Geometry) -> np.ndarray:
    """Poses (K, 3) [m, m, rad], world frame, of ``run`` dead-reckoned from its start pose with ``geometry``."""
    return _integrate(_wheel_travel(run), run.start_pose, geometry)


def _integrate(dphi: np.ndarray, start: np.ndarray, geometry: Geometry) -> np.ndarray:
    """Exact integration of a constant body twist over each cycle (an arc), vectorised over cycles."""
    dq = dphi @ np.linalg.pinv(geometry.wheel_matrix()).T  # (K−1, 3) body displacement per cycle
    dth = dq[:, 2]
    theta = start[2] + np.concatenate([[0.0], np.cumsum(dth)])
    # Over an arc the body-frame chord is [[s, −(1−c)], [1−c, s]]/Δθ · (Δx_b, Δy_b); series near Δθ = 0.
    small = np.abs(dth) < 1e-4
    safe = np.where(small, 1.0, dth)
    a = np.where(small, 1.0 - dth**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, dth / 2.0 - dth**3 / 24.0, (1.0 - np.cos(safe)) / safe)
    cx = a * dq[:, 0] - b * dq[:, 1]
    cy = b * dq[:, 0] + a * dq[:, 1]
    c0, s0 = np.cos(theta[:-1]), np.sin(theta[:-1])
    dx = c0 * cx - s0 * cy
    dy = s0 * cx + c0 * cy
    poses = np.empty((len(theta), 3))
    poses[:, 0] = start[0] + np.concatenate([[0.0], np.cumsum(dx)])
    poses[:, 1] = start[1] + np.concatenate([[0.0], np.cumsum(dy)])
    poses[:, 2] = theta
    return poses


def position_rms(measured: np.ndarray, predicted: np.ndarray) -> float:
    """RMS [m] over observed rows of the Euclidean position error (NaN rows of ``measured`` skipped)."""
    ok = np.all(np.isfinite(measured), axis=1)
    e = measured[ok, :2] - predicted[ok, :2]
    return float(math.sqrt(np.mean(np.sum(e**2, axis=1)))) if ok.any() else math.nan


def calibrate(runs: list[Run], nominal: SimModel, lever: float | None = None) -> KinematicCalibration:
    """Fit the n effective wheel diameters and L to ``runs`` (module docstring); start at ``nominal``.

    ``lever`` [m] weighs the heading error as the workflow does (default
    :func:`omni_gym.discrepancy.synth.pose_lever` of the nominal model, held fixed during the fit).
    ValueError (naming the run) if a run has no encoder columns or no observed row after its start.
    """
    from scipy.optimize import least_squares

    if not runs:
        raise ValueError("kinematic calibration: no training runs")
    lever = pose_lever(nominal) if lever is None else float(lever)
    g0 = nominal_geometry(nominal)
    n = len(g0.diameters)
    prepared = []
    for run in runs:
        if run.enc is not None and run.enc.shape[1] != n:
            raise ValueError(f"run {run.name}: {run.enc.shape[1]} encoder columns, the model has {n} wheels")
        obs = run.observed
        obs[0] = False  # the start pose is the integration's initial condition: no information
        if not obs.any():
            raise ValueError(f"run {run.name}: no observed pose after the start: nothing to calibrate against")
        prepared.append((_wheel_travel(run), run.start_pose, run.pose[obs], obs))
    x0 = np.concatenate([g0.diameters, [g0.L]])

    def geometry(x: np.ndarray) -> Geometry:
        return replace(g0, diameters=x[:n], L=float(x[n]))

    def residuals(x: np.ndarray) -> np.ndarray:
        g = geometry(x)
        out = [pose_residual(meas, _integrate(dphi, start, g)[obs], lever).ravel()
               for dphi, start, meas, obs in prepared]
        return np.concatenate(out)

    fit = least_squares(residuals, x0, bounds=(x0 * _LO, x0 * _HI), x_scale=x0, xtol=1e-12, ftol=1e-12)
    if not fit.success:
        raise ValueError(f"kinematic calibration did not converge: {fit.message}")
    x = fit.x

    def rms(xv: np.ndarray) -> tuple[float, float]:
        r = residuals(xv).reshape(-1, 3)
        return float(math.sqrt(np.mean(np.sum(r[:, :2] ** 2, axis=1)))), float(math.sqrt(np.mean(r**2)))

    pos1, pose1 = rms(x)
    pos0, pose0 = rms(x0)
    rows = sum(int(p[3].sum()) for p in prepared)
    diameters = x[:n].copy()
    return KinematicCalibration(
        diameters=diameters, L=float(x[n]), train_position_rms=pos1, train_pose_rms=pose1,
        nominal_diameters=g0.diameters.copy(), nominal_L=g0.L, nominal_position_rms=pos0, nominal_pose_rms=pose0,
        lever=lever, runs=len(runs), rows=rows, nominal=nominal,
        model=calibrated_model(nominal, diameters, float(x[n])))


def calibrated_model(nominal: SimModel, diameters: np.ndarray, L: float) -> SimModel:
    """``nominal`` with the wheel diameters ``diameters`` (n,) [m] and the centre-to-wheel distance ``L`` [m].

    Diameters: a ``wheel_radius`` effect with scales D_i / (2·r_nominal) (replacing any the nominal has).
    L: the ``wheel_geometry`` effect's ``distance`` (L / L_nominal on every wheel, no mount yaw) if the
    effect library has it, otherwise the nominal wheel positions scaled by L / L_nominal.
    """
    g0 = nominal_geometry(nominal)
    r = nominal.robot
    model = nominal.with_effect("wheel_radius",
                                {"scale": [float(d / (2.0 * r.wheel_radius)) for d in np.asarray(diameters)]})
    ratio = float(L / g0.L)
    if "wheel_geometry" in effect_library.REGISTRY and "wheel_geometry" not in nominal.effects:
        effect = effect_library.REGISTRY["wheel_geometry"]
        params: dict = {"distance": [ratio] * r.n_wheels}
        if "mount" in effect.keys:
            params["mount"] = [0.0] * r.n_wheels
        return model.with_effect("wheel_geometry", params)
    wheels = tuple(Wheel(position=(w.position[0] * ratio, w.position[1] * ratio), drive=w.drive) for w in r.wheels)
    return replace(model, robot=r.with_changes(wheels=wheels))


def to_model(result: KinematicCalibration) -> SimModel:
    """The calibrated :class:`SimModel` of ``result`` (the same as ``result.model``)."""
    return calibrated_model(result.nominal, result.diameters, result.L)
