"""The candidate fits of one ``gap`` search step as tasks finer than a candidate, and their work record.

A candidate fit (:func:`~omni_gym.discrepancy.fit.fitting.fit_candidate`) is a chain of search rounds; each
round simulates a batch of parameter points on every run (or every shooting window). On a parallel
backend (:mod:`omni_gym.parallel`: local processes or Ray) the fits run side by side in threads of the
driver, and each round's batch is split into **chunk tasks** of about :data:`CHUNK_ROBOT_S` seconds of
robot time (contiguous parts of the round's job list, :meth:`Evaluator.jobs`), mapped on the backend.
A job's simulation does not depend on the other robots of its world, and the driver puts the chunks
back together in job order (:meth:`Evaluator.assemble`), so every fit sees the same numbers, bit for
bit, whatever the backend, the worker count, the chunking and the order tasks finish in. The
stochastic candidate (``wheel_liftoff``: lift-event inference, :mod:`.events`) builds its own jobs
(scheduled lift events); its batches are cut the same way (:meth:`TaskEvaluator.simulate`).
In this process (the serial backend) the fits run one after another and a round is one batch, one
world shared by numba's threads.

The work record (:class:`FitWork`, :class:`StepWork`): per task the CPU seconds it ran (the worker's
process time: a worker runs one task at a time on one thread), per fit the CPU seconds of its own
driver-side search arithmetic (the fit thread's time outside its simulations), and per step the
decision's. A fit's dependency chain is its rounds one after another, each as long as its longest task,
plus its driver arithmetic; a step's critical path is its longest fit chain plus the decision (the
step's fits all start together and the decision waits for all), and its total work the sum of all.
With W workers a step cannot take less than max(critical path, total / W): :func:`reachable_speedup`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from omni_gym.discrepancy.fit.candidates import Candidate
from omni_gym.discrepancy.fit.fitting import Evaluator, FitResult, fit_candidate
from omni_gym.discrepancy.replay.simulate import Job, simulate_poses
from omni_gym.discrepancy.settings import GapSettings
from omni_gym.parallel import Executor
from omni_gym.physics.model import SimModel
from omni_gym.progress import Progress

# Robot time [s] one chunk task simulates at most (unless one job is longer): 120 s is one point on 24
# runs of 5 s, about 40 ms of one core's work on the real omni3 segments, far above a task's dispatch
# cost (about a millisecond) and far below a step's work (minutes).
CHUNK_ROBOT_S = 120.0
WORKERS = (1, 2, 4, 8, 16, 32)  # worker counts of the reachable speed-up table


@dataclass(frozen=True)
class FitShared:
    """What every fit task of a gap run needs (sent to each worker once): the evaluator, with its
    cached nominal baseline, noise floor and shooting windows, the runs' folds, and the fit's and
    event search's settings."""

    ev: Evaluator
    fold_of: np.ndarray
    settings: GapSettings = field(default_factory=GapSettings)


@dataclass(frozen=True)
class FitTask:
    """One candidate fit: the candidate, the model it is fitted on top of, and its own seed."""

    candidate: Candidate
    base: SimModel
    seed: np.random.SeedSequence


@dataclass(frozen=True)
class Chunk:
    """A chunk task: jobs ``lo``..``hi`` - 1 of a round's job list (:meth:`Evaluator.jobs` of the round's
    models), where ``models`` are the round's models ``first``, ``first + 1``, ... that those jobs use."""

    models: tuple[SimModel, ...]
    first: int
    shooting: bool
    lo: int
    hi: int


@dataclass
class ChunkResult:
    """A chunk task's residuals (per job, :meth:`Evaluator.job_residuals`; or poses, :class:`JobsChunk`),
    jobs simulated, CPU seconds."""

    residuals: list[np.ndarray]
    simulated: int
    seconds: float


@dataclass(frozen=True)
class JobsChunk:
    """A chunk task of any jobs (the lift-event inference's): each job as its model's index in ``models``,
    its run's index in the shared dataset and the rest of its fields, or as the :class:`Job` itself when
    its run is not one of the dataset's."""

    models: tuple[SimModel, ...]
    jobs: tuple[tuple | Job, ...]
    dt: float
    max_batch: int


def jobs_task(shared: FitShared, chunk: JobsChunk) -> ChunkResult:
    """Simulate one chunk of jobs (a backend task): their poses."""
    t0 = time.process_time()
    runs = shared.ev.ds.runs
    jobs = [j if isinstance(j, Job) else Job(chunk.models[j[0]], runs[j[1]], *j[2:]) for j in chunk.jobs]
    poses = simulate_poses(jobs, chunk.dt, chunk.max_batch, shared.ev.start_window)
    return ChunkResult(poses, len(jobs), time.process_time() - t0)


