"""Progress lines of long loops on stderr, for logs and pipes where a progress bar cannot draw.

A run makes one :class:`ProgressLines` (where the lines go, whether they are on, how often) and, per long
loop, a :class:`Progress` from it. A loop whose length N is known prints
``PREFIX: WHAT k/N UNIT, T s, about R s left`` (R: the time per item so far times the items left); a loop
of unknown length prints ``PREFIX: WHAT k UNIT, T s``. All loops of a run share one clock: a line at most
every :data:`PROGRESS_EVERY_S` seconds, whichever loop it comes from, each flushed. No line after a loop's
last item (what follows says it finished). Thread safe: fits running side by side in threads tick their
own loops.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import TextIO

PROGRESS_EVERY_S = 10.0  # a progress line at most this often [s] (read at each tick: a test may set it to 0)


class ProgressLines:
    """Where one run's progress lines go: ``stream`` (None: stderr at the time of writing), each line
    prefixed ``PREFIX: ``; nothing at all when not ``enabled``. ``every_s``: least seconds between two
    lines (None: :data:`PROGRESS_EVERY_S`)."""

    def __init__(self, prefix: str, enabled: bool = True, every_s: float | None = None,
                 stream: TextIO | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.prefix = prefix
        self.enabled = enabled
        self.every_s = every_s
        self.stream = stream
        self.clock = clock
        self._last = clock()
        self._lock = threading.Lock()

    def loop(self, what: str, total: int | None = None, unit: str = "rounds") -> Progress:
        """A :class:`Progress` of a loop of ``total`` items (None: not known in advance) named ``what``."""
        return Progress(self, what, total, unit)

    def due(self) -> bool:
        """True when a line may be written now (enabled, and the interval since the last line has passed)."""
        if not self.enabled:
            return False
        every = PROGRESS_EVERY_S if self.every_s is None else self.every_s
        return self.clock() - self._last >= every

    def write(self, text: str) -> None:
        """One line ``PREFIX: text``, flushed, if due (:meth:`due`)."""
        with self._lock:
            if not self.due():
                return
            self._last = self.clock()
            print(f"{self.prefix}: {text}", file=self.stream or sys.stderr, flush=True)


OFF = ProgressLines("", enabled=False)  # prints nothing


class Progress:
    """One loop's progress: :meth:`update` after each item (or ``n`` items). ``what`` may change while the loop
    runs (:meth:`rename`, e.g. the search step it is in); :meth:`inner` reports a loop inside the current item
    (the worlds or tasks of one simulated batch) in the same line."""

    def __init__(self, lines: ProgressLines, what: str, total: int | None = None, unit: str = "rounds") -> None:
        self.lines = lines
        self.what = what
        self.total = total
        self.unit = unit
        self.k = 0
        self.t0 = lines.clock()
        self._lock = threading.Lock()

    def start(self) -> None:
        """(Re)start the loop's clock and count: for a loop made before its work begins (fits made for a whole
        search step, run one after another)."""
        with self._lock:
            self.k = 0
            self.t0 = self.lines.clock()

    def rename(self, what: str) -> None:
        self.what = what

    def update(self, n: int = 1) -> None:
        """``n`` more items done; a line if one is due and the loop is not over."""
        with self._lock:
            self.k += n
            k = self.k
        if self.total is not None and k >= self.total:
            return
        if self.lines.due():
            self.lines.write(self.text())

    def text(self) -> str:
        """The loop's line (without the prefix)."""
        return _line(self.what, self.k, self.total, self.unit, self.lines.clock() - self.t0)

    def inner(self, unit: str) -> Callable[[int, int], None]:
        """``done(j, m)`` for a loop inside the current item: ``j`` of its ``m`` parts (``unit``) finished. Its
        line is this loop's text followed by ``; this batch j/m UNIT, T s, about R s left``, T counted from the
        call of ``inner`` (the item's start). No line after its last part."""
        t0 = self.lines.clock()

        def done(j: int, m: int) -> None:
            if j >= m or not self.lines.due():
                return
            self.lines.write(f"{self.text()}; this batch {_line('', j, m, unit, self.lines.clock() - t0).strip()}")
        return done


def _line(what: str, k: int, total: int | None, unit: str, elapsed: float) -> str:
    """``WHAT k/N UNIT, T s, about R s left`` (N known and k > 0) or ``WHAT k UNIT, T s``."""
    if total is None:
        return f"{what} {k} {unit}, {elapsed:.0f} s"
    if k <= 0:
        return f"{what} {k}/{total} {unit}, {elapsed:.0f} s"
    return f"{what} {k}/{total} {unit}, {elapsed:.0f} s, about {elapsed / k * (total - k):.0f} s left"
