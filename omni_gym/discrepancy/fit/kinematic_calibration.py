"""Kinematic odometry calibration: the anchor a dynamic model has to beat.

The classical calibration of an OptiOdom robot type, by least squares of dead-reckoned poses against
motion capture:

* ``omni3`` (three omni wheels, OptiOdom's omni3): the three effective wheel diameters D_i [m] and one
  common centre-to-wheel distance L [m];
* ``omni4`` (four mecanum wheels at (±l1/2, ±l2/2), OptiOdom's omni4 after Lin et al., ICCSE 2019): the
  four effective wheel diameters D_i [m] and l1 + l2 [m]. The wheel lengths enter the kinematics only as
  the lever c = (l1 + l2)/2 of every wheel (Δ_i = ±dx ± dy − c·dθ), so only the sum is identified: the
  fit scales l1 and l2 together.

Both are one model: a :class:`Geometry` whose wheel matrix row i is (e_i, e_i·(z × s·p_i)) / (D_i / 2), with
e_i the wheel's rolling direction (r times the first two columns of the robot's no-slip wheel matrix: the
unit drive direction for an omni wheel, d + tan γ·(z × d) for a mecanum wheel of roller angle γ), p_i the
nominal wheel position and s = size / nominal size the one fitted length scale (``size``: L for omni3,
l1 + l2 for omni4).

Dead reckoning (:func:`dead_reckon`), per control cycle (t_{k-1}, t_k]:

1. wheel travel Δφ_i = enc_i(t_k) − enc_i(t_{k-1}) [rad] (the dataset's ``enc`` columns);
2. body displacement Δq = (Δx_b, Δy_b, Δθ) by least squares on the wheel geometry, W⁺·Δφ (for omni4 this is
   the data README's forward kinematics, dx = (Δ1 − Δ2 + Δ3 − Δ4)/4, …);
3. exact integration of that twist held constant over the cycle (an arc), from the pose at t_{k-1}.

Every run starts at its start pose (the first row). The cost (:func:`calibrate`) is the pose residual
of :func:`omni_gym.discrepancy.replay.simulate.pose_residual` (x, y and heading × lever [m]) on every observed
row of every training run, minimised with :func:`scipy.optimize.least_squares`.

With ``tracker=True`` the tracked frame is fitted with the kinematics, over the same whole runs: the
tracked point's offset o [m] (body frame) and the tracked heading's yaw ψ [rad] of the ``tracker_offset``
effect (``omni_gym.physics.effects.tracker_offset``). The centre starts at the tracked start pose moved back
by o and ψ, is dead-reckoned as above, and is compared with the tracker through the same offset: a point
o off the centre moves at v + ω z × o, a frame turned by ψ sees every displacement turned by ψ. Both are
linear in the wheel speeds, which is why a free linear wheel-to-twist map captures them and a calibration
of diameters and size alone cannot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from omni_gym.discrepancy.data.dataset import Run
from omni_gym.discrepancy.data.importers.optiodom import Metadata, layout
from omni_gym.discrepancy.replay.simulate import pose_residual
from omni_gym.physics import effects as effect_library
from omni_gym.physics.model import SimModel

# Search box around the nominal values (as scales): a factor 1.5 either way is far outside any real
# calibration (a few per cent) yet keeps the model from degenerating (D or L → 0).
_LO, _HI = 1.0 / 1.5, 1.5


@dataclass(frozen=True)
class Geometry:
    """The kinematic model of one calibration: nominal wheel layout, fitted sizes.

    ``positions`` (n, 2) [m]: nominal wheel centres (body frame, at ``nominal_size``); ``directions``
    (n, 2): rolling directions e_i (module docstring; unit length for omni wheels, √2 for 45° mecanum
    wheels); ``diameters`` (n,) [m]; ``size`` [m]: the fitted length (``size_name``: ``L`` the
    centre-to-wheel distance for omni wheels, ``l1+l2`` for mecanum wheels); every wheel sits at
    positions_i · size / nominal_size.
    """

    positions: np.ndarray
    directions: np.ndarray
    diameters: np.ndarray
    size: float
    nominal_size: float
    size_name: str = "L"

    @property
    def L(self) -> float:
        """The fitted length [m] (``size``; the name of the omni3 calibration)."""
        return self.size

    def wheel_matrix(self) -> np.ndarray:
        """W (n×3): body displacement (Δx_b [m], Δy_b [m], Δθ [rad]) → wheel travel [rad]."""
        p = self.positions * (self.size / self.nominal_size)
        e = self.directions
        lever = e[:, 1] * p[:, 0] - e[:, 0] * p[:, 1]  # e · (z × p)
        return np.column_stack([e[:, 0], e[:, 1], lever]) / (0.5 * self.diameters[:, None])

    @property
    def reach(self) -> float:
        """Largest nominal wheel-centre distance [m] (the default heading lever of the cost)."""
        return float(np.max(np.hypot(*self.positions.T)))


def layout_geometry(positions, drives, roller_angles, diameters) -> Geometry:
    """A :class:`Geometry` from a wheel layout: positions (n, 2) [m], unit drive directions (n, 2), roller
    angles γ (n,) [rad] (0 for omni wheels) and diameters (n,) [m].

    The rolling direction of a wheel whose rollers sit at γ to its plane is e = d + tan γ·(z × d) (the
    rim speed is e · the wheel-centre velocity; ``docs/model.md``). The size is L (the mean wheel
    distance) if every γ is 0, otherwise l1 + l2 = 2·mean |e·(z × p)| (the mecanum lever c is (l1 + l2)/2).
    """
    p = np.asarray(positions, dtype=float)
    d = np.asarray(drives, dtype=float)
    gamma = np.asarray(roller_angles, dtype=float)
    e = d + np.tan(gamma)[:, None] * np.column_stack([-d[:, 1], d[:, 0]])
    return _geometry(p, e, np.asarray(diameters, dtype=float), mecanum=bool(np.any(gamma != 0)))


def optiodom_geometry(meta: Metadata) -> Geometry:
    """The nominal kinematic model of an OptiOdom session (its metadata, read by
    :func:`omni_gym.discrepancy.data.importers.optiodom.read_metadata`): the layout of its type (as in the
    importer's nominal model) and the metadata's diameters. Pure kinematics: it needs no physics (an omni4
    geometry exists even where :func:`~omni_gym.discrepancy.data.importers.optiodom.nominal_model` refuses)."""
    wheels = layout(meta)
    return layout_geometry([w["position"] for w in wheels], [w["drive"] for w in wheels],
                           [w.get("roller_angle", 0.0) for w in wheels], meta.D)


def _geometry(p: np.ndarray, e: np.ndarray, diameters: np.ndarray, mecanum: bool) -> Geometry:
    dist = np.hypot(p[:, 0], p[:, 1])
    if np.any(dist <= 0):
        raise ValueError("a wheel sits at the geometric centre; no length to calibrate")
    if mecanum:
        size = 2.0 * float(np.mean(np.abs(e[:, 1] * p[:, 0] - e[:, 0] * p[:, 1])))
        name = "l1+l2"
    else:
        size, name = float(np.mean(dist)), "L"
    return Geometry(positions=p, directions=e, diameters=diameters, size=size, nominal_size=size, size_name=name)


@dataclass(frozen=True)
class KinematicCalibration:
    """Result of :func:`calibrate`.

    ``diameters`` (n,) [m] effective wheel diameters and ``L`` [m] the fitted length (``size_name``: ``L``
    the common centre-to-wheel distance for omni3, ``l1+l2`` for omni4); ``nominal_diameters``,
    ``nominal_L`` the nominal model's; ``tracker``: the fitted ``tracker_offset`` parameters (``offset`` [m],
    body frame; ``yaw`` [rad], counter-clockwise) or None. ``train_position_rms`` [m]: RMS over every observed
    training row of the position error (Euclidean, x and y), ``train_pose_rms`` [m]: RMS of the fitted cost's components
    (x, y, heading × ``lever``); ``nominal_*`` the same with the nominal geometry. ``model``: the
    calibrated :class:`SimModel` (:func:`to_model`); ``nominal``: the model it started from (both None when
    calibrated from a bare :class:`Geometry`). ``runs`` and ``rows``: training runs and observed rows used.
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
    nominal: SimModel | None = field(repr=False)
    model: SimModel | None = field(repr=False)
    start: Geometry = field(repr=False)
    tracker: dict | None = None  # fitted tracker_offset parameters (offset [m] (2,), yaw [rad]); None: not fitted

    @property
    def size_name(self) -> str:
        """What ``L`` is: ``L`` (omni3) or ``l1+l2`` (omni4)."""
        return self.start.size_name

    @property
    def geometry(self) -> Geometry:
        """The fitted kinematic model (for :func:`dead_reckon`)."""
        return replace(self.start, diameters=np.asarray(self.diameters, dtype=float), size=float(self.L))

    def to_json(self) -> dict:
        """Plain numbers (metres) for reports."""
        return {"diameters": [float(v) for v in self.diameters], "L": float(self.L), "size_name": self.size_name,
                "nominal_diameters": [float(v) for v in self.nominal_diameters], "nominal_L": float(self.nominal_L),
                "train_position_rms": self.train_position_rms, "train_pose_rms": self.train_pose_rms,
                "nominal_position_rms": self.nominal_position_rms, "nominal_pose_rms": self.nominal_pose_rms,
                "lever": self.lever, "runs": self.runs, "rows": self.rows,
                **({"tracker": self.tracker} if self.tracker is not None else {})}

    def predict(self, run: Run) -> np.ndarray:
        """Poses (K, 3) the tracker would report for ``run`` dead-reckoned with the fitted geometry from its
        start pose (through the fitted tracked frame, if any)."""
        return predict_tracked(wheel_travel(run), run.start_pose, self.geometry, self.tracker)


