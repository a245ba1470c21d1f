"""Import OptiOdom sessions (``omni-gym import optiodom``): wheel odometry + motion capture → a dataset.

Two robot types of the public OptiOdom dataset are read (``data/optiodom-omni3/README.md``,
``data/optiodom-omni4/README.md``):

* ``omni3``: three omni wheels, a 40 ms control cycle, encoder ticks per cycle (whole numbers), ``Li`` one
  centre-to-wheel distance L [m];
* ``omni4``: four wheels with mecanum kinematics (rollers at 45°), a 10 ms cycle, wheel rotation per cycle in
  encoder units (``ngear`` 1, ``encRes`` 1: revolutions, fractional), ``Li`` two values l1, l2 [m] (wheel
  centres at (±l1/2, ±l2/2)).

A session folder holds

* ``<id>_metadata.csv``: rows ``key,value[,value…]`` (trailing empty cells allowed): ``type`` (``omni3`` or
  ``omni4``), ``ngear`` (gear ratio n:1), ``encRes`` (encoder units per motor turn), ``Li`` [m] (one value for
  omni3, two for omni4), ``Di`` [m] (one wheel diameter per wheel), optionally ``gt_ti``, ``gt_tf``,
  ``odo_ti``, ``odo_tf`` [s] (one value per run: the synchronisation windows); other rows are ignored;
* ``<id>_run-NN.csv`` or ``<id>_run-NN.csv.gz`` (gzip-compressed; the same content): no header, one row per
  control cycle: ``time [s], x [m], y [m], theta [rad], then one column per wheel`` (encoder units counted
  during the cycle): the pose of the robot centre in the motion-capture world frame (``NaN`` where tracking
  dropped out) and each wheel's signed rotation.

Mapping to the dataset format (``docs/formats.md`` "Dataset" and "Importing OptiOdom logs"):

* Model wheel i is the data's wheel i; a positive command is a positive count.
* The counts of row k are the wheel motion over (t_{k−1}, t_k], so the command of row k−1 is the speed
  count_k · 2π / (ngear · encRes) / (t_k − t_{k−1}) [rad/s of the wheel], held until t_k; the last row's
  command is 0 (it ends the run). The first row's counts are motion before the run's start: ignored
  (24 of the 41 bundled omni3 runs have a few there, at most 32 ticks, under 1 mm of wheel travel).
  Wheel travel in one cycle [m] = (D_i / 2) · that angle = π · D_i · count / (ngear · encRes).
* ``enc1…encn`` [rad] = cumulative counts · 2π / (ngear · encRes), 0 at t = 0.
* Times are shifted so the first row is t = 0 (the bundled files already start at 0), then put on the
  tracker's clock: row k at t_k · s, s = (gt_tf − gt_ti)/(odo_tf − odo_ti) from the run's synchronisation
  window in the metadata (``--time-base``, :func:`read_sessions_timed`, :class:`RobotType`
  ``counts_are``; the evidence in docs/formats.md, "The time base").
* The first row's pose is the run's start pose (kept, not moved to the origin); it must be tracked.
  A row with a NaN pose cell becomes an unobserved row (empty x, y, theta). NaN counts are refused.
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

from omni_gym.bounds import FILES, LOGS
from omni_gym.bounds import MODEL as MODEL_BOUNDS
from omni_gym.discrepancy.data.dataset import Run
from omni_gym.discrepancy.data.importers.logs import write_imported
from omni_gym.discrepancy.data.units import check_run_units, check_travel_scale, travel
from omni_gym.io import InputError, read_text
from omni_gym.physics.friction import surface_preset
from omni_gym.physics.model import SimModel
from omni_gym.physics.robot import PRESETS, RobotSpec

# --- the nominal models: geometry from the data's READMEs, assumptions where nothing is published -------


@dataclass(frozen=True)
class RobotType:
    """What differs between OptiOdom robot types (the metadata's ``type``).

    ``n_wheels``; ``li_count``: how many values ``Li`` has (omni3: L; omni4: l1, l2); ``column``: the
    name of a wheel's count column in messages; ``whole_counts``: the counts are whole encoder ticks
    (omni3) rather than fractional encoder units (omni4 logs wheel revolutions: encRes 1); ``cycle`` [s]:
    the documented control cycle (for descriptions; the times are read from the files); ``counts_are``:
    what a row's count measures when the tracker's clock and the log's disagree (docs/formats.md, "The time
    base"): ``"rotation"``, the encoder ticks counted over the cycle, whatever it lasted (omni3: whole
    ticks), or ``"speed"``, the wheel speed times the nominal cycle (omni4: fractional revolutions, whose
    sum over a run falls short of the tracked travel by the clock scale).
    """

    kind: str
    n_wheels: int
    li_count: int
    column: str
    whole_counts: bool
    cycle: float
    counts_are: str

    def run_columns(self) -> tuple[str, ...]:
        return ("time", "x", "y", "theta", *(f"{self.column}_{i + 1}" for i in range(self.n_wheels)))


TYPES: dict[str, RobotType] = {
    "omni3": RobotType("omni3", 3, 1, "ticks", True, 0.04, "rotation"),
    "omni4": RobotType("omni4", 4, 2, "odo", False, 0.01, "speed"),
}

# Each robot type's geometry, mass properties, rollers and body radius are the physics presets
# ``optiodom_omni3`` and ``optiodom_omni4`` (omni_gym.physics.robot, with the reasons for each assumed
# value: mass, inertia and rollers are not published with the data), at the session's lengths and wheel
# diameters. On the default floor (SURFACE) the replay hardly depends on the mass (the wheels do not slip);
# ``--mass`` and ``--inertia`` change it. Both presets' rollers always touch the floor: roller_fraction 1.0
# and the ``initial`` friction model (no roller-gap switching).
ROLLER_FRACTION = 1.0
FRICTION = "initial"
# The floor is not characterised. OptiOdom (like every kinematic odometry calibration) assumes the
# wheels roll without slipping; ``grip`` is the project's no-slip floor (drive μ 2, free rollers), so
# the nominal model is the kinematic model the data's authors used. ``--surface`` picks another preset.
SURFACE = "grip"

N_WHEELS = 3  # omni3 (kept for callers of the first version)
RUN_COLUMNS = TYPES["omni3"].run_columns()
_RUN_FILE = re.compile(r"^(?P<session>.+)_run-(?P<number>\d+)\.csv(?P<gz>\.gz)?$")
_METADATA_SUFFIX = "_metadata.csv"
# A decimal number as the OptiOdom files (MATLAB) write it; NaN is handled separately.
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_NAN = re.compile(r"[+-]?nan", re.IGNORECASE)


def default_mass(kind: str) -> float:
    """The assumed mass [kg] of a robot type's nominal model (not published with the data)."""
    return PRESETS[f"optiodom_{kind}"]().mass


