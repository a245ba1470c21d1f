"""Diagnosis of the privileged PPO agent: one factor changed per run, learning curves side by side.

Each variant is a hyperparameter file in ``agents/hyperparams/diagnosis/`` (``base.yml``: the original
``ppo_privileged.yml`` entry; every other file changes one thing, said in its first line). Train a run::

    omni-gym train --algo ppo --env OmniPathFollow-Williams-v1 --hyperparams agents/hyperparams/diagnosis/VARIANT.yml \\
                   --timesteps 500000 --seed S --out RUNS/VARIANT-sS --eval-freq 100000 --eval-episodes 10 \\
                   --max-minutes 10

then draw every run's validation curve (10 episodes, seeds 5000…5009, the id's default condition) and
tabulate them::

    python benchmarks/privileged_diagnosis.py --runs RUNS/* --out benchmarks/results

Writes ``privileged_diagnosis.md`` and ``privileged_diagnosis.png`` (validation tracking RMSE [m] against
training steps, one colour per variant, ids other than Williams-v1 dashed; lost episodes count with their
RMSE over the steps they ran) and copies each run's ``curve.csv`` and ``meta.json`` to ``OUT/diagnosis_runs/RUN/``.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import sys
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args


def read_run(path: Path) -> tuple[str, dict, np.ndarray]:
    """(variant, meta, curve rows [timesteps, wall_s, val_rmse, val_final_error, val_success, reward])."""
    meta = json.loads((path / "meta.json").read_text())
    data = np.genfromtxt(path / "curve.csv", delimiter=",", skip_header=1, ndmin=2)
    variant = Path(meta.get("hyperparams_file") or path.name).stem
    return variant, meta, data


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", nargs="+", required=True, help="training run directories (meta.json, curve.csv)")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    args = ap.parse_args(argv)
    recorded = record_args(argv if argv is not None else sys.argv[1:])
    command = "python benchmarks/privileged_diagnosis.py " + shlex.join(recorded)
    runs = []
    for r in sorted(args.runs):
        p = Path(r)
        if not (p / "meta.json").is_file() or not (p / "curve.csv").is_file():
            print(f"privileged_diagnosis.py: error: {r}: not a training run (meta.json and curve.csv)", file=sys.stderr)
            return 2
        runs.append((p, *read_run(p)))
    out = Path(args.out)
    variants = sorted({v for _, v, _, _ in runs})
    colours = {v: plt.cm.tab10(i % 10) for i, v in enumerate(variants)}
    fig, ax = plt.subplots(figsize=(8, 4.5))
    lines = ["# Privileged PPO agent: diagnosis runs", "", "```", command, "```", "",
             "Validation: 10 episodes (seeds 5000–5009) of the id's default condition at each validation (every "
             "100k steps; 50k for the BC-initialised runs, whose first point is the clone itself); "
             "'lost' = final error at the 0.5 m termination distance in all 10. Wall time on the shared 2-core "
             "machine (many other jobs). Hyperparameters: `agents/hyperparams/diagnosis/VARIANT.yml`.", "",
             "| run | env | steps | wall [min] | validation RMSE [m] at each validation | best | final success |",
             "|---|---|---|---|---|---|---|"]
    for path, variant, meta, data in runs:
        style = "-o" if meta["env_id"].endswith("Williams-v1") else "--s"  # other ids dashed
        ax.plot(data[:, 0], data[:, 2], style, ms=3, color=colours[variant], label=f"{path.name}")
        curve = ", ".join(f"{v:.4f}" for v in data[:, 2])
        best = np.nanmin(data[1:, 2]) if len(data) > 1 else data[0, 2]
        lines.append(f"| {path.name} | {meta['env_id'].split('-', 1)[1]} | {int(data[-1, 0]):,} | "
                     f"{data[-1, 1] / 60:.1f} | {curve} | {best:.4f} | {data[-1, 4]:.1f} |")
        dest = out / "diagnosis_runs" / path.name
        dest.mkdir(parents=True, exist_ok=True)
        for f in ("meta.json", "curve.csv"):
            if (path / f).resolve() != (dest / f).resolve():  # runs already under OUT/diagnosis_runs stay as they are
                shutil.copyfile(path / f, dest / f)
    ax.set_xlabel("training steps")
    ax.set_ylabel("validation tracking RMSE [m]")
    ax.set_yscale("log")
    ax.set_title("privileged PPO, one factor per variant")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "privileged_diagnosis.png", dpi=110)
    write_text_atomic(out / "privileged_diagnosis.md", "\n".join(lines) + "\n")
    print(f"wrote {out / 'privileged_diagnosis.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
