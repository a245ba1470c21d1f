"""Reading and writing the CSV formats of the command line (``docs/formats.md``).

Every reader error is a :class:`InputError` whose one-line message names the file and the row
(1-based, counting the header as row 1).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np


class InputError(ValueError):
    """Bad user input: the message is one line naming the file and, where it applies, the row."""


def read_commands(path: str | Path, n_wheels: int) -> tuple[np.ndarray, np.ndarray]:
    """Read ``t,w1,…,wn``: times [s] from 0, strictly increasing; wheel speeds [rad/s].

    Returns (times (K,), commands (K, n)).
    """
    path = Path(path)
    rows = _read_rows(path)
    header = [h.strip() for h in rows[0]]
    expected = ["t"] + [f"w{i + 1}" for i in range(n_wheels)]
    if header != expected:
        wheels = sum(1 for h in header if h.startswith("w"))
        if header and header[0] == "t" and wheels != n_wheels:
            raise InputError(f"{path}: row 1: header has {wheels} wheel columns, the model has {n_wheels} wheels "
                             f"(expected {','.join(expected)})")
        raise InputError(f"{path}: row 1: header must be {','.join(expected)}, got {','.join(header)}")
    if len(rows) < 2:
        raise InputError(f"{path}: no command rows after the header")
    data = np.empty((len(rows) - 1, n_wheels + 1))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != n_wheels + 1:
            raise InputError(f"{path}: row {r}: expected {n_wheels + 1} values, got {len(row)}")
        for c, cell in enumerate(row):
            data[r - 2, c] = _parse_float(cell, path, r, expected[c])
    times = data[:, 0]
    if times[0] != 0.0:
        raise InputError(f"{path}: row 2: the first time must be 0, got {times[0]:g}")
    bad = np.nonzero(np.diff(times) <= 0)[0]
    if bad.size:
        r = int(bad[0]) + 3
        raise InputError(f"{path}: row {r}: times must be strictly increasing "
                         f"({times[bad[0] + 1]:g} after {times[bad[0]]:g})")
    return times, data[:, 1:]


def _read_rows(path: Path) -> list[list[str]]:
    try:
        with path.open(newline="") as fh:
            rows = [row for row in csv.reader(fh) if row and any(cell.strip() for cell in row)]
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    if not rows:
        raise InputError(f"{path}: empty file (expected a header row)")
    return rows


def _parse_float(cell: str, path: Path, row: int, column: str) -> float:
    try:
        value = float(cell)
    except ValueError:
        raise InputError(f"{path}: row {row}: column {column}: not a number: {cell.strip()!r}") from None
    if not math.isfinite(value):
        raise InputError(f"{path}: row {row}: column {column}: value must be finite, got {cell.strip()}")
    return value


def write_csv_atomic(path: str | Path, header: list[str], rows: np.ndarray) -> None:
    """Write a CSV through a temporary file and rename, so a failure never leaves a partial file
    (``omni_gym.outputs``: the user's umask applies)."""
    from omni_gym.outputs import write_csv_atomic as write

    write(path, header, rows)


TRAJECTORY_HEADER = ["t", "x", "y", "theta", "vx", "vy", "omega"]
