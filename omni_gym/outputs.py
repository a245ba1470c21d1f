"""Outputs that are complete or absent (``docs/formats.md`` "Outputs: complete or absent").

Every file and folder the command line writes goes through this module:

* :func:`write_bytes_atomic` (and the text/JSON/CSV helpers): a temporary sibling created with
  mode 0666 (the user's umask applies, as for any ``open``), written, fsync'ed and renamed.
* :class:`Output`: a transactional output file or folder. On entry, before any work: the target is
  checked (it is not one of the inputs, not inside one, an existing target is refused unless
  ``force``), a lock is taken (a second writer of the same target is refused at once) and stale
  temporary siblings of killed runs are removed. A folder is built in a temporary sibling
  ``.NAME.tmp-PID`` (same parent, so the final rename is atomic) and renamed into place on success;
  an old target is moved aside to ``.NAME.old-PID`` first and removed after. On failure the
  temporary sibling is removed and the old target is untouched. A run killed between the two renames
  leaves the old output in ``.NAME.old-PID``; the next run to that target puts it back first.
"""

from __future__ import annotations

import csv
import errno
import fcntl
import io
import json
import math
import os
import re
import shutil
import stat
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# Temporary siblings: ".NAME.tmp-PID", ".NAME.old-PID" (folders, staged companions) and the lock
# ".NAME.lock". Any path component of that shape is an unfinished write.
_TEMP_NAME = re.compile(r"^\..+\.(tmp|old)-\d+(-\d+)?$")


class OutputError(ValueError):
    """An output that cannot be written as asked (exists, is an input, is locked): one line naming it."""


def is_temporary(path: str | Path) -> bool:
    """True when ``path`` is (inside) a temporary sibling of an unfinished omni-gym write."""
    return any(_TEMP_NAME.match(part) for part in Path(path).parts)


# A name inside an output folder (a run's NAME of runs/NAME.csv) is at most this many UTF-8 bytes, so that
# NAME plus a suffix such as ".csv" stays within the 255 bytes most file systems allow for one name.
MAX_NAME_BYTES = 200


def check_file_name(name, what: str = "run name", where: str = "") -> str:
    """``name`` if it is a plain file name to write inside an output folder; OutputError (one line naming
    ``where`` and the name, escaped) otherwise.

    The one check of every name that untrusted input (``--window NAME=…``, a mapping file, a log's file name)
    turns into a path: refused are the empty name, path separators (``/``, ``\\``, so no absolute path and
    no ``..`` component), ``.`` and ``..``, a leading ``.`` (a hidden file, which readers skip, and the shape
    of the outputs' temporary siblings), control characters (newlines, escape sequences, NUL) and names over
    :data:`MAX_NAME_BYTES` bytes.
    """
    prefix = f"{where}: " if where else ""
    if not isinstance(name, str) or not name:
        raise OutputError(f"{prefix}{what} {name!r}: empty or not a string; give a plain file name")
    shown = ascii(name) if len(name) <= 80 else ascii(name[:77]) + "..."
    if "/" in name or "\\" in name:
        raise OutputError(f"{prefix}{what} {shown} contains a path separator; a {what} is a plain file name "
                          "written inside --out")
    if name.startswith("."):
        raise OutputError(f"{prefix}{what} {shown} starts with '.' ('.', '..' and hidden names are refused); "
                          "give a plain file name")
    if any(ord(c) < 32 or 127 <= ord(c) < 160 or c in "\u2028\u2029" for c in name):
        raise OutputError(f"{prefix}{what} {shown} contains control characters; give a plain file name")
    try:
        size = len(name.encode("utf-8"))
    except UnicodeEncodeError:  # a lone surrogate (undecodable bytes of a file name)
        raise OutputError(f"{prefix}{what} {shown} is not valid Unicode; give a plain file name") from None
    if size > MAX_NAME_BYTES:
        raise OutputError(f"{prefix}{what} {shown} is {size} bytes long (at most {MAX_NAME_BYTES})")
    return name


