"""Import any CSV log with a header (``omni-gym import csv``): a column map and units → a dataset.

A spreadsheet or another logger's CSV holds a time column, the tracked pose and one column per wheel
(angles or speeds). ``--columns`` names them (dataset name = file column)::

    t=time,x=pose_x,y=pose_y,theta=yaw,enc1=wheel_fl,enc2=-wheel_fr,enc3=wheel_rear

``t``, ``x``, ``y``, ``theta`` are required, and either ``enc1 … encn`` (wheel angles) or ``w1 … wn`` (wheel
speeds) for the model's n wheels, in the model's wheel order; a leading ``-`` flips a wheel's sign. A row
may leave the pose cells empty (no pose sample at that time) or the wheel cells empty (no wheel sample):
a logger that writes both streams into one table interleaves them. ``--units`` converts to SI
(:func:`~omni_gym.discrepancy.data.importers.logs.parse_units`). Each file is one run (named after the file),
or each ``--window`` of each file is one. The conversion is
:func:`~omni_gym.discrepancy.data.importers.logs.make_run`.

Every error is a one-line :class:`~omni_gym.io.InputError` naming the file, the row (row 1 = the header) and
the column. Files may start with a UTF-8 byte-order mark and use CRLF line ends.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omni_gym.discrepancy.data.importers.logs import (
    PoseLog,
    Units,
    WheelLog,
    Window,
    check_increasing,
    check_moving,
    make_run,
    write_imported,
)
from omni_gym.io import InputError, read_csv_rows
from omni_gym.physics.model import SimModel

_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
MAX_ROWS = 10_000_000  # rows per file: 28 hours at 100 Hz
MAX_BYTES = 2**30  # 1 GiB per file (10^7 rows of 100 characters): a larger file is refused before it is read


@dataclass(frozen=True)
class ColumnMap:
    """Dataset column → (file column, sign). ``wheels``: the wheel columns in model order; ``kind``:
    "position" (``enc``) or "velocity" (``w``)."""

    t: str
    x: str
    y: str
    theta: str
    wheels: tuple[tuple[str, float], ...]
    kind: str

    def describe(self) -> str:
        tag = "enc" if self.kind == "position" else "w"
        wheels = ", ".join(f"{tag}{i + 1}={'-' if s < 0 else ''}{c}" for i, (c, s) in enumerate(self.wheels))
        return f"t={self.t}, x={self.x}, y={self.y}, theta={self.theta}, {wheels}"


def parse_columns(spec: str, n_wheels: int, option: str = "--columns") -> ColumnMap:
    """``t=time,x=px,…,enc1=a,enc2=-b`` → :class:`ColumnMap` for a model of ``n_wheels``; InputError naming
    the entry."""
    pairs: dict[str, tuple[str, float]] = {}
    for item in spec.split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, col = item.partition("=")
        key, col = key.strip(), col.strip()
        if not sep or not col:
            raise InputError(f"{option}: {item!r}: expected NAME=COLUMN (e.g. t=time)")
        sign = 1.0
        if col.startswith("-"):
            sign, col = -1.0, col[1:].strip()
        if key in pairs:
            raise InputError(f"{option}: {key} given twice")
        if sign < 0 and key in ("t", "x", "y", "theta"):
            raise InputError(f"{option}: {key}: only wheel columns take a sign")
        pairs[key] = (col, sign)
    for key in ("t", "x", "y", "theta"):
        if key not in pairs:
            raise InputError(f"{option}: no {key}=COLUMN (t, x, y, theta are required)")
    enc = [f"enc{i + 1}" for i in range(n_wheels)]
    w = [f"w{i + 1}" for i in range(n_wheels)]
    has_enc, has_w = any(k in pairs for k in enc), any(k in pairs for k in w)
    if has_enc and has_w:
        raise InputError(f"{option}: give wheel angles (enc1…enc{n_wheels}) or wheel speeds (w1…w{n_wheels}), "
                         "not both")
    names = enc if has_enc or not has_w else w
    missing = [k for k in names if k not in pairs]
    if missing:
        raise InputError(f"{option}: no {', '.join(missing)} (the model has {n_wheels} wheels: "
                         f"{names[0]}…{names[-1]})")
    unknown = sorted(set(pairs) - {"t", "x", "y", "theta", *names})
    if unknown:
        raise InputError(f"{option}: unknown name(s) {', '.join(unknown)} (t, x, y, theta, {names[0]}…{names[-1]})")
    users: dict[str, list[str]] = {}
    for key, (col, _) in pairs.items():
        users.setdefault(col, []).append(key)
    shared = {col: keys for col, keys in users.items() if len(keys) > 1}
    if shared:  # one column read as two quantities (a copy-paste slip: theta=enc1, y=x) is never meant
        col, keys = next(iter(shared.items()))
        raise InputError(f"{option}: column {col!r} is mapped to {' and '.join(keys)}; each name needs its own column")
    return ColumnMap(pairs["t"][0], pairs["x"][0], pairs["y"][0], pairs["theta"][0],
                     tuple(pairs[k] for k in names), "position" if names is enc else "velocity")


def read_log(path: str | Path, columns: ColumnMap, units: Units) -> tuple[WheelLog, PoseLog]:
    """Read one CSV log into SI wheel and pose streams; InputError naming file, row and column."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError:
        size = 0  # a missing file: read_csv_rows names it
    if size > MAX_BYTES:
        raise InputError(f"{path}: {size / 2**20:.0f} MiB; at most {MAX_BYTES // 2**20} MiB per file (split the log)")
    rows = read_csv_rows(path)
    if len(rows) > MAX_ROWS + 1:
        raise InputError(f"{path}: {len(rows) - 1} rows; at most {MAX_ROWS} per file (split the log)")
    header = [h.strip() for h in rows[0]]
    wanted = [columns.t, columns.x, columns.y, columns.theta, *(c for c, _ in columns.wheels)]
    index = {}
    for col in wanted:
        if col not in header:
            shown = ", ".join(header[:12]) + (" …" if len(header) > 12 else "")
            raise InputError(f"{path}: row 1: no column {col!r} (the header has: {shown})")
        if header.count(col) > 1:
            raise InputError(f"{path}: row 1: column {col!r} appears {header.count(col)} times")
        index[col] = header.index(col)
    if len(rows) < 2:
        raise InputError(f"{path}: row 2: no data rows after the header")
    data = np.full((len(rows) - 1, len(wanted)), np.nan)
    for r, row in enumerate(rows[1:], start=2):
        for c, col in enumerate(wanted):
            j = index[col]
            cell = row[j].strip() if j < len(row) else ""
            if not cell:
                if c == 0:
                    raise InputError(f"{path}: row {r}: column {col}: empty time cell")
                continue
            if not _NUMBER.fullmatch(cell):
                raise InputError(f"{path}: row {r}: column {col}: not a number: {cell[:20]!r}")
            v = float(cell)
            if not math.isfinite(v):
                raise InputError(f"{path}: row {r}: column {col}: too large to be a number: {cell[:20]}…")
            data[r - 2, c] = v
    t = data[:, 0] * units.time
    check_increasing(t, str(path), "row", first=2)  # row 1 is the header
    pose = data[:, 1:4] * np.array([units.length, units.length, units.angle])
    seen = np.all(np.isfinite(pose), axis=1)
    partial = np.nonzero(np.any(np.isfinite(pose), axis=1) & ~seen)[0]
    if partial.size:
        raise InputError(f"{path}: row {int(partial[0]) + 2}: {columns.x}, {columns.y} and {columns.theta} must be "
                         "all given or all empty")
    wheel = data[:, 4:]
    full = np.all(np.isfinite(wheel), axis=1)
    partial = np.nonzero(np.any(np.isfinite(wheel), axis=1) & ~full)[0]
    if partial.size:
        raise InputError(f"{path}: row {int(partial[0]) + 2}: the wheel columns must be all given or all empty")
    if np.count_nonzero(seen) < 2:
        raise InputError(f"{path}: fewer than two rows with a pose ({columns.x}, {columns.y}, {columns.theta})")
    if np.count_nonzero(full) < 2:
        raise InputError(f"{path}: fewer than two rows with every wheel column")
    signs = np.array([s for _, s in columns.wheels])
    factor = units.wheel
    names = tuple(f"{'-' if s < 0 else ''}{c}" for c, s in columns.wheels)
    wheels = WheelLog(t[full], wheel[full] * signs * factor, columns.kind, str(path), names)
    check_moving(wheels)
    return wheels, PoseLog(t[seen], pose[seen], str(path))


