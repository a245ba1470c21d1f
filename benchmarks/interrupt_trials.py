"""Ctrl-C during ``omni-gym gap --jobs 2``: how long the command takes to end, in many trials.

Each trial starts ``python -m omni_gym.cli gap DATASET --jobs 2`` in its own session, waits until its two
worker processes run, waits a delay spread over the fit (so that the interrupt finds the workers starting,
fitting or writing results), then sends SIGINT to the main process or to the whole process group (what a
terminal's Ctrl-C does), a second and third time 0.15 s apart. Measured: the time from the first SIGINT to
the command's exit, its status and last line, the report folder (must not exist) and the workers left.

Target: every trial ends within 2 s, status 130, one line
``omni-gym: interrupted``, nothing written, no worker left.

    python benchmarks/interrupt_trials.py --trials 24 --out benchmarks/results/interrupt_trials.md
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from omni_gym.record_paths import record_args

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 2.0  # s: every interrupted run must end within 2 s (the reliability target, docs/scaling.md)
HANG_S = 60.0  # a trial still running this long after SIGINT counts as a hang (and is killed)


@dataclass
class Trial:
    """One interrupted run."""

    index: int
    delay_s: float
    target: str  # "main" or "group"
    status: int | None
    end_s: float  # first SIGINT -> exit (HANG_S when it hung)
    last_line: str
    wrote_report: bool
    workers_left: int

    @property
    def clean(self) -> bool:
        return (self.status == 130 and self.last_line == "omni-gym: interrupted" and not self.wrote_report
                and self.workers_left == 0)


def _default_sigint() -> None:
    """In the command before it runs: SIGINT at its default, as from a terminal. Started in the background
    (``nohup ... &``) this script has SIGINT ignored, the commands would inherit that and rightly ignore
    every interrupt (an inherited SIG_IGN is respected): each trial would look like a hang."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _children(pid: int) -> list[int]:
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if int((entry / "stat").read_text().rpartition(")")[2].split()[1]) == pid:
                    kids.append(int(entry.name))
            except (OSError, ValueError, IndexError):
                continue
    return kids


def _alive(pid: int) -> bool:
    try:
        return (Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]) not in ("Z", "X")
    except OSError:
        return False


def run_trial(index: int, dataset: Path, work: Path, delay_s: float, target: str) -> Trial:
    out = work / f"report{index}"
    # PYTHONFAULTHANDLER: a hung command is ended with SIGABRT, which then prints every thread's stack.
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONFAULTHANDLER": "1"}
    err_file = work / f"stderr{index}.txt"  # a file, not a pipe nobody reads while the command runs
    with open(err_file, "w") as err_out:
        proc = subprocess.Popen([sys.executable, "-m", "omni_gym.cli", "gap", str(dataset), "--out", str(out),
                                 "--jobs", "2", "--no-plots"], stdout=subprocess.DEVNULL, stderr=err_out,
                                text=True, env=env, start_new_session=True, preexec_fn=_default_sigint)
    deadline = time.monotonic() + 120
    kids: list[int] = []
    while time.monotonic() < deadline and proc.poll() is None:
        kids = _children(proc.pid)
        if len(kids) >= 3:  # two workers and the resource tracker
            break
        time.sleep(0.05)
    time.sleep(delay_s)
    kids = sorted(set(kids) | set(_children(proc.pid)))
    def interrupt() -> None:
        try:
            if target == "main":
                os.kill(proc.pid, signal.SIGINT)
            else:
                os.killpg(proc.pid, signal.SIGINT)
        except ProcessLookupError:
            pass

    t0 = time.monotonic()
    sent = 0
    while proc.poll() is None and time.monotonic() - t0 < HANG_S:
        if sent < 3 and time.monotonic() - t0 >= 0.15 * sent:  # three interrupts, 0.15 s apart
            interrupt()
            sent += 1
        time.sleep(0.005)
    end_s = time.monotonic() - t0
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGABRT)  # the stacks, for the report
        time.sleep(2.0)
        os.killpg(proc.pid, signal.SIGKILL)
        end_s = HANG_S
    proc.wait()
    err = err_file.read_text(errors="replace")
    if end_s >= HANG_S:
        print(f"trial {index} hung; its stderr ends:\n{err[-6000:]}", file=sys.stderr, flush=True)
    time.sleep(1.0)  # the parent watch of a worker polls every 0.5 s
    left = [k for k in kids if _alive(k)]
    for k in left:
        try:
            os.kill(k, signal.SIGKILL)
        except ProcessLookupError:
            pass
    lines = err.strip().splitlines()
    return Trial(index, delay_s, target, proc.returncode, end_s, lines[-1] if lines else "", out.exists(), len(left))


def report(trials: list[Trial], wall_s: float, command: str) -> str:
    ends = [t.end_s for t in trials]
    clean = sum(t.clean for t in trials)
    within = sum(t.end_s <= TARGET_S for t in trials)
    hung = sum(t.end_s >= HANG_S for t in trials)
    lines = [
        "# Ctrl-C during `omni-gym gap --jobs 2`",
        "",
        f"`{command}` ({wall_s:.0f} s). Each trial interrupts a fit at a different point (delay after its two "
        "workers started; SIGINT three times, 0.15 s apart, to the main process or its whole group). Clean: "
        "status 130, the last line `omni-gym: interrupted`, no report written, no worker left.",
        "",
        "| trials | clean | ended within 2 s | hung (> 60 s) | median end (s) | max end (s) |",
        "|---|---|---|---|---|---|",
        f"| {len(trials)} | {clean} | {within} | {hung} | {statistics.median(ends):.2f} | {max(ends):.2f} |",
        "",
        "| trial | delay (s) | signal to | status | end (s) | last line | report | workers left |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for t in trials:
        lines.append(f"| {t.index} | {t.delay_s:.2f} | {t.target} | {t.status} | {t.end_s:.2f} | {t.last_line[:40]} | "
                     f"{'written' if t.wrote_report else 'none'} | {t.workers_left} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=24)
    parser.add_argument("--max-delay", type=float, default=6.0,
                        help="the last trial's delay after the workers start (s)")
    parser.add_argument("--out", type=Path, default=None, help="markdown table (default: print only)")
    args = parser.parse_args(argv)
    if not Path("/proc/self/stat").exists():
        print("interrupt_trials: reads processes from /proc (Linux only)", file=sys.stderr)
        return 2
    t_start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="omni-gym-interrupts-") as tmp:
        work = Path(tmp)
        dataset = work / "ds"
        subprocess.run([sys.executable, "-m", "omni_gym.cli", "synth", "--model", "williams2002", "--hidden",
                        "viscous_drag", "--runs", "4", "--duration", "3", "--out", str(dataset)], check=True,
                       stdout=subprocess.DEVNULL, env={**os.environ, "PYTHONPATH": str(ROOT)})
        trials = []
        for i in range(args.trials):
            delay = args.max_delay * i / max(args.trials - 1, 1)
            t = run_trial(i, dataset, work, delay, "main" if i % 2 == 0 else "group")
            trials.append(t)
            print(f"trial {i + 1}/{args.trials}: delay {delay:.2f} s, {t.target}: status {t.status}, "
                  f"ended in {t.end_s:.2f} s{'' if t.clean else '  NOT CLEAN'}", flush=True)
    recorded = record_args(argv if argv is not None else sys.argv[1:])
    command = "python benchmarks/interrupt_trials.py " + " ".join(recorded)
    text = report(trials, time.monotonic() - t_start, command.strip())
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0 if all(t.clean and t.end_s <= TARGET_S for t in trials) else 1


if __name__ == "__main__":
    sys.exit(main())