@dataclass(frozen=True)
class SyncWindow:
    """One run's synchronisation window, as OptiOdom's synchronisation wrote it to the metadata
    (``gt_ti``, ``gt_tf``, ``odo_ti``, ``odo_tf`` [s]): the motion-capture interval [gt_ti, gt_tf] on the
    tracker's clock was resampled onto the odometry rows of [odo_ti, odo_tf] on the robot's log clock.
    ``line``: the metadata line of ``gt_ti`` (for messages)."""

    gt_ti: float
    gt_tf: float
    odo_ti: float
    odo_tf: float
    line: int

    @property
    def clock_scale(self) -> float:
        """Tracker seconds per logged second over the run: (gt_tf − gt_ti) / (odo_tf − odo_ti)."""
        return (self.gt_tf - self.gt_ti) / (self.odo_tf - self.odo_ti)


# The time bases an OptiOdom run can be imported on (``--time-base``; docs/formats.md, "The time base"):
# "tracker": each row lasts the tracker's share of the run (the synchronisation window), the logged counts
# are wheel speed × the nominal cycle; "file": the time column as written, the counts as wheel rotation.
TIME_BASES = ("auto", "tracker", "file")  # auto: tracker where the metadata has the windows, else file
# A run's clock scale further than this from its session's median is reported (measured: every bundled run
# is within 0.53 % of its session's median; the two path families differ by 4 %).
CLOCK_SCALE_SPREAD = 0.01
# Clock scales outside this range are refused: no logger's clock is off by a factor of two (the bundled
# sessions: 1.01–1.11), so the window belongs to another file.
CLOCK_SCALE_RANGE = (0.5, 2.0)


@dataclass(frozen=True)
class Metadata:
    """One session's ``<id>_metadata.csv``: the numbers the import uses (SI units).

    ``Li`` [m]: omni3 (L,) the centre-to-wheel distance; omni4 (l1, l2), wheel centres at (±l1/2, ±l2/2).
    ``D`` [m]: the wheel diameters Di, one per wheel.
    """

    path: Path
    session: str
    kind: str
    ngear: float
    enc_res: float
    Li: tuple[float, ...]
    D: tuple[float, ...]
    sync: tuple[SyncWindow, ...] = ()  # per run (run-01 first); empty: the metadata has no windows
    sync_error: str = ""  # why the window rows could not be read (raised only where a window is needed)

    @property
    def robot_type(self) -> RobotType:
        return TYPES[self.kind]

    @property
    def L(self) -> float:
        """omni3's centre-to-wheel distance [m] (Li); ValueError for a type with two lengths."""
        if len(self.Li) != 1:
            raise ValueError(f"{self.path}: type {self.kind} has Li = l1, l2, not one distance L")
        return self.Li[0]

    @property
    def rad_per_tick(self) -> float:
        """Wheel angle of one encoder unit [rad]: 2π / (ngear · encRes)."""
        return 2.0 * math.pi / (self.ngear * self.enc_res)

    def robot_key(self) -> dict[str, object]:
        """The numbers sessions of one robot configuration must share (name → value)."""
        return {"type": self.kind, "ngear": self.ngear, "encRes": self.enc_res, "Li": self.Li, "Di": self.D}


