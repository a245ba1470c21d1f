"""Cost of one robot's physics substep, split into the force kernel, pymunk's part and the whole step,
beside the limit of this machine for the kernel's operation mix.

    python benchmarks/substep_micro.py --out benchmarks/results

For N = 1, 64, 1024, 16384 robots and both wheel laws (the omni law: ``phunopas2018`` on
``roller_gap``, four omni wheels with the roller-gap coefficient switch; the mecanum law:
``optiodom_omni4`` on ``initial``, four 45° mecanum wheels), with the environments' default ideal
actuation and 0.5 ms substeps, it reports nanoseconds per robot-substep of

* the force kernel alone (``physics.kernel.substep`` called from a compiled loop, so no Python
  dispatch is counted; one thread), and the threaded kernel (``substep_parallel``, all cores);
* pymunk's part: the batched state read, the batched force write and the space step, called from
  a compiled loop as ``World.substeps`` calls them (``run_substeps`` in :mod:`omni_gym.physics.kernel`;
  on older versions without it, from Python, as the world then did);
* the whole ``World.substeps`` on one thread and with the default threading (threads from 256
  robots on; without obstacles each thread then steps its own pymunk space).

The limit: the kernel's floating-point operations and transcendental calls per robot-substep are
counted by hand from ``physics/kernel.py`` (table :data:`MIXES`, each line of the count commented),
and a plain numba loop of the same mix (the same number of additions and multiplications,
``atan``, ``floor``, divisions, one ``sin`` and one ``cos`` per robot, reading and writing as many
float64 per robot as the kernel does, laid out robot-major as the kernel's arrays) is timed on one
core. measured ÷ limit is the single-thread kernel's ns over the limit loop's ns at the same N.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from pathlib import Path

import numba
import numpy as np

from omni_gym.outputs import write_text_atomic
from omni_gym.physics import kernel as K
from omni_gym.physics.model import load_model
from omni_gym.physics.world import World

SIZES = (1, 64, 1024, 16384)
LAWS = (("omni: phunopas2018, roller_gap", "phunopas2018", "roller_gap"),
        ("mecanum: optiodom_omni4, initial", "optiodom_omni4", "initial"))

# Operation mix per robot-substep of the ideal-actuation kernel, counted from physics/kernel.py
# (flops: additions, subtractions and multiplications; comparisons and moves not counted).
# Per wheel, omni law with the roller gap (gap > 0):
#   geometry (lever arm, drive direction, contact velocity) 18; ideal actuation (dθ, θ1) 2;
#   gap_fraction: θ+phase ×2, d, one gap_measure (div, floor, 7 flops; the start's measure is the
#   last substep's end, remembered), (m1 − m0)/d → 11 flops, 2 div, 1 floor; coefficient blend
#   (1−f)a + fb ×2: 8;
#   slips v_W, v_T: 8; two friction laws μ = (2/π)atan(kv)·μs, μ' = (2/π)k/(1+(kv)²)·μs: 7 flops,
#   1 atan, 1 div each → 14, 2 atan, 2 div; forces and torque 14; K = N(μ'_W eeᵀ + μ'_T ffᵀ) 17;
#   A accumulation (a00..a22) 25.  → 117 flops, 2 atan, 4 div, 1 floor per wheel.
# Mecanum law (initial: no gap, gap_fraction returns 0 at once): no gap flops, no floor; the roller
#   axis e = cos γ d + sin γ z×d (6), r cos γ, r sin γ (2), v_T += r sin γ w (2) → 106 + 10 = 116
#   flops, 2 atan, 2 div per wheel.
# (Before the memo of the rigid-material measure the omni law had 123 flops, 5 div, 2 floor per wheel.)
# Per robot: cos θ, sin θ; the 3×3 solve (M + dt A), adjugate, determinant, right-hand side and
#   the three outputs: 56 flops, 2 div (1/det, 1/dt).
MIXES = {
    "phunopas2018": {"wheels": 4, "flops_wheel": 117, "atan_wheel": 2, "div_wheel": 4, "floor_wheel": 1,
                     "flops_robot": 56, "div_robot": 2},
    "optiodom_omni4": {"wheels": 4, "flops_wheel": 116, "atan_wheel": 2, "div_wheel": 2, "floor_wheel": 0,
                       "flops_robot": 56, "div_robot": 2},
}
# float64 the kernel reads / writes per robot: state 6, sp 15, per wheel wp 12 + wheels 7 read,
# wheels 4 (speed, angle, memo) + slip 2 written; ext 3 read, force 3 written.
READ_ROBOT, READ_WHEEL, WRITE_ROBOT, WRITE_WHEEL = 24, 19, 3, 6


def limit_source(mix: dict) -> str:
    """Source of a numba loop with exactly ``mix``'s operations per robot (four independent chains,
    as the kernel's wheel arithmetic has: the compiler may overlap them as it does the kernel's)."""
    lines = ["def limit_loop(inp, win, out, wout, reps):",
             "    B = inp.shape[0]",
             "    for _ in range(reps):",
             "        for b in range(B):",
             "            th = inp[b, 0]",
             "            c = math.cos(th)",
             "            s = math.sin(th)",
             "            r0 = inp[b, 1] + c",
             "            r1 = inp[b, 2] - s",
             "            acc = 0.0"]
    # Reads beyond the ones used as operands are summed so that none is dropped (these adds are
    # counted among the flops).
    n_flops_robot = mix["flops_robot"] - (READ_ROBOT - 3) - 2 - mix["div_robot"]
    lines.append("            t = " + " + ".join(f"inp[b, {k}]" for k in range(3, READ_ROBOT)))
    lines.append(f"            for i in range({mix['wheels']}):")
    lines.append("                x0 = win[b, i, 0] * c + r0")
    lines.append("                x1 = win[b, i, 1] * s + r1")
    lines.append("                x2 = win[b, i, 2] * c - r1")
    lines.append("                x3 = win[b, i, 3] * s - r0")
    lines.append("                u = " + " + ".join(f"win[b, i, {k}]" for k in range(4, READ_WHEEL)))
    used = 8 + (READ_WHEEL - 5)
    ops = ["x0 = x0 * x1 + u", "x1 = x1 * x2 - u", "x2 = x2 * x3 + t", "x3 = x3 * x0 - t"]
    n = (mix["flops_wheel"] - used - mix["atan_wheel"] - mix["div_wheel"] - mix["floor_wheel"]) // 2
    for k in range(n):
        lines.append("                " + ops[k % 4])
    for k in range(mix["atan_wheel"]):
        v = f"x{k % 4}"
        lines.append(f"                {v} = math.atan({v}) * 0.6366")
    for k in range(mix["div_wheel"]):
        v = f"x{(k + 1) % 4}"
        lines.append(f"                {v} = 1.0 / (1.0 + {v} * {v})")
    for k in range(mix["floor_wheel"]):
        v = f"x{(k + 2) % 4}"
        lines.append(f"                {v} = {v} - math.floor({v})")
    lines.append("                wout[b, i, 0] = x0")
    lines.append("                wout[b, i, 1] = x1")
    lines.append("                wout[b, i, 2] = x2")
    lines.append("                wout[b, i, 3] = x3")
    for k in range(4, WRITE_WHEEL):
        lines.append(f"                wout[b, i, {k}] = x{k % 4} - u")
    lines.append("                acc += x0 + x1 - x2")
    lines.append("            y0 = acc + t")
    lines.append("            y1 = acc - t")
    lines.append("            y2 = acc * t")
    ops_r = ["y0 = y0 * y1 + r0", "y1 = y1 * y2 - r1", "y2 = y2 * y0 + r0"]
    for k in range(max(0, (n_flops_robot - 3) // 2)):
        lines.append("            " + ops_r[k % 3])
    for k in range(mix["div_robot"]):
        lines.append(f"            y{k % 3} = 1.0 / (1.0 + y{k % 3} * y{k % 3})")
    lines.append("            out[b, 0] = y0")
    lines.append("            out[b, 1] = y1")
    lines.append("            out[b, 2] = y2")
    return "\n".join(lines) + "\n"


def build_limit(mix: dict):
    namespace = {"math": math}
    exec(compile(limit_source(mix), "<limit_loop>", "exec"), namespace)  # noqa: S102 (generated above)
    return numba.njit(namespace["limit_loop"])


@numba.njit
def repeat_kernel(reps, dt, state, wheels, sp, wp, ext, force, slip):
    """``reps`` serial kernel calls from compiled code (no Python dispatch in the timing)."""
    for _ in range(reps):
        K.substep(dt, state, wheels, sp, wp, ext, force, slip)


@numba.njit(parallel=True)
def _parallel_once(dt, state, wheels, sp, wp, ext, force, slip):
    for b in numba.prange(wheels.shape[0]):
        K._robot_substep(b, dt, state, wheels, sp, wp, ext, force, slip)


def reps_for(n: int) -> int:
    return max(4, 200_000 // n)


def moving_world(robot: str, friction: str, n: int, threads: int | None = None) -> World:
    """n robots driving (commands of a few rad/s, varied per robot and wheel) so the laws see slip,
    in a world built with ``threads`` numba threads (default: all)."""
    all_threads = numba.config.NUMBA_NUM_THREADS
    numba.set_num_threads(threads or all_threads)
    try:
        world = World(load_model(robot, friction=friction), n_robots=n)
    finally:
        numba.set_num_threads(all_threads)
    rng = np.random.default_rng(0)
    world.set_commands(rng.uniform(-20.0, 20.0, (n, world.n_wheels)))
    world.substeps(40)
    return world


def pymunk_runner(world: World):
    """fn(reps): reps substeps of pymunk's part alone (read, write, step of every space)."""
    if not hasattr(K, "run_substeps"):  # before the compiled substep loop: the Python calls the world made
        batch = world._batch

        def python_calls(reps):
            for _ in range(reps):
                batch.read()
                batch.write()
                batch.step(world.dt)

        return python_calls

    @numba.njit
    def compiled(reps, c, dt):
        for _ in range(reps):
            K._read(c)
            K._write_and_step(c, dt)

    tables = [b.c_table for b in getattr(world, "_batches", [world._batch])]

    def run(reps):
        for c in tables:
            compiled(reps, c, world.dt)

    return run