def job_chunks(jobs: list[Job], runs: list, dt: float, max_batch: int,
               robot_s: float = CHUNK_ROBOT_S) -> list[JobsChunk]:
    """``jobs`` cut into contiguous :class:`JobsChunk` of at most ``robot_s`` of robot time each (a longer job
    is a chunk of its own); ``runs``: the shared dataset's runs, which the chunks name by index."""
    index = {id(r): i for i, r in enumerate(runs)}
    out: list[JobsChunk] = []
    for lo, hi in _cuts([_duration(j) for j in jobs], robot_s):
        models: list[SimModel] = []
        refs: list[tuple | Job] = []
        for j in jobs[lo:hi]:
            ri = index.get(id(j.run))
            if ri is None:
                refs.append(j)
                continue
            mi = next((i for i, m in enumerate(models) if m is j.model), None)
            if mi is None:
                models.append(j.model)
                mi = len(models) - 1
            refs.append((mi, ri, j.k0, j.k1, j.state0, j.seed, j.drag, j.schedule))
        out.append(JobsChunk(tuple(models), tuple(refs), dt, max_batch))
    return out


def _duration(job: Job) -> float:
    """Robot time [s] a job simulates."""
    t = job.run.t
    return float(t[job.k1] - t[job.k0])


def _cuts(durations: list[float], robot_s: float) -> list[tuple[int, int]]:
    """Contiguous (lo, hi) ranges of at most ``robot_s`` summed duration (a longer item alone)."""
    out: list[tuple[int, int]] = []
    lo, acc = 0, 0.0
    for j, d in enumerate(durations):
        if j > lo and acc + d > robot_s:
            out.append((lo, j))
            lo, acc = j, 0.0
        acc += d
    if lo < len(durations):
        out.append((lo, len(durations)))
    return out


def chunk_task(shared: FitShared, chunk: Chunk) -> ChunkResult:
    """Simulate one chunk (a backend task)."""
    t0 = time.process_time()
    ev = shared.ev
    per = ev.jobs_per_model(chunk.shooting)
    jobs = ev.jobs(list(chunk.models), chunk.shooting)
    offset = chunk.first * per
    jobs = jobs[chunk.lo - offset:chunk.hi - offset]
    res = ev.job_residuals(jobs, chunk.shooting)
    return ChunkResult(res, len(jobs), time.process_time() - t0)


def chunks(ev: Evaluator, models: list[SimModel], shooting: bool, robot_s: float = CHUNK_ROBOT_S) -> list[Chunk]:
    """A round's jobs (:meth:`Evaluator.jobs`) cut into contiguous chunks of at most ``robot_s`` of robot
    time each (a longer job is a chunk of its own); the cut depends on the round alone."""
    per = ev.jobs_per_model(shooting)
    return [_chunk(models, per, shooting, lo, hi)
            for lo, hi in _cuts([_duration(j) for j in ev.jobs(models, shooting)], robot_s)]


def _chunk(models: list[SimModel], per: int, shooting: bool, lo: int, hi: int) -> Chunk:
    first, last = lo // per, (hi - 1) // per
    return Chunk(tuple(models[first:last + 1]), first, shooting, lo, hi)


@dataclass
class FitWork:
    """One fit's work: its tasks' CPU seconds, round by round, and its driver-side arithmetic."""

    candidate: str
    tasks: int = 0
    rounds: int = 0
    work_s: float = 0.0  # CPU seconds of all its tasks
    chain_s: float = 0.0  # sum over its rounds of the round's longest task
    max_task_s: float = 0.0
    driver_s: float = 0.0  # CPU seconds of its search arithmetic in the driver

    def add_round(self, seconds: list[float]) -> None:
        """Record one round of tasks (they run side by side; the next round waits for all)."""
        self.tasks += len(seconds)
        self.rounds += 1
        self.work_s += sum(seconds)
        self.chain_s += max(seconds, default=0.0)
        self.max_task_s = max(self.max_task_s, *seconds) if seconds else self.max_task_s

    @property
    def critical_path_s(self) -> float:
        return self.chain_s + self.driver_s

    @property
    def total_s(self) -> float:
        return self.work_s + self.driver_s

    def to_json(self) -> dict:
        return {"candidate": self.candidate, "tasks": self.tasks, "rounds": self.rounds, "work_s": self.work_s,
                "driver_s": self.driver_s, "total_s": self.total_s, "critical_path_s": self.critical_path_s,
                "max_task_s": self.max_task_s}


