"""Import OptiOdom sessions (``omni-gym import optiodom``): encoder ticks + motion capture → a dataset.

An OptiOdom session folder (the public OptiOdom dataset, ``data/optiodom-omni3/README.md``) holds

* ``<id>_metadata.csv``: rows ``key,value[,value…]`` (trailing empty cells allowed): ``type`` (``omni3``),
  ``ngear`` (gear ratio n:1), ``encRes`` (encoder ticks per motor turn), ``Li`` [m] (centre-to-wheel
  distance), ``Di`` [m] (three wheel diameters); other rows are ignored;
* ``<id>_run-NN.csv``: no header, one row per control cycle (40 ms):
  ``time [s], x [m], y [m], theta [rad], ticks_1, ticks_2, ticks_3``: the pose of the robot centre in the
  motion-capture world frame (``NaN`` where tracking dropped out) and the signed encoder ticks of each
  wheel counted during the cycle.

Mapping to the dataset format (``docs/formats.md`` "Dataset" and "Importing OptiOdom logs"):

* Model wheel i is the data's wheel i; a positive command is a positive tick count.
* The ticks of row k are the wheel motion over (t_{k−1}, t_k], so the command of row k−1 is the speed
  ticks_k · 2π / (ngear · encRes) / (t_k − t_{k−1}) [rad/s of the wheel], held until t_k; the last row's
  command is 0 (it ends the run). The first row's ticks are motion before the run's start: ignored
  (24 of the 41 bundled runs have a few there, at most 32 ticks, under 1 mm of wheel travel).
* ``enc1…enc3`` [rad] = cumulative ticks · 2π / (ngear · encRes), 0 at t = 0.
* Times are shifted so the first row is t = 0 (the bundled files already start at 0).
* The first row's pose is the run's start pose (kept, not moved to the origin); it must be tracked.
  A row with a NaN pose cell becomes an unobserved row (empty x, y, theta). NaN ticks are refused.
* The nominal model comes from the metadata (:func:`nominal_model`): the geometry of the data's README,
  wheel radius Di/2, and documented assumptions for what OptiOdom does not publish (mass, inertia,
  rollers, floor).

Every error is a one-line :class:`~omni_gym.io.InputError` naming the file and the line (these files
have no header: line 1 is the first row). Files may start with a UTF-8 byte-order mark and use CRLF.
"""

from __future__ import annotations

import csv
import glob
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omni_gym.bounds import FILES
from omni_gym.bounds import MODEL as MODEL_BOUNDS
from omni_gym.discrepancy.dataset import Run, write_dataset
from omni_gym.io import InputError, read_text
from omni_gym.outputs import Output
from omni_gym.physics.friction import surface_preset
from omni_gym.physics.model import SimModel

# --- the nominal model: geometry from the data's README, assumptions where nothing is published ------

# Wheel i sits at distance Li at these body-frame angles [deg] (x forward, y left) and drives clockwise
# tangentially, d_i = (sin α_i, −cos α_i): the README's table, (−0.866, −0.5), (0.866, −0.5), (0, 1).
# Equal positive ticks then turn the robot clockwise (yaw rate −r·w/Li), as the README states.
WHEEL_ANGLES_DEG = (-60.0, 60.0, 180.0)

# Not published with the data. The robot is a three-wheeled base about 0.45 m across (wheels at
# 0.195 m, 102 mm wheels, geared DC motors, battery and computer on board): 8 kg is an assumed,
# typical mass for such a base. On the default floor (SURFACE) the replay hardly depends on it (the
# wheels do not slip); ``--mass`` changes it.
MASS = 8.0  # kg
# Yaw inertia [kg·m²] default: 0.5·m·Li², a uniform disc of the wheel-circle radius (the convention of
# the project's presets, omni_gym.physics.robot.regular); ``--inertia`` changes it.
INERTIA_DISC_FACTOR = 0.5
# A 102 mm (4-inch class) omni wheel is most often a double-row wheel with two staggered rows of 9
# rollers: 18 rollers. With two staggered rows a roller always touches the floor, so no rigid
# material does: roller_fraction 1.0 and the ``initial`` friction model (no roller-gap switching).
ROLLERS = 18
ROLLER_FRACTION = 1.0
FRICTION = "initial"
# The floor is not characterised. OptiOdom (like every kinematic odometry calibration) assumes the
# wheels roll without slipping; ``grip`` is the project's no-slip floor (drive μ 2, free rollers), so
# the nominal model is the kinematic model the data's authors used. ``--surface`` picks another preset.
SURFACE = "grip"
BODY_MARGIN = 0.05  # m: collision disc radius = Li + half a 102 mm wheel (the world's walls only)