def interleaved(fns: dict, seconds: float) -> dict:
    """Best seconds per call of each ``fn(reps)`` / reps, ``fns``: name → (fn, reps). The candidates
    take turns, one try each per round, for ``seconds`` per candidate in all: on a shared machine
    they then see the same load, so their ratios hold even when the absolute figures do not."""
    best = {name: math.inf for name in fns}
    for fn, _ in fns.values():
        fn(1)
    start = time.perf_counter()
    while time.perf_counter() - start < seconds * len(fns):
        for name, (fn, reps) in fns.items():
            t0 = time.perf_counter()
            fn(reps)
            best[name] = min(best[name], (time.perf_counter() - t0) / reps)
    return best


def limit_runner(robot: str, n: int):
    """fn(reps): the limit loop of ``robot``'s operation mix over n robots."""
    mix = MIXES[robot]
    loop = build_limit(mix)
    rng = np.random.default_rng(0)
    inp = rng.uniform(-1.0, 1.0, (n, READ_ROBOT))
    win = rng.uniform(-1.0, 1.0, (n, mix["wheels"], READ_WHEEL))
    out = np.zeros((n, WRITE_ROBOT))
    wout = np.zeros((n, mix["wheels"], WRITE_WHEEL))
    return lambda r: loop(inp, win, out, wout, r)