@dataclass
class StepWork:
    """One search step's work: its fits and the decision after them (CPU seconds), and its wall time."""

    fits: list[FitWork] = field(default_factory=list)
    decide_s: float = 0.0
    wall_s: float = 0.0

    @property
    def tasks(self) -> int:
        return sum(f.tasks for f in self.fits)

    @property
    def total_s(self) -> float:
        return sum(f.total_s for f in self.fits) + self.decide_s

    @property
    def critical_path_s(self) -> float:
        return max((f.critical_path_s for f in self.fits), default=0.0) + self.decide_s

    @property
    def max_task_s(self) -> float:
        return max((f.max_task_s for f in self.fits), default=0.0)

    def to_json(self) -> dict:
        return {"tasks": self.tasks, "total_work_s": self.total_s, "critical_path_s": self.critical_path_s,
                "max_task_s": self.max_task_s, "decide_s": self.decide_s, "wall_s": self.wall_s,
                "reachable_speedup": {str(w): reachable_speedup(self.total_s, self.critical_path_s, w)
                                      for w in WORKERS},
                "fits": [f.to_json() for f in self.fits]}


def reachable_speedup(total_s: float, critical_path_s: float, workers: int) -> float:
    """The most a run of ``total_s`` of work whose longest dependency chain is ``critical_path_s`` can gain
    on ``workers`` workers over one: total / max(critical path, total / W)."""
    bound = max(critical_path_s, total_s / workers)
    return total_s / bound if bound > 0 else 1.0


def work_json(steps: list[StepWork], serial_s: float, wall_s: float, backend: str,
              driver_cpu_s: float | None = None) -> dict:
    """``result.json``'s ``work``: per step and for the whole run. The whole run's bound with W workers is
    its serial part (the driver's work outside the steps: start model, localising, the held-out replays,
    the report) plus, per step (steps run one after another), max(critical path, total / W)."""
    total = serial_s + sum(s.total_s for s in steps)
    critical = serial_s + sum(s.critical_path_s for s in steps)

    def bound(w: int) -> float:
        return serial_s + sum(max(s.critical_path_s, s.total_s / w) for s in steps)

    return {
        "unit": "CPU seconds", "backend": backend, "wall_s": wall_s, "serial_s": serial_s,
        "driver_cpu_s": serial_s if driver_cpu_s is None else driver_cpu_s,
        "total_work_s": total, "critical_path_s": critical, "tasks": sum(s.tasks for s in steps),
        "reachable_speedup": {str(w): total / bound(w) if bound(w) > 0 else 1.0 for w in WORKERS},
        "steps": [s.to_json() for s in steps],
        "note": "measured, so not the same from run to run (everything else in result.json is): per task the CPU "
                "seconds it ran; a fit's critical path is its rounds one after another, each as long as its "
                "longest task, plus its search arithmetic in the driver; a step's is its longest fit's plus the "
                "decision; driver_cpu_s: the driver process's own CPU time (on a parallel backend: the serial part, "
                "the fits' search arithmetic and the tasks' dispatch); reachable_speedup with W workers: total / "
                "(serial + sum over steps of max(critical path, total / W)), the bound the dependencies allow "
                "(omni_gym.discrepancy.fit.fit_tasks)",
    }


