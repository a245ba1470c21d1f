"""The dataset folder format (a contract, see ``docs/formats.md`` "Dataset"): read, validate, write.

A dataset is a folder::

    DATASET/dataset.json      {"model": MODEL JSON (the nominal model), "description": "...",
                               "sessions": {"RUN NAME": "SESSION ID", ...} (optional)}
    DATASET/runs/*.csv        one run per file, header t,w1..wn[,enc1..encn],x,y,theta[,gyro]

Columns: t [s] from 0, strictly increasing; w_i commanded wheel speeds [rad/s], each held until the
next row (the last row ends the run); enc_i measured wheel angles [rad] (optional, all or none);
x, y [m], theta [rad] the tracked world-frame pose of the geometric centre, cells empty where
nothing was observed; gyro [rad/s] (optional). Every run starts at rest; an empty first pose means
the origin (0, 0, 0).

Every error is a one-line :class:`~omni_gym.io.InputError` naming the file and the row (row 1 is
the header). Files may start with a UTF-8 byte-order mark and use CRLF line ends; every value must
lie inside its bound (``omni_gym.bounds.FILES``, ``docs/bounds.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omni_gym import outputs
from omni_gym.checks import known_keys
from omni_gym.discrepancy.data.units import check_run_units
from omni_gym.io import InputError, check_times, parse_cell, read_csv_rows, read_json
from omni_gym.physics.model import SimModel

DATASET_KEYS = ("model", "description", "sessions")  # dataset.json: any other key is refused (a typo, not data)
# s: tracked rows closer than this before a run's first command are not averaged into its start pose (the
# time_offset effect's bound: a tracker that many seconds off the odometry's clock may show the motion there).
REST_MARGIN = 0.15


@dataclass
class Run:
    """One run: times (K,) [s], commands (K, n) [rad/s], pose (K, 3) [m, m, rad] with NaN where not
    observed, encoders (K, n) [rad] or None, gyro (K,) [rad/s] or None.

    ``state0``: None for a run as the format defines it (starting at rest at ``start_pose``); the
    segments the workflow cuts from long runs (:mod:`omni_gym.discrepancy.data.segments`) start moving, from
    (pose (3,), geometric-centre world velocity (3,) [m/s, m/s, rad/s], wheel angles (n,) [rad], wheel
    speeds (n,) [rad/s]). Not part of the file format. ``start_weight``: how far a replay of the run trusts its
    first tracked rows over its start pose (:mod:`omni_gym.discrepancy.replay.start_trust`).
    """

    name: str
    t: np.ndarray
    cmd: np.ndarray
    pose: np.ndarray
    enc: np.ndarray | None = None
    gyro: np.ndarray | None = None
    state0: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
    session: str | None = None  # the recording session (dataset.json "sessions"); None: not recorded
    # (position, heading) share of the start-window offset a whole-run replay is moved by
    # (omni_gym.discrepancy.replay.start_trust); not part of the file format.
    start_weight: tuple[float, float] = (1.0, 1.0)

    @property
    def observed(self) -> np.ndarray:
        """(K,) bool: rows with a complete measured pose."""
        return np.all(np.isfinite(self.pose), axis=1)

    @property
    def start_pose(self) -> np.ndarray:
        """Pose at t = 0 [m, m, rad] (the origin when the first row is empty).

        Every run starts at rest, so each tracked row before the first command is a measurement of the same
        pose: the start pose is their mean (heading: the mean of the wraps about the first row's), with a
        row's tracker noise / sqrt(rows). A single first row's noise would turn the whole replay: 2 mrad of
        heading noise is 2 mm of drift per metre travelled, which ``gap`` would read as a model error. Rows
        within :data:`REST_MARGIN` [s] of the first command are left out (a tracker that lags or leads the
        odometry may already show the motion there); with none, the first row alone."""
        p = self.pose[0]
        if not np.all(np.isfinite(p)):
            return np.zeros(3)
        moving = np.flatnonzero(np.any(self.cmd != 0.0, axis=1))
        t_move = self.t[moving[0]] if moving.size else self.t[-1] + REST_MARGIN
        rest = self.pose[self.t <= t_move - REST_MARGIN]
        rest = rest[np.all(np.isfinite(rest), axis=1)]
        if len(rest) < 2:
            return p.copy()
        dtheta = np.angle(np.exp(1j * (rest[:, 2] - p[2])))  # wrapped about the first row's heading
        return np.array([rest[:, 0].mean(), rest[:, 1].mean(), p[2] + dtheta.mean()])

    def start_state(self, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The replay state at row 0 (a :class:`~omni_gym.discrepancy.replay.simulate.Job`'s ``state0``): the
        run's own ``state0`` for a segment, else at rest at ``start_pose`` with wheel ``angles`` (n,) [rad]."""
        if self.state0 is not None:
            return self.state0
        return self.start_pose, np.zeros(3), angles, np.zeros(self.cmd.shape[1])


@dataclass
class Dataset:
    """A loaded dataset: the nominal model (and its JSON as given), a description and the runs."""

    path: Path
    model: SimModel
    model_json: dict
    description: str
    runs: list[Run]

    @property
    def n_wheels(self) -> int:
        return self.model.n_wheels


def run_header(n_wheels: int, encoders: bool, gyro: bool = False) -> list[str]:
    """The CSV header of a run."""
    head = ["t"] + [f"w{i + 1}" for i in range(n_wheels)]
    if encoders:
        head += [f"enc{i + 1}" for i in range(n_wheels)]
    head += ["x", "y", "theta"]
    if gyro:
        head.append("gyro")
    return head


def load_dataset(folder: str | Path) -> Dataset:
    """Read and validate a dataset folder; raise InputError (one line: file, row, what) on bad input."""
    folder = Path(folder)
    meta_path = folder / "dataset.json"
    if outputs.is_temporary(folder):
        raise InputError(f"{folder}: a temporary folder of an unfinished or killed omni-gym write, not a dataset")
    if not folder.is_dir():
        raise InputError(f"{folder}: not a dataset folder (expected dataset.json and runs/*.csv)")
    meta = read_json(meta_path)
    if not isinstance(meta, dict) or "model" not in meta:
        raise InputError(f"{meta_path}: expected an object with key 'model'")
    try:
        known_keys(meta, DATASET_KEYS)
    except ValueError as exc:
        raise InputError(f"{meta_path}: {exc}") from None
    model = SimModel.from_json(meta["model"], where=f"{meta_path}: model")
    desc = meta.get("description", "")
    if not isinstance(desc, str):
        raise InputError(f"{meta_path}: 'description' must be a string")
    # Hidden files (e.g. an editor's or an unfinished write's temporary file) are not runs.
    files = sorted(f for f in (folder / "runs").glob("*.csv") if not f.name.startswith("."))
    if not files:
        raise InputError(f"{folder / 'runs'}: no run files (*.csv)")
    runs = [read_run(f, model.n_wheels) for f in files]
    _attach_sessions(meta_path, meta.get("sessions"), runs)
    for f, run in zip(files, runs, strict=True):
        check_run_units(f, run.t, run.cmd, run.pose, model.robot.wheel_radius)
    return Dataset(path=folder, model=model, model_json=meta["model"], description=desc, runs=runs)


def _attach_sessions(meta_path: Path, sessions: object, runs: list[Run]) -> None:
    """Set each run's ``session`` from ``dataset.json``'s optional ``sessions`` object (run name → session
    id); a run it does not list keeps None. InputError (one line) for a malformed entry or an unknown run."""
    if sessions is None:
        return
    if not isinstance(sessions, dict):
        raise InputError(f"{meta_path}: 'sessions' must be an object (run name -> session id)")
    by_name = {r.name: r for r in runs}
    for name, sid in sessions.items():
        if not isinstance(sid, str) or not sid:
            raise InputError(f"{meta_path}: sessions: run {name!r}: the session id must be a non-empty string")
        if name not in by_name:
            raise InputError(f"{meta_path}: sessions: run {name!r} has no file runs/{name}.csv")
        by_name[name].session = sid


def sessions_of(runs: list[Run]) -> list[str] | None:
    """The runs' sessions when every run records one and there are at least two, else None (then
    held-out folds split by run, not by session)."""
    ids = [r.session for r in runs]
    if any(s is None for s in ids) or len(set(ids)) < 2:
        return None
    return ids  # type: ignore[return-value]


def read_run(path: Path, n_wheels: int) -> Run:
    """Read one run CSV (format in the module docstring)."""
    rows = read_csv_rows(path)
    header = [h.strip() for h in rows[0]]
    encoders = any(h.startswith("enc") for h in header)
    gyro = bool(header) and header[-1] == "gyro"
    expected = run_header(n_wheels, encoders, gyro)
    if header != expected:
        wheels = sum(1 for h in header if h.startswith("w") and h[1:].isdigit())
        if wheels != n_wheels:
            raise InputError(f"{path}: row 1: header has {wheels} wheel columns, the model has {n_wheels} wheels")
        missing = [h for h in expected if h not in header]
        what = f"missing column(s) {','.join(missing)}" if missing else f"unexpected columns {','.join(header)}"
        raise InputError(f"{path}: row 1: {what}; expected {','.join(expected)}")
    if len(rows) < 2:
        raise InputError(f"{path}: row 2: no data rows after the header")
    # Pose, encoder and gyro cells may be empty (not observed); time and commands may not.
    may_be_empty = {h for h in expected if h in ("x", "y", "theta", "gyro") or h.startswith("enc")}
    data = np.full((len(rows) - 1, len(expected)), np.nan)
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != len(expected):
            raise InputError(f"{path}: row {r}: expected {len(expected)} values, got {len(row)}")
        for c, cell in enumerate(row):
            col = expected[c]
            if not cell.strip():
                if col in may_be_empty:
                    continue
                raise InputError(f"{path}: row {r}: column {col}: empty cell")
            data[r - 2, c] = parse_cell(cell, path, r, col)
    t = data[:, 0]
    check_times(path, t)
    pose = data[:, [expected.index("x"), expected.index("y"), expected.index("theta")]]
    partial = np.nonzero(np.any(np.isfinite(pose), axis=1) & ~np.all(np.isfinite(pose), axis=1))[0]
    if partial.size:
        raise InputError(f"{path}: row {int(partial[0]) + 2}: x, y and theta must be all given or all empty")
    if not np.any(np.isfinite(pose[1:, 0])):
        raise InputError(f"{path}: row 2: no observed pose after t = 0 (nothing to compare with)")
    return Run(
        name=path.stem,
        t=t.copy(),
        cmd=data[:, 1:1 + n_wheels].copy(),
        pose=pose.copy(),
        enc=data[:, 1 + n_wheels:1 + 2 * n_wheels].copy() if encoders else None,
        gyro=data[:, -1].copy() if gyro else None,
    )


def write_dataset(folder: str | Path, model_json: dict, description: str, runs: list[Run]) -> None:
    """Write a dataset folder (runs first, dataset.json last). For a complete-or-absent dataset write
    into the temporary folder of an :class:`omni_gym.outputs.Output` (as ``omni-gym synth`` does)."""
    folder = Path(folder)
    for run in runs:  # every name before anything is written: never a path out of runs/
        outputs.check_file_name(run.name, "run name", str(folder))
    (folder / "runs").mkdir(parents=True, exist_ok=True)
    for run in runs:
        n = run.cmd.shape[1]
        cols = [run.t[:, None], run.cmd]
        if run.enc is not None:
            cols.append(run.enc)
        cols.append(run.pose)
        if run.gyro is not None:
            cols.append(run.gyro[:, None])
        outputs.write_csv_atomic(folder / "runs" / f"{run.name}.csv",
                                 run_header(n, run.enc is not None, run.gyro is not None), np.column_stack(cols),
                                 empty_nan=True)
    meta: dict = {"model": model_json, "description": description}
    sessions = {r.name: r.session for r in runs if r.session is not None}
    if sessions:
        meta["sessions"] = sessions
    outputs.write_json_atomic(folder / "dataset.json", meta)