@dataclass
class RawRun:
    """One run file as read: times (K,) [s] as in the file, pose (K, 3) [m, m, rad] with NaN rows where
    tracking dropped out, counts (K, n) per cycle [encoder units], and each row's line in the file."""

    path: Path
    t: np.ndarray
    pose: np.ndarray
    ticks: np.ndarray
    lines: np.ndarray


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote: sessions, runs, robot time [s], the dataset folder and the assumed mass
    [kg], inertia [kg·m²] and surface preset of its nominal model; ``kind`` the robot type; the time base
    and any notes on it."""

    sessions: tuple[str, ...]
    runs: int
    duration: float
    out: Path
    mass: float
    inertia: float
    surface: str
    kind: str = "omni3"
    time_base: str = ""  # one sentence (Sessions.describe_time_base)
    notes: tuple[str, ...] = ()  # lines to print: runs whose clock is unlike their session's


# --- reading ----------------------------------------------------------------------------------------


def _rows(path: Path) -> list[tuple[int, list[str]]]:
    """(line, cells) of every non-blank row (BOM and CRLF accepted, ``.gz`` decompressed); InputError
    naming the file."""
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
    """A plain decimal number (may overflow to ±inf: callers bound it); InputError naming file, line and
    ``what``."""
    text = cell.strip()
    if not _NUMBER.fullmatch(text):
        raise InputError(f"{path}: line {line}: {what}: not a number: {text!r}")
    return float(text)


def read_metadata(path: str | Path) -> Metadata:
    """Read ``<id>_metadata.csv`` (format in the module docstring); InputError on a bad or missing key.

    ``Li`` and ``Di``/2 are held to the model bounds here (``docs/bounds.md``: wheel positions within
    ±10 m, wheel radius 1 mm to 2 m), so that an absurd value (``Li,1e308``) is named with its line
    rather than overflowing later.
    """
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
    if len(cells) != 1 or kind not in TYPES:
        got = ",".join(cells)
        match = re.fullmatch(r"omni(\d+)", kind)
        wheels = f" ({match.group(1)} wheels)" if match and len(cells) == 1 else ""
        raise InputError(f"{path}: line {line}: type {got!r}{wheels}: only {' and '.join(TYPES)} sessions "
                         "(three- and four-wheeled omnidirectional) can be imported")
    rt = TYPES[kind]
    scalars = {}
    for key in ("ngear", "encRes"):
        line, cells = get(key)
        if len(cells) != 1:
            raise InputError(f"{path}: line {line}: {key} must be one value, got {len(cells)}")
        scalars[key] = positive(key, cells, line)[0]
        if not LOGS[key].contains(scalars[key]):  # docs/bounds.md, "Logged robot metadata"
            what = "a motor-to-wheel gear ratio" if key == "ngear" else "encoder units per motor turn"
            raise InputError(f"{path}: line {line}: {key} ({what}) {LOGS[key].describe()}, got {scalars[key]:g}; "
                             "outside, the wheel readings would be 0 or noise")
    line, cells = get("Li")
    if len(cells) != rt.li_count:
        want = "one value (L)" if rt.li_count == 1 else "two values (l1, l2)"
        raise InputError(f"{path}: line {line}: Li has {len(cells)} value(s); type {kind} has {want}")
    Li = tuple(positive("Li", cells, line))
    position = MODEL_BOUNDS["wheels[i].position"]
    for v in Li:
        if not position.contains(v / rt.li_count):  # omni3: L; omni4: the wheel sits at l/2
            raise InputError(f"{path}: line {line}: Li {v:g} m puts a wheel outside the model bound "
                             f"(wheel positions {position.within()})")
        if not LOGS["Li"].contains(v):  # docs/bounds.md, "Logged robot metadata"
            raise InputError(f"{path}: line {line}: Li (the wheel-centre distance) {LOGS['Li'].describe()}, "
                             f"got {v:g}")
    line, cells = get("Di")
    if len(cells) != rt.n_wheels:
        raise InputError(f"{path}: line {line}: Di has {len(cells)} value(s); type {kind} has {rt.n_wheels} wheels")
    D = tuple(positive("Di", cells, line))
    radius = MODEL_BOUNDS["wheel_radius"]
    for v in D:
        if not radius.contains(v / 2):
            raise InputError(f"{path}: line {line}: Di {v:g} m: a wheel radius {radius.within()} is required")
    try:
        sync, sync_error = _sync_windows(path, values), ""
    except InputError as exc:  # needed for the tracker's time base only: --time-base file reads without them
        sync, sync_error = (), str(exc)
    return Metadata(path=path, session=session, kind=kind, ngear=scalars["ngear"], enc_res=scalars["encRes"],
                    Li=Li, D=D, sync=sync, sync_error=sync_error)


SYNC_KEYS = ("gt_ti", "gt_tf", "odo_ti", "odo_tf")


def _sync_windows(path: Path, values: dict[str, tuple[int, list[str]]]) -> tuple[SyncWindow, ...]:
    """The per-run synchronisation windows of a metadata file (rows ``gt_ti``, ``gt_tf``, ``odo_ti``,
    ``odo_tf``, one value per run); () if none of the rows is there; InputError naming the line if only
    some are, their lengths differ, or a window is not a finite interval of positive length."""
    present = [k for k in SYNC_KEYS if k in values]
    if not present:
        return ()
    if len(present) != len(SYNC_KEYS):
        missing = [k for k in SYNC_KEYS if k not in values]
        raise InputError(f"{path}: has {', '.join(present)} but no {', '.join(missing)} row: the synchronisation "
                         "windows need all four (or none: then import with --time-base file)")
    columns = {}
    for key in SYNC_KEYS:
        line, cells = values[key]
        numbers = [_number(c, path, line, key) for c in cells]
        for v in numbers:
            if not math.isfinite(v) or abs(v) > FILES["t"].hi:
                raise InputError(f"{path}: line {line}: {key} {FILES['t'].describe()}, got {v:g}")
        columns[key] = (line, numbers)
    counts = {len(columns[k][1]) for k in SYNC_KEYS}
    if len(counts) != 1:
        raise InputError(f"{path}: line {columns['gt_ti'][0]}: gt_ti, gt_tf, odo_ti and odo_tf have "
                         f"{', '.join(str(len(columns[k][1])) for k in SYNC_KEYS)} values: one per run each")
    out = []
    for i, (gi, gf, oi, of) in enumerate(zip(*(columns[k][1] for k in SYNC_KEYS), strict=True)):
        for key, lo, hi in (("gt", gi, gf), ("odo", oi, of)):
            if not hi > lo:
                raise InputError(f"{path}: line {columns[key + '_tf'][0]}: run {i + 1}: {key}_tf {hi:g} is not after "
                                 f"{key}_ti {lo:g}")
        out.append(SyncWindow(gi, gf, oi, of, columns["gt_ti"][0]))
    return tuple(out)


def read_run_file(path: str | Path, kind: str = "omni3") -> RawRun:
    """Read a run file of robot type ``kind`` (no header; ``.csv`` or ``.csv.gz``); InputError naming the
    file and the line."""
    path = Path(path)
    rt = TYPES[kind]
    columns = rt.run_columns()
    rows = _rows(path)
    if not rows:
        raise InputError(f"{path}: line 1: empty run file (no rows)")
    K = len(rows)
    data = np.empty((K, len(columns)))
    lines = np.empty(K, dtype=np.int64)
    for k, (line, row) in enumerate(rows):
        if len(row) != len(columns):
            raise InputError(f"{path}: line {line}: expected {len(columns)} values "
                             f"({', '.join(columns)}) for type {kind}, got {len(row)}")
        lines[k] = line
        for c, (cell, col) in enumerate(zip(row, columns, strict=True)):
            if _NAN.fullmatch(cell.strip()):
                if c >= 4:
                    raise InputError(f"{path}: line {line}: {col} is NaN: the wheel's motion in that cycle is "
                                     "unknown (only pose cells may be NaN)")
                if col == "time":
                    raise InputError(f"{path}: line {line}: time is NaN")
                data[k, c] = math.nan
                continue
            v = _number(cell, path, line, col)
            if not math.isfinite(v):  # a 400-digit number parses as inf
                raise InputError(f"{path}: line {line}: {col} is too large to be a number: {cell.strip()[:20]}…")
            if c >= 4 and rt.whole_counts and v != math.floor(v):
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
    return RawRun(path=path, t=t.copy(), pose=data[:, 1:4].copy(), ticks=data[:, 4:].copy(), lines=lines)


def run_name(path: Path) -> str:
    """``<id>_run-NN`` of ``<id>_run-NN.csv`` or ``<id>_run-NN.csv.gz``."""
    name = path.name
    for suffix in (".gz", ".csv"):
        name = name[: -len(suffix)] if name.endswith(suffix) else name
    return name


def convert_run(raw: RawRun, meta: Metadata, name: str | None = None, clock_scale: float = 1.0) -> Run:
    """A :class:`Run` of our format from one OptiOdom run (mapping in the module docstring).

    ``clock_scale``: tracker seconds per logged second (:attr:`SyncWindow.clock_scale`; 1: the file's time
    base). Row k is at t_k · clock_scale. If the type's counts are a rotation (omni3), the wheel angles are
    the counts and the speeds the counts over the stretched interval; if they are a speed times the nominal
    cycle (omni4), the speeds are the counts over the file's interval and the angles the counts ·
    clock_scale (:class:`RobotType`).

    Times are shifted to start at 0 if the file's first time is not 0. A pose row with any NaN cell
    becomes unobserved (NaN x, y, theta). InputError if the run has fewer than two rows, its first pose
    is not tracked, no pose after the first row is tracked, or a value leaves its bound
    (``docs/bounds.md``, "Command and dataset files").
    """
    path = raw.path
    K = len(raw.t)
    n = raw.ticks.shape[1]
    if K < 2:
        raise InputError(f"{path}: line {raw.lines[0]}: a run needs at least two rows (one cycle), got {K}")
    file_t = raw.t - raw.t[0]
    t = file_t * clock_scale
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
    ticks = raw.ticks[1:]  # row k's counts: the motion over (t_{k-1}, t_k]; row 0's came before the run
    cmd = np.zeros((K, n))
    with np.errstate(over="ignore"):  # a huge count overflows to inf: refused by the bound below
        speed_scale, angle_scale = ((1.0 / clock_scale, 1.0) if meta.robot_type.counts_are == "rotation"
                                    else (1.0, clock_scale))
        cmd[:-1] = ticks * (q * speed_scale) / np.diff(file_t)[:, None] + 0.0  # + 0.0: a "-0" count is 0.0
        enc = np.zeros((K, n))
        enc[1:] = np.cumsum(ticks, axis=0) * (q * angle_scale) + 0.0  # omni3: sum whole ticks first: exact
    for what, values, bound in (("wheel speed", cmd[:-1], FILES["w1 … wn"]),
                                ("wheel angle", enc[1:], FILES["enc1 … encn"])):
        outside = np.nonzero(~np.all((values >= bound.lo) & (values <= bound.hi), axis=1))[0]
        if outside.size:
            k = int(outside[0]) + 1
            raise InputError(f"{path}: line {raw.lines[k]}: the counts give a {what} outside "
                             f"{bound.within()} ({np.max(np.abs(values[k - 1])):.4g})")
    return Run(name=name or run_name(path), t=t, cmd=cmd, pose=pose, enc=enc, session=meta.session)


def find_session(folder: str | Path) -> tuple[Path, list[Path]]:
    """(metadata file, run files in run-number order) of one session folder; InputError if missing.

    Run files are ``<id>_run-NN.csv`` or ``<id>_run-NN.csv.gz``; one run in both forms is refused (which
    one is meant is unknown).
    """
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
    runs: dict[int, Path] = {}
    for p in sorted(folder.glob(f"{glob.escape(session)}_run-*.csv*")):
        m = _RUN_FILE.match(p.name)
        if m and m.group("session") == session:
            number = int(m.group("number"))
            if number in runs:
                raise InputError(f"{folder}: run {number} is there twice ({runs[number].name} and {p.name}); "
                                 "keep one of them")
            runs[number] = p
    if not runs:
        raise InputError(f"{folder}: no run files {session}_run-NN.csv (or .csv.gz)")
    return metas[0], [runs[k] for k in sorted(runs)]


@dataclass
class Sessions:
    """What :func:`read_sessions_timed` read: the sessions' metadata, the converted runs, each session's
    time base (session → ``"tracker"`` or ``"file"``), each run's clock scale (run name → tracker s per
    logged s; 1.0 on the file's time base), and lines to report (a run whose clock scale is unlike its
    session's, a session without windows under ``auto``)."""

    metas: list[Metadata]
    runs: list[Run]
    time_bases: dict[str, str]
    clock_scales: dict[str, float]
    notes: list[str]

    def describe_time_base(self) -> str:
        """One sentence on the time base, for the dataset's description and the import's output."""
        parts = []
        for meta in self.metas:
            if self.time_bases[meta.session] == "file":
                parts.append(f"{meta.session} the file's time column")
                continue
            mine = [self.clock_scales[r.name] for r in self.runs if r.session == meta.session]
            parts.append(f"{meta.session} the tracker's clock, {min(mine):.4f}–{max(mine):.4f} tracker s per logged s"
                         if len(mine) > 1 else f"{meta.session} the tracker's clock, {mine[0]:.4f} tracker s per "
                         "logged s")
        return f"time base: {'; '.join(parts)}"