# -- atomic files ---------------------------------------------------------------------------------


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary sibling, fsync and rename (never a partial file).

    The file is created with mode ``0o666 & ~umask`` (``os.open`` applies the umask), like a plain
    ``open(path, "w")``, not the 0600 of ``tempfile.mkstemp``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _unique_sibling(path, "tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        _remove(tmp)
        raise
    _fsync_dir(path.parent)


def write_text_atomic(path: str | Path, text: str) -> None:
    """UTF-8 text through :func:`write_bytes_atomic`."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | Path, data) -> None:
    """Standard JSON (indent 2, trailing newline) through :func:`write_bytes_atomic`; NaN/inf raise ValueError."""
    write_text_atomic(path, json.dumps(data, indent=2, allow_nan=False) + "\n")  # standard JSON only


def csv_text(header: list[str], rows: np.ndarray, empty_nan: bool = False) -> str:
    """CSV text: the header, then one row per line with ``repr`` floats (NaN as an empty cell if
    ``empty_nan``: "not observed" in a dataset run)."""
    buf = io.StringIO(newline="")
    writer = csv.writer(buf)
    writer.writerow(header)
    for row in np.asarray(rows, dtype=float):
        writer.writerow(["" if empty_nan and not math.isfinite(v) else repr(float(v)) for v in row])
    return buf.getvalue()


def write_csv_atomic(path: str | Path, header: list[str], rows: np.ndarray, empty_nan: bool = False) -> None:
    """A CSV file (see :func:`csv_text`) through :func:`write_bytes_atomic`."""
    write_text_atomic(path, csv_text(header, rows, empty_nan))


def _unique_sibling(path: Path, tag: str) -> Path:
    """A fresh temporary name beside ``path``: ``.NAME.tag-PID-N``."""
    for n in range(1000):
        cand = path.with_name(f".{path.name}.{tag}-{os.getpid()}-{n}")
        if not os.path.lexists(cand):
            return cand
    raise OutputError(f"{path}: cannot find a free temporary name beside it")


def _fsync_dir(folder: Path) -> None:
    """Make a rename in ``folder`` durable (best effort: some file systems refuse directory fsync)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _remove(path: Path) -> None:
    """Remove a file or folder if present."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        try:
            os.unlink(path)
        except FileNotFoundError:
            pass


# -- transactional outputs -------------------------------------------------------------------------


@dataclass
class Output:
    """A transactional output file (``kind="file"``) or folder (``kind="dir"``); a context manager.

    ``with Output(target, "dir", force=..., inputs=[...], marker="result.json", what="gap report") as o:``
    validates and locks on entry (before the caller's work), yields itself; write into ``o.path``
    (the temporary folder, or for a file the temporary file name). On a normal exit the content is
    renamed to ``target``; on an exception the temporary content is removed and ``target`` is unchanged.

    ``marker``: a file whose presence identifies an existing folder as an output of this kind: only
    such a folder (or an empty one) is replaced with ``force``; anything else is refused even then,
    so ``--force`` cannot delete an unrelated folder. ``companions``: files beside the target written
    by the same transaction (e.g. ``DATASET.truth.json``), staged with :meth:`stage_companion` and
    renamed after the target.
    """

    target: Path
    kind: str = "dir"
    force: bool = False
    inputs: Iterable[str | Path] = ()
    marker: str | None = None
    what: str = "output"
    companions: tuple[Path, ...] = ()
    path: Path = field(init=False)
    _lock_fd: int | None = field(default=None, init=False, repr=False)
    _lock_path: Path = field(init=False, repr=False)
    _staged: dict[Path, Path] = field(default_factory=dict, init=False, repr=False)
    _created: list[Path] = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.kind not in ("file", "dir"):
            raise ValueError(f"kind must be 'file' or 'dir', got {self.kind!r}")
        self.target = Path(self.target)
        self.companions = tuple(Path(c) for c in self.companions)
        # Only inputs that exist as paths: a preset name such as "williams2002" is not a file.
        self.inputs = [Path(p) for p in self.inputs if p is not None and os.path.lexists(p)]

    # The context manager -------------------------------------------------------------------------

    def __enter__(self) -> Output:
        self.open()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                self.commit()
            else:
                self.abort()
        finally:
            self._unlock()

    def preflight(self) -> None:
        """The checks of :meth:`open` alone (the lock taken and released): a caller can refuse a bad
        output before its slow imports; :meth:`open` checks again under the lock."""
        self._prepare()
        self._unlock()

    def open(self) -> None:
        """Check the target, take the lock, clean stale temporaries, create the temporary folder."""
        self._prepare()
        try:
            self.path = _unique_sibling(self.target, "tmp")
            if self.kind == "dir":
                os.mkdir(self.path, 0o777)  # the umask applies (tempfile.mkdtemp would give 0700)
        except BaseException:
            self._unlock()
            raise

    def _prepare(self) -> None:
        """Refuse an input or a bad name, take the lock, recover stale temporaries, check the target."""
        self._check_not_input()
        if self.target.name in ("", ".", ".."):
            raise OutputError(f"{self.target}: not a usable {self.what} name")
        self._make_parents()
        try:
            self._lock()
        except BaseException:
            self._unlock()  # removes the parents made for it
            raise
        try:
            self._recover_stale()
            self._check_existing()
        except BaseException:
            self._unlock()
            raise

    def stage_companion(self, companion: str | Path, data: bytes) -> None:
        """Write a companion file's content now (temporary sibling); it is renamed in at commit."""
        companion = Path(companion)
        if companion not in self.companions:
            raise ValueError(f"{companion}: not a declared companion of {self.target}")
        tmp = _unique_sibling(companion, "tmp")
        write_bytes_atomic(tmp, data)
        self._staged[companion] = tmp

    def commit(self) -> None:
        """Swap the new content in: old target aside, new renamed in, old removed; then companions."""
        parent = self.target.parent
        if self.kind == "dir":
            _fsync_dir(self.path)
        if not os.path.lexists(self.path):
            raise OutputError(f"{self.target}: nothing was written (no {self.path.name})")
        old = None
        if os.path.lexists(self.target):
            _check_replaceable(self.target, self.what)  # again: it may have changed while the work ran
            if self.kind == "file" and not self.target.is_dir():
                os.replace(self.path, self.target)  # atomic for a file: no moment without it
            else:
                old = _unique_sibling(self.target, "old")
                os.rename(self.target, old)
        if os.path.lexists(self.path):
            os.rename(self.path, self.target)
        for companion, tmp in self._staged.items():
            os.replace(tmp, companion)
        self._staged.clear()
        self._created = []  # the output now lives in them
        _fsync_dir(parent)
        if old is not None:
            _remove(old)

    def abort(self) -> None:
        """Remove the temporary content; the target is untouched."""
        if hasattr(self, "path"):
            _remove(self.path)
        for tmp in self._staged.values():
            _remove(tmp)
        self._staged.clear()

    # Checks ----------------------------------------------------------------------------------------

    def _check_not_input(self) -> None:
        """Refuse a target (or companion) that is an input, lies inside one, or contains one."""
        outs = [self.target, *self.companions]
        for out in outs:
            o = _resolved(out)
            for inp in self.inputs:
                i = _resolved(inp)
                same = o == i or (out.exists() and inp.exists() and os.path.samefile(out, inp))
                if same:
                    raise OutputError(f"{out}: the {self.what} would overwrite the input {inp}; choose another --out")
                if i in o.parents:
                    raise OutputError(f"{out}: the {self.what} would be written inside the input {inp}; "
                                      "choose another --out")
                if o in i.parents:
                    raise OutputError(f"{out}: replacing it would delete the input {inp} inside it; "
                                      "choose another --out")

    def _check_existing(self) -> None:
        """Refuse an existing target unless ``force``; never replace something of another kind."""
        t = self.target
        if os.path.lexists(t):
            _check_replaceable(t, self.what)
            if self.kind == "dir" and not t.is_dir():
                raise OutputError(f"{t}: exists and is not a folder; the {self.what} must be a folder "
                                  "(remove it or choose another --out)")
            if self.kind == "file" and t.is_dir():
                raise OutputError(f"{t}: is a folder; the {self.what} must be a file (choose another --out)")
            if self.kind == "dir" and any(t.iterdir()):
                if self.marker is not None and not (t / self.marker).exists():
                    raise OutputError(f"{t}: exists and is not a {self.what} (no {self.marker}); "
                                      "refusing to replace it, even with --force")
                if not self.force:
                    raise OutputError(f"{t}: exists; its {self.what} ({_describe(t)}) would be lost: "
                                      "use --force to replace it, or choose another --out")
            elif self.kind == "file" and not self.force:
                raise OutputError(f"{t}: exists ({t.stat().st_size} bytes would be lost): use --force to replace it, "
                                  "or choose another --out")
        for c in self.companions:
            if os.path.lexists(c):
                _check_replaceable(c, "file")
            if os.path.lexists(c) and not self.force:
                raise OutputError(f"{c}: exists and would be replaced: use --force, or choose another --out")

    # Locking and stale temporaries ----------------------------------------------------------------

    def _lock(self) -> None:
        """Take ``.NAME.lock`` beside the target without waiting; refuse if another process holds it."""
        self._lock_path = self.target.with_name(f".{self.target.name}.lock")
        for _ in range(100):  # retry only if the file was removed under us by a finishing holder
            fd = os.open(self._lock_path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno in (errno.EWOULDBLOCK, errno.EACCES, errno.EAGAIN):
                    raise OutputError(f"{self.target}: another process is writing this {self.what} (lock "
                                      f"{self._lock_path} is held); wait for it or choose another --out") from None
                raise
            try:
                same = os.fstat(fd).st_ino == os.stat(self._lock_path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                self._lock_fd = fd
                return
            os.close(fd)
        raise OutputError(f"{self.target}: cannot take the lock {self._lock_path}")

    def _make_parents(self) -> None:
        """Create the target's missing parent folders (the lock and the temporary live there) and remember
        them: a run that does not commit removes them again (:meth:`_unlock`), so a refused or failed run
        leaves no empty folder behind."""
        missing = []
        p = self.target.parent
        while not os.path.lexists(p) and p != p.parent:
            missing.append(p)
            p = p.parent
        self.target.parent.mkdir(parents=True, exist_ok=True)
        self._created = missing  # deepest first

    def _unlock(self) -> None:
        """Remove the lock file (while holding it: a waiter re-checks the inode) and release it; remove the
        parent folders this output created unless it was committed into them."""
        if self._lock_fd is not None:
            try:
                os.unlink(self._lock_path)
            except FileNotFoundError:
                pass
            os.close(self._lock_fd)
            self._lock_fd = None
        for folder in self._created:  # deepest first; a folder another writer uses is not empty: kept
            try:
                os.rmdir(folder)
            except OSError:
                break
        self._created = []

    def _recover_stale(self) -> None:
        """With the lock held no other run writes this target: every temporary sibling is stale.

        A run killed between its two renames left the old output aside (``.NAME.old-PID``) and the
        target absent: put the old output back. Everything else is removed.
        """
        parent = self.target.parent
        names = [self.target.name, *(c.name for c in self.companions)]
        for name in names:
            sibling = re.compile(rf"^\.{re.escape(name)}\.(tmp|old)-\d+(-\d+)?$")
            # a temporary of a temporary (a staged companion's own atomic write): "..NAME.tmp-P-0.tmp-P-0"
            nested = re.compile(rf"^\.\.+{re.escape(name)}(\.(tmp|old)-\d+(-\d+)?){{2,}}$")
            for entry in sorted(parent.iterdir()):
                m = sibling.match(entry.name)
                if not m:
                    if nested.match(entry.name):
                        _remove(entry)
                    continue
                if m.group(1) == "old" and name == self.target.name and not os.path.lexists(self.target):
                    os.rename(entry, self.target)
                else:
                    _remove(entry)


def _check_replaceable(path: Path, what: str) -> None:
    """Refuse an existing ``path`` that is neither a regular file nor a folder (after symbolic links): a
    device, a pipe, a socket or a broken link is never replaced, not even with ``--force`` (the rename
    would put a plain file in place of ``/dev/full`` or a FIFO another program reads)."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise OutputError(f"{path}: exists but cannot be examined ({exc.strerror or exc}; a broken link?); "
                          f"refusing to replace it with the {what}, even with --force") from None
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        kind = ("a character device" if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode)
                else "a named pipe (FIFO)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
                else "not a regular file")
        link = " (through a symbolic link)" if os.path.islink(path) else ""
        raise OutputError(f"{path}: is {kind}{link}, not a file or folder omni-gym writes; refusing to replace "
                          "it, even with --force (choose another --out)")


def _resolved(path: Path) -> Path:
    return Path(os.path.realpath(path))


def _describe(folder: Path) -> str:
    """What a folder holds, for the refusal message: ``N files, e.g. a, b``."""
    files = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    shown = ", ".join(files[:3]) + (", …" if len(files) > 3 else "")
    return f"{len(files)} file{'s' if len(files) != 1 else ''}: {shown}"
