"""PPO training throughput (environment steps per second, learning included) on our stacks and a reference env.

    python benchmarks/training_speed.py --out benchmarks/results [--seconds 60]
    python benchmarks/training_speed.py --out benchmarks/results --plot-only   # re-draw the plot from the table

The same PPO configuration (SB3 defaults, MlpPolicy, ``n_steps=256``, ``batch_size=4096``,
``n_epochs=4``, 64 environments, CPU, one torch thread) trains, one after the other in this process, on:

* the Gymnasium reference ``Pendulum-v1`` in ``DummyVecEnv`` of 64 Monitor-wrapped environments (SB3 has
  no adapter for Gymnasium vector envs): the reference of every ratio;
* the privileged envs (``obs_mode="state"``) of both path-following ids through
  :class:`agents.sb3_vec_env.NativeVecEnv` (the native vector env, ``same_step`` autoreset);
* the EKF-feature and the residual stacks on ``OmniPathFollow-Phunopas-v0`` (``obs_mode="sensors"``, four
  wheels, lift-off: the heavier detector) with the batched EKF + PID
  (:class:`agents.wrappers.VectorEKFFeatures` over the native vector env), and the residual stack with the
  per-robot EKF + PID (:class:`agents.wrappers.EKFFeatures` on each of 64 single environments in
  ``DummyVecEnv``: how agents trained before);
* the privileged Williams env in ``DummyVecEnv`` of single environments (the earlier way).

Each runs for ``--seconds`` of wall time, and at least one whole PPO iteration (a rollout of 64 × 256
steps and its update); the rate counts whole iterations, from the start of learning to the end of the
last complete one. Targets: the privileged native stacks ≥ 0.8× the Pendulum reference; the
batched EKF stacks ≥ 10 000 steps/s and ≥ 25× the per-robot stack. The machine is shared (the table
records the load average): compare the ratios, measured in one run, rather than absolute figures
across runs.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

import gymnasium as gym  # noqa: E402
import torch  # noqa: E402

import omni_gym  # noqa: E402,F401  (registers the environments)
from omni_gym.outputs import write_text_atomic  # noqa: E402

PHUNOPAS, WILLIAMS = "OmniPathFollow-Phunopas-v0", "OmniPathFollow-Williams-v1"
N_ENVS = 64
PPO_KW = {"n_steps": 256, "batch_size": 4096, "n_epochs": 4}
PER_ROBOT = f"{PHUNOPAS} residual, EKFFeatures per robot, DummyVecEnv"


def ppo_rate(venv, seconds: float) -> tuple[float, int, int]:
    """(environment steps per second over whole iterations, steps counted, episodes ended) of PPO on ``venv``."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    class Clock(BaseCallback):
        """Stops after ``seconds`` and one whole iteration; notes the time and step count at each iteration's end."""

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
            return self.steps == 0 or time.perf_counter() - self.t0 < seconds

    model = PPO("MlpPolicy", venv, seed=0, device="cpu", verbose=0, **PPO_KW)
    clock = Clock()
    model.learn(total_timesteps=10**9, callback=clock)
    venv.close()
    return clock.steps / (clock.done_at - clock.t0), clock.steps, clock.episodes


def configurations() -> dict:
    """Name → constructor of the SB3 vector env, in the order they run (the reference first)."""
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from agents.rollout import make_env
    from agents.sb3_vec_env import make_native_vec_env
    from agents.wrappers import EKFFeatures, VectorEKFFeatures

    def native_ekf(scale: float):
        return make_native_vec_env(PHUNOPAS, N_ENVS, wrap=lambda raw: VectorEKFFeatures(raw, scale, "squared"),
                                   obs_mode="sensors")

    return {
        "Pendulum-v1, DummyVecEnv + Monitor (reference)": lambda: DummyVecEnv(
            [lambda: Monitor(gym.make("Pendulum-v1")) for _ in range(N_ENVS)]),
        f"{WILLIAMS} privileged (state), NativeVecEnv": lambda: make_native_vec_env(WILLIAMS, N_ENVS, obs_mode="state"),
        f"{PHUNOPAS} privileged (state), NativeVecEnv": lambda: make_native_vec_env(PHUNOPAS, N_ENVS, obs_mode="state"),
        f"{PHUNOPAS} EKF features, VectorEKFFeatures (batched), NativeVecEnv": lambda: native_ekf(0.0),
        f"{PHUNOPAS} residual, VectorEKFFeatures (batched), NativeVecEnv": lambda: native_ekf(0.3),
        PER_ROBOT: lambda: DummyVecEnv(
            [lambda: Monitor(EKFFeatures(make_env(PHUNOPAS), 0.3, "squared")) for _ in range(N_ENVS)]),
        f"{WILLIAMS} privileged (state), DummyVecEnv + Monitor": lambda: DummyVecEnv(
            [lambda: Monitor(gym.make(WILLIAMS, obs_mode="state")) for _ in range(N_ENVS)]),
    }


