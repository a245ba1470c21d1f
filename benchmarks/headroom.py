"""How much better could a controller track if it knew the true state? A scripted headroom estimate.

The learned privileged agents (PPO 3 M steps, SAC 300k steps on ``obs_mode="state"``) did not
reach ``ekf-pid``, so they cannot say whether headroom exists. This script asks a simpler question with
no training: a true-state feedback controller, reference feed-forward plus proportional feedback on the
true position and heading errors,

    v_body = v_ref,body + k·e_body,    ω = ω_ref + k·e_θ     (e from the ``state`` observation, k in 1/s)

clipped to the action box, against ``ekf-pid`` on the same held-out seeds and conditions as
``benchmarks/rl_vs_baselines.py`` (seeds 10000…, paired). It is privileged (reads the true state): an
estimate of what perfect estimation is worth with the simplest control law, not a robot controller and
not an upper bound on learning (a better control law could do more). Three gains are shown, none tuned
on these seeds. Writes ``headroom.md`` (command line first). Usage::

    python benchmarks/headroom.py [--episodes 50] [--seed 10000] [--gains 1 2 4] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from baselines import CONDITIONS, fmt_ci, paired_bootstrap_ratio  # noqa: E402
from tqdm import tqdm  # noqa: E402

from agents.batched.policies import make_vector_policy  # noqa: E402
from agents.evaluate import summarize  # noqa: E402
from agents.feedback_law import TrueStateFeedback  # noqa: E402
from agents.vector_rollout import make_vector_env, run_episodes_vector  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args

ENV_IDS = ("OmniPathFollow-Phunopas-v0", "OmniPathFollow-Williams-v1")


def run(env_id: str, cond: str, seeds: list[int], gain: float | None) -> list:
    """Episodes of ekf-pid (gain None, sensors observation) or the true-state law with ``gain``."""
    kw = CONDITIONS[cond]
    venv = make_vector_env(env_id, len(seeds), kw, obs_mode="sensors" if gain is None else "state")
    try:
        policy = make_vector_policy("ekf-pid", venv) if gain is None else TrueStateFeedback(venv, gain)
        return run_episodes_vector(venv, policy, seeds)
    finally:
        venv.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=50, help="paired episodes per id and condition (default 50)")
    ap.add_argument("--seed", type=int, default=10_000, help="first seed (default 10000)")
    ap.add_argument("--gains", type=float, nargs="+", default=[1.0, 2.0, 4.0], help="feedback gains k [1/s]")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    args = ap.parse_args(argv)
    if args.episodes < 2 or any(not (0.0 < g < 100.0) for g in args.gains):
        ap.error("--episodes must be ≥ 2 and every gain in (0, 100) 1/s")
    command = "python benchmarks/headroom.py " + shlex.join(record_args(argv if argv is not None else sys.argv[1:]))
    seeds = list(range(args.seed, args.seed + args.episodes))
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    cells = [(e, c, g) for e in ENV_IDS for c in CONDITIONS for g in [None, *args.gains]]
    results = {}
    for env_id, cond, gain in tqdm(cells, desc="cells", file=sys.stderr):
        results[(env_id, cond, gain)] = run(env_id, cond, seeds, gain)
    lines = ["# Headroom: true-state feedback vs ekf-pid", "", "```", command.strip(), "```", "",
             f"{args.episodes} paired held-out episodes per id and condition (seeds {seeds[0]}–{seeds[-1]}, the "
             "seeds of `rl_vs_baselines.md`). Tracking RMSE mean [95 % bootstrap interval]; ratio to ekf-pid "
             "with its 95 % paired-bootstrap interval. The true-state law is privileged (reads the true pose): "
             "what perfect estimation is worth with feed-forward + proportional feedback, not a robot "
             f"controller. Wall time {(time.perf_counter() - start) / 60:.1f} min.", "",
             "| id | condition | ekf-pid [m] | "
             + " | ".join(f"true state, k = {g:g}/s [m] (ratio)" for g in args.gains) + " |",
             "|---|---|---|" + "---|" * len(args.gains)]
    for env_id in ENV_IDS:
        for cond in CONDITIONS:
            base = results[(env_id, cond, None)]
            b = np.array([e.tracking_rmse for e in base])
            row = [env_id, cond, fmt_ci(summarize(base)["tracking_rmse"])]
            for g in args.gains:
                eps = results[(env_id, cond, g)]
                v = np.array([e.tracking_rmse for e in eps])
                ci, _ = paired_bootstrap_ratio(v, b, rng)
                lost = sum(e.terminated for e in eps)
                row.append(f"{v.mean():.4f} ({v.mean() / b.mean():.2f} [{ci[0]:.2f}, {ci[1]:.2f}])"
                           + (f", {lost} lost" if lost else ""))
            lines.append("| " + " | ".join(row) + " |")
    path = Path(args.out) / "headroom.md"
    write_text_atomic(path, "\n".join(lines) + "\n")  # creates the folder
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