def _check_time_base(time_base: str) -> None:
    if time_base not in TIME_BASES:
        raise InputError(f"--time-base {time_base!r}: choose one of {', '.join(TIME_BASES)}")


def _run_number(path: Path) -> int:
    match = _RUN_FILE.match(path.name)
    return int(match.group("number")) if match else 0


def clock_scale_of(meta: Metadata, raw: RawRun) -> float:
    """The run's clock scale from its synchronisation window (:class:`SyncWindow`); InputError naming the
    metadata line if the session has no windows, none for this run, or a window that does not describe
    the file (its odometry interval is not the file's duration, or the scale is out of reach)."""
    number = _run_number(raw.path)
    if meta.sync_error:
        raise InputError(meta.sync_error)
    if not meta.sync:
        raise InputError(f"{meta.path}: no synchronisation windows (gt_ti, gt_tf, odo_ti, odo_tf rows): the "
                         "tracker's time base is unknown; import with --time-base file to use the time column")
    if not 1 <= number <= len(meta.sync):
        raise InputError(f"{meta.path}: line {meta.sync[0].line}: {len(meta.sync)} synchronisation window(s), none "
                         f"for run {number} ({raw.path.name}); import with --time-base file to use the time column")
    window = meta.sync[number - 1]
    duration = float(raw.t[-1] - raw.t[0])
    cycle = float(np.median(np.diff(raw.t))) if len(raw.t) > 1 else 0.0
    logged = window.odo_tf - window.odo_ti
    if abs(duration - logged) > 1.5 * cycle:
        raise InputError(f"{meta.path}: line {window.line}: run {number}: the odometry window odo_tf − odo_ti = "
                         f"{logged:g} s but {raw.path.name} lasts {duration:g} s: the window is not this file's; "
                         "import with --time-base file to use the time column")
    scale = window.clock_scale
    lo, hi = CLOCK_SCALE_RANGE
    if not lo <= scale <= hi:
        raise InputError(f"{meta.path}: line {window.line}: run {number}: the tracker window lasts {scale:.3g}× the "
                         f"odometry window (allowed {lo:g}–{hi:g}): the clocks cannot differ that much")
    return scale


