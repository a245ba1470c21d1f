"""PPO training throughput (environment steps per second, learning included) through SB3 vector envs.

    python benchmarks/sb3_throughput.py --out benchmarks/results [--seconds 60]

The same PPO configuration (SB3 defaults, MlpPolicy, ``n_steps=256``, ``batch_size=4096``,
``n_epochs=4``, 64 environments, CPU, one torch thread) trains, one after the other in this process, on:

* ``OmniPathFollow-Williams-v0`` (``obs_mode="state"``) through :class:`agents.sb3_vec_env.NativeVecEnv`
  (the native vector env, ``same_step`` autoreset);
* the Gymnasium reference ``Pendulum-v1`` in ``DummyVecEnv`` of 64 Monitor-wrapped environments (SB3 has
  no adapter for Gymnasium vector envs);
* ``OmniPathFollow-Williams-v0`` (``obs_mode="state"``) in ``DummyVecEnv`` of 64 Monitor-wrapped single
  environments (how ``omni-gym train --vec-env dummy`` trains).

Each runs for ``--seconds`` of wall time; the rate counts whole PPO iterations (a rollout of 64 × 256
steps and its update), from the start of learning to the end of the last complete iteration.
Targets: the native adapter ≥ 0.8× the Pendulum reference, and ≥ 10 000 steps/s. The machine is shared
(the table records the load average): compare the ratios, measured in one run, rather than absolute
figures across runs.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import gymnasium as gym
import torch

import omni_gym  # noqa: F401  (registers the environments)

ENV_ID = "OmniPathFollow-Williams-v0"
N_ENVS = 64
PPO_KW = {"n_steps": 256, "batch_size": 4096, "n_epochs": 4}


def ppo_rate(venv, seconds: float) -> tuple[float, int, int]:
    """(environment steps per second over whole iterations, steps counted, episodes ended) of PPO on ``venv``."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    class Clock(BaseCallback):
        """Stops after ``seconds``; notes the time and step count at the end of each complete iteration."""

        def __init__(self) -> None:
            super().__init__()
            self.t0 = self.done_at = 0.0
            self.steps = self.episodes = 0

        def _on_training_start(self) -> None:
            self.t0 = time.perf_counter()

        def _on_rollout_start(self) -> None:  # the previous iteration (rollout + update) is complete
            self.done_at, self.steps = time.perf_counter(), self.num_timesteps

        def _on_step(self) -> bool:
            self.episodes += int(self.locals["dones"].sum())
            return time.perf_counter() - self.t0 < seconds

    model = PPO("MlpPolicy", venv, seed=0, device="cpu", verbose=0, **PPO_KW)
    clock = Clock()
    model.learn(total_timesteps=10**9, callback=clock)
    venv.close()
    return clock.steps / (clock.done_at - clock.t0), clock.steps, clock.episodes


def main() -> None:
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from agents.sb3_vec_env import make_native_vec_env

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--seconds", type=float, default=60.0, help="training wall time per configuration [s]")
    args = parser.parse_args()
    torch.set_num_threads(1)
    runs = {
        f"{ENV_ID} state, NativeVecEnv": lambda: make_native_vec_env(ENV_ID, N_ENVS, obs_mode="state"),
        "Pendulum-v1, DummyVecEnv + Monitor": lambda: DummyVecEnv(
            [lambda: Monitor(gym.make("Pendulum-v1")) for _ in range(N_ENVS)]),
        f"{ENV_ID} state, DummyVecEnv + Monitor": lambda: DummyVecEnv(
            [lambda: Monitor(gym.make(ENV_ID, obs_mode="state")) for _ in range(N_ENVS)]),
    }
    rows = []
    load = [os.getloadavg()[0]]
    for name, make in runs.items():
        rate, steps, episodes = ppo_rate(make(), args.seconds)
        rows.append((name, rate, steps, episodes))
        print(f"{name}: {rate:,.0f} env steps/s ({steps} steps, {episodes} episodes ended)", flush=True)
    load.append(os.getloadavg()[0])
    reference = rows[1][1]
    lines = [
        "# PPO training throughput: environment steps per second with learning",
        "",
        "`python benchmarks/sb3_throughput.py --out benchmarks/results" + (
            "`" if args.seconds == 60.0 else f" --seconds {args.seconds:g}`"),
        "",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, torch "
        f"{torch.__version__} (1 thread, CPU). PPO (MlpPolicy, n_steps={PPO_KW['n_steps']}, "
        f"batch_size={PPO_KW['batch_size']}, n_epochs={PPO_KW['n_epochs']}), {N_ENVS} environments, "
        f"{args.seconds:g} s each, one after the other in one process; whole iterations (rollout + update) counted. "
        f"Load average (1 min) before / after: {load[0]:.1f} / {load[1]:.1f} on {os.cpu_count()} cores (a shared "
        "machine: other jobs slow every row alike, so read the ratios).",
        "",
        "| configuration | env steps/s | × Pendulum-v1 | steps | episodes ended | target |",
        "|---|---|---|---|---|---|",
    ]
    for k, (name, rate, steps, episodes) in enumerate(rows):
        target = "≥ 0.8×, ≥ 10 000/s" if k == 0 else ""
        lines.append(f"| {name} | {rate:,.0f} | {rate / reference:.2f} | {steps} | {episodes} | {target} |")
    text = "\n".join(lines) + "\n"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "sb3_throughput.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