N_WHEELS = 3
RUN_COLUMNS = ("time", "x", "y", "theta", "ticks_1", "ticks_2", "ticks_3")
_RUN_FILE = re.compile(r"^(?P<session>.+)_run-(?P<number>\d+)\.csv$")
_METADATA_SUFFIX = "_metadata.csv"
# A decimal number as the OptiOdom files (MATLAB) write it; NaN is handled separately.
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_NAN = re.compile(r"[+-]?nan", re.IGNORECASE)


@dataclass(frozen=True)
class Metadata:
    """One session's ``<id>_metadata.csv``: the numbers the import uses (SI units)."""

    path: Path
    session: str
    kind: str
    ngear: float
    enc_res: float
    L: float  # m, centre-to-wheel distance Li
    D: tuple[float, ...]  # m, wheel diameters Di

    @property
    def rad_per_tick(self) -> float:
        """Wheel angle of one encoder tick [rad]: 2π / (ngear · encRes)."""
        return 2.0 * math.pi / (self.ngear * self.enc_res)

    def robot_key(self) -> dict[str, object]:
        """The numbers sessions of one robot configuration must share (name → value)."""
        return {"ngear": self.ngear, "encRes": self.enc_res, "Li": self.L, "Di": self.D}


@dataclass
class RawRun:
    """One ``<id>_run-NN.csv`` as read: times (K,) [s] as in the file, pose (K, 3) [m, m, rad] with NaN
    rows where tracking dropped out, ticks (K, 3) per cycle, and each row's line in the file."""

    path: Path
    t: np.ndarray
    pose: np.ndarray
    ticks: np.ndarray
    lines: np.ndarray


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote: sessions, runs, robot time [s], the dataset folder and the assumed mass
    [kg], inertia [kg·m²] and surface preset of its nominal model."""

    sessions: tuple[str, ...]
    runs: int
    duration: float
    out: Path
    mass: float
    inertia: float
    surface: str


# --- reading ----------------------------------------------------------------------------------------


def _rows(path: Path) -> list[tuple[int, list[str]]]:
    """(line, cells) of every non-blank row (BOM and CRLF accepted); InputError naming the file."""
    text = read_text(path)
    reader = csv.reader(io.StringIO(text, newline=""))
    out = []
    try:
        for row in reader:
            if row and any(cell.strip() for cell in row):
                out.append((reader.line_num, row))
    except csv.Error as exc:
        raise InputError(f"{path}: line {reader.line_num}: cannot read ({exc})") from None
    return out


def _number(cell: str, path: Path, line: int, what: str) -> float:
    """A plain finite decimal number; InputError naming file, line and ``what``."""
    text = cell.strip()
    if not _NUMBER.fullmatch(text):
        raise InputError(f"{path}: line {line}: {what}: not a number: {text!r}")
    return float(text)


def read_metadata(path: str | Path) -> Metadata:
    """Read ``<id>_metadata.csv`` (format in the module docstring); InputError on a bad or missing key."""
    path = Path(path)
    session = path.name[: -len(_METADATA_SUFFIX)] if path.name.endswith(_METADATA_SUFFIX) else path.stem
    values: dict[str, tuple[int, list[str]]] = {}
    for line, row in _rows(path):
        key = row[0].strip()
        if key in values:
            raise InputError(f"{path}: line {line}: {key!r} given twice (first on line {values[key][0]})")
        values[key] = (line, [c.strip() for c in row[1:] if c.strip()])

    def get(key: str) -> tuple[int, list[str]]:
        if key not in values:
            raise InputError(f"{path}: no {key!r} row (an OptiOdom metadata file has type, ngear, encRes, Li, Di)")
        line, cells = values[key]
        if not cells:
            raise InputError(f"{path}: line {line}: {key} has no value")
        return line, cells

    def positive(key: str, cells: list[str], line: int) -> list[float]:
        out = [_number(c, path, line, key) for c in cells]
        for v in out:
            if not (math.isfinite(v) and v > 0):  # 1e400 parses as inf
                raise InputError(f"{path}: line {line}: {key} must be a finite number > 0, got {v:g}")
        return out

    line, cells = get("type")
    kind = cells[0]
    match = re.fullmatch(r"omni(\d+)", kind)
    if len(cells) != 1 or match is None or int(match.group(1)) != N_WHEELS:
        got = ",".join(cells)
        wheels = f" ({match.group(1)} wheels)" if match and len(cells) == 1 else ""
        raise InputError(f"{path}: line {line}: type {got!r}{wheels}: only omni3 sessions (three-wheeled "
                         "omnidirectional) can be imported")
    scalars = {}
    for key in ("ngear", "encRes", "Li"):
        line, cells = get(key)
        if len(cells) != 1:
            raise InputError(f"{path}: line {line}: {key} must be one value, got {len(cells)}")
        scalars[key] = positive(key, cells, line)[0]
    line, cells = get("Di")
    if len(cells) != N_WHEELS:
        raise InputError(f"{path}: line {line}: Di has {len(cells)} value(s); type {kind} has {N_WHEELS} wheels")
    D = tuple(positive("Di", cells, line))
    return Metadata(path=path, session=session, kind=kind, ngear=scalars["ngear"], enc_res=scalars["encRes"],
                    L=scalars["Li"], D=D)


def read_run_file(path: str | Path) -> RawRun:
    """Read ``<id>_run-NN.csv`` (7 columns, no header); InputError naming the file and the line."""
    path = Path(path)
    rows = _rows(path)
    if not rows:
        raise InputError(f"{path}: line 1: empty run file (no rows)")
    K = len(rows)
    data = np.empty((K, len(RUN_COLUMNS)))
    lines = np.empty(K, dtype=np.int64)
    for k, (line, row) in enumerate(rows):
        if len(row) != len(RUN_COLUMNS):
            raise InputError(f"{path}: line {line}: expected {len(RUN_COLUMNS)} values "
                             f"({', '.join(RUN_COLUMNS)}), got {len(row)}")
        lines[k] = line
        for c, (cell, col) in enumerate(zip(row, RUN_COLUMNS, strict=True)):
            if _NAN.fullmatch(cell.strip()):
                if col.startswith("ticks"):
                    raise InputError(f"{path}: line {line}: {col} is NaN: the wheel's motion in that cycle is "
                                     "unknown (only pose cells may be NaN)")
                if col == "time":
                    raise InputError(f"{path}: line {line}: time is NaN")
                data[k, c] = math.nan
                continue
            v = _number(cell, path, line, col)
            if col.startswith("ticks") and v != math.floor(v):
                raise InputError(f"{path}: line {line}: {col} must be a whole number of encoder ticks, got {v:g}")
            bound = FILES["x, y"] if col in ("x", "y") else FILES["theta"] if col == "theta" else None
            if bound is not None and not bound.contains(v):
                raise InputError(f"{path}: line {line}: {col} {bound.describe()}, got {cell.strip()}")
            data[k, c] = v
    t = data[:, 0]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        j = int(bad[0]) + 1
        raise InputError(f"{path}: line {lines[j]}: times must be strictly increasing "
                         f"({t[j]:g} after {t[j - 1]:g})")
    return RawRun(path=path, t=t.copy(), pose=data[:, 1:4].copy(), ticks=data[:, 4:7].copy(), lines=lines)


def convert_run(raw: RawRun, meta: Metadata, name: str | None = None) -> Run:
    """A :class:`Run` of our format from one OptiOdom run (mapping in the module docstring).

    Times are shifted to start at 0 if the file's first time is not 0. A pose row with any NaN cell
    becomes unobserved (NaN x, y, theta). InputError if the run has fewer than two rows, its first pose
    is not tracked, no pose after the first row is tracked, or a value leaves its bound
    (``docs/bounds.md``, "Command and dataset files").
    """
    path = raw.path
    K = len(raw.t)
    if K < 2:
        raise InputError(f"{path}: line {raw.lines[0]}: a run needs at least two rows (one cycle), got {K}")
    t = raw.t - raw.t[0]
    if not FILES["t"].contains(t[-1]):
        raise InputError(f"{path}: line {raw.lines[-1]}: run duration {FILES['t'].describe()}, got {t[-1]:g}")
    pose = raw.pose.copy()
    pose[~np.all(np.isfinite(pose), axis=1)] = np.nan  # a tracker gives all three or nothing
    if not np.all(np.isfinite(pose[0])):
        raise InputError(f"{path}: line {raw.lines[0]}: the first pose is NaN (not tracked): the run's start "
                         "pose is unknown")
    if not np.any(np.isfinite(pose[1:, 0])):
        raise InputError(f"{path}: line {raw.lines[1]}: no tracked pose after the first row (nothing to compare with)")
    q = meta.rad_per_tick
    ticks = raw.ticks[1:]  # row k's ticks: the motion over (t_{k-1}, t_k]; row 0's came before the run
    cmd = np.zeros((K, N_WHEELS))
    cmd[:-1] = ticks * q / np.diff(t)[:, None] + 0.0  # + 0.0: a "-0" tick count is written as 0.0
    enc = np.zeros((K, N_WHEELS))
    enc[1:] = np.cumsum(ticks, axis=0) * q + 0.0  # sum whole ticks first: exact
    for what, values, bound in (("wheel speed", cmd[:-1], FILES["w1 … wn"]),
                                ("wheel angle", enc[1:], FILES["enc1 … encn"])):
        outside = np.nonzero(~np.all((values >= bound.lo) & (values <= bound.hi), axis=1))[0]
        if outside.size:
            k = int(outside[0]) + 1
            raise InputError(f"{path}: line {raw.lines[k]}: the ticks give a {what} outside "
                             f"{bound.within()} ({np.max(np.abs(values[k - 1])):.4g})")
    return Run(name=name or path.stem, t=t, cmd=cmd, pose=pose, enc=enc)


def find_session(folder: str | Path) -> tuple[Path, list[Path]]:
    """(metadata file, run files in run-number order) of one session folder; InputError if missing."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder (expected an OptiOdom session folder with <id>_metadata.csv "
                         "and <id>_run-NN.csv)")
    metas = sorted(p for p in folder.glob(f"*{_METADATA_SUFFIX}") if not p.name.startswith("."))
    if not metas:
        raise InputError(f"{folder}: no <id>_metadata.csv: not an OptiOdom session folder")
    if len(metas) > 1:
        raise InputError(f"{folder}: several metadata files ({', '.join(p.name for p in metas)}); "
                         "one session per folder")
    session = metas[0].name[: -len(_METADATA_SUFFIX)]
    runs = []
    for p in folder.glob(f"{glob.escape(session)}_run-*.csv"):
        m = _RUN_FILE.match(p.name)
        if m and m.group("session") == session:
            runs.append((int(m.group("number")), p))
    if not runs:
        raise InputError(f"{folder}: no run files {session}_run-NN.csv")
    return metas[0], [p for _, p in sorted(runs)]


