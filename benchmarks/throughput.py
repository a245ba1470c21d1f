"""Environment throughput, as ratios to Gymnasium's LunarLander-v3 measured in the same run.

    python benchmarks/throughput.py --out benchmarks/results

Measures environment steps per second, with uniformly random actions drawn beforehand from the seeded
action space (so that the cost of sampling is not counted, for either environment) and every reset
included (episodes end when the robot is lost, so random actions reset often):

* LunarLander-v3 through ``gym.make`` (the reference);
* one omni-gym environment through ``gym.make`` (default physics: 0.5 ms substeps, 100 Hz control,
  no rendering);
* the native vectorised environment (``gym.make_vec(..., vectorization_mode="vector_entry_point")``)
  at N = 1, 64, 1024, counting N environment steps per vector step, and at N = 1024 once more on
  one numba thread (``numba.set_num_threads(1)`` before the environment is built) to give the gain
  of all cores over one;
* the same in ``obs_mode="sensors"`` on ``OmniPathFollow-Phunopas-v0`` (four wheels, random lift-off)
  at N = 64 and 256: the observation a policy trained for a real robot sees.

Targets: one environment ≥ 1.0× LunarLander-v3; the vectorised environment at N = 1024 on one thread
≥ 25×, and on all cores ≥ 1.8× its one-thread rate (two cores); the sensors-mode vector at N = 256
≥ 60,000 steps/s (PPO with learning at ≥ 10k steps/s on that stack).
Each measurement is repeated (best of ``--repeats``) because this machine is shared and noisy.
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
from omni_gym.outputs import write_text_atomic

ENV_ID = "OmniPathFollow-WilliamsPaper-v0"
SENSORS_ID = "OmniPathFollow-Phunopas-v0"
# Four omni wheels (roller-gap friction) against four mecanum wheels, each with random lift-off: the mecanum
# id is to step at least as fast as the Phunopas id, in the same run.
FOUR_WHEEL_IDS = ("OmniPathFollow-Phunopas-v0", "OmniPathFollow-Mecanum-v0")
ACTION_POOL = 4096  # random actions drawn before timing and cycled


def single_rate(env_id: str, seconds: float, **kwargs) -> tuple[float, int]:
    """(steps per second, episodes finished) of one environment under random actions."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(ACTION_POOL)]
    for k in range(200):  # warm up caches and compiled code
        _, _, term, trunc, _ = env.step(actions[k])
        if term or trunc:
            env.reset()
    steps = episodes = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        for _ in range(100):
            _, _, term, trunc, _ = env.step(actions[steps % ACTION_POOL])
            steps += 1
            if term or trunc:
                env.reset()
                episodes += 1
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate, episodes


def vector_rate(env_id: str, n: int, seconds: float, obs_mode: str = "state",
                threads: int | None = None) -> tuple[float, int]:
    """(environment steps per second, episodes finished) of the native vector environment, on
    ``threads`` numba threads (default: all)."""
    all_threads = numba.config.NUMBA_NUM_THREADS
    numba.set_num_threads(threads or all_threads)
    try:
        return _vector_rate(env_id, n, seconds, obs_mode)
    finally:
        numba.set_num_threads(all_threads)


def _vector_rate(env_id: str, n: int, seconds: float, obs_mode: str) -> tuple[float, int]:
    env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", obs_mode=obs_mode)
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(max(ACTION_POOL // n, 8))]
    for k in range(20):
        env.step(actions[k % len(actions)])
    steps = episodes = calls = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        _, _, term, trunc, _ = env.step(actions[calls % len(actions)])
        calls += 1
        steps += n
        episodes += int(np.sum(term | trunc))
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate, episodes


def best(fn, repeats: int, *args) -> tuple[float, int]:
    runs = [fn(*args) for _ in range(repeats)]
    return max(runs, key=lambda r: r[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--seconds", type=float, default=3.0, help="duration of each measurement")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rows = []
    load_before = os.getloadavg()[0]
    lunar, lunar_eps = best(single_rate, args.repeats, "LunarLander-v3", args.seconds)
    rows.append(("LunarLander-v3 (gym.make)", 1, lunar, lunar_eps))
    rate, eps = best(single_rate, args.repeats, ENV_ID, args.seconds)
    rows.append((f"{ENV_ID} (gym.make)", 1, rate, eps))
    for n in (1, 64, 1024):
        rate, eps = best(vector_rate, args.repeats, ENV_ID, n, args.seconds)
        rows.append((f"{ENV_ID} vector_entry_point", n, rate, eps))
    all_cores = rate
    one, eps = best(vector_rate, args.repeats, ENV_ID, 1024, args.seconds, "state", 1)
    rows.append((f"{ENV_ID} vector_entry_point, 1 thread", 1024, one, eps))
    for n in (64, 256):
        rate, eps = best(vector_rate, args.repeats, SENSORS_ID, n, args.seconds, "sensors")
        rows.append((f"{SENSORS_ID} vector_entry_point, obs_mode=sensors", n, rate, eps))
    four = {}
    for env_id in FOUR_WHEEL_IDS:
        four[env_id] = best(single_rate, args.repeats, env_id, args.seconds)
        rows.append((f"{env_id} (gym.make)", 1, *four[env_id]))
        rate, eps = best(vector_rate, args.repeats, env_id, 1024, args.seconds, "state", 1)
        four[env_id, 1024] = rate
        rows.append((f"{env_id} vector_entry_point, 1 thread", 1024, rate, eps))
    omni, mecanum = FOUR_WHEEL_IDS
    lines = [
        "# Throughput: environment steps per second, ratio to LunarLander-v3 in the same run",
        "",
        "`python benchmarks/throughput.py --out benchmarks/results`",
        "",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}; random actions, "
        f"resets included, best of {args.repeats} runs of {args.seconds:g} s. Default physics (0.5 ms substeps, "
        "20 per 10 ms control step). Load average (1 min) of the machine, other jobs included: "
        f"{load_before:.1f} at the start, {os.getloadavg()[0]:.1f} at the end of the run ({os.cpu_count()} cores: "
        "a higher load slows every row, the threaded N = 1024 row most). N = 1024 on all "
        f"{numba.config.NUMBA_NUM_THREADS} numba threads ÷ on one thread: {all_cores / one:.2f}× (target ≥ 1.8×). "
        f"Mecanum ÷ Phunopas (four mecanum against four omni wheels, both with lift-off; target ≥ 1): "
        f"{four[mecanum][0] / four[omni][0]:.2f}× through gym.make, "
        f"{four[mecanum, 1024] / four[omni, 1024]:.2f}× at N = 1024 on one thread.",
        "",
        "| environment | N | env steps/s | × LunarLander-v3 | episodes ended | target |",
        "|---|---|---|---|---|---|",
    ]
    for name, n, rate, eps in rows:
        target = ""
        if "gym.make" in name and ENV_ID in name:
            target = "≥ 1.0×"
        elif n == 1024 and "1 thread" in name and ENV_ID in name:
            target = "≥ 25×"
        elif "sensors" in name and n == 256:
            target = "≥ 60,000 steps/s"
        lines.append(f"| {name} | {n} | {rate:,.0f} | {rate / lunar:.2f} | {eps} | {target} |")
    text = "\n".join(lines) + "\n"
    write_text_atomic(Path(args.out) / "throughput.md", text)
    print(text)


if __name__ == "__main__":
    main()
