"""Estimation + control stack throughput: single-robot classes vs the batched ones, in the same process.

    python benchmarks/batched_stack.py --out benchmarks/results

The stack is the ``ekf-pid`` baseline's per-step work: decode the sensor observation, one EKF period
(accelerometer, gyro, slip detector, wheels, compass, camera) and one PID update. Observations are
recorded beforehand from the native vector environment (``OmniPathFollow-Phunopas-v0``, four wheels,
slip and lift-off; ekf-pid actions with noise, so wheels slip, gates reject and robots reset), so
the environment is not timed. Measured:

* single: :class:`agents.policies.EKFPIDPolicy` ``act`` robot by robot (the reference classes);
* batched: :class:`agents.batched.policies.VectorEKFPIDPolicy` ``act`` on the (N, D) batch, serial
  and with the EKF kernel on numba's threads (``threads=True``).

Rates are robot-steps per second (N per batched step), wall clock, best of ``--repeats`` (the machine
is shared). Target: batched ≥ 100k robot-steps/s at N = 256.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np

import omni_gym  # noqa: F401  (registers the environments)
from agents.batched.policies import make_vector_policy
from agents.policies import make_policy
from omni_gym.outputs import write_text_atomic

ENV_ID = "OmniPathFollow-Phunopas-v0"
SIZES = (1, 64, 256)
TARGET = 100_000  # robot-steps/s at N = 256


def record(n: int, steps: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, object]:
    """Observations (steps, n, D) and autoreset masks (steps, n) of ``n`` robots under noisy ekf-pid actions."""
    venv = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", obs_mode="sensors")
    policy = make_vector_policy("ekf-pid", venv)
    rng = np.random.default_rng(seed)
    obs, _ = venv.reset(seed=seed)
    policy.reset(obs)
    out, resets = [obs], [np.ones(n, dtype=bool)]
    autoreset = np.zeros(n, dtype=bool)
    for _ in range(steps - 1):
        a = np.clip(policy.act(obs) + rng.normal(0.0, 0.3, (n, 3)), -1, 1).astype(np.float32)
        obs, _, terminated, truncated, _ = venv.step(a)
        if autoreset.any():
            policy.reset(obs, autoreset)
        out.append(obs)
        resets.append(autoreset.copy())
        autoreset = terminated | truncated
    return np.stack(out), np.stack(resets), venv


def batched_rate(obs: np.ndarray, resets: np.ndarray, venv, threads: bool) -> tuple[float, float]:
    """Robot-steps per wall-clock second and per CPU second (this process) of the vector ekf-pid policy."""
    policy = make_vector_policy("ekf-pid", venv, threads=threads)
    steps, n = resets.shape
    policy.reset(obs[0])
    policy.act(obs[0])  # compile / warm up
    start, cpu = time.perf_counter(), time.process_time()
    for t in range(1, steps):
        if resets[t].any():
            policy.reset(obs[t], resets[t])
        policy.act(obs[t])
    work = (steps - 1) * n
    return work / (time.perf_counter() - start), work / (time.process_time() - cpu)


def single_rate(obs: np.ndarray, resets: np.ndarray, robots: int) -> tuple[float, float]:
    """Robot-steps per wall-clock and per CPU second of the single ekf-pid policy, robot by robot."""
    env = gym.make(ENV_ID, obs_mode="sensors")
    steps = resets.shape[0]
    policies = [make_policy("ekf-pid", env) for _ in range(robots)]
    start, cpu = time.perf_counter(), time.process_time()
    for i, p in enumerate(policies):
        for t in range(steps):
            if resets[t, i]:
                p.reset(obs[t, i])
            p.act(obs[t, i])
    work = steps * robots
    return work / (time.perf_counter() - start), work / (time.process_time() - cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--steps", type=int, default=300, help="recorded control steps per robot")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--single-robots", type=int, default=8, help="robots timed one by one for the single stack")
    args = parser.parse_args()
    for name in ("steps", "repeats", "single_robots"):
        if getattr(args, name) < 2 and name == "steps" or getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be a positive integer (--steps at least 2)")
    obs, resets, _ = record(max(SIZES), args.steps)
    best = lambda runs: tuple(max(r[k] for r in runs) for k in range(2))  # noqa: E731 (best wall, best CPU)
    single = best([single_rate(obs, resets, args.single_robots) for _ in range(args.repeats)])
    rows = []
    for n in SIZES:
        venv = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", obs_mode="sensors")
        serial = best([batched_rate(obs[:, :n], resets[:, :n], venv, False) for _ in range(args.repeats)])
        threaded = best([batched_rate(obs[:, :n], resets[:, :n], venv, True) for _ in range(args.repeats)])
        rows.append((n, serial, threaded))
        print(f"N={n}: single {single[0]:,.0f}, batched {serial[0]:,.0f} ({serial[0] / single[0]:.0f}x), "
              f"threaded {threaded[0]:,.0f} robot-steps/s; per CPU second {single[1]:,.0f} vs {serial[1]:,.0f}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [
        "# Estimation + control stack (decode, EKF + slip detector, PID): robot-steps per second",
        "",
        "`python benchmarks/batched_stack.py --out benchmarks/results`",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, numba "
        f"{numba.__version__} ({numba.get_num_threads()} threads); load average {load:.1f} when the run ended "
        f"(shared machine). {ENV_ID} sensors observations recorded beforehand ({args.steps} steps per robot, "
        f"noisy ekf-pid actions, resets included); environment not timed; best of {args.repeats}. Single: "
        f"agents.policies.EKFPIDPolicy robot by robot ({args.single_robots} robots). Batched: agents.batched "
        "VectorEKFPIDPolicy on the (N, D) batch. Wall: robot-steps per wall-clock second; CPU: per CPU second "
        "of this process (less sensitive to other jobs on the machine; not meaningful for threads).",
        "",
        "| N | single wall | single CPU | batched wall | batched CPU | × single (CPU) | threads wall | target |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for n, serial, threaded in rows:
        target = f"≥ {TARGET:,}" if n == 256 else ""
        lines.append(f"| {n} | {single[0]:,.0f} | {single[1]:,.0f} | {serial[0]:,.0f} | {serial[1]:,.0f} | "
                     f"{serial[1] / single[1]:.0f} | {threaded[0]:,.0f} | {target} |")
    text = "\n".join(lines) + "\n"
    write_text_atomic(Path(args.out) / "batched_stack.md", text)
    print(text)


if __name__ == "__main__":
    main()