def plot(path: Path, rows: list[tuple[str, float]]) -> None:
    """Horizontal bars: env steps/s with learning per configuration, the 10 000/s target as a line."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [name.replace(", NativeVecEnv", "").replace(" (reference)", "") for name, _ in rows]
    rates = [rate for _, rate in rows]
    colors = ["C7" if "Pendulum" in n else "C1" if "DummyVecEnv" in n else "C0" for n, _ in rows]
    fig, ax = plt.subplots(figsize=(11, 0.5 * len(rows) + 1.5))
    ax.barh(range(len(rows)), rates, color=colors)
    ax.axvline(10_000, color="k", ls="--", lw=1, label="10 000 steps/s target (EKF stacks)")
    ax.set_yticks(range(len(rows)), names, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("PPO env steps/s with learning, 64 envs (grey: reference; orange: one env per robot)")
    ax.set_title("training_speed.md", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def rows_from_table(path: Path) -> list[tuple[str, float]]:
    """(configuration, steps/s) rows of a table this script wrote."""
    rows = []
    for line in path.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 7 and cells[1].replace(",", "").isdigit():
            rows.append((cells[0], float(cells[1].replace(",", ""))))
    if not rows:
        raise SystemExit(f"training_speed: error: {path} holds no table rows")
    return rows


def target(name: str) -> str:
    if "privileged" in name and "NativeVecEnv" in name:
        return "≥ 0.8× Pendulum"
    if "batched" in name:
        return "≥ 10 000/s, ≥ 25× per robot"
    return ""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--seconds", type=float, default=60.0, help="training wall time per configuration [s]")
    parser.add_argument("--plot-only", action="store_true", help="re-draw training_speed.png from the table")
    args = parser.parse_args()
    out = Path(args.out)
    if args.plot_only:
        plot(out / "training_speed.png", rows_from_table(out / "training_speed.md"))
        return
    torch.set_num_threads(1)
    rows = []
    load = [os.getloadavg()[0]]
    for name, make in configurations().items():
        rate, steps, episodes = ppo_rate(make(), args.seconds)
        rows.append((name, rate, steps, episodes))
        print(f"{name}: {rate:,.0f} env steps/s ({steps} steps, {episodes} episodes ended)", flush=True)
    load.append(os.getloadavg()[0])
    reference = rows[0][1]
    per_robot = next(rate for name, rate, _, _ in rows if name == PER_ROBOT)
    lines = [
        "# PPO training throughput: environment steps per second with learning",
        "",
        "`python benchmarks/training_speed.py --out benchmarks/results" + (
            "`" if args.seconds == 60.0 else f" --seconds {args.seconds:g}`"),
        "",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, torch "
        f"{torch.__version__} (1 thread, CPU). PPO (MlpPolicy, n_steps={PPO_KW['n_steps']}, "
        f"batch_size={PPO_KW['batch_size']}, n_epochs={PPO_KW['n_epochs']}), {N_ENVS} environments, "
        f"{args.seconds:g} s (and at least one whole iteration) each, one after the other in one process; whole "
        f"iterations (rollout + update) counted. Load average (1 min) before / after: {load[0]:.1f} / {load[1]:.1f} "
        f"on {os.cpu_count()} cores (a shared machine: other jobs slow every row alike, so read the ratios).",
        "",
        "| configuration | env steps/s | × Pendulum-v1 | × per-robot EKF | steps | episodes ended | target |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, rate, steps, episodes in rows:
        lines.append(f"| {name} | {rate:,.0f} | {rate / reference:.2f} | {rate / per_robot:.1f} | {steps} | "
                     f"{episodes} | {target(name)} |")
    text = "\n".join(lines) + "\n"
    write_text_atomic(out / "training_speed.md", text)
    plot(out / "training_speed.png", [(name, rate) for name, rate, _, _ in rows])
    print(text)


if __name__ == "__main__":
    main()
