"""Where independent tasks run: this process, local worker processes, or Ray.

One ordered map of a picklable function over task arguments, with a backend chosen by :class:`Backend`:

* serial (the default): every task in this process, one after another; nothing to start;
* ``jobs`` > 1: that many local worker processes (``spawn``: a clean interpreter, no forked threads);
* ``ray``: Ray tasks, on a fresh local Ray (``address`` None, started and stopped here) or on the
  cluster at ``address`` (``ray start --head`` on one machine, ``ray start --address`` on the others).

The results come back in the order of the arguments whatever order the tasks finish in, so a caller
that makes every task a pure function of its arguments (its random numbers from a seed in the
arguments, never from the worker) gets the same result bit for bit from every backend and worker
count. A large input every task needs (``shared``) is pickled once and read by each local worker
process once, when it starts (from an in-memory file of the driver that the kernel frees with it, or
elsewhere a temporary file removed when the workers stop; a new shared input starts new
workers), or is put once into Ray's object store. Ray retries a task whose worker died
(``max_retries``). Each worker runs its task on one thread (numba, BLAS): the parallelism is the tasks'.

:meth:`Executor.map` may be called from several threads of the driver at once (``gap`` runs its
candidate fits in driver threads, each mapping its simulation batches as tasks): open the backend from
the main thread first (:meth:`Executor.start`), and stop it from there (:meth:`Executor.abort`).

Local workers die with the process that started them, however it ends: an exception or an interrupt in
:meth:`Executor.map` kills them at once (a running candidate fit is not waited for), and each worker
watches its parent (Linux ``PR_SET_PDEATHSIG``, and a thread polling the parent's pid), so a parent
killed with SIGKILL leaves no worker behind, nor multiprocessing's resource tracker (it exits when the
last process holding its pipe is gone). Workers never see SIGINT (a Ctrl-C to the whole process group
is the parent's to handle): they start with it blocked, then ignore it.

Ray is imported only when the Ray backend is used; without it the error names the extra to install.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import pickle
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Any

RAY_EXTRA = "pip install -c constraints.txt -e '.[rllib]' (from the omni-gym checkout's root)"
# Threading libraries whose thread count a task pins to 1 (set before a worker loads them).
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
_NO_SHARED = object()
# Module state of a local worker process: the shared input it was started with.
_worker_shared: Any = _NO_SHARED


class BackendError(ValueError):
    """A backend that cannot be used (ray missing, cluster unreachable, bad settings): one line for the CLI."""


@dataclass(frozen=True)
class Backend:
    """The execution backend of :func:`executor`.

    ``jobs``: local worker processes (1: serial in this process). ``ray``: run on Ray instead;
    ``address``: the cluster's ``HOST:PORT`` (None: a fresh local Ray with ``cpus`` CPUs; ``cpus`` None:
    ``jobs`` if ``jobs`` > 1, else all cores). ``max_retries``: Ray re-runs a task whose worker died up to
    this often. ``pool``: run even a single job in a worker process (not in this process), so that one
    and N local workers are measured the same way (``benchmarks/scaling.py``).
    """

    jobs: int = 1
    ray: bool = False
    address: str | None = None
    max_retries: int = 3
    cpus: int | None = None
    pool: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.jobs, bool) or not isinstance(self.jobs, int) or self.jobs < 1:
            raise BackendError(f"jobs must be an integer >= 1, got {self.jobs!r}")
        if self.address is not None and not self.ray:
            raise BackendError("a Ray address needs ray=True")
        if self.max_retries < 0:
            raise BackendError(f"max_retries must be >= 0, got {self.max_retries}")
        if self.cpus is not None and (isinstance(self.cpus, bool) or not isinstance(self.cpus, int) or self.cpus < 1):
            raise BackendError(f"cpus must be an integer >= 1 or None, got {self.cpus!r}")

    @property
    def serial(self) -> bool:
        """True when the tasks run in this process, one after another."""
        return not self.ray and self.jobs == 1 and not self.pool

    def preflight(self) -> None:
        """Raise :class:`BackendError` now for a backend that cannot work (ray not installed, nothing
        listening at ``address``), before any work is done."""
        if not self.ray:
            return
        _import_ray()
        if self.address is not None:
            _check_reachable(self.address)

    def describe(self) -> str:
        """One phrase for logs and reports."""
        if self.ray:
            cpus = self.cpus or (self.jobs if self.jobs > 1 else None)
            if self.address:
                return f"Ray at {self.address}"
            return "a local Ray" + (f" with {cpus} CPU{'s' * (cpus > 1)}" if cpus else "")
        if self.serial:
            return "this process"
        return f"{self.jobs} local process" + ("es" if self.jobs > 1 else "")


SERIAL = Backend()

# on_done(i, result): called in the driver as task i finishes (finishing order; for progress).
OnDone = Callable[[int, Any], None]


class Executor:
    """An open backend: :meth:`map` as often as needed, then closed by :func:`executor`."""

    def __init__(self, backend: Backend) -> None:
        self.backend = backend
        self._pool: ProcessPoolExecutor | None = None
        self._pool_shared: Any = _NO_SHARED  # the shared input the pool's workers were started with
        self._pool_file: tuple[str, int | None] | None = None  # the file the workers read it from (path, fd)
        self._ray: Any = None
        self._ray_task: Any = None  # the remote function of _call_ray, made once
        self._started_ray = False
        self._ray_shared: Any = _NO_SHARED  # the shared input last put into the object store, and its ref
        self._ray_ref: Any = None
        self._lock = threading.RLock()  # the pool, the Ray connection and the shared input, for threads
        self._aborted = False

    def start(self, shared: Any = _NO_SHARED) -> None:
        """Start the workers now, from the calling (main) thread, with ``shared`` as their shared input:
        every local worker process (they start with SIGINT blocked, which only the main thread can
        arrange), or the Ray connection. Optional before :meth:`map` from the main thread; needed before
        maps from other threads, which then reuse these workers. A no-op in this process (serial)."""
        if self.backend.ray:
            self._connect_ray()
            return
        if self.backend.serial:
            return
        with self._lock:
            with _sigint_deferred():  # only while the processes are started (submit starts them), not after
                pool = self._open_pool(shared)
                # A spawn pool starts its processes as tasks arrive: as many tasks as workers, submitted at
                # once (each start takes far longer than a submit), start them all.
                started = [pool.submit(time.sleep, 0.0) for _ in range(self.backend.jobs)]
            try:
                for f in started:
                    f.result()
            except BaseException:  # an interrupt while the workers start up
                self._kill_pool()
                raise

    def abort(self) -> None:
        """Kill the local workers now (a task running in one is not waited for); later maps raise
        :class:`BackendError`. For the main thread when it is interrupted while other threads map."""
        with self._lock:
            self._aborted = True
            self._kill_pool()

    def map(self, fn: Callable, args: Sequence, shared: Any = _NO_SHARED, on_done: OnDone | None = None,
            inline_single: bool = True) -> list:
        """``[fn(a) for a in args]`` (``fn(shared, a)`` when ``shared`` is given), in the order of ``args``.

        ``on_done(i, result)`` is called in this process as each task finishes (in finishing order;
        for progress). ``fn``, the arguments and ``shared`` must pickle; ``fn`` must be importable by
        the workers (a module-level function). ``inline_single``: a single task runs in this process
        (nothing to share it with) unless the backend is a ``pool``; False sends it to a worker too (a
        caller mapping from several threads at once keeps its tasks off the driver's cores).
        """
        args = list(args)
        if self._aborted:
            raise BackendError("the backend was stopped")
        if self.backend.ray:
            return self._map_ray(fn, args, shared, on_done)
        if self.backend.serial or (len(args) <= 1 and not self.backend.pool and inline_single):
            out = []
            for i, a in enumerate(args):
                out.append(fn(a) if shared is _NO_SHARED else fn(shared, a))
                if on_done:
                    on_done(i, out[-1])
            return out
        return self._map_processes(fn, args, shared, on_done)

    # --- local processes -------------------------------------------------------------------------

    def _open_pool(self, shared: Any) -> ProcessPoolExecutor:
        """The pool whose workers hold ``shared`` (a new one when they hold another); under ``_lock``.

        The shared input is pickled once here into a temporary file that each worker reads when it starts
        (not in the start-up data itself: a large one would keep the driver writing it, with SIGINT
        ignored, until the new process reads it); the worker unpickles it after pinning its threads:
        unpickling it imports numba, which reads NUMBA_NUM_THREADS once (see pin_threads).
        """
        if self._pool is not None and self._pool_shared is not shared:
            self._close_pool()  # a new shared input: new workers
        if self._pool is None:
            if shared is not _NO_SHARED:
                self._pool_file = _shared_file(pickle.dumps(shared, pickle.HIGHEST_PROTOCOL))
            self._pool = ProcessPoolExecutor(self.backend.jobs, mp_context=get_context("spawn"),
                                             initializer=_init_worker,
                                             initargs=(os.getpid(), self._pool_file and self._pool_file[0]))
            self._pool_shared = shared
        return self._pool

    def _remove_pool_file(self) -> None:
        held, self._pool_file = self._pool_file, None
        if held is None:
            return
        path, fd = held
        try:
            if fd is not None:
                os.close(fd)
            else:
                os.unlink(path)
        except OSError:
            pass

    def _map_processes(self, fn: Callable, args: list, shared: Any, on_done: OnDone | None) -> list:
        try:
            # The workers start (spawn: fork + exec) on submit. SIGINT is held back meanwhile, a few
            # milliseconds: they inherit it blocked and so never raise KeyboardInterrupt, not even while
            # they start (a worker that died then left Process.start blocked in its pipe write); this process
            # gets it when the block ends. Off the main thread it cannot be held: there the workers were
            # started by start().
            with self._lock, _sigint_deferred():
                if self._aborted:
                    raise BackendError("the backend was stopped")
                pool = self._open_pool(shared)
                has_shared = shared is not _NO_SHARED
                futures = {pool.submit(_call_local, fn, a, has_shared): i for i, a in enumerate(args)}
            return _collect(futures, len(args), on_done)
        except BaseException:  # an interrupt, a failed task: stop every worker now, not after its task
            with self._lock:
                self._kill_pool()
            raise

    def _close_pool(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._pool_shared = _NO_SHARED
        self._remove_pool_file()

    def _kill_pool(self) -> None:
        """Kill the worker processes (SIGKILL) and wait for them; a second Ctrl-C cannot cut this short."""
        pool, self._pool, self._pool_shared = self._pool, None, _NO_SHARED
        self._remove_pool_file()
        if pool is None:
            return
        with _sigint_deferred():
            procs = list((getattr(pool, "_processes", None) or {}).values())  # no public handle before 3.14
            manager = _manager_handles(pool)  # shutdown() drops them
            for p in procs:
                try:
                    p.kill()
                except (OSError, ValueError):  # already gone, or closed
                    pass
            pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                try:
                    p.join(timeout=10)
                except (OSError, ValueError, AssertionError):
                    pass
            _unblock_manager(*manager)

    # --- Ray -------------------------------------------------------------------------------------

    def _connect_ray(self) -> Any:
        with self._lock:
            return self._connect_ray_locked()

    def _connect_ray_locked(self) -> Any:
        if self._ray is not None:
            return self._ray
        ray = _import_ray()
        if not ray.is_initialized():
            address = self.backend.address
            if address is not None:
                _check_reachable(address)
                _use_token_if_available()
                try:
                    ray.init(address=address, log_to_driver=False, configure_logging=False)
                except Exception as exc:  # Ray's own errors: ConnectionError, RuntimeError (auth), ...
                    raise BackendError(f"cannot connect to the Ray cluster at {address}: "
                                       f"{str(exc).strip().splitlines()[-1] if str(exc).strip() else exc!r}") from None
            else:
                cpus = self.backend.cpus or (self.backend.jobs if self.backend.jobs > 1 else None)
                ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False, configure_logging=False)
            self._started_ray = True
        self._ray = ray
        return ray

    def _map_ray(self, fn: Callable, args: list, shared: Any, on_done: OnDone | None) -> list:
        ray = self._connect_ray()
        with self._lock:
            if self._ray_task is None:
                self._ray_task = ray.remote(num_cpus=1, max_retries=self.backend.max_retries,
                                            retry_exceptions=False)(_call_ray)
            task = self._ray_task
            if shared is not _NO_SHARED and shared is not self._ray_shared:
                self._ray_shared, self._ray_ref = shared, ray.put(shared)  # once into the object store
            ref = None if shared is _NO_SHARED else self._ray_ref
        refs = [task.remote(fn, a, ref, ref is not None) for a in args]
        index = {r: i for i, r in enumerate(refs)}
        out: list = [None] * len(refs)
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for r in done:
                i = index[r]
                out[i] = ray.get(r)
                if on_done:
                    on_done(i, out[i])
        return out

    def close(self) -> None:
        """Stop the worker processes, and the Ray this executor started (a cluster it joined stays up)."""
        self._close_pool()
        if self._started_ray and self._ray is not None:
            self._ray.shutdown()
        self._ray, self._started_ray, self._ray_shared, self._ray_ref = None, False, _NO_SHARED, None
        self._ray_task = None


@contextmanager
def executor(backend: Backend = SERIAL) -> Iterator[Executor]:
    """Open ``backend`` for the ``with`` block; workers and a Ray it started are stopped at the end."""
    ex = Executor(backend)
    try:
        yield ex
    finally:
        ex.close()


def add_ray_option(parser: argparse.ArgumentParser, tasks: str, cpus: str) -> None:
    """``--ray [ADDRESS]`` on ``parser``, for the commands and benchmarks that run ``tasks`` on a backend; the
    ``cpus`` option (e.g. ``--jobs``) sizes a fresh local Ray. Read it with :func:`backend_from_options`."""
    parser.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                        help=f"run {tasks} as Ray tasks: on the cluster at ADDRESS (HOST:PORT of `ray start --head`), "
                             f"or without ADDRESS on a fresh local Ray with {cpus} CPUs; the result is the same as "
                             "without --ray")


def backend_from_options(jobs: int, ray: str | None) -> Backend:
    """The backend of ``--jobs``/``--workers`` and ``--ray [ADDRESS]`` (:func:`add_ray_option`), checked now
    (:meth:`Backend.preflight`: ray missing, nothing listening at the address) before any work is done."""
    backend = Backend(jobs=jobs, ray=ray is not None, address=ray or None)
    backend.preflight()
    return backend


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one, else all)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def parallel_map(fn: Callable, args: Sequence, backend: Backend = SERIAL, shared: Any = _NO_SHARED,
                 on_done: OnDone | None = None) -> list:
    """One :meth:`Executor.map` on a backend opened and closed for it."""
    with executor(backend) as ex:
        return ex.map(fn, args, shared=shared, on_done=on_done)


def pin_threads() -> None:
    """One thread per task for numba's parallel kernel and BLAS (the workers are the parallelism).

    numba reads ``NUMBA_NUM_THREADS`` when it is imported and re-reads it at every compile, refusing a
    value that differs from the one its thread pool was launched with. So the variable is set only while
    numba is not yet loaded; once it is (a task's arguments import it on unpickling, e.g. in a Ray
    worker), changing it would make the next compilation fail ("Cannot set NUMBA_NUM_THREADS to a
    different value once the threads have been launched") on a cold cache, and ``set_num_threads(1)``
    alone limits the threads that run.
    """
    numba_loaded = "numba" in sys.modules
    for k in THREAD_ENV:
        if k == "NUMBA_NUM_THREADS" and numba_loaded:
            continue
        os.environ[k] = "1"
    try:
        import numba

        numba.set_num_threads(1)
    except (ImportError, ValueError):  # no numba, or numba's thread pool already fixed below
        pass
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:
        pass


def _shared_file(blob: bytes) -> tuple[str, int | None]:
    """``blob`` in a file the workers can open by path: (path, fd to close) for an in-memory file
    (Linux ``memfd``, opened through ``/proc/PID/fd``: freed when the driver closes it or dies, even by
    SIGKILL), else (path of a temporary file, None)."""
    proc = f"/proc/{os.getpid()}/fd"
    if hasattr(os, "memfd_create") and os.path.isdir(proc):
        fd = os.memfd_create("omni-gym-shared", os.MFD_CLOEXEC)
        view = memoryview(blob)
        done = 0
        while done < len(blob):
            done += os.pwrite(fd, view[done:], done)
        return f"{proc}/{fd}", fd
    fd, path = tempfile.mkstemp(prefix="omni-gym-shared-", suffix=".pickle")
    with os.fdopen(fd, "wb") as f:
        f.write(blob)
    return path, None


def _init_worker(parent: int, shared_file: str | None = None) -> None:
    """A local worker's start: SIGINT ignored (it was inherited blocked), die with ``parent`` (pid), one thread,
    then the shared input read from ``shared_file`` (after the pinning: unpickling it may import numba)."""
    global _worker_shared
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and stops the workers
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # started blocked (_sigint_deferred); now ignored
    _die_with_parent(parent)
    pin_threads()
    if shared_file is not None:
        with open(shared_file, "rb") as f:
            _worker_shared = pickle.load(f)


PR_SET_PDEATHSIG = 1  # linux/prctl.h
MANAGER_JOIN_S = 1.0  # how long a killed pool's manager thread is waited for (see _unblock_manager)
WATCH_PARENT_S = 0.5  # how often a worker checks that its parent lives (where PR_SET_PDEATHSIG is missing)


def _die_with_parent(parent: int) -> None:
    """Make this worker end when its parent process ends, however it ends (SIGKILL included)."""
    if sys.platform.startswith("linux"):
        try:  # the kernel sends SIGKILL when the parent exits
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the above took effect
        os._exit(1)

    def watch() -> None:  # also where prctl is missing (checks between the kernel's calls, which hold the GIL)
        while True:
            time.sleep(WATCH_PARENT_S)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="omni-gym-parent-watch", daemon=True).start()


def _manager_handles(pool: ProcessPoolExecutor) -> tuple[Any, Any]:
    """(this process's write end of the pool's result pipe, the pool's manager thread); no public handles."""
    return (getattr(getattr(pool, "_result_queue", None), "_writer", None),
            getattr(pool, "_executor_manager_thread", None))


def _unblock_manager(writer: Any, thread: Any) -> None:
    """End a pool's manager thread after its workers were killed (call after they are joined).

    A worker killed while writing its result leaves a partial message in the result pipe, and the
    manager thread blocks reading the rest of it; the interpreter's exit joins that thread, so the
    process would never end. The workers' ends of the pipe closed with them; closing this process's own
    (unused) write end too makes the read see end-of-file, and the thread ends, marking the pool broken.
    """
    try:
        if writer is not None:
            writer.close()
    except OSError:
        pass
    if thread is not None and thread is not threading.current_thread():
        # Normally milliseconds. Bounded short: the command line leaves with os._exit after an interrupt
        # (interrupts.exit_interrupted) whether or not the thread ended, and must end within 2 s.
        thread.join(timeout=MANAGER_JOIN_S)


@contextmanager
def _sigint_deferred() -> Iterator[None]:
    """SIGINT held back for the ``with`` block and delivered when it ends: nothing is lost, nothing interrupts
    the block (starting or killing worker processes half way would leave the pool inconsistent).

    Two parts. In this (main) thread the signal is blocked (``pthread_sigmask``): processes started inside
    inherit the block through fork and exec, so a Ctrl-C to the process group stays pending in a new worker
    until :func:`_init_worker` ignores it (which discards it) and unblocks it; no worker raises
    ``KeyboardInterrupt`` while it starts. And a recording handler catches a SIGINT that another thread of
    this process receives meanwhile. At the end the previous handler is restored and, if an interrupt came,
    the signal is raised again for it: a Python handler raises ``KeyboardInterrupt`` here, after the block,
    an ignored SIGINT stays ignored, the default one ends the process. (Ignoring SIGINT during the block, as
    before, would lose a Ctrl-C that arrives in those milliseconds: the user presses it and nothing happens.)
    A no-op off the main thread (handlers live there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        # A SIGINT held by the mask arrives at the unblock and is recorded, or, if Python runs its handler
        # only after the next line, the previous handler gets it directly: either way it is handled once.
        signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)
        signal.signal(signal.SIGINT, previous)
        if caught:
            signal.raise_signal(signal.SIGINT)  # whatever the previous disposition is, it decides


def _call_local(fn: Callable, a: Any, has_shared: bool) -> Any:
    return fn(_worker_shared, a) if has_shared else fn(a)


def _call_ray(fn: Callable, a: Any, shared: Any, has_shared: bool) -> Any:
    pin_threads()
    return fn(shared, a) if has_shared else fn(a)  # Ray resolves a top-level ObjectRef argument


def _collect(futures: dict, n: int, on_done: OnDone | None) -> list:
    out: list = [None] * n
    pending = set(futures)
    while pending:
        done, pending = wait(pending, return_when=FIRST_COMPLETED)
        for f in done:
            i = futures[f]
            out[i] = f.result()
            if on_done:
                on_done(i, out[i])
    return out


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise BackendError(f"the Ray backend needs ray: {RAY_EXTRA}") from None
    return ray


def check_ray_address(address: str, timeout: float = 5.0) -> None:
    """BackendError (one line) unless something listens at the Ray ``address`` (HOST:PORT; ``auto``, ``local``
    and ``ray://`` pass): ``ray.init`` would retry an unreachable one for a minute or more. For every command
    that connects to a cluster (``gap --ray``, ``train --backend rllib --address``)."""
    _check_reachable(address, timeout)


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """A fast one-line error for an address nothing listens on (ray.init would retry for a minute)."""
    if address in ("auto", "local") or address.startswith("ray://"):
        return
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit():
        raise BackendError(f"Ray address must be HOST:PORT, got {address!r}")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            pass
    except OSError as exc:
        raise BackendError(f"cannot reach the Ray cluster at {address}: {exc.strerror or exc}") from None


def _use_token_if_available() -> None:
    """Send the cluster's token when one is at hand (``RAY_AUTH_TOKEN``, ``~/.ray/auth_token``) and the
    user did not choose a mode: a cluster started by ``ray.init``/``ray start`` has token authentication
    on, and a client without the mode set would not send the token (``RAY_AUTH_MODE=disabled`` opts out)."""
    if "RAY_AUTH_MODE" in os.environ:
        return
    if os.environ.get("RAY_AUTH_TOKEN") or os.environ.get("RAY_AUTH_TOKEN_PATH") or \
            os.path.isfile(os.path.expanduser("~/.ray/auth_token")):
        os.environ["RAY_AUTH_MODE"] = "token"
