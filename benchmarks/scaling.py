"""Scaling of the recovery benchmark's case map from 1 to N local workers (goal: efficiency >= 0.8 at 2).

A fixed, balanced workload: ``--cases`` recovery cases of one effect (motor_lag, large, 1 mm noise),
differing only in the data seed, so every case costs about the same; more cases than workers. Each
backend runs the same cases: local processes and a fresh local Ray, at 1 and ``--workers`` workers.
Efficiency = t1 / (N · tN). The results (minus wall times) must be identical across every run.

    # the measurement (7.8 min on 2 cores):
    python benchmarks/scaling.py --cases 8 --runs 4 --duration 2 --workers 2 --out benchmarks/results
    # a tiny check that it works (seconds of work, mostly start-up):
    python benchmarks/scaling.py --cases 2 --runs 3 --duration 1 --workers 2 --out /tmp/scaling

``--gap-result REPORT/result.json``: instead, the scaling table of one ``gap`` run from the work it recorded
(``result.json``'s ``work``: per search step its tasks, total work and critical path): the speed-up W
workers can reach on that work, per step and for the whole run, beside the run's measured wall time
(``benchmarks/results/gap_work.md``)::

    python benchmarks/scaling.py --gap-result REPORT/result.json --out benchmarks/results
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path

from omni_gym.discrepancy.fit.fit_tasks import WORKERS
from omni_gym.discrepancy.synthetic.recovery import SIZES, run_case
from omni_gym.parallel import Backend, parallel_map

EFFECT = "motor_lag"


@dataclass(frozen=True)
class Case:
    """One recovery case of the workload."""

    seed: int
    runs: int
    duration: float


@dataclass
class Timing:
    """One backend at one worker count."""

    backend: str
    workers: int
    wall_s: float


def run(case: Case) -> dict:
    """A task: one recovery case; the wall time is dropped (it differs between runs, the rest must not)."""
    out = run_case(EFFECT, SIZES[EFFECT]["large"], 0.001, case.seed, case.runs, case.duration)
    out.pop("wall_s")
    return out


def measure(cases: list[Case], backend: Backend) -> tuple[float, str]:
    """Wall time [s] of the case map on ``backend`` (start-up included) and its results as JSON."""
    t0 = time.perf_counter()
    results = parallel_map(run, cases, backend)
    return time.perf_counter() - t0, json.dumps(results, sort_keys=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=8)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--backends", default="processes,ray", help="comma-separated: processes, ray")
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--gap-result", default=None, metavar="RESULT_JSON",
                    help="write the scaling table of this gap run's recorded work instead (gap_work.md)")
    args = ap.parse_args()
    if args.gap_result is not None:
        result = json.loads(Path(args.gap_result).read_text())
        text = gap_work_table(result, f"python benchmarks/scaling.py --gap-result {args.gap_result}")
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "gap_work.md").write_text(text)
        print(text)
        return
    cases = [Case(200 + i, args.runs, args.duration) for i in range(args.cases)]
    # One case first, not timed: numba's compiled kernels land in its disk cache for every worker to load.
    run(cases[0])
    timings: list[Timing] = []
    outputs: set[str] = set()
    for name in args.backends.split(","):
        for n in (1, args.workers):
            # One worker is measured as N are: a worker process (pool) or a local Ray of that many CPUs.
            # (Run serially in this process the same 8 cases took 198.5 s against 153.8 s in one worker
            # process: a serial baseline flattered the speed-up, 2.45x with two processes.)
            backend = Backend(jobs=n, ray=name == "ray", cpus=n if name == "ray" else None, pool=True)
            wall, out = measure(cases, backend)
            timings.append(Timing(name, n, wall))
            outputs.add(out)
            print(f"{name} x{n}: {wall:.1f} s", flush=True)
    write(Path(args.out), args, timings, identical=len(outputs) == 1)


def write(out: Path, args: argparse.Namespace, timings: list[Timing], identical: bool) -> None:
    """benchmarks/results/scaling.md: wall time, speed-up and efficiency per backend."""
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# Scaling of the recovery benchmark's case map", "",
             f"`python benchmarks/scaling.py --cases {args.cases} --runs {args.runs} --duration {args.duration:g} "
             f"--workers {args.workers}` on {platform.machine()} ({os.cpu_count()} cores). {args.cases} cases of "
             f"{EFFECT} (large, 1 mm), {args.runs} runs x {args.duration:g} s each, seeds 200..; wall times include "
             "the start-up of the workers (and of Ray); 1 worker is a pool of one process, or a local Ray "
             "with 1 CPU, measured as N workers are.", "",
             "| backend | workers | wall [s] | speed-up | efficiency |", "|---|---|---|---|---|"]
    for t in timings:
        t1 = next(x.wall_s for x in timings if x.backend == t.backend and x.workers == 1)
        speedup = t1 / t.wall_s
        lines.append(f"| {t.backend} | {t.workers} | {t.wall_s:.1f} | {speedup:.2f} | {speedup / t.workers:.2f} |")
    lines += ["", f"Results identical across all runs (wall times aside): {'yes' if identical else 'NO'}."]
    (out / "scaling.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def gap_work_table(result: dict, command: str) -> str:
    """Markdown: per search step and for the whole run, tasks, total work, critical path, longest task and
    the speed-up reachable with W workers (``result['work']``, :func:`omni_gym.discrepancy.fit.fit_tasks.work_json`),
    then each step's candidate fits."""
    work = result["work"]
    heads = " | ".join(f"W = {w}" for w in WORKERS)
    lines = ["# Scaling of one gap run, from its recorded work", "", f"`{command}`", "",
             f"Measured: wall time {work['wall_s']:.1f} s on {work['backend']}; CPU seconds of work below. "
             "Reachable speed-up with W workers: total / max(critical path, total / W) per step; for the whole "
             "run total / (serial part + sum over steps of max(critical path, total / W)).", "",
             f"| part | tasks | total work [s] | critical path [s] | longest task [s] | {heads} |",
             "|---|---|---|---|---|" + "---|" * len(WORKERS)]
    for i, s in enumerate(work["steps"], start=1):
        cells = " | ".join(f"{s['reachable_speedup'][str(w)]:.2f}" for w in WORKERS)
        lines.append(f"| step {i} | {s['tasks']} | {s['total_work_s']:.1f} | {s['critical_path_s']:.1f} | "
                     f"{s['max_task_s']:.2f} | {cells} |")
    cells = " | ".join(f"**{work['reachable_speedup'][str(w)]:.2f}**" for w in WORKERS)
    lines.append(f"| whole run (serial part {work['serial_s']:.1f} s) | {work['tasks']} | {work['total_work_s']:.1f} | "
                 f"{work['critical_path_s']:.1f} | | {cells} |")
    for i, s in enumerate(work["steps"], start=1):
        lines += ["", f"Step {i}, per candidate fit (decision {s['decide_s']:.3f} s):", "",
                  "| candidate | tasks | rounds | work [s] | driver [s] | critical path [s] | longest task [s] |",
                  "|---|---|---|---|---|---|---|"]
        lines += [f"| {f['candidate']} | {f['tasks']} | {f['rounds']} | {f['work_s']:.1f} | {f['driver_s']:.2f} | "
                  f"{f['critical_path_s']:.2f} | {f['max_task_s']:.3f} |"
                  for f in sorted(s["fits"], key=lambda f: -f["critical_path_s"])]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
