"""``omni-gym calibrate DATASET --out model.json``: kinematic odometry calibration of an imported dataset.

Fits the effective wheel diameters and the robot's length (omni wheels: the centre-to-wheel distance L;
mecanum wheels: l1 + l2), with ``--tracker`` also the tracked frame (the tracked point's offset from the
centre and the frame's yaw, a ``tracker_offset`` effect in the written model), by least squares of the
runs' dead reckoning against their tracked poses (:mod:`omni_gym.discrepancy.fit.kinematic_calibration`),
and writes the dataset's nominal model with the
fitted values as a model JSON (``docs/formats.md``) that ``score``, ``simulate``, ``gap``-free use and
``gym.make(..., model=...)`` read. It needs wheel odometry: every run must have the ``enc1 … encn``
columns (an imported OptiOdom dataset has them).

The output file is complete or absent (:class:`omni_gym.outputs.Output`): an existing file is refused
without ``force``, the dataset folder itself never.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omni_gym.discrepancy.data.dataset import Run, load_dataset
from omni_gym.discrepancy.fit.kinematic_calibration import (
    KinematicCalibration,
    calibrate,
    dead_reckon,
    nominal_geometry,
    position_rms,
    predict_tracked,
    values_at_bounds,
    wheel_travel,
)
from omni_gym.outputs import Output, write_json_atomic


@dataclass(frozen=True)
class SessionCheck:
    """One recording session held out: the calibration fitted on the other sessions' runs, scored on this
    session's by whole-run dead reckoning from each start pose (mean over its runs of the position RMS [m]
    against the tracker), beside the nominal geometry's."""

    session: str
    runs: int
    nominal_rms: float
    calibrated_rms: float


def session_checks(runs: list[Run], model, tracker: bool) -> list[SessionCheck]:
    """Leave-one-session-out check of the calibration (runs grouped by ``Run.session``); [] when the runs do
    not come from at least two recorded sessions (then nothing here is held out)."""
    sessions = sorted({r.session for r in runs if r.session is not None})
    if len(sessions) < 2 or any(r.session is None for r in runs):
        return []
    nominal = nominal_geometry(model)
    out = []
    for s in sessions:
        held = [r for r in runs if r.session == s]
        fit = calibrate([r for r in runs if r.session != s], model, tracker=tracker)
        nom = float(np.mean([position_rms(r.pose, dead_reckon(r, nominal)) for r in held]))
        cal = float(np.mean([position_rms(r.pose, fit.predict(r)) for r in held]))
        out.append(SessionCheck(s, len(held), nom, cal))
    return out


# --- What calibrate refuses to write: values that are not an answer --------------------------------------
# Dead reckoning is restarted from the tracked pose every RESIDUAL_WINDOW seconds and its position error at the
# window's end is compared with what noise and an honest kinematic model leave: NOISE_FLOOR times the noise of
# that error (2σ: two noisy tracked positions, σ per axis measured from the data, :func:`tracker_noise`) plus
# RESIDUAL_SHARE of the window's tracked travel. The tracker noise alone is no bar: the shipped OptiOdom sessions'
# 1 s errors after calibration are 9-79 times their noise (1.7-18 mm against 0.2-0.36 mm: drift, the tracked
# frame), as are slipping robots' (30-45 times); relative to the travel they are 3-17 % on the shipped sessions,
# against 31 % (the omni3 on carpet) and 58 % (the Williams robot) on synthetic slipping robots, so 25 % parts them.
RESIDUAL_WINDOW = 1.0  # s
RESIDUAL_SHARE = 0.25  # of the tracked travel in a window
NOISE_FLOOR = 3.0  # times the noise of a window's end-point error (a still robot is never refused for noise)