def _is_mecanum(model: SimModel) -> bool:
    return any(getattr(w, "roller_angle", 0.0) != 0.0 for w in model.robot.wheels)


def nominal_geometry(model: SimModel) -> Geometry:
    """The kinematic model of ``model``: its wheel positions, rolling directions (r times the first two
    columns of its no-slip wheel matrix), effective diameters 2·r·scale_i (the ``wheel_radius`` effect's
    scales, if any) and the size L (omni wheels: mean wheel distance) or l1 + l2 (mecanum wheels).

    Other effects (``wheel_geometry`` included) are not read: the calibration starts from the layout.
    """
    r = model.robot
    scale = np.ones(r.n_wheels)
    if "wheel_radius" in model.effects:
        scale = np.asarray(model.effects["wheel_radius"]["scale"], dtype=float)
    e = r.wheel_matrix()[:, :2] * r.wheel_radius
    try:
        return _geometry(r.positions(), e, 2.0 * r.wheel_radius * scale, _is_mecanum(model))
    except ValueError as exc:
        raise ValueError(f"model {r.name!r}: {exc}") from None


def wheel_travel(run: Run) -> np.ndarray:
    """(K−1, n) wheel angle increments [rad] of each cycle, from the run's ``enc`` columns."""
    if run.enc is None:
        raise ValueError(f"run {run.name}: no measured wheel angles (enc columns): kinematic calibration "
                         "dead-reckons from the encoders")
    if not np.all(np.isfinite(run.enc)):
        k = int(np.nonzero(~np.all(np.isfinite(run.enc), axis=1))[0][0])
        raise ValueError(f"run {run.name}: row {k + 2}: empty encoder cell; dead reckoning needs every wheel angle")
    return np.diff(run.enc, axis=0)


