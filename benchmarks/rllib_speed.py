"""RLlib PPO against SB3 PPO: env steps per second with learning, same env, same budget, one machine.

    python benchmarks/rllib_speed.py --out benchmarks/results [--timesteps 100000] [--env OmniPathFollow-Phunopas-v0]

Both trainers run as ``omni-gym train`` runs them (``agents.train.train_into`` and
``agents.rllib.train.train_into``, no validation), one after the other in this process, on the privileged
agent: ``obs_mode="state"``, the squared tracking reward, the same domain randomisation, 64 robots in
native vector envs, 16 384-step iterations (64 × 256), 5 epochs of 4096-step minibatches, 64×64 tanh
networks, one torch thread (``agents/hyperparams/ppo_privileged.yml`` and ``agents/rllib/ppo.yml``).
Each trains whole iterations until ``--timesteps`` (100 000: 7 iterations, about 115 000 steps on both; the
committed table, 2 min).

Rows: SB3 (``--vec-env native``), and RLlib with 0 env runners (sampling in the driver), 1 and 2 env
runner actors (64, 64 and 32 robots each: 64 in all; the fixed-budget row at 1 and 2 local workers).
Rate = env steps / training wall time (SB3 ``learn()``; RLlib the ``train()`` loop; both without start-up);
the start-up (Ray, actors, algorithm build) is a separate column. Target: RLlib ≥ 0.5× SB3.
The Ray cluster is local (127.0.0.1, 2 CPUs), started once. The machine may be shared: the table records the
load average; compare ratios measured in one run.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from omni_gym.outputs import write_text_atomic  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SB3_FILE = ROOT / "agents" / "hyperparams" / "ppo_privileged.yml"
ROBOTS = 64


@dataclass(frozen=True)
class Row:
    """One measured configuration: ``steps`` env steps in ``train_s`` [s] of training, ``total_s`` [s] with
    start-up."""

    name: str
    steps: int
    train_s: float
    total_s: float

    @property
    def rate(self) -> float:
        """env steps per second of training"""
        return self.steps / self.train_s


def run_sb3(env_id: str, timesteps: int, out: Path) -> Row:
    from agents.train import train_into

    t0 = time.perf_counter()
    meta = train_into("ppo", env_id, timesteps, 0, out, hyperparams=SB3_FILE, n_envs=ROBOTS, eval_freq=0,
                      progress=False)
    return Row("SB3 PPO, native vector env", int(meta["timesteps"]), float(meta["wall_time_s"]),
               time.perf_counter() - t0)


def run_rllib(env_id: str, timesteps: int, out: Path, runners: int) -> Row:
    from agents.rllib.train import train_into

    n = ROBOTS // max(1, runners)
    t0 = time.perf_counter()
    meta = train_into(env_id, timesteps, 0, out, n_envs=n, num_env_runners=runners, eval_freq=0, progress=False)
    where = "in the driver" if runners == 0 else f"{runners} env runner{'s' * (runners > 1)} × {n} robots"
    return Row(f"RLlib PPO, {where}", int(meta["timesteps"]), float(meta["wall_time_s"]), time.perf_counter() - t0)


@dataclass(frozen=True)
class Breakdown:
    """Where an RLlib iteration (sampling in the driver) spends its time: RLlib's own timers [s per
    iteration, moving averages] after ``iterations`` iterations."""

    iterations: int
    steps_per_iteration: float
    sampling_s: float
    learner_s: float


def rllib_breakdown(env_id: str, iterations: int = 4) -> Breakdown:
    """Run RLlib PPO (0 env runners, the committed configuration) and read its sampling and learner timers."""
    from agents.rllib.config import load, ppo_config
    from agents.rllib.train import register_training_env

    hp = load(env_id)
    env_config = {**hp.env_kwargs, "env_id": env_id, "reward": hp.spec.reward, "seed": 0}
    algo = ppo_config(hp, env_config, ROBOTS, 0, 0, register_training_env(), "breakdown").build_algo()
    try:
        for _ in range(iterations):
            result = algo.train()
    finally:
        algo.stop()
    timers = result["timers"]
    steps = result["num_env_steps_sampled_lifetime"] / iterations
    return Breakdown(iterations, steps, float(timers["env_runner_sampling_timer"]),
                     float(timers["learner_update_timer"]))


def table(rows: list[Row], env_id: str, timesteps: int, breakdown: Breakdown | None = None) -> str:
    ref = rows[0].rate
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    lines = [
        "# RLlib PPO vs SB3 PPO: training throughput (benchmarks/rllib_speed.py)",
        "",
        f"Env `{env_id}` (privileged state, squared tracking reward, domain randomisation), budget {timesteps} "
        f"env steps (whole 16 384-step iterations), {ROBOTS} robots in all, one torch thread. "
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, load average {load[0]:.1f} / {load[1]:.1f} / "
        f"{load[2]:.1f} at the end. Target: RLlib ≥ 0.5× SB3.",
        "",
        "| configuration | env steps | training [s] | with start-up [s] | env steps/s | × SB3 |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r.name} | {r.steps} | {r.train_s:.1f} | {r.total_s:.1f} | {r.rate:.0f} | "
                     f"{r.rate / ref:.2f} |")
    if breakdown is not None:
        b = breakdown
        lines += ["", f"Where RLlib's time goes (in the driver, RLlib's timers after {b.iterations} iterations of "
                  f"{b.steps_per_iteration:.0f} env steps): sampling {b.sampling_s:.2f} s per iteration "
                  f"({b.steps_per_iteration / b.sampling_s:.0f} env steps/s, policy forward passes, connectors and "
                  f"per-robot episode bookkeeping included), learner update {b.learner_s:.2f} s. The native vector "
                  "env alone steps 64 robots at about 50 000 env steps/s (`benchmarks/results/throughput.md`): "
                  "RLlib's sampling loop, not the simulation or the learning, sets its rate."]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--timesteps", type=int, default=100_000, help="budget per configuration [env steps]")
    parser.add_argument("--env", default="OmniPathFollow-Phunopas-v0")
    parser.add_argument("--runners", type=int, nargs="+", default=[0, 1, 2], help="RLlib env runner counts")
    args = parser.parse_args()
    import ray

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rows.append(run_sb3(args.env, args.timesteps, Path(tmp) / "sb3"))
        print(rows[-1], flush=True)
        ray.init(num_cpus=max(2, *args.runners), include_dashboard=False, _node_ip_address="127.0.0.1",
                 log_to_driver=False, configure_logging=False)
        try:
            for k in args.runners:
                rows.append(run_rllib(args.env, args.timesteps, Path(tmp) / f"rllib{k}", k))
                print(rows[-1], flush=True)
            breakdown = rllib_breakdown(args.env)
            print(breakdown, flush=True)
        finally:
            ray.shutdown()
    text = table(rows, args.env, args.timesteps, breakdown)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "rllib_speed.md", text)
    print(text)


if __name__ == "__main__":
    main()