def read_sessions(folders: list[str | Path]) -> tuple[list[Metadata], list[Run]]:
    """Read and convert every run of the given session folders (in the order given).

    Refuses sessions of different robot configurations (``ngear``, ``encRes``, ``Li``, ``Di``) and a
    session given twice; run names are the file names without ``.csv`` (``<id>_run-NN``).
    """
    if not folders:
        raise InputError("optiodom: no session folder given")
    metas: list[Metadata] = []
    runs: list[Run] = []
    for folder in folders:
        meta_path, run_paths = find_session(folder)
        meta = read_metadata(meta_path)
        for other in metas:
            if other.session == meta.session:
                raise InputError(f"{meta.path}: session {meta.session} is given twice (also {other.path})")
        if metas:
            first = metas[0]
            for key, value in first.robot_key().items():
                if meta.robot_key()[key] != value:
                    raise InputError(f"{first.path} and {meta.path}: {key} differs ({_fmt(value)} vs "
                                     f"{_fmt(meta.robot_key()[key])}); import sessions of one robot configuration "
                                     "together")
        metas.append(meta)
        runs.extend(convert_run(read_run_file(p), meta) for p in run_paths)
    return metas, runs


def _fmt(value) -> str:
    """A metadata value for a message: ``12`` or ``0.102,0.102,0.102``."""
    return ",".join(f"{v:g}" for v in value) if isinstance(value, tuple) else f"{value:g}"