def _unlike_session(meta: Metadata, names: list[str], scales: list[float]) -> list[str]:
    """Lines naming the runs whose clock scale is further than CLOCK_SCALE_SPREAD from the session median."""
    if len(scales) < 3:  # a median of two says nothing about which one is unusual
        return []
    median = float(np.median(scales))
    return [f"note: {name}: clock scale {s:.4f} is {100 * (s / median - 1):+.1f} % from its session's "
            f"({meta.session}, median {median:.4f}): its synchronisation window may be off"
            for name, s in zip(names, scales, strict=True) if abs(s / median - 1) > CLOCK_SCALE_SPREAD]


def read_sessions_timed(folders: list[str | Path], time_base: str = "auto") -> Sessions:
    """Read and convert every run of the given session folders (in the order given) on ``time_base``
    (``"tracker"``: each run's synchronisation window, :func:`clock_scale_of`; ``"file"``: the time column;
    ``"auto"``: tracker for a session whose metadata has the windows, file (with a note) for one without).

    Refuses sessions of different robot types or configurations (``type``, ``ngear``, ``encRes``, ``Li``,
    ``Di``) and a session given twice; run names are the file names without ``.csv``/``.csv.gz``
    (``<id>_run-NN``).
    """
    _check_time_base(time_base)
    if not folders:
        raise InputError("optiodom: no session folder given")
    metas: list[Metadata] = []
    runs: list[Run] = []
    scales: dict[str, float] = {}
    bases: dict[str, str] = {}
    notes: list[str] = []
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
        base = time_base
        if base == "auto":
            if meta.sync_error:
                raise InputError(meta.sync_error)
            base = "tracker" if meta.sync else "file"
            if not meta.sync:
                notes.append(f"note: {meta.path}: no synchronisation windows (gt_ti, gt_tf, odo_ti, odo_tf): session "
                             f"{meta.session} keeps the file's time column")
        raws = [read_run_file(p, meta.kind) for p in run_paths]
        session_scales = [1.0] * len(raws)
        if base == "tracker":
            try:
                session_scales = [clock_scale_of(meta, raw) for raw in raws]
            except InputError as exc:
                if time_base == "tracker":
                    raise
                # auto: windows that do not describe these files (a cut run, say) give the session no time base
                base = "file"
                notes.append(f"note: {exc}; session {meta.session} keeps the file's time column")
        bases[meta.session] = base
        converted = [convert_run(raw, meta, clock_scale=scale) for raw, scale in zip(raws, session_scales, strict=True)]
        runs.extend(converted)
        names = [r.name for r in converted]
        scales.update(zip(names, session_scales, strict=True))
        if base == "tracker":
            notes.extend(_unlike_session(meta, names, session_scales))
    return Sessions(metas, runs, bases, scales, notes)


