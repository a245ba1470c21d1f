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


def calibrate_dataset(dataset: str | Path, out: str | Path, force: bool = False,
                      tracker: bool = False) -> tuple[KinematicCalibration, list[SessionCheck]]:
    """Calibrate the nominal model of ``dataset`` on all its runs and write the result to ``out`` [JSON];
    ``tracker``: fit the tracked frame (offset, yaw) jointly, written as a ``tracker_offset`` effect.
    Returns the calibration and, for a dataset of two or more recorded sessions, each session held out
    (:func:`session_checks`).

    ValueError (one line, naming the dataset and the run) for a dataset without wheel odometry; an
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
    try:
        cal = calibrate(ds.runs, ds.model, tracker=tracker)
        checks = session_checks(ds.runs, ds.model, tracker)
    except ValueError as exc:
        raise ValueError(f"{dataset}: {exc}") from None
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