def describe(files: list[Path], columns: ColumnMap, units: Units, model_name: str, max_gap: float) -> str:
    """The dataset description: the source and every assumption of the import."""
    what = ("wheel angles; the held command is the mean speed between samples" if columns.kind == "position"
            else "wheel speeds; the held command is the mean of two samples (trapezoid)")
    return (f"imported by omni-gym import csv from {', '.join(f.name for f in files)}: columns {columns.describe()} "
            f"({what}); units {units.describe()}; the pose is interpolated linearly to the wheel sample times "
            f"(rows between pose samples more than {max_gap:g} s apart are unobserved); nominal model {model_name}.")


def import_csv(files: list[str | Path], out: str | Path, model: SimModel, columns: str, units: Units,
               windows: list[Window] | None = None, max_gap: float = 0.25, force: bool = False,
               model_name: str = "") -> tuple[list[str], str]:
    """Import CSV logs into the dataset folder ``out`` (complete or absent); returns (run names, description)."""
    paths = [Path(f) for f in files]
    if not paths:
        raise InputError("csv: no log file given")
    cmap = parse_columns(columns, model.n_wheels)
    desc = describe(paths, cmap, units, model_name or model.robot.name, max_gap)
    names: list[str] = []

    def build():
        runs = []
        for p in paths:
            wheels, pose = read_log(p, cmap, units)
            for w in windows or [None]:
                name = p.stem if w is None else (w.name if len(paths) == 1 else f"{p.stem}-{w.name}")
                runs.append(make_run(name, wheels, pose, model.robot.wheel_radius, w, max_gap))
        names.extend(r.name for r in runs)
        return model.to_json(), desc, runs

    write_imported(out, paths, force, build)
    return names, desc