def read_sessions(folders: list[str | Path], time_base: str = "auto") -> tuple[list[Metadata], list[Run]]:
    """(metadata, runs) of :func:`read_sessions_timed`."""
    read = read_sessions_timed(folders, time_base)
    return read.metas, read.runs


def _fmt(value) -> str:
    """A metadata value for a message: ``12``, ``omni4`` or ``0.102,0.102,0.102``."""
    if isinstance(value, str):
        return value
    return ",".join(f"{v:g}" for v in value) if isinstance(value, tuple) else f"{value:g}"


# --- the nominal model --------------------------------------------------------------------------------


def _wheels_json(robot: RobotSpec) -> list[dict]:
    """A preset's wheels as model JSON: positions [m], unit drive directions, roller angles [rad] where not 0."""
    return [{"position": list(w.position), "drive": list(w.drive),
             **({"roller_angle": w.roller_angle} if w.roller_angle else {})} for w in robot.wheels]


def wheel_layout(L: float) -> list[dict]:
    """omni3: the three wheels of the physics preset ``optiodom_omni3`` at distance ``L`` [m], body frame."""
    return _wheels_json(PRESETS["optiodom_omni3"](L))


def omni4_wheel_layout(l1: float, l2: float) -> list[dict]:
    """omni4: the four mecanum wheels of the physics preset ``optiodom_omni4`` at (±l1/2, ±l2/2) [m], with
    drive directions and roller angles [rad] (model JSON ``wheels[i].roller_angle``); its wheel matrix is
    the data README's inverse kinematics (OptiOdom's simulateRobot_omni4.m)."""
    return _wheels_json(PRESETS["optiodom_omni4"](l1, l2))


