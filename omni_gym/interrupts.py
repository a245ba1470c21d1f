"""Ctrl-C in the ``omni-gym`` command line: one line ``omni-gym: interrupted`` and exit status 130.

Two phases. While the command starts (the console script imports :mod:`omni_gym`, which loads
Gymnasium and numpy: the first ~0.2 s), nothing has been written yet, so :func:`guard_startup` makes an
interrupt print the line and exit at once. From :func:`main_handler` on, the first interrupt raises
``KeyboardInterrupt`` where the work is (so the output transaction is rolled back and worker processes
are stopped on the way out), and later ones are ignored: the cleanup the first one started must not be
cut short by a second Ctrl-C (a traceback, workers left behind).

Once the way out is done (output rolled back, workers killed), the command line leaves with
:func:`exit_interrupted`: ``os._exit`` after flushing, not the interpreter's normal exit, which joins the
process pools' manager threads and so could wait forever on a thread still reading a message a killed worker
left half written (measured: 1 in about 25 interrupts of ``gap --jobs 2``).

Only the command line installs these handlers; ``import omni_gym`` in a program of the user changes no
signal handling (:func:`is_command_line`).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from typing import Any

EXIT_INTERRUPTED = 130  # 128 + SIGINT, what a shell reports for a process ended by Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM (kill PID, a job scheduler's stop): handled as an interrupt
MESSAGE = "omni-gym: interrupted"
_exit_status = {"status": EXIT_INTERRUPTED}  # what exit_interrupted() leaves with: 143 after a SIGTERM


def is_command_line() -> bool:
    """True in the ``omni-gym`` console script and in ``python -m omni_gym.cli`` (read from the
    interpreter's own arguments, since ``sys.argv[0]`` is only ``-m`` while the package is imported)."""
    mp = sys.modules.get("multiprocessing")
    if mp is not None and mp.parent_process() is not None:  # a worker process: its parent handles Ctrl-C
        return False
    if sys.argv and os.path.basename(sys.argv[0]) in ("omni-gym", "omni-gym.exe"):
        return True
    argv = getattr(sys, "orig_argv", [])
    return any(a == "-m" and nxt == "omni_gym.cli" for a, nxt in zip(argv, argv[1:], strict=False))


def _startup_interrupt(signum: int, frame: Any) -> None:
    os.write(2, (MESSAGE + "\n").encode())
    os._exit(EXIT_INTERRUPTED)


def guard_startup() -> None:
    """In the command line only: an interrupt before :func:`main_handler` exits at once with the line.
    An inherited ``SIG_IGN`` (a background job of a script) is respected."""
    if (is_command_line() and threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
        signal.signal(signal.SIGINT, _startup_interrupt)


def exit_interrupted() -> None:
    """End this process now with :data:`EXIT_INTERRUPTED`, after flushing stdout and stderr.

    For the command line once an interrupt was handled (the work rolled back, the workers killed, the line
    printed): nothing is left to do, and the interpreter's own exit would join every thread that
    ``concurrent.futures`` registered, one of which may block forever on a pipe a killed worker wrote
    half a message into. ``os._exit`` skips that join (and every other exit hook, none of which has
    anything left to undo here)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed, or a broken pipe: nothing more can be said there
            pass
    os._exit(_exit_status["status"])


class WorkHandler:
    """The work phase's SIGINT handling, installed by :func:`main_handler`.

    Calling it restores the previous handling. ``interrupted`` is True once an interrupt arrived: an
    exception that surfaces after it is the interrupt's, whatever its type (numba, for one, turns a
    ``KeyboardInterrupt`` raised while it loads its extension modules into an ``ImportError``)."""

    def __init__(self) -> None:
        self.interrupted = False
        self._previous: Any = None
        self._previous_term: Any = None
        self._installed = False
        self._pid = os.getpid()

    def install(self) -> WorkHandler:
        if threading.current_thread() is not threading.main_thread():
            return self
        previous = signal.getsignal(signal.SIGINT)
        if previous is signal.SIG_IGN:
            return self
        self._previous, self._installed = previous, True
        signal.signal(signal.SIGINT, self._first)
        # SIGTERM (kill PID) takes the same way out, so the output's lock and temporary folder are removed; a
        # handler the caller installed is left alone.
        if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
            self._previous_term = signal.SIG_DFL
            signal.signal(signal.SIGTERM, self._first)
        return self

    def _first(self, signum: int, frame: Any) -> None:
        if signum == signal.SIGTERM and os.getpid() != self._pid:  # a forked child: die as it would have
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)
            return
        self.interrupted = True
        if signum == signal.SIGTERM:
            _exit_status["status"] = EXIT_TERMINATED
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # the way out has begun: later interrupts wait for it
        if self._previous_term is not None:
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise KeyboardInterrupt

    def __call__(self) -> None:
        """Restore: in the command line the work is over (committed or rolled back) once ``main()``
        returns, and an interrupt while the interpreter exits would only turn its status into -2 without a
        message, so SIGINT stays ignored; elsewhere the caller's handler comes back."""
        if not self._installed:
            return
        if self._previous_term is not None:
            signal.signal(signal.SIGTERM, self._previous_term)
        if not is_command_line():
            signal.signal(signal.SIGINT, self._previous)
        else:
            signal.signal(signal.SIGINT, signal.SIG_IGN)


def main_handler() -> WorkHandler:
    """Install the work phase's handler (first interrupt raises ``KeyboardInterrupt``, later ones are
    ignored); returns the :class:`WorkHandler`, whose call restores the previous handler when ``main()``
    returns, so that ``main()`` called from Python (the tests) leaves the caller's handling as it found
    it. In the command line SIGINT stays ignored once ``main()`` returns: Python's finalisation resets a
    Python-level handler to the default, and a late Ctrl-C would then kill the exiting process (status
    -2, no message). A no-op off the main thread or under an inherited ``SIG_IGN``."""
    return WorkHandler().install()
