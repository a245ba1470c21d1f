"""Reading and writing the file formats of the command line (``docs/formats.md``): CSV and JSON.

Every reader error is a :class:`InputError` whose one-line message names the file and the row
(1-based, counting the header as row 1).
"""

from __future__ import annotations

import csv
import gzip
import io
import json
import re
import zlib
from pathlib import Path

import numpy as np

from omni_gym.bounds import FILES, Bound


class InputError(ValueError):
    """Bad user input: the message is one line naming the file and, where it applies, the row."""


def read_commands(path: str | Path, n_wheels: int) -> tuple[np.ndarray, np.ndarray]:
    """Read ``t,w1,…,wn``: times [s] from 0, strictly increasing; wheel speeds [rad/s].

    Returns (times (K,), commands (K, n)). Values outside ``omni_gym.bounds.FILES`` are refused.
    """
    path = Path(path)
    rows = read_csv_rows(path)
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
            data[r - 2, c] = parse_cell(cell, path, r, expected[c])
    times = data[:, 0]
    check_times(path, times)
    return times, data[:, 1:]


def check_times(path: Path, times: np.ndarray) -> None:
    """Refuse times [s] that do not start at 0 or do not strictly increase (rows counted from 2)."""
    if times[0] != 0.0:
        raise InputError(f"{path}: row 2: the first time must be 0, got {times[0]:g}")
    bad = np.nonzero(np.diff(times) <= 0)[0]
    if bad.size:
        r = int(bad[0]) + 3
        raise InputError(f"{path}: row {r}: times must be strictly increasing "
                         f"({times[bad[0] + 1]:g} after {times[bad[0]]:g})")


def read_text(path: str | Path) -> str:
    """The text of a UTF-8 file, without a leading byte-order mark; InputError naming the file.

    Spreadsheet programs and some editors start UTF-8 files with a byte-order mark (and end lines
    with CRLF, which the CSV and JSON readers accept): both are read as if absent. A name ending in
    ``.gz`` is gzip-decompressed first.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, expected a file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if path.name.endswith(".gz"):
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError, zlib.error) as exc:  # not gzip, truncated, corrupt
            raise InputError(f"{path}: not a readable gzip file ({exc})") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(f"{path}: UTF-16 text; save it as UTF-8 (e.g. 'CSV UTF-8')")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text file (byte 0x{raw[exc.start]:02x} at offset {exc.start})") from None


def read_json(path: str | Path):
    """A JSON file's content (UTF-8, optional byte-order mark); ValueError naming the file."""
    text = read_text(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    except RecursionError:
        raise InputError(f"{path}: not valid JSON (nested too deeply)") from None


# Separators other than ',' that spreadsheets and loggers write: named when a header has only one cell.
SEPARATORS = {";": "';'", "\t": "tabs", " ": "spaces", "|": "'|'"}


def read_csv_rows(path: Path) -> list[list[str]]:
    """Non-blank rows of a CSV file (BOM and CRLF accepted); InputError naming the file."""
    text = read_text(path)
    try:
        rows = [row for row in csv.reader(io.StringIO(text, newline=""))
                if row and any(cell.strip() for cell in row)]
    except csv.Error as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    if not rows:
        raise InputError(f"{path}: row 1: empty file (expected a header row)")
    if len(rows[0]) == 1:  # a one-cell header: the file is split by something other than commas
        for sep, name in SEPARATORS.items():
            if sep in rows[0][0].strip():
                raise InputError(f"{path}: row 1: the file uses {name} as separator; omni-gym reads comma-separated "
                                 "values (save it as CSV with ',' between values and '.' as decimal point)")
    return rows


# A decimal number as spreadsheets write it: no digit-group underscores, no non-ASCII digits.
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_NON_FINITE = re.compile(r"[+-]?(nan|inf|infinity)", re.IGNORECASE)


def parse_cell(cell: str, path: Path, row: int, column: str) -> float:
    """One CSV cell as a float inside ``bounds.FILES`` for ``column``; InputError naming file/row/column."""
    text = cell.strip()
    if _NON_FINITE.fullmatch(text):
        raise InputError(f"{path}: row {row}: column {column}: value must be finite, got {text}")
    if not _NUMBER.fullmatch(text):
        hint = " (write digits without '_' group separators)" if "_" in text else ""
        raise InputError(f"{path}: row {row}: column {column}: not a number: {text!r}{hint}")
    value = float(text)
    bound = column_bound(column)
    if bound is not None and not bound.contains(value):
        raise InputError(f"{path}: row {row}: column {column}: {bound.describe()}, got {text}")
    return value


def column_bound(column: str) -> Bound | None:
    """The bound of a command or run CSV column (``t``, ``w3``, ``enc2``, ``x``, …), None if unknown."""
    if column in ("x", "y"):
        return FILES["x, y"]
    if column in ("t", "theta", "gyro"):
        return FILES[column]
    for prefix, key in (("enc", "enc1 … encn"), ("w", "w1 … wn")):
        if column.startswith(prefix) and column[len(prefix):].isdigit():
            return FILES[key]
    return None


def write_csv_atomic(path: str | Path, header: list[str], rows: np.ndarray) -> None:
    """Write a CSV through a temporary file and rename, so a failure never leaves a partial file
    (``omni_gym.outputs``: the user's umask applies)."""
    from omni_gym.outputs import write_csv_atomic as write

    write(path, header, rows)


TRAJECTORY_HEADER = ["t", "x", "y", "theta", "vx", "vy", "omega"]
