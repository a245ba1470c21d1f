"""Learning curves over seeds: validation tracking RMSE against environment steps and wall-clock time.

Reads training runs (directories written by ``omni-gym train``: ``meta.json`` and ``curve.csv``), groups
them by (environment id, agent, algorithm) and draws, per group, the mean over seeds with its 95 %
Student-t band, against steps and against wall-clock seconds. Each run's curve is interpolated
linearly onto a common grid that ends where the shortest run of the group ends (no extrapolation).
Writes ``learning_curves.png`` and ``learning_curves.md`` (per group: seeds, steps, wall time,
validation RMSE of the untrained policy and the best checkpoint, mean and 95 % interval over seeds).

    python benchmarks/learning_curves.py --runs benchmarks/results/training_runs/* --out benchmarks/results

The agent label comes from ``meta.json``: ``obs_mode="state"`` is the privileged upper bound ("privileged,
BC-init" with ``bc_init``: BC-initialised from the feedback law),
``wrapper="ekf-features"`` the EKF-feature agent, ``wrapper="residual-ekf-pid"`` the residual agent,
``wrapper="none"`` with sensors the raw-sensor agent.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402
from scipy import stats  # noqa: E402

from omni_gym.outputs import write_bytes_atomic, write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args

GRID_POINTS = 50
FLOOR = 1e-3  # m: lower end of the drawn bands (log axis)


@dataclass(frozen=True)
class Run:
    """One training run: its group key, seed and curve (steps, wall-clock [s], validation RMSE [m])."""

    env_id: str
    agent: str
    algo: str
    seed: int
    steps: np.ndarray
    wall_s: np.ndarray
    rmse: np.ndarray
    path: Path


def agent_label(meta: dict) -> str:
    """privileged / ekf-features / residual / sensors (", BC-init" when behaviour-cloned before fine-tuning), from a
    run's meta.json."""
    if meta.get("obs_mode") == "state":
        kind = "privileged"
    else:
        kind = {"ekf-features": "ekf-features", "residual-ekf-pid": "residual"}.get(meta.get("wrapper"), "sensors")
    label = f"{kind}, BC-init" if "bc_init" in meta else kind
    # Runs of different hyperparameter files are different agents even with the same observation and start.
    stem = Path(str(meta.get("hyperparams_file") or "")).stem
    return f"{label} [{stem}]" if stem else label


def load_run(path: Path) -> Run:
    """A run directory → :class:`Run`; ValueError naming the file if meta.json or curve.csv is unusable."""
    try:
        meta = json.loads((path / "meta.json").read_text(encoding="utf-8"))
        data = np.genfromtxt(path / "curve.csv", delimiter=",", names=True, encoding="utf-8-sig")
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a training run ({exc})") from None
    data = np.atleast_1d(data)
    if data.size < 2 or not {"timesteps", "wall_s", "val_tracking_rmse"} <= set(data.dtype.names or ()):
        raise ValueError(f"{path}/curve.csv: needs at least two validation rows with timesteps, wall_s, "
                         "val_tracking_rmse")
    return Run(meta["env_id"], agent_label(meta), meta["algo"], int(meta["seed"]), data["timesteps"].astype(float),
               data["wall_s"].astype(float), data["val_tracking_rmse"].astype(float), path)