class TaskEvaluator:
    """An :class:`Evaluator` for one fit whose simulations run as chunk tasks on ``ex`` (None: in this
    process, one batch per round), recording the fit's work. Everything else is the evaluator's."""

    def __init__(self, ev: Evaluator, ex: Executor | None, shared: FitShared, work: FitWork) -> None:
        self._ev = ev
        self._ex = ex
        self._shared = shared
        self.work = work
        self.simulated = 0
        self.eval_thread_s = 0.0  # this thread's CPU time inside residuals() (not the fit's own arithmetic)

    def __getattr__(self, name: str):
        return getattr(self._ev, name)

    def residuals(self, models: list[SimModel], shooting: bool = False) -> list[list[np.ndarray]]:
        """:meth:`Evaluator.residuals`, the same bits."""
        t_thread = time.thread_time()
        if self._ex is None:
            t0 = time.process_time()
            jobs = self._ev.jobs(models, shooting)
            flat = self._ev.job_residuals(jobs, shooting)
            self.work.add_round([time.process_time() - t0])
            self.simulated += len(jobs)
        else:
            parts = self._ex.map(chunk_task, chunks(self._ev, models, shooting), shared=self._shared,
                                 inline_single=False)
            flat = [r for p in parts for r in p.residuals]
            self.work.add_round([p.seconds for p in parts])
            self.simulated += sum(p.simulated for p in parts)
        out = self._ev.assemble(len(models), flat, shooting)
        self.eval_thread_s += time.thread_time() - t_thread
        return out

    def simulate(self, jobs: list[Job], dt: float, max_batch: int,
                 done: Callable[[int, int], None] | None = None) -> list[np.ndarray]:
        """:meth:`Evaluator.simulate`, the same bits (not counted in ``simulated``: the caller counts).
        ``done(j, m)``: progress, after each of the m worlds (this process) or chunk tasks (a backend)."""
        t_thread = time.thread_time()
        if self._ex is None:
            t0 = time.process_time()
            poses = simulate_poses(jobs, dt, max_batch, self._ev.start_window, done=done)
            self.work.add_round([time.process_time() - t0])
        else:
            tasks = job_chunks(jobs, self._ev.ds.runs, dt, max_batch)
            finished = [0]

            def on_done(_i: int, _result: ChunkResult) -> None:
                finished[0] += 1
                if done is not None:
                    done(finished[0], len(tasks))
            parts = self._ex.map(jobs_task, tasks, shared=self._shared, inline_single=False, on_done=on_done)
            poses = [p for part in parts for p in part.residuals]
            self.work.add_round([p.seconds for p in parts])
        self.eval_thread_s += time.thread_time() - t_thread
        return poses


def run_fits(tasks: list[FitTask], ev: Evaluator, ex: Executor | None, shared: FitShared,
             tick: Callable[[], None] | None = None,
             started: Callable[[int], None] | None = None,
             finished: Callable[[int], None] | None = None,
             progress: list[Progress] | None = None) -> tuple[list[FitResult], int, list[FitWork]]:
    """Fit every task's candidate; returns the fits (in task order), the robot-runs simulated and each fit's
    work. ``ex`` None or serial: one fit after another in this thread. Else side by side in threads of
    the driver, their rounds as chunk tasks on ``ex``.
    ``tick`` per search round, ``started(i)``/``finished(i)`` per fit (progress; called from the fit's
    thread, one at a time); ``progress``: per task its fit's progress lines (:class:`omni_gym.progress.Progress`)."""
    n = len(tasks)
    fits: list[FitResult | None] = [None] * n
    sims = [0] * n
    works = [FitWork(t.candidate.name) for t in tasks]
    parallel = ex is not None and not ex.backend.serial
    lock = threading.Lock()

    def locked(fn: Callable | None) -> Callable | None:
        if fn is None:
            return None

        def call(*a) -> None:
            with lock:
                fn(*a)
        return call

    tick_l, started_l, finished_l = locked(tick), locked(started), locked(finished)

    def one(i: int) -> None:
        task, work = tasks[i], works[i]
        if started_l:
            started_l(i)
        t0 = time.thread_time()
        tev = TaskEvaluator(ev, ex if parallel else None, shared, work)
        fit = fit_candidate(task.candidate, tev, task.base, shared.fold_of, np.random.default_rng(task.seed),
                            shared.settings, tick=tick_l, progress=None if progress is None else progress[i])
        work.driver_s = max(time.thread_time() - t0 - tev.eval_thread_s, 0.0)
        sim = tev.simulated
        fits[i], sims[i] = fit, sim
        if finished_l:
            finished_l(i)

    if not parallel:
        for i in range(n):
            one(i)
        return fits, sum(sims), works  # type: ignore[return-value]
    errors: list[BaseException | None] = [None] * n

    def guarded(i: int) -> None:
        try:
            one(i)
        except BaseException as exc:  # noqa: BLE001 -- handed to the main thread, which re-raises it
            errors[i] = exc

    ex.start(shared)  # the workers start from the main thread (SIGINT ignored in them)
    threads = [threading.Thread(target=guarded, args=(i,), name=f"fit-{t.candidate.name}", daemon=True)
               for i, t in enumerate(tasks)]
    try:
        for th in threads:
            th.start()
        for th in threads:
            while th.is_alive():
                th.join(0.1)  # short waits: an interrupt reaches the main thread here
                failed = next((e for e in errors if e is not None), None)
                if failed is not None:
                    raise failed
    except BaseException:
        ex.abort()  # the other fits' tasks stop with their workers; their threads end on the error
        raise
    failed = next((e for e in errors if e is not None), None)
    if failed is not None:
        raise failed
    return fits, sum(sims), works  # type: ignore[return-value]