def measure(robot: str, friction: str, n: int, seconds: float) -> dict:
    """ns per robot-substep of every column, measured interleaved (see :func:`interleaved`)."""
    one = moving_world(robot, friction, n, threads=1)
    world = moving_world(robot, friction, n)
    batch = one._batch
    dt = one.dt
    args = (dt, batch.states, one.wheels, one.sp, one.wp, one.ext_force, batch.forces, one.slip)
    reps = max(2, reps_for(n) // 10)
    few = max(2, reps // 10)

    def parallel(r):
        for _ in range(r):
            _parallel_once(*args)

    fns = {"kernel": (lambda r: repeat_kernel(r, *args), reps), "limit": (limit_runner(robot, n), reps),
           "pymunk": (pymunk_runner(one), few), "world_one": (one.substeps, few), "world": (world.substeps, few)}
    if n >= 64:
        fns["kernel_threads"] = (parallel, few)
    row = {name: t / n * 1e9 for name, t in interleaved(fns, seconds).items()}
    row.setdefault("kernel_threads", math.nan)
    row["threads"] = world.parallel
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--seconds", type=float, default=1.0, help="time spent on each measurement")
    parser.add_argument("--sizes", type=int, nargs="*", default=list(SIZES))
    args = parser.parse_args()
    load0 = os.getloadavg()[0]
    lines = [
        "# Substep micro-benchmark: ns per robot-substep, and the machine's limit for the kernel's mix",
        "",
        "`python benchmarks/substep_micro.py --out benchmarks/results`",
        "",
    ]
    table = ["| wheel law | N | kernel, 1 thread | kernel, threads | pymunk (read, write, step) | world "
             "substep, 1 thread | world substep, threads | limit loop, 1 thread | kernel ÷ limit |",
             "|---|---|---|---|---|---|---|---|---|"]
    mixes = []
    for label, robot, friction in LAWS:
        mix = MIXES[robot]
        flops = mix["wheels"] * mix["flops_wheel"] + mix["flops_robot"]
        mixes.append(f"| {label} | {flops} | {mix['wheels'] * mix['atan_wheel']} | "
                     f"{mix['wheels'] * mix['div_wheel'] + mix['div_robot']} | {mix['wheels'] * mix['floor_wheel']} "
                     "| 1 + 1 |")
        for n in args.sizes:
            row = measure(robot, friction, n, args.seconds)
            lim = row["limit"]
            kernel_ns = row["kernel"]
            threads = "" if math.isnan(row["kernel_threads"]) else f"{row['kernel_threads']:.0f}"
            world = f"{row['world']:.0f}" if row["threads"] else "(1 thread below 256)"
            table.append(f"| {label} | {n} | {kernel_ns:.0f} | {threads} | {row['pymunk']:.0f} | "
                         f"{row['world_one']:.0f} | {world} | {lim:.0f} | {kernel_ns / lim:.2f} |")
            print(table[-1], flush=True)
    lines += [
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, numba {numba.__version__}. Shared machine: load average (1 min) "
        f"{load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end (other jobs included). Best of repeated "
        f"timings, about {args.seconds:g} s per column, the columns of a row taking turns (same load for "
        "all); ideal actuation, 0.5 ms substeps, robots driving with slip.",
        "",
        "Operation mix per robot-substep (counted from `omni_gym/physics/kernel.py`, see `MIXES` in the script):",
        "",
        "| wheel law | flops (add, sub, mul) | atan | divisions | floor | sin + cos |",
        "|---|---|---|---|---|---|",
        *mixes,
        "",
        "Nanoseconds per robot-substep. *kernel*: the force kernel alone, called from a compiled loop; "
        "*threads*: the threaded kernel on all cores; *pymunk*: batched read, write and space step (from "
        "compiled code, as `World.substeps` calls them); *world substep*: `World.substeps`, built on one numba "
        "thread or on all; *limit loop*: a plain numba loop of the "
        "kernel's operation mix on one core (same reads and writes per robot); *kernel ÷ limit*: one thread.",
        "",
        *table,
    ]
    text = "\n".join(lines) + "\n"
    write_text_atomic(Path(args.out) / "substep_micro.md", text)
    print(text)


if __name__ == "__main__":
    main()