# --- the nominal model --------------------------------------------------------------------------------


def wheel_layout(L: float) -> list[dict]:
    """The three wheels at distance ``L`` [m]: positions [m] and unit drive directions, body frame."""
    wheels = []
    for deg in WHEEL_ANGLES_DEG:
        a = math.radians(deg)
        pos = [L * math.cos(a), L * math.sin(a)]
        drive = [math.sin(a), -math.cos(a)]
        # cos(90°) and sin(180°) are 6e-17 in floating point: write exact zeros.
        wheels.append({"position": [_zero(v, L) for v in pos], "drive": [_zero(v, 1.0) for v in drive]})
    return wheels


def _zero(v: float, scale: float) -> float:
    return 0.0 if abs(v) < 1e-12 * scale else v


def nominal_model(meta: Metadata, mass: float = MASS, inertia: float | None = None,
                  surface: str = SURFACE) -> SimModel:
    """The nominal model of a session: geometry and wheel size from the metadata, assumed mass properties.

    ``mass`` [kg]; ``inertia`` [kg·m²] (default 0.5·mass·Li²); ``surface``: a preset name. If the three
    Di differ, ``wheel_radius`` is mean(Di)/2 and a ``wheel_radius`` effect carries the scales Di/mean.
    """
    MODEL_BOUNDS["mass"].check(mass, "--mass")
    inertia = INERTIA_DISC_FACTOR * mass * meta.L**2 if inertia is None else inertia
    MODEL_BOUNDS["inertia"].check(inertia, "--inertia")
    D = np.asarray(meta.D, dtype=float)
    mean = float(np.mean(D))
    effects = {}
    if np.any(D != D[0]):
        effects["wheel_radius"] = {"scale": [float(d / mean) for d in D]}
    data = {
        "name": "optiodom-omni3",
        "mass": float(mass),
        "inertia": float(inertia),
        "gravity": 9.81,
        "wheel_radius": mean / 2.0,
        "wheels": wheel_layout(meta.L),
        "com": [0.0, 0.0],
        "rollers": ROLLERS,
        "roller_fraction": ROLLER_FRACTION,
        "body_radius": meta.L + BODY_MARGIN,
        "friction": FRICTION,
        "surface": surface_preset(surface).to_json(),
        "effects": effects,
    }
    try:
        return SimModel.from_json(data, where="nominal model")
    except ValueError as exc:  # Li or Di outside the model bounds: name the metadata file
        raise InputError(f"{meta.path}: {exc}") from None