def tracker_noise(runs: list[Run]) -> float:
    """Tracker noise σ [m] per axis, measured from the runs: the robust spread (median |·| / 0.6745) of the second
    differences of three consecutive observed positions, over √6 (white noise σ gives them variance 6σ²). The
    robot's own acceleration adds a·dt², so this bounds the noise from above (0.2-0.36 mm on the shipped OptiOdom
    sessions; 1.00 mm measured on ``synth --noise 0.001``)."""
    d2 = []
    for run in runs:
        p = run.pose[:, :2]
        ok = np.all(np.isfinite(p), axis=1)
        three = ok[2:] & ok[1:-1] & ok[:-2]
        d2.append((p[2:] - 2.0 * p[1:-1] + p[:-2])[three].ravel())
    d = np.concatenate(d2) if d2 else np.zeros(0)
    return float(np.median(np.abs(d)) / 0.6745 / np.sqrt(6.0)) if d.size else 0.0


def window_residual(runs: list[Run], cal: KinematicCalibration) -> tuple[float, float]:
    """(RMS [m] of the position error at the end of each :data:`RESIDUAL_WINDOW`, mean tracked travel [m] of a
    window): dead reckoning with the fitted geometry (through the fitted tracked frame) restarted from the
    tracked pose at each window's start."""
    errors, travels = [], []
    for run in runs:
        dphi = wheel_travel(run)
        seen = np.nonzero(np.all(np.isfinite(run.pose), axis=1))[0]
        starts = [int(seen[0])] if seen.size else []
        for k in seen[1:]:
            if run.t[k] - run.t[starts[-1]] >= RESIDUAL_WINDOW:
                starts.append(int(k))
        for a, b in zip(starts[:-1], starts[1:], strict=True):
            end = predict_tracked(dphi[a:b], run.pose[a], cal.geometry, cal.tracker)[-1]
            errors.append(float(np.hypot(*(end[:2] - run.pose[b, :2]))))
            travels.append(float(np.hypot(*(run.pose[b, :2] - run.pose[a, :2]))))
    if not errors:
        return 0.0, 0.0
    return float(np.sqrt(np.mean(np.square(errors)))), float(np.mean(travels))


def frozen_encoders(runs: list[Run]) -> list[str]:
    """Wheels whose encoder never changes while the other wheels turn and the robot moves (a dead encoder or an
    unplugged cable: dead reckoning then has a wheel standing still), as text naming the wheel."""
    turned = sum(np.sum(np.abs(np.diff(r.enc, axis=0)), axis=0) for r in runs)
    moved = sum(float(np.nansum(np.hypot(*np.diff(r.pose[:, :2], axis=0).T))) for r in runs)
    if moved < 0.05 or np.max(turned) <= 0:  # 5 cm: too little motion to tell (units.MIN_MOTION)
        return []
    return [f"enc{i + 1} never changes while the other wheels turn ({np.max(turned):.3g} rad) and the robot moves "
            f"{moved:.2f} m (a frozen encoder)" for i in np.nonzero(turned <= 1e-9 * np.max(turned))[0]]


def refusals(runs: list[Run], cal: KinematicCalibration) -> list[str]:
    """Why ``cal`` is no answer (empty if it is one): values at their search bounds
    (:func:`~omni_gym.discrepancy.fit.kinematic_calibration.values_at_bounds`) and a dead-reckoning residual far
    above noise and modelling (:data:`RESIDUAL_SHARE`)."""
    out = values_at_bounds(cal)
    sigma = tracker_noise(runs)
    rms, travel = window_residual(runs, cal)
    allowed = NOISE_FLOOR * 2.0 * sigma + RESIDUAL_SHARE * travel
    if rms > allowed:
        out.append(f"after the fit dead reckoning is still {1e3 * rms:.1f} mm off over {RESIDUAL_WINDOW:g} s windows "
                   f"(tracker noise {1e3 * sigma:.2f} mm, travel {1e3 * travel:.0f} mm a window; at most "
                   f"{1e3 * allowed:.1f} mm expected)")
    return out