def dead_reckon(run: Run, geometry: Geometry, start: np.ndarray | None = None) -> np.ndarray:
    """Poses (K, 3) [m, m, rad], world frame, of ``run`` dead-reckoned with ``geometry`` from ``start`` (None:
    the run's start pose, :attr:`Run.start_pose`)."""
    return _integrate(wheel_travel(run), run.start_pose if start is None else start, geometry)


def _integrate(dphi: np.ndarray, start: np.ndarray, geometry: Geometry) -> np.ndarray:
    """Dead reckoning with ``geometry``: wheel travel (K−1, n) [rad] to poses (K, 3) from ``start``."""
    return integrate_twist(dphi @ np.linalg.pinv(geometry.wheel_matrix()).T, start)


def integrate_twist(dq: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Poses (K, 3) [m, m, rad], world frame, from body displacements ``dq`` (K−1, 3) [m, m, rad] per cycle
    held constant over each cycle (an arc: exact integration, vectorised over cycles) from ``start``."""
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


def predict_tracked(dphi: np.ndarray, start: np.ndarray, geometry: Geometry, tracker: dict | None) -> np.ndarray:
    """Tracked poses (K, 3) from wheel travel (K−1, n) [rad] and the tracked start pose ``start`` (3,):
    dead reckoning of the centre with ``geometry``, through the tracked frame ``tracker`` (``offset`` [m],
    ``yaw`` [rad]; None: the tracker sees the centre)."""
    if tracker is None:
        return _integrate(dphi, start, geometry)
    frame = effect_library.REGISTRY["tracker_offset"]  # the effect's own measurement and its inverse
    centre, _ = frame.unmeasure(tracker, np.asarray(start, dtype=float), np.zeros(3))
    return frame.measure(tracker, None, _integrate(dphi, centre, geometry))


def position_rms(measured: np.ndarray, predicted: np.ndarray) -> float:
    """RMS [m] over observed rows of the Euclidean position error (NaN rows of ``measured`` skipped)."""
    ok = np.all(np.isfinite(measured), axis=1)
    e = measured[ok, :2] - predicted[ok, :2]
    return float(math.sqrt(np.mean(np.sum(e**2, axis=1)))) if ok.any() else math.nan


def prepare_runs(runs: list[Run], n: int, purpose: str) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Per run, what a whole-run dead-reckoning fit needs: (wheel travel (K−1, n) [rad], start pose (3,),
    tracked poses (M, 3) of the observed rows after the first, the (K,) mask of those rows). ValueError naming
    the run for a wrong encoder count, no encoders, or no observed row after the start (nothing to
    ``purpose`` against)."""
    prepared = []
    for run in runs:
        if run.enc is not None and run.enc.shape[1] != n:
            raise ValueError(f"run {run.name}: {run.enc.shape[1]} encoder columns, the model has {n} wheels")
        obs = run.observed
        obs[0] = False  # the start pose is the integration's initial condition: no information
        if not obs.any():
            raise ValueError(f"run {run.name}: no observed pose after the start: nothing to {purpose} against")
        prepared.append((wheel_travel(run), run.start_pose, run.pose[obs], obs))
    return prepared


# Search box of the tracked frame (tracker=True): the tracked point within one wheel-centre distance of the
# centre (the tracker_offset effect's fit box), the frame within ±0.2 rad (about 11°).
_TRACKER_YAW = 0.2


def calibrate(runs: list[Run], nominal: SimModel | Geometry, lever: float | None = None,
              tracker: bool = False) -> KinematicCalibration:
    """Fit the n effective wheel diameters and the length (L or l1 + l2) to ``runs`` (module docstring);
    start at ``nominal`` (a model, or a bare :class:`Geometry`: then the result has no ``model``).
    ``tracker``: also fit the tracked frame (offset, yaw) jointly (module docstring); the model then
    carries a ``tracker_offset`` effect.

    ``lever`` [m] weighs the heading error as the workflow does (default: the largest nominal wheel-centre
    distance, :func:`omni_gym.discrepancy.synthetic.synth.pose_lever`, held fixed during the fit).
    ValueError (naming the run) if a run has no encoder columns or no observed row after its start.
    """
    from scipy.optimize import least_squares

    if not runs:
        raise ValueError("kinematic calibration: no training runs")
    g0 = nominal if isinstance(nominal, Geometry) else nominal_geometry(nominal)
    lever = g0.reach if lever is None else float(lever)
    n = len(g0.diameters)
    prepared = prepare_runs(runs, n, "calibrate")
    x0 = np.concatenate([g0.diameters, [g0.size]])
    lo, hi, scale = x0 * _LO, x0 * _HI, x0.copy()
    if tracker:
        reach = g0.reach
        x0 = np.concatenate([x0, [0.0, 0.0, 0.0]])
        lo = np.concatenate([lo, [-reach, -reach, -_TRACKER_YAW]])
        hi = np.concatenate([hi, [reach, reach, _TRACKER_YAW]])
        scale = np.concatenate([scale, [0.1 * reach, 0.1 * reach, 0.05]])

    def geometry(x: np.ndarray) -> Geometry:
        return replace(g0, diameters=x[:n], size=float(x[n]))

    def frame(x: np.ndarray) -> dict | None:
        return {"offset": [float(x[n + 1]), float(x[n + 2])], "yaw": float(x[n + 3])} if tracker else None

    def residuals(x: np.ndarray) -> np.ndarray:
        g, f = geometry(x), frame(x)
        out = [pose_residual(meas, predict_tracked(dphi, start, g, f)[obs], lever).ravel()
               for dphi, start, meas, obs in prepared]
        return np.concatenate(out)

    fit = least_squares(residuals, x0, bounds=(lo, hi), x_scale=scale, xtol=1e-12, ftol=1e-12)
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
    model = None
    if isinstance(nominal, SimModel):
        model = calibrated_model(nominal, diameters, float(x[n]), frame(x))
    return KinematicCalibration(
        diameters=diameters, L=float(x[n]), train_position_rms=pos1, train_pose_rms=pose1,
        nominal_diameters=g0.diameters.copy(), nominal_L=g0.size, nominal_position_rms=pos0, nominal_pose_rms=pose0,
        lever=lever, runs=len(runs), rows=rows, nominal=nominal if isinstance(nominal, SimModel) else None,
        model=model, start=g0, tracker=frame(x))


# A fitted value this close (relative to the bound) to its search bound is "at the bound": least squares
# stops on an active bound within about 1e-10; the real calibrations stay 3-6 % from nominal, far inside.
AT_BOUND = 1e-3


def values_at_bounds(cal: KinematicCalibration) -> list[str]:
    """The fitted values of ``cal`` that sit at their search bound (:data:`AT_BOUND`), each as text
    (``D3 = 40.00 mm at its lower bound (nominal 60.00 / 1.5)``); [] when none does. A value at its bound
    is where the optimiser was stopped, not an answer: the kinematic model cannot explain the runs."""
    g0 = cal.start
    nominal = np.concatenate([g0.diameters, [g0.size]])
    names = [f"D{i + 1}" for i in range(len(g0.diameters))] + [cal.size_name]
    out = []
    for name, value, nom in zip(names, np.concatenate([cal.diameters, [cal.L]]), nominal, strict=True):
        for bound, side, how in ((nom * _LO, "lower", "/ 1.5"), (nom * _HI, "upper", "× 1.5")):
            if abs(value - bound) <= AT_BOUND * abs(bound):
                out.append(f"{name} = {1e3 * value:.2f} mm at its {side} bound (nominal {1e3 * nom:.2f} {how})")
    if cal.tracker is not None:
        reach = g0.reach
        for name, value in zip(("offset x", "offset y"), cal.tracker["offset"], strict=True):
            if abs(abs(value) - reach) <= AT_BOUND * reach:
                out.append(f"tracker {name} = {1e3 * value:.2f} mm at its bound ±{1e3 * reach:.2f} (the wheels' reach)")
        if abs(abs(cal.tracker["yaw"]) - _TRACKER_YAW) <= AT_BOUND * _TRACKER_YAW:
            out.append(f"tracker yaw = {1e3 * cal.tracker['yaw']:.1f} mrad at its bound ±{1e3 * _TRACKER_YAW:.0f}")
    return out


def calibrated_model(nominal: SimModel, diameters: np.ndarray, L: float, tracker: dict | None = None) -> SimModel:
    """``nominal`` with the wheel diameters ``diameters`` (n,) [m] and the length ``L`` [m] (omni wheels: the
    centre-to-wheel distance; mecanum wheels: l1 + l2, see :func:`nominal_geometry`), and the tracked frame
    ``tracker`` as a ``tracker_offset`` effect (None: the nominal's tracker effects, if any, kept).

    Diameters: a ``wheel_radius`` effect with scales D_i / (2·r_nominal) (replacing any the nominal has).
    Length: omni wheels: the ``wheel_geometry`` effect's ``distance`` (L / L_nominal on every wheel, no
    mount yaw) if the effect library has it; otherwise, and always for mecanum wheels (whose lengths the
    calibration scales together, as that effect would), the nominal wheel positions scaled by the ratio.
    """
    if tracker is not None:
        nominal = nominal.with_effect("tracker_offset", {"offset": list(tracker["offset"]), "yaw": tracker["yaw"]})
    g0 = nominal_geometry(nominal)
    r = nominal.robot
    model = nominal.with_effect("wheel_radius",
                                {"scale": [float(d / (2.0 * r.wheel_radius)) for d in np.asarray(diameters)]})
    ratio = float(L / g0.size)
    if (not _is_mecanum(nominal) and "wheel_geometry" in effect_library.REGISTRY
            and "wheel_geometry" not in nominal.effects):
        effect = effect_library.REGISTRY["wheel_geometry"]
        params: dict = {"distance": [ratio] * r.n_wheels}
        if "mount" in effect.keys:
            params["mount"] = [0.0] * r.n_wheels
        return model.with_effect("wheel_geometry", params)
    # replace(): a wheel keeps its drive and any other attribute (a mecanum wheel's roller angle)
    wheels = tuple(replace(w, position=(w.position[0] * ratio, w.position[1] * ratio)) for w in r.wheels)
    return replace(model, robot=r.with_changes(wheels=wheels))


def to_model(result: KinematicCalibration) -> SimModel:
    """The calibrated :class:`SimModel` of ``result`` (the same as ``result.model``); ValueError if it was
    calibrated from a bare :class:`Geometry`."""
    if result.nominal is None:
        raise ValueError("this calibration started from a bare geometry: it has no model")
    return calibrated_model(result.nominal, result.diameters, result.L, result.tracker)