def describe(metas: list[Metadata], n_runs: int, mass: float, inertia: float, surface: str) -> str:
    """The dataset's description: sources and the assumptions of the nominal model."""
    ids = ", ".join(m.session for m in metas)
    return (f"OptiOdom omni3 sessions {ids} ({n_runs} runs; encoder ticks and motion capture, public OptiOdom "
            f"dataset, MIT licence), imported by omni-gym import optiodom. Geometry and wheel diameters from the "
            f"metadata; assumed (not published): mass {mass:g} kg, inertia {inertia:.4g} kg·m², {ROLLERS} rollers, "
            f"roller_fraction {ROLLER_FRACTION:g}, friction {FRICTION}, surface {surface} "
            f"(docs/formats.md, 'Importing OptiOdom logs').")


def import_optiodom(folders: list[str | Path], out: str | Path, force: bool = False, mass: float = MASS,
                    inertia: float | None = None, surface: str = SURFACE) -> ImportSummary:
    """Import OptiOdom session folders into the dataset folder ``out``; returns what was written.

    The output is complete or absent (:class:`omni_gym.outputs.Output`, as ``omni-gym synth``): an
    existing dataset is refused unless ``force``; an output inside (or equal to) a session folder always.
    """
    surface_preset(surface)  # an unknown preset is refused before anything is read or locked
    MODEL_BOUNDS["mass"].check(mass, "--mass")
    if inertia is not None:
        MODEL_BOUNDS["inertia"].check(inertia, "--inertia")
    folders = [Path(f) for f in folders]
    out = Path(out)
    with Output(out, "dir", force=force, inputs=folders, marker="dataset.json", what="dataset") as tx:
        metas, runs = read_sessions(folders)
        model = nominal_model(metas[0], mass, inertia, surface)
        desc = describe(metas, len(runs), mass, model.robot.inertia, surface)
        write_dataset(tx.path, model.to_json(), desc, runs)
    return ImportSummary(sessions=tuple(m.session for m in metas), runs=len(runs),
                         duration=float(sum(r.t[-1] for r in runs)), out=out, mass=model.robot.mass,
                         inertia=model.robot.inertia, surface=surface)