def calibrate_dataset(dataset: str | Path, out: str | Path, force: bool = False,
                      tracker: bool = False) -> tuple[KinematicCalibration, list[SessionCheck]]:
    """Calibrate the nominal model of ``dataset`` on all its runs and write the result to ``out`` [JSON];
    ``tracker``: fit the tracked frame (offset, yaw) jointly, written as a ``tracker_offset`` effect.
    Returns the calibration and, for a dataset of two or more recorded sessions, each session held out
    (:func:`session_checks`).

    ValueError (one line, naming the dataset and the run) for a dataset without wheel odometry, with a frozen
    encoder (:func:`frozen_encoders`), or whose calibration is no answer (:func:`refusals`: values at their
    bounds, a residual far above noise; nothing is written and the line points to ``omni-gym gap``); an
    :class:`omni_gym.outputs.OutputError` for an ``out`` that may not be written.
    """
    output = Output(out, "file", force=force, inputs=[dataset], what="model JSON")
    output.preflight()  # a bad --out is refused before the dataset is read
    ds = load_dataset(dataset)
    for run in ds.runs:
        if run.enc is None:
            raise ValueError(f"{dataset}: run {run.name} has no wheel odometry (no enc1 … enc{ds.n_wheels} "
                             "columns): calibrate dead-reckons from measured wheel angles")
        if not np.all(np.isfinite(run.enc)):
            k = int(np.nonzero(~np.all(np.isfinite(run.enc), axis=1))[0][0])
            raise ValueError(f"{dataset}: run {run.name}: row {k + 2}: empty encoder cell; calibrate needs every "
                             "wheel angle")
    gap = f"the kinematic model does not explain these runs (slip?): find what does with omni-gym gap {dataset}"
    if frozen := frozen_encoders(ds.runs):
        raise ValueError(f"{dataset}: calibrate refuses: {'; '.join(frozen)}; {gap}")
    try:
        cal = calibrate(ds.runs, ds.model, tracker=tracker)
        checks = session_checks(ds.runs, ds.model, tracker)
    except ValueError as exc:
        raise ValueError(f"{dataset}: {exc}") from None
    if why := refusals(ds.runs, cal):
        raise ValueError(f"{dataset}: calibrate refuses, nothing written: {'; '.join(why)}; {gap}")
    with output as tx:
        write_json_atomic(tx.path, cal.model.to_json())
    return cal, checks


def summary_lines(cal: KinematicCalibration, out: str | Path,
                  checks: list[SessionCheck] | None = None) -> list[str]:
    """What ``omni-gym calibrate`` prints: the fitted values beside the nominal ones [mm], the training
    position RMS of dead reckoning against the tracker [mm] before and after, and each session held out
    (``checks``; or why there is no held-out check)."""
    def mm(values) -> str:
        return ", ".join(f"{1e3 * float(v):.2f}" for v in values)

    frame = []
    if cal.tracker is not None:
        frame = [f"tracked frame (tracker_offset): offset ({mm(cal.tracker['offset'])}) mm from the centre, body "
                 f"frame; yaw {1e3 * cal.tracker['yaw']:.1f} mrad"]
    return [
        f"calibrated on {cal.runs} runs ({cal.rows} tracked rows): D = [{mm(cal.diameters)}] mm "
        f"(nominal [{mm(cal.nominal_diameters)}]), {cal.size_name} = {1e3 * cal.L:.2f} mm "
        f"(nominal {1e3 * cal.nominal_L:.2f})",
        *frame,
        f"position RMS of dead reckoning against the tracker: {1e3 * cal.nominal_position_rms:.1f} mm nominal -> "
        f"{1e3 * cal.train_position_rms:.1f} mm calibrated (these runs)",
        *held_out_lines(checks or [], out),
        f"wrote {out}",
    ]


def held_out_lines(checks: list[SessionCheck], out: str | Path) -> list[str]:
    """One line per session held out, or one saying there was nothing to hold out."""
    if not checks:
        return [f"held out: the runs are one recording session; check other sessions with omni-gym score HELDOUT "
                f"--model {out}"]
    return [f"held out: session {c.session} ({c.runs} runs), calibrated on the other sessions: "
            f"{1e3 * c.nominal_rms:.1f} mm nominal -> {1e3 * c.calibrated_rms:.1f} mm calibrated "
            f"({c.calibrated_rms / c.nominal_rms:.2f}x; mean position RMS of dead reckoning over its runs)"
            for c in checks]