def layout(meta: Metadata) -> list[dict]:
    """The model JSON ``wheels`` list of a session's robot type and lengths."""
    return _wheels_json(_preset(meta))


def _preset(meta: Metadata) -> RobotSpec:
    """The physics preset of the session's robot type at its lengths and mean wheel diameter (wheels,
    inertia, rollers and body radius of the nominal model)."""
    mean = float(np.mean(meta.D))
    if meta.kind == "omni4":
        return PRESETS["optiodom_omni4"](meta.Li[0], meta.Li[1], (mean,) * 4)
    return PRESETS["optiodom_omni3"](meta.L, mean)


def nominal_model_json(meta: Metadata, mass: float | None = None, inertia: float | None = None,
                       surface: str = SURFACE) -> dict:
    """The nominal model of a session as model JSON (``docs/formats.md``): geometry and wheel size from the
    metadata, assumed mass properties (:func:`nominal_model` builds it).

    ``mass`` [kg] (default :func:`default_mass`); ``inertia`` [kg·m²] (default: the physics preset's,
    scaled to ``mass``: omni3 0.5·mass·L², a disc of the wheel circle; omni4 a plate the size of the
    footprint); ``surface``: a preset name. If the Di differ, ``wheel_radius`` is mean(Di)/2 and a
    ``wheel_radius`` effect carries the scales Di/mean. Wheels, rollers and body radius come from the
    physics presets ``optiodom_omni3`` and ``optiodom_omni4``.
    """
    mass = default_mass(meta.kind) if mass is None else mass
    MODEL_BOUNDS["mass"].check(mass, "--mass")
    preset = _preset(meta)
    wheels = _wheels_json(preset)
    body_radius, rollers = preset.body_radius, preset.rollers
    inertia = preset.inertia * mass / preset.mass if inertia is None else inertia
    MODEL_BOUNDS["inertia"].check(inertia, "--inertia")
    D = np.asarray(meta.D, dtype=float)
    mean = float(np.mean(D))
    effects = {}
    if np.any(D != D[0]):
        effects["wheel_radius"] = {"scale": [float(d / mean) for d in D]}
    return {
        "name": f"optiodom-{meta.kind}",
        "mass": float(mass),
        "inertia": float(inertia),
        "gravity": 9.81,
        "wheel_radius": mean / 2.0,
        "wheels": wheels,
        "com": [0.0, 0.0],
        "rollers": rollers,
        "roller_fraction": ROLLER_FRACTION,
        "body_radius": body_radius,
        "friction": FRICTION,
        "surface": surface_preset(surface).to_json(),
        "effects": effects,
    }


