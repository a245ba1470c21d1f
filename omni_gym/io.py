"""Reading and writing the file formats of the command line (``docs/formats.md``): CSV, JSON and YAML.

Every reader error is a :class:`InputError` whose one-line message names the file and the row
(1-based, counting the header as row 1). Every read is bounded (docs/bounds.md, "Files"): only regular
files (no devices, pipes or sockets), at most :func:`max_input_bytes` (``--max-input-mb`` raises it),
JSON nested at most :data:`MAX_JSON_DEPTH` levels, YAML without aliases; a message quotes at most
:data:`EXCERPT` characters of a value (:func:`excerpt`).
"""

from __future__ import annotations

import csv
import gzip
import io
import json
import os
import re
import stat
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from omni_gym.bounds import FILES, Bound


class InputError(ValueError):
    """Bad user input: the message is one line naming the file and, where it applies, the row."""


# The limits of every file read (docs/bounds.md, "Files"); one home. A CSV is parsed into Python objects
# about fifteen times its size (a 63 MB commands file peaks at 1.0 GB), so 32 MB keeps a command near
# 0.5 GB; an hour of 100 Hz logs with ten columns is about 30 MB, the largest shipped data file under 1 MB.
DEFAULT_MAX_INPUT_MB = 32.0
MAX_INPUT_MB_RANGE = (0.001, 4096.0)  # what --max-input-mb accepts
MAX_JSON_DEPTH = 64  # the deepest shipped JSON (meta.json, dataset.json) nests 5 levels
MAX_YAML_BYTES = 1 * 2**20  # hyperparameter and RL Zoo files are a few kB
EXCERPT = 60  # characters of a value quoted in a message
_limits = {"input_bytes": int(DEFAULT_MAX_INPUT_MB * 2**20)}


def max_input_bytes() -> int:
    """The size limit [bytes] of a text input (after gzip decompression)."""
    return _limits["input_bytes"]


def set_max_input_mb(mb: float) -> None:
    """Raise (or lower) the text-input limit for this process (``--max-input-mb``); ValueError outside
    :data:`MAX_INPUT_MB_RANGE`."""
    lo, hi = MAX_INPUT_MB_RANGE
    if not (isinstance(mb, (int, float)) and lo <= mb <= hi):
        raise ValueError(f"--max-input-mb must be in [{lo:g}, {hi:g}], got {excerpt(mb)}")
    _limits["input_bytes"] = int(mb * 2**20)


@contextmanager
def input_limit_mb(mb: float | None) -> Iterator[None]:
    """The text-input limit set to ``mb`` (None: unchanged) for the ``with`` block, then restored exactly."""
    before = _limits["input_bytes"]
    if mb is not None:
        set_max_input_mb(mb)
    try:
        yield
    finally:
        _limits["input_bytes"] = before


def excerpt(value, limit: int = EXCERPT) -> str:
    """``value`` as at most ``limit`` characters on one line (longer text ends with '...')."""
    text = " ".join(str(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _escape(ch: str) -> str:
    code = ord(ch)
    return {"\n": "\\n", "\r": "\\r", "\t": "\\t"}.get(ch) or (f"\\x{code:02x}" if code < 256 else f"\\u{code:04x}")


# Characters a terminal acts on instead of showing: C0 and C1 controls, DEL, line and paragraph separators,
# and the bidirectional overrides that reorder what follows them.
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def printable(text) -> str:
    """``text`` with every control character escaped as ``repr`` writes it (``\\n``, ``\\x1b``, ``\\u202e``),
    everything else kept: for echoing an untrusted string (a bag's frame id, a column name) in a message
    or on the terminal, where an escape sequence or a newline would otherwise act or forge a line."""
    return _CONTROL.sub(lambda m: _escape(m.group()), str(text))


def _mb(n: int) -> str:
    return f"{n / 2**20:.3g} MB"


def check_readable(path: str | Path, limit: int | None = None, what: str = "input") -> int:
    """The size [bytes] of ``path`` if it is a regular file of at most ``limit`` bytes (default
    :func:`max_input_bytes`); InputError naming the file otherwise (devices such as /dev/zero, pipes and
    sockets are refused before they are opened: reading them never ends or never returns)."""
    path = Path(path)
    limit = max_input_bytes() if limit is None else limit
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path}: is a directory, expected a file")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{path}: not a regular file (a device, pipe or socket); omni-gym reads only plain files")
    if st.st_size > limit:
        raise InputError(f"{path}: {_mb(st.st_size)} is more than the {_mb(limit)} limit for {what} "
                         f"(docs/bounds.md; --max-input-mb raises it)")
    return st.st_size