def mean_band(xs: list[np.ndarray], ys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Common grid, mean over runs and the 95 % Student-t half-width (0 for a single run)."""
    end = min(float(x[-1]) for x in xs)
    grid = np.linspace(0.0, end, GRID_POINTS)
    table = np.array([np.interp(grid, x, y) for x, y in zip(xs, ys, strict=True)])
    mean = table.mean(axis=0)
    if len(xs) < 2:
        return grid, mean, np.zeros_like(mean)
    half = stats.t.ppf(0.975, len(xs) - 1) * table.std(axis=0, ddof=1) / np.sqrt(len(xs))
    return grid, mean, half


def ci_text(values: np.ndarray) -> str:
    if values.size < 2:
        return f"{values.mean():.4f}"
    half = stats.t.ppf(0.975, values.size - 1) * values.std(ddof=1) / np.sqrt(values.size)
    return f"{values.mean():.4f} [{values.mean() - half:.4f}, {values.mean() + half:.4f}]"


def group(runs: list[Run]) -> dict[tuple[str, str, str], list[Run]]:
    out: dict[tuple[str, str, str], list[Run]] = {}
    for r in sorted(runs, key=lambda r: (r.env_id, r.agent, r.algo, r.seed)):
        out.setdefault((r.env_id, r.agent, r.algo), []).append(r)
    return out


def plot(path: Path, groups: dict) -> None:
    env_ids = sorted({k[0] for k in groups})
    fig, axes = plt.subplots(len(env_ids), 2, figsize=(11, 3.8 * len(env_ids)), squeeze=False)
    for row, env_id in enumerate(env_ids):
        for i, ((eid, agent, algo), runs) in enumerate(groups.items()):
            if eid != env_id:
                continue
            for col, xs in enumerate(([r.steps for r in runs], [r.wall_s / 60.0 for r in runs])):
                grid, mean, half = mean_band(xs, [r.rmse for r in runs])
                ax = axes[row, col]
                ax.plot(grid, mean, color=f"C{i}", label=f"{agent} / {algo.upper()} ({len(runs)} seeds)")
                # An RMSE is positive: the band is cut at 1 mm (with 2 seeds t(1) = 12.7 makes it very wide).
                ax.fill_between(grid, np.maximum(mean - half, FLOOR), mean + half, color=f"C{i}", alpha=0.2)
        for col, xlabel in enumerate(("environment steps [thousands]", "wall-clock [min]")):
            ax = axes[row, col]
            ax.set_xlabel(xlabel)
            if col == 0:  # 50000100000… ran together as plain tick labels
                ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x / 1e3:g}"))
            ax.set_ylabel("validation tracking RMSE [m]")
            ax.set_yscale("log")
            ax.set_title(env_id)
            ax.grid(alpha=0.3)
        axes[row, 0].legend(fontsize=8)
    fig.suptitle("Learning curves: mean over seeds with 95 % Student-t band")
    fig.tight_layout()
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())


def markdown(command: str, groups: dict) -> str:
    lines = ["# Learning curves", "", "```", command, "```", "",
             "Validation tracking RMSE [m] (each run's fixed validation seeds, `meta.json` `validation_seeds`; "
             "the id's defaults without randomisation); mean over seeds and 95 % Student-t interval. `best` is "
             "the checkpoint kept as `model.zip` (after step 0; for BC-initialised runs step 0, the clone of the "
             "feedback law, counts too).", "",
             "| environment | agent | algorithm | seeds | steps per run | wall time per run [min] | step 0 (untrained; "
             "BC-init: the clone) | best |",
             "|---|---|---|---|---|---|---|---|"]
    for (env_id, agent, algo), runs in groups.items():
        steps = np.array([r.steps[-1] for r in runs])
        wall = np.array([r.wall_s[-1] / 60.0 for r in runs])
        first = np.array([r.rmse[0] for r in runs])
        best = np.array([(r.rmse if "BC-init" in agent else r.rmse[1:]).min() for r in runs])
        lines.append(f"| {env_id} | {agent} | {algo.upper()} | {', '.join(str(r.seed) for r in runs)} | "
                     f"{steps.mean():,.0f} | {wall.mean():.1f} | {ci_text(first)} | {ci_text(best)} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", nargs="+", required=True, help="training run directories (meta.json, curve.csv)")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    args = ap.parse_args(argv)
    try:
        runs = [load_run(Path(p)) for p in args.runs if (Path(p) / "meta.json").exists()]
    except ValueError as exc:
        print(f"learning_curves: error: {exc}", file=sys.stderr)
        return 2
    if not runs:
        print("learning_curves: error: no training run (a directory with meta.json) among --runs", file=sys.stderr)
        return 2
    groups = group(runs)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    recorded = record_args(argv or sys.argv[1:])
    command = "python benchmarks/learning_curves.py " + " ".join(shlex.quote(a) for a in recorded)
    plot(out / "learning_curves.png", groups)
    write_text_atomic(out / "learning_curves.md", markdown(command, groups))
    print(f"{len(runs)} runs in {len(groups)} groups → {out / 'learning_curves.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
