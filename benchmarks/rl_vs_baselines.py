"""Trained SB3 agents against the scripted baselines (open-loop, odometry-pid, ekf-pid) on held-out episodes.

Two evaluation sets, each in the three conditions of the baseline table (``CONDITIONS`` from
``benchmarks/baselines.py``: no slip, slip, slip + lift-off) on ``OmniPathFollow-Phunopas-v0``:

* **held-out seeds**: random-waypoint paths (the training family) on seeds ``--seed``… (default 10 000;
  training used seeds 0…n_envs−1 and their continuations, validation 5000…);
* **unseen families**: circle, figure-eight and line paths, never seen in training, episode i on
  family i mod 3, seeds ``--seed`` + ``UNSEEN_OFFSET``….

Every policy runs the same seeds (paired comparisons). Per metric: mean and 95 % Student-t interval;
success rate with its 95 % Wilson interval. For each trained agent under slip + lift-off: the ratio of
its mean tracking RMSE to ekf-pid's with a 95 % paired-bootstrap interval, a two-sided paired
Wilcoxon test, and the goal check (ratio ≤ 0.8 with non-overlapping 95 % intervals). The training
wall-clock cost comes from each model's ``meta.json``.

Writes ``rl_vs_baselines.md`` (command line first), ``rl_vs_baselines.png`` (bars with 95 % whiskers) and
``rl_training_curves.png`` into ``--out``. With ``--cache FILE`` every episode's metrics are kept in a JSON
file keyed by (policy, set, condition, seed, overrides) and reused on the next run (e.g. run the
scripted baselines first with no ``--models``, while the agents train). Usage::

    python benchmarks/rl_vs_baselines.py --models agents/models/ppo-residual [more dirs] [--episodes 50]
                                         [--seed 10000] [--workers 2] [--cache FILE] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
sys.path.insert(0, str(Path(__file__).resolve().parent))

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from baselines import CONDITIONS, ENV_ID, paired_bootstrap_ratio  # noqa: E402
from scipy import stats  # noqa: E402
from tqdm import tqdm  # noqa: E402

from agents.evaluate import METRICS, summarize  # noqa: E402
from agents.policies import POLICY_NAMES, make_policy  # noqa: E402
from agents.rollout import Episode, make_env, run_episode  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402

SETS = ("held-out seeds", "unseen families")
UNSEEN = ("circle", "figure_eight", "line")
UNSEEN_OFFSET = 1000  # unseen-family episodes start at --seed + 1000
LIFT = "slip + lift-off"
GOAL = 0.8  # learned / ekf-pid tracking RMSE under slip + lift-off
LABELS = {"tracking_rmse": "tracking RMSE [m]", "final_position_error": "final position error [m]",
          "final_heading_error": "final heading error [rad]", "success_rate": "success rate"}

_cache: dict = {}
_overrides: dict = {}  # extra env kwargs for every episode (--episode-seconds, for quick checks only)


def episode_kwargs(cond: str, eval_set: str, seed: int, first: int) -> tuple[dict, str]:
    """(env kwargs, family) of one episode."""
    kw = {**CONDITIONS[cond], **_overrides}
    if eval_set == SETS[1]:
        fam = UNSEEN[(seed - first) % len(UNSEEN)]
        kw["trajectory"] = fam
        return kw, fam
    return kw, "waypoints"


def _episode(task: tuple) -> tuple[tuple[str, str, str], Episode]:
    """One episode in a worker; envs and policies are built once per (policy, condition, family)."""
    policy, eval_set, cond, seed, first, overrides = task
    _overrides.update(overrides)
    kw, fam = episode_kwargs(cond, eval_set, seed, first)
    key = (policy, cond, fam)
    if key not in _cache:
        import torch

        torch.set_num_threads(1)
        if policy in POLICY_NAMES:
            env = make_env(ENV_ID, kw)
            _cache[key] = (env, make_policy(policy, env))
        else:
            from agents.sb3_policy import build

            _cache[key] = build(policy, ENV_ID, kw)
    env, pol = _cache[key]
    return (policy, eval_set, cond), run_episode(env, pol, seed)


def _cache_key(task: tuple) -> str:
    policy, eval_set, cond, seed, _, overrides = task
    return json.dumps([policy, eval_set, cond, seed, sorted(overrides.items())])


def run_all(policies: list[str], episodes: int, seed: int, workers: int, overrides: dict,
            cache: Path | None = None) -> dict:
    tasks = []
    for eval_set in SETS:
        first = seed if eval_set == SETS[0] else seed + UNSEEN_OFFSET
        tasks += [(p, eval_set, c, first + i, first, overrides)
                  for c in CONDITIONS for p in policies for i in range(episodes)]
    out: dict = {}
    stored = json.loads(cache.read_text()) if cache is not None and cache.is_file() else {}
    todo = []
    for task in tasks:
        if _cache_key(task) in stored:
            out.setdefault(task[:3], []).append(Episode(**stored[_cache_key(task)]))
        else:
            todo.append(task)
    tasks = todo
    bar = tqdm(total=len(tasks), desc="episodes", file=sys.stderr, unit="ep")
    if workers > 1:
        with get_context("spawn").Pool(workers) as pool:
            for task, (key, ep) in zip(tasks, pool.imap(_episode, tasks, chunksize=5), strict=True):
                out.setdefault(key, []).append(ep)
                stored[_cache_key(task)] = ep.metrics()
                bar.update()
    else:
        for task in tasks:
            key, ep = _episode(task)
            out.setdefault(key, []).append(ep)
            stored[_cache_key(task)] = ep.metrics()
            bar.update()
    bar.close()
    if cache is not None:
        write_text_atomic(cache, json.dumps(stored))
    return {k: sorted(v, key=lambda e: e.seed) for k, v in out.items()}


def fmt_ci(r: dict, digits: int = 4) -> str:
    lo, hi = r["ci95"]
    return f"{r['mean']:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def label(policy: str) -> str:
    return policy if policy in POLICY_NAMES else Path(policy).name


def rmse(eps: list[Episode]) -> np.ndarray:
    return np.array([e.tracking_rmse for e in eps])


def goal_rows(models: list[str], eps: dict, summaries: dict) -> tuple[list[str], dict]:
    """Markdown rows of the goal check for every model and set, and the verdicts."""
    rows, verdicts = [], {}
    rng = np.random.default_rng(0)
    for m in models:
        for eval_set in SETS:
            a, b = rmse(eps[(m, eval_set, LIFT)]), rmse(eps[("ekf-pid", eval_set, LIFT)])
            ratio = float(a.mean() / b.mean())
            ci, _ = paired_bootstrap_ratio(a, b, rng)
            p = float(stats.wilcoxon(a, b).pvalue)
            ca, cb = summaries[(m, eval_set, LIFT)]["tracking_rmse"]["ci95"], \
                summaries[("ekf-pid", eval_set, LIFT)]["tracking_rmse"]["ci95"]
            apart = ca[1] < cb[0]
            met = ratio <= GOAL and apart
            verdicts[(m, eval_set)] = {"ratio": ratio, "ci95": ci, "wilcoxon_p": p, "intervals_apart": apart,
                                       "goal_met": met}
            rows.append(f"| {label(m)} | {eval_set} | **{ratio:.3f}** [{ci[0]:.3f}, {ci[1]:.3f}] | "
                        f"{np.mean(a < b):.2f} | {p:.2g} | {'yes' if apart else 'no'} | "
                        f"{'**met**' if met else '**not met**'} |")
    return rows, verdicts


def write_markdown(path: Path, command: str, policies: list[str], models: list[str], metas: dict, eps: dict,
                   summaries: dict, episodes: int, seed: int, elapsed: float) -> dict:
    lines = [f"# Trained agents vs scripted baselines on {ENV_ID}", "", "```", command, "```", "",
             f"{episodes} episodes per policy, condition and set (the same seeds for every policy: paired). "
             f"Held-out seeds: random-waypoint paths (the training family) on seeds {seed}–{seed + episodes - 1}. "
             f"Unseen families: {', '.join(UNSEEN)} in turn on seeds {seed + UNSEEN_OFFSET}–"
             f"{seed + UNSEEN_OFFSET + episodes - 1}. Mean and 95 % Student-t interval per metric; success "
             f"(within 5 cm and 0.1 rad at the end, not lost) with its 95 % Wilson interval. Wall time of this run "
             f"{elapsed / 60:.1f} min (episodes reused from `--cache` not counted; without a cache every episode "
             "is recomputed, bit for bit the same).", "", "## Trained agents", "",
             "| agent | algorithm | observation / action | training steps | training wall time | seed | "
             "validation RMSE: untrained → trained |", "|---|---|---|---|---|---|---|"]
    for m in models:
        meta = metas[m]
        obs = {"residual-ekf-pid": f"EKF features; residual ±{meta.get('residual_scale')} on ekf-pid",
               "ekf-features": "EKF features; full twist",
               "none": f"{meta.get('obs_mode')} observation; full twist"}[meta["wrapper"]]
        if meta.get("obs_mode") == "state":
            obs += " (privileged: UPPER BOUND, not a real-robot controller)"
        curve = Path(m) / "curve.csv"
        val = "n/a"
        if curve.is_file():
            d = np.atleast_1d(np.genfromtxt(curve, delimiter=",", names=True))
            val = f"{d['val_tracking_rmse'][0]:.4f} → {d['val_tracking_rmse'][-1]:.4f} m"
        lines.append(f"| {label(m)} | {meta['algo'].upper()} | {obs} | {meta.get('timesteps', 0):,} | "
                     f"{meta.get('wall_time_s', 0) / 60:.1f} min | {meta['seed']} | {val} |")
    lines += ["", "Training wall time is on this 2-core machine, shared with other jobs while it ran (see each "
              "model's `meta.json` for the exact command, git commit and `curve.csv` for the curve).", ""]
    lines += ["## Goal: tracking RMSE under slip + lift-off, learned / ekf-pid ≤ 0.8 with non-overlapping 95 % "
              "intervals", "",
              "| agent | set | ratio of mean tracking RMSE [95 % paired bootstrap] | agent better on | "
              "Wilcoxon p (two-sided) | intervals apart | goal |", "|---|---|---|---|---|---|---|"]
    rows, verdicts = goal_rows(models, eps, summaries)
    met = [f"{label(m)} ({s})" for (m, s), v in verdicts.items() if v["goal_met"]]
    lines += rows + ["", "**Goal met by: " + ", ".join(met) + ".**" if met else
                     "**The goal is not met by any trained agent on either set** (see `docs/agents.md` for what was "
                     "tried and what the evidence suggests).", ""]
    for eval_set in SETS:
        for cond, kw in CONDITIONS.items():
            extra = f"; trajectory {', '.join(UNSEEN)}" if eval_set == SETS[1] else "; trajectory waypoints"
            lines += [f"## {eval_set}: {cond} (`{', '.join(f'{k}={v!r}' for k, v in kw.items())}`{extra})", "",
                      "| policy | tracking RMSE [m] | final position error [m] | final heading error [rad] "
                      "| success rate | lost |", "|---|---|---|---|---|---|"]
            for p in policies:
                s = summaries[(p, eval_set, cond)]
                lost = sum(e.terminated for e in eps[(p, eval_set, cond)])
                lines.append(f"| {label(p)} | {fmt_ci(s['tracking_rmse'])} | {fmt_ci(s['final_position_error'])} | "
                             f"{fmt_ci(s['final_heading_error'])} | {fmt_ci(s['success_rate'], 2)} | {lost} |")
            lines.append("")
    path.write_text("\n".join(lines))
    return verdicts


def plot(path: Path, policies: list[str], summaries: dict) -> None:
    fig, axes = plt.subplots(len(SETS), 4, figsize=(18, 4.2 * len(SETS)), squeeze=False)
    conds = list(CONDITIONS)
    width = 0.8 / len(policies)
    for row, eval_set in enumerate(SETS):
        for ax, metric in zip(axes[row], [*METRICS, "success_rate"], strict=True):
            for j, p in enumerate(policies):
                means = np.array([summaries[(p, eval_set, c)][metric]["mean"] for c in conds])
                cis = np.array([summaries[(p, eval_set, c)][metric]["ci95"] for c in conds])
                lo = means - cis[:, 0]
                if metric != "success_rate":
                    lo = np.minimum(lo, means * 0.999)  # log axis: a t-interval below 0 is drawn to the axis
                x = np.arange(len(conds)) + (j - (len(policies) - 1) / 2) * width
                ax.bar(x, means, width, color=f"C{j}", label=label(p))
                ax.errorbar(x, means, yerr=[lo, cis[:, 1] - means], fmt="none", ecolor="k", capsize=2, lw=1)
            ax.set_xticks(np.arange(len(conds)), conds)
            ax.set_title(f"{eval_set}: {LABELS[metric]}")
            if metric == "success_rate":
                ax.set_ylim(0, 1.05)
            else:
                ax.set_yscale("log")
            ax.grid(axis="y", alpha=0.3, which="both")
        axes[row][0].legend(loc="upper left", fontsize=8)
    fig.suptitle(f"{ENV_ID}: trained agents vs scripted baselines, means with 95 % CIs")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_curves(path: Path, models: list[str]) -> None:
    fig, ax = plt.subplots(figsize=(7, 4))
    for j, m in enumerate(models):
        f = Path(m) / "curve.csv"
        if not f.is_file():
            continue
        d = np.genfromtxt(f, delimiter=",", names=True)
        ax.plot(np.atleast_1d(d["timesteps"]), np.atleast_1d(d["val_tracking_rmse"]), "o-", ms=3, color=f"C{j}",
                label=label(m))
    ax.set_xlabel("training steps")
    ax.set_ylabel("validation tracking RMSE [m] (5 episodes)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="*", default=[],
                    help="trained model directories (agents/models/<name>); none: only fill --cache with the baselines")
    ap.add_argument("--episodes", type=int, default=50, help="episodes per policy, condition and set (default 50)")
    ap.add_argument("--seed", type=int, default=10_000, help="first seed (default 10000)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    ap.add_argument("--cache", default=None, help="JSON file of episode metrics to reuse and extend")
    ap.add_argument("--episode-seconds", type=float, default=None,
                    help="shorter episodes for a quick check (default: the id's 20 s; the table uses 20 s)")
    args = ap.parse_args(argv)
    if args.episodes < 2:
        ap.error("--episodes must be >= 2 (confidence intervals need two episodes)")
    from agents.sb3_policy import read_meta

    try:
        metas = {m: read_meta(m) for m in args.models}
    except ValueError as exc:
        ap.error(str(exc))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = "python benchmarks/rl_vs_baselines.py " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
    policies = [*args.models, *POLICY_NAMES]
    t0 = time.time()
    overrides = {} if args.episode_seconds is None else {"episode_seconds": args.episode_seconds}
    cache = None if args.cache is None else Path(args.cache)
    eps = run_all(policies, args.episodes, args.seed, max(1, args.workers), overrides, cache)
    if not args.models:
        print(f"baseline episodes stored in {cache}" if cache else "no --models: nothing to compare")
        return 0
    summaries = {k: summarize(v, interval="t") for k, v in eps.items()}  # Student-t, as the header says
    verdicts = write_markdown(out / "rl_vs_baselines.md", command.strip(), policies, args.models, metas, eps,
                              summaries, args.episodes, args.seed, time.time() - t0)
    plot(out / "rl_vs_baselines.png", policies, summaries)
    plot_curves(out / "rl_training_curves.png", args.models)
    for (m, eval_set), v in verdicts.items():
        print(f"{label(m)} / ekf-pid tracking RMSE under {LIFT}, {eval_set}: {v['ratio']:.3f} "
              f"[{v['ci95'][0]:.3f}, {v['ci95'][1]:.3f}]; goal {'met' if v['goal_met'] else 'not met'}")
    print(json.dumps({f"{label(m)} | {s}": v for (m, s), v in verdicts.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