def read_bytes(path: str | Path, limit: int | None = None, what: str = "input") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (:func:`check_readable`); a name ending in
    ``.gz`` is decompressed, and the decompressed size is bounded by the same limit."""
    path = Path(path)
    limit = max_input_bytes() if limit is None else limit
    check_readable(path, limit, what)
    try:
        with open(path, "rb") as fh:
            raw = fh.read(limit + 1)  # the file may have grown since stat
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if len(raw) > limit:
        raise InputError(f"{path}: more than the {_mb(limit)} limit for {what} (docs/bounds.md; --max-input-mb "
                         f"raises it)")
    if path.name.endswith(".gz"):
        try:
            with gzip.GzipFile(fileobj=io.BytesIO(raw)) as gz:
                raw = gz.read(limit + 1)
        except (OSError, EOFError, zlib.error) as exc:  # not gzip (BadGzipFile), truncated (EOFError), corrupt (zlib)
            raise InputError(f"{path}: not a readable gzip file ({excerpt(exc)})") from None
        if len(raw) > limit:
            raise InputError(f"{path}: decompresses to more than the {_mb(limit)} limit for {what} "
                             f"(docs/bounds.md; --max-input-mb raises it)")
    return raw


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
    k = first_not_increasing(times)
    if k is not None:
        raise InputError(f"{path}: row {k + 2}: times must be strictly increasing "
                         f"({times[k]:g} after {times[k - 1]:g})")


def first_not_increasing(times: np.ndarray) -> int | None:
    """Index k of the first time that does not come after the one before it (times[k] <= times[k-1]), or None."""
    bad = np.nonzero(np.diff(times) <= 0)[0]
    return int(bad[0]) + 1 if bad.size else None


def read_text(path: str | Path) -> str:
    """The text of a UTF-8 file, without a leading byte-order mark; InputError naming the file.

    Spreadsheet programs and some editors start UTF-8 files with a byte-order mark (and end lines
    with CRLF, which the CSV and JSON readers accept): both are read as if absent. A name ending in
    ``.gz`` is gzip-decompressed first.
    """
    path = Path(path)
    raw = read_bytes(path)
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(f"{path}: UTF-16 text; save it as UTF-8 (e.g. 'CSV UTF-8')")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text file (byte 0x{raw[exc.start]:02x} at offset {exc.start})") from None


def read_json(path: str | Path):
    """A JSON file's content (UTF-8, optional byte-order mark); ValueError naming the file."""
    return parse_json(read_text(path), str(path))


def _depth(value) -> int:
    """How deeply lists and objects nest in parsed JSON (iteratively: no recursion limit to hit)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, (list, dict)):
            deepest = max(deepest, d)
            stack.extend((c, d + 1) for c in (v.values() if isinstance(v, dict) else v))
    return deepest


def parse_json(text: str, where: str):
    """JSON text (a file's content or a command-line value) nested at most :data:`MAX_JSON_DEPTH` levels;
    InputError naming ``where`` (a file or an option) with the line and column."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    except RecursionError:
        raise InputError(f"{where}: not valid JSON (nested too deeply)") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise InputError(f"{where}: not valid JSON ({excerpt(exc)})") from None
    if _depth(value) > MAX_JSON_DEPTH:
        raise InputError(f"{where}: JSON nested more than {MAX_JSON_DEPTH} levels (docs/bounds.md)")
    return value


MAX_YAML_NODES = 100_000  # values after aliases are expanded; a hyperparameter file has a few hundred


def _expanded_size(node, memo: dict) -> int:
    """How many values a YAML node stands for once every alias is written out (shared nodes counted
    each time they are referred to, computed once each)."""
    key = id(node)
    if key not in memo:
        memo[key] = 1  # a cycle (a recursive alias) counts once
        value = node.value
        if isinstance(value, list):
            children = [c for pair in value for c in (pair if isinstance(pair, tuple) else (pair,))]
            memo[key] = 1 + sum(_expanded_size(c, memo) for c in children)
    return memo[key]


def read_yaml(path: str | Path, loader=None):
    """A YAML file's content, read with PyYAML's safe loader (or ``loader``, a subclass of it), at most
    :data:`MAX_YAML_BYTES` and :data:`MAX_YAML_NODES` values once aliases are expanded (an alias bomb
    expands a few lines into gigabytes); InputError naming the file (and line)."""
    import yaml

    path = Path(path)
    raw = read_bytes(path, MAX_YAML_BYTES, "a YAML file")
    reader = None
    try:
        reader = (loader or yaml.SafeLoader)(raw)  # reads the encoding: may fail already
        node = reader.get_single_node()
        if node is not None and _expanded_size(node, {}) > MAX_YAML_NODES:
            raise InputError(f"{path}: more than {MAX_YAML_NODES} values once its aliases (*name) are expanded "
                             "(docs/bounds.md)")
        return None if node is None else reader.construct_document(node)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or exc
        raise InputError(f"{path}: not valid YAML ({line}{excerpt(problem)})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not valid YAML (not UTF-8/16/32 text: {excerpt(exc.reason)} at byte "
                         f"{exc.start})") from None
    except RecursionError:
        raise InputError(f"{path}: not valid YAML (nested too deeply)") from None
    finally:
        if reader is not None:
            reader.dispose()


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