def nominal_model(meta: Metadata, mass: float | None = None, inertia: float | None = None,
                  surface: str = SURFACE) -> SimModel:
    """The nominal :class:`SimModel` of a session (:func:`nominal_model_json`)."""
    data = nominal_model_json(meta, mass, inertia, surface)
    try:
        return SimModel.from_json(data, where="nominal model")
    except ValueError as exc:  # Li or Di outside the model bounds: name the metadata file
        raise InputError(f"{meta.path}: {exc}") from None


def describe(metas: list[Metadata], n_runs: int, mass: float, inertia: float, surface: str) -> str:
    """The dataset's description: sources and the assumptions of the nominal model."""
    ids = ", ".join(m.session for m in metas)
    kind = metas[0].kind
    counts = "wheel revolutions per 10 ms" if kind == "omni4" else "encoder ticks per 40 ms"
    rollers = PRESETS[f"optiodom_{kind}"]().rollers
    return (f"OptiOdom {kind} sessions {ids} ({n_runs} runs; {counts} and motion capture, public OptiOdom "
            f"dataset, MIT licence), imported by omni-gym import optiodom. Geometry and wheel diameters from the "
            f"metadata; assumed (not published): mass {mass:g} kg, inertia {inertia:.4g} kg·m², {rollers} rollers, "
            f"roller_fraction {ROLLER_FRACTION:g}, friction {FRICTION}, surface {surface} "
            f"(docs/formats.md, 'Importing OptiOdom logs').")


def check_scale(metas: list[Metadata], runs: list[Run]) -> None:
    """Refuse, before anything is written, runs whose rates are out of reach (positions in millimetres,
    a heading in degrees: :func:`~omni_gym.discrepancy.data.units.check_run_units`, as reading the
    dataset would) and sessions whose tracked motion does not match the wheel travel the encoder settings
    give (:func:`~omni_gym.discrepancy.data.units.check_travel_scale`; ``docs/bounds.md``, "Logged robot
    metadata")."""
    for meta in metas:
        mine = [r for r in runs if r.session == meta.session]
        radii = np.asarray(meta.D) / 2.0
        W = nominal_model(meta).robot.wheel_matrix()  # the mean wheel radius: enough to tell a unit error
        motion = np.zeros(4)
        for run in mine:
            files = sorted(meta.path.parent.glob(f"{glob.escape(run.name)}.csv*"))
            source = files[0] if files else meta.path.parent / run.name
            check_run_units(source, run.t, run.cmd, run.pose, float(np.mean(radii)))
            motion += travel(run.t, run.pose, run.enc, W)
        settings = f"ngear {meta.ngear:g}, encRes {meta.enc_res:g}, Di {', '.join(f'{d:g}' for d in meta.D)} m"
        check_travel_scale(f"{meta.path} ({len(mine)} runs)", motion, settings)


def import_optiodom(folders: list[str | Path], out: str | Path, force: bool = False, mass: float | None = None,
                    inertia: float | None = None, surface: str = SURFACE, time_base: str = "auto") -> ImportSummary:
    """Import OptiOdom session folders into the dataset folder ``out``; returns what was written.

    ``mass`` [kg]: default :func:`default_mass` of the sessions' type. ``time_base``: see
    :func:`read_sessions_timed`. The output is complete or absent
    (:class:`omni_gym.outputs.Output`, as ``omni-gym synth``): an existing dataset is refused unless
    ``force``; an output inside (or equal to) a session folder always.
    """
    surface_preset(surface)  # an unknown preset is refused before anything is read or locked
    _check_time_base(time_base)  # refused before anything is read or locked, as the surface
    if mass is not None:
        MODEL_BOUNDS["mass"].check(mass, "--mass")
    if inertia is not None:
        MODEL_BOUNDS["inertia"].check(inertia, "--inertia")
    folders = [Path(f) for f in folders]
    out = Path(out)
    read: dict = {}

    def build():
        sessions = read_sessions_timed(folders, time_base)
        metas, runs = sessions.metas, sessions.runs
        check_scale(metas, runs)
        model = nominal_model(metas[0], mass, inertia, surface)
        read.update(sessions=sessions, model=model)
        desc = describe(metas, len(runs), model.robot.mass, model.robot.inertia, surface)
        timing = sessions.describe_time_base()
        return model.to_json(), f"{desc} {timing[0].upper()}{timing[1:]}.", runs

    write_imported(out, folders, force, build, hint="check the metadata's ngear, encRes and Di")
    sessions, model = read["sessions"], read["model"]
    metas, runs = sessions.metas, sessions.runs
    return ImportSummary(sessions=tuple(m.session for m in metas), runs=len(runs),
                         duration=float(sum(r.t[-1] for r in runs)), out=out, mass=model.robot.mass,
                         inertia=model.robot.inertia, surface=surface, kind=metas[0].kind,
                         time_base=sessions.describe_time_base(), notes=tuple(sessions.notes))
