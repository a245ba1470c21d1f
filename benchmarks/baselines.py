"""Baseline table: every scripted policy (open-loop, odometry-pid, ekf-pid, ekf-pid-traction) on the path-following ids.

The ids: ``OmniPathFollow-Phunopas-v0`` (phunopas2018, 4 omni wheels), ``OmniPathFollow-WilliamsPaper-v0``
(williams2002, 3 omni wheels) and ``OmniPathFollow-Mecanum-v0`` (optiodom_omni4, 4 mecanum wheels);
``--env`` picks a subset. The same conditions, seeds and code path run on every id, so one id's rows do not
depend on whether the others are computed too.

Conditions (everything else the id's defaults: 20 s random-waypoint paths, sensors at default noise):

* no slip: ``surface="grip", friction="initial", lift_rate=0``
* slip: ``surface="carpet", friction="roller_gap", lift_rate=0``
* slip + lift-off: ``surface="carpet", friction="roller_gap", lift_rate=0.5`` (the Phunopas id's defaults)

On the mecanum id every condition uses the only friction model of mecanum wheels, ``initial``
(:data:`MECANUM_CONDITIONS`; slip: ``surface="carpet", friction="initial"``, the id's defaults).

Every policy runs the same held-out seeds (from ``--seed``, default 10 000; the tests use seeds below
10 000), so the comparisons are paired: the same reference, lift-off schedule and sensor noise. Per
metric: mean and 95 % Student-t interval; success rate with its 95 % Wilson interval; one-sided paired
Wilcoxon signed-rank tests on the final position error (with Holm-adjusted p-values over the nine
tests per id); the ratio of mean final position errors ekf-pid / open-loop under slip + lift-off with a 95 %
paired-bootstrap (percentile) interval (checked against the goal for the Phunopas id only).

Confirmation run: odometry-pid and open-loop differ little, so the 50-episode comparison of the two
under slip + lift-off is repeated on ``--confirm-episodes`` (default 200) further seeds (from
``--seed`` + 40 000), reported two-sided with the mean paired difference and its t-interval; on the
Phunopas id only (the question it answers was asked there).

Writes ``baselines.md`` (command line first) and ``baselines.png`` (bars with 95 % CI whiskers) into
``--out``: one section per id. With ``--merge`` the ids run replace (or add) only their own sections of an
existing ``baselines.md``, every other line is kept, and the plot goes to ``baselines-<ids>.png``. Usage::

    python benchmarks/baselines.py [--episodes 50] [--confirm-episodes 200] [--seed 10000] [--workers 2]
                                   [--ray [ADDRESS]]
                                   [--env ID ...] [--merge] [--out benchmarks/results]
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

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402
from tqdm import tqdm  # noqa: E402

from agents.evaluate import BOOTSTRAP_RESAMPLES, METRICS, paired_bootstrap_ratio, summarize  # noqa: E402
from agents.policies import POLICY_NAMES, make_policy  # noqa: E402
from agents.rollout import Episode, make_env, run_episode  # noqa: E402
from omni_gym.parallel import SERIAL, Backend, add_ray_option, backend_from_options, parallel_map  # noqa: E402
from omni_gym.record_paths import record_args

GOAL_ENV = "OmniPathFollow-Phunopas-v0"  # the goal and the confirmation run are defined on this id
MECANUM_ENV = "OmniPathFollow-Mecanum-v0"
ENV_IDS = (GOAL_ENV, "OmniPathFollow-WilliamsPaper-v0", MECANUM_ENV)
ENV_ID = GOAL_ENV  # imported by rl_vs_baselines.py, which compares on this id only
CONDITIONS = {
    "no slip": {"surface": "grip", "friction": "initial", "lift_rate": 0.0},
    "slip": {"surface": "carpet", "friction": "roller_gap", "lift_rate": 0.0},
    "slip + lift-off": {"surface": "carpet", "friction": "roller_gap", "lift_rate": 0.5},
}
# Mecanum wheels: roller_gap friction does not apply (docs/model.md); the same floors with the initial model.
MECANUM_CONDITIONS = {
    "no slip": {"surface": "grip", "friction": "initial", "lift_rate": 0.0},
    "slip": {"surface": "carpet", "friction": "initial", "lift_rate": 0.0},
    "slip + lift-off": {"surface": "carpet", "friction": "initial", "lift_rate": 0.5},
}


def conditions(env_id: str) -> dict[str, dict]:
    """The three conditions (same names on every id) with the keywords they pass to ``env_id``."""
    return MECANUM_CONDITIONS if env_id == MECANUM_ENV else CONDITIONS
GOAL_RATIO = 0.2  # ekf-pid / open-loop mean final position error under slip + lift-off
BOOTSTRAP = BOOTSTRAP_RESAMPLES  # resamples of the paired bootstrap (agents.evaluate.paired_bootstrap_ratio)
LABELS = {"tracking_rmse": "tracking RMSE [m]", "final_position_error": "final position error [m]",
          "final_heading_error": "final heading error [rad]", "success_rate": "success rate"}

LOST_NOTE = ("A lost episode's errors are those at the moment it was lost (about `lost_distance` = 0.5 m), so "
             "where many are lost the error columns and the paired tests compare capped values: read the lost and "
             "success columns first.")

_cache: dict = {}


CONFIRM = "confirm"  # tag of the confirmation episodes
# Their first seed is --seed + CONFIRM_OFFSET (30 000–30 099 were used to design odometry's gyro offset tracking).
CONFIRM_OFFSET = 40_000
LIFT = "slip + lift-off"


def _episode(task: tuple[str, str, str, int, str]) -> tuple[tuple[str, str, str, str], Episode]:
    """One episode in a worker process; the env and policy are built once per (id, policy, condition)."""
    env_id, policy, cond, seed, tag = task
    if (env_id, policy, cond) not in _cache:
        env = make_env(env_id, conditions(env_id)[cond])
        _cache[(env_id, policy, cond)] = (env, make_policy(policy, env))
    env, pol = _cache[(env_id, policy, cond)]
    return (env_id, policy, cond, tag), run_episode(env, pol, seed)


CHUNK = 5  # episodes per task (a worker builds an env and policy once per id, policy and condition)


def _episodes(chunk: list[tuple[str, str, str, int, str]]) -> list[tuple[tuple[str, str, str, str], Episode]]:
    """A task: a few episodes, one after another, in a worker (or in this process)."""
    return [_episode(task) for task in chunk]


def run_all(env_ids: list[str], episodes: int, seed: int, confirm: int, backend: Backend = SERIAL) -> dict:
    """Episodes keyed by (id, policy, condition, tag): tag "" for the table, CONFIRM for the confirmation run.

    Each episode is a function of its seed alone, so the result is the same on every backend."""
    tasks = [(e, p, c, seed + i, "") for e in env_ids for c in CONDITIONS for p in POLICY_NAMES
             for i in range(episodes)]
    if GOAL_ENV in env_ids:
        tasks += [(GOAL_ENV, p, LIFT, seed + CONFIRM_OFFSET + i, CONFIRM) for p in ("open-loop", "odometry-pid")
                  for i in range(confirm)]
    out: dict = {}
    bar = tqdm(total=len(tasks), desc="baseline episodes", file=sys.stderr, unit="ep")
    chunks = [tasks[i:i + CHUNK] for i in range(0, len(tasks), CHUNK)]
    done = parallel_map(_episodes, chunks, backend, on_done=lambda _i, eps: bar.update(len(eps)))
    for key, ep in (x for chunk in done for x in chunk):
        out.setdefault(key, []).append(ep)
    bar.close()
    return {k: sorted(v, key=lambda e: e.seed) for k, v in out.items()}


def holm(pvalues: list[float]) -> list[float]:
    """Holm–Bonferroni adjusted p-values (family-wise error control), in the input order."""
    order = np.argsort(pvalues)
    m = len(pvalues)
    adjusted = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * pvalues[i]))
        adjusted[i] = running
    return adjusted.tolist()


def fmt_ci(r: dict, digits: int = 4) -> str:
    lo, hi = r["ci95"]
    return f"{r['mean']:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def final_errors(episodes: list[Episode]) -> np.ndarray:
    return np.array([e.final_position_error for e in episodes])


def condition_tables(env_id: str, summaries: dict, eps: dict) -> list[str]:
    """One table per condition for ``env_id``: metric means with 95 % intervals and the lost count."""
    lines = []
    for cond, kw in conditions(env_id).items():
        lines += [f"### {cond} (`{', '.join(f'{k}={v!r}' for k, v in kw.items())}`)", "",
                  "| policy | tracking RMSE [m] | final position error [m] | final heading error [rad] "
                  "| success rate | lost |", "|---|---|---|---|---|---|"]
        for p in POLICY_NAMES:
            s = summaries[(env_id, p, cond)]
            lost = sum(e.terminated for e in eps[(env_id, p, cond)])
            lines.append(f"| {p} | {fmt_ci(s['tracking_rmse'])} | {fmt_ci(s['final_position_error'])} | "
                         f"{fmt_ci(s['final_heading_error'])} | {fmt_ci(s['success_rate'], 2)} | {lost} |")
        lines.append("")
    return lines


def paired_tests(env_id: str, eps: dict) -> list[str]:
    """One-sided Wilcoxon tests on the final position error, Holm-adjusted over this id's nine tests."""
    lines = ["### Paired tests on the final position error", "",
             "One-sided Wilcoxon signed-rank tests over the paired seeds (H₁: the first policy's error is "
             "smaller); 'wins' is the share of seeds on which it is smaller; p (Holm) is adjusted over the "
             "nine tests of this id.", "",
             "| condition | comparison | wins | median difference [m] | p | p (Holm) |", "|---|---|---|---|---|---|"]
    rows, pvals = [], []
    for cond in CONDITIONS:
        for a, b in (("ekf-pid", "odometry-pid"), ("ekf-pid", "open-loop"), ("odometry-pid", "open-loop")):
            x, y = final_errors(eps[(env_id, a, cond)]), final_errors(eps[(env_id, b, cond)])
            pvals.append(float(stats.wilcoxon(x, y, alternative="less").pvalue))
            rows.append(f"| {cond} | {a} < {b} | {np.mean(x < y):.2f} | {np.median(x - y):+.4f} | {pvals[-1]:.2g}")
    return lines + [f"{row} | {p:.2g} |" for row, p in zip(rows, holm(pvals), strict=True)]


def confirmation(confirm: list) -> list[str]:
    """The odometry-pid vs open-loop confirmation on further seeds (two-sided)."""
    ol_c, od_c = confirm
    d = final_errors(od_c) - final_errors(ol_c)
    ci = stats.t.interval(0.95, len(d) - 1, loc=d.mean(), scale=stats.sem(d))
    return ["", f"### Confirmation: odometry-pid vs open-loop under {LIFT}, {len(d)} further seeds "
            f"({ol_c[0].seed}–{ol_c[-1].seed})", "",
            f"Mean final position error open-loop {final_errors(ol_c).mean():.4f} m, odometry-pid "
            f"{final_errors(od_c).mean():.4f} m; odometry-pid smaller on {np.mean(d < 0):.2f} of the seeds; "
            f"mean paired difference (odometry-pid − open-loop) {d.mean():+.4f} m, 95 % t-interval "
            f"[{ci[0]:+.4f}, {ci[1]:+.4f}]; Wilcoxon signed-rank p = {stats.wilcoxon(d).pvalue:.2g} "
            f"(two-sided), {stats.wilcoxon(d, alternative='less').pvalue:.2g} (H₁: odometry-pid smaller).",
            "Where this disagrees with the 50-episode row above, trust the larger sample: the difference "
            "between the two policies is small against the episode-to-episode spread."]


def ratio_section(env_id: str, eps: dict) -> tuple[list[str], dict]:
    """ekf-pid / open-loop mean final position error under slip + lift-off; the goal is judged on GOAL_ENV."""
    ekf, ol = final_errors(eps[(env_id, "ekf-pid", LIFT)]), final_errors(eps[(env_id, "open-loop", LIFT)])
    ratio = float(ekf.mean() / ol.mean())
    ci, upper = paired_bootstrap_ratio(ekf, ol, np.random.default_rng(0))
    if env_id != GOAL_ENV:
        verdict = f"The goal ≤ {GOAL_RATIO} is set for {GOAL_ENV} only; shown for comparison."
    elif ci[1] <= GOAL_RATIO:
        verdict = f"Goal ≤ {GOAL_RATIO}: the whole interval is below the goal."
    elif ratio <= GOAL_RATIO:
        verdict = (f"Goal ≤ {GOAL_RATIO}: the point estimate meets the goal, but the interval reaches above it: "
                   f"{len(ekf)} episodes cannot exclude a ratio slightly above {GOAL_RATIO}.")
    else:
        verdict = f"Goal ≤ {GOAL_RATIO}: the point estimate misses the goal."
    lines = ["", "### Goal" if env_id == GOAL_ENV else "### ekf-pid / open-loop", "",
             f"Mean final position error under slip + lift-off, ekf-pid / open-loop = **{ratio:.3f}**; 95 % "
             f"paired-bootstrap interval [{ci[0]:.3f}, {ci[1]:.3f}] (one-sided 95 % upper bound {upper:.3f}; "
             f"{BOOTSTRAP} resamples of the seeds). {verdict}", ""]
    return lines, {"ratio": ratio, "ratio_ci95": ci, "upper95": upper}


def write_markdown(path: Path, command: str, env_ids: list[str], summaries: dict, eps: dict, confirm: list,
                   episodes: int, seed: int, elapsed: float, merge: bool = False) -> dict:
    """Write the table (one section per id); return the ekf-pid / open-loop ratio per id."""
    lines = [f"# Baselines on {' and '.join(env_ids)}", "", "```", command, "```", "",
             f"{episodes} episodes per id, policy and condition on seeds {seed}–{seed + episodes - 1} (the same "
             "seeds for every policy: paired), 20 s random-waypoint paths, default sensor noise. Mean and 95 % "
             "Student-t interval per metric; success (within 5 cm and 0.1 rad at the end, not lost) with its "
             "95 % Wilson interval; 'lost' counts episodes ended early because the robot left the reference by "
             f"more than the id's limit. {LOST_NOTE} Wall time {elapsed / 60:.1f} min.", ""]
    goals, sections = {}, {}
    for env_id in env_ids:
        sec = [f"## {env_id}", ""] + condition_tables(env_id, summaries, eps) + paired_tests(env_id, eps)
        if env_id == GOAL_ENV and confirm:
            sec += confirmation(confirm)
        ratio_lines, goals[env_id] = ratio_section(env_id, eps)
        sections[env_id] = sec + ratio_lines
    if merge and path.is_file():
        text = merge_sections(path.read_text(encoding="utf-8"), sections, command, episodes, seed, elapsed)
    else:
        text = "\n".join(lines + [x for env_id in env_ids for x in sections[env_id]])
    path.write_text(text, encoding="utf-8")
    return goals


def merge_sections(text: str, sections: dict[str, list[str]], command: str, episodes: int, seed: int,
                   elapsed: float) -> str:
    """``text`` (an earlier baselines.md) with the ``## <id>`` section of every id in ``sections`` replaced, or
    appended in :data:`ENV_IDS` order; every other line kept. A merged section opens with its own command."""
    lines = text.rstrip("\n").split("\n")
    starts = [i for i, x in enumerate(lines) if x.startswith("## ")]
    head = lines[:starts[0]] if starts else lines
    old = {lines[a][3:].strip(): lines[a:b] for a, b in zip(starts, [*starts[1:], len(lines)], strict=True)}
    note = ["```", command, "```", "", f"Merged into this file by the command above: {episodes} episodes per policy "
            f"and condition on seeds {seed}–{seed + episodes - 1}, wall time {elapsed / 60:.1f} min.", ""]
    for env_id, sec in sections.items():
        old[env_id] = sec[:2] + note + sec[2:] + [""]
    order = [e for e in ENV_IDS if e in old] + [e for e in old if e not in ENV_IDS]
    ids = [e for e in order if e in ENV_IDS]
    if head and head[0].startswith("# Baselines on "):
        head = [f"# Baselines on {', '.join(ids[:-1])} and {ids[-1]}" if len(ids) > 1 else f"# Baselines on {ids[0]}",
                *head[1:]]
    out = list(head)
    for env_id in order:
        sec = list(old[env_id])
        while sec and not sec[-1].strip():  # one blank line between sections, whatever the old file had
            sec.pop()
        out += [*sec, ""]
    return "\n".join(out).rstrip("\n") + "\n"


def plot(path: Path, env_ids: list[str], summaries: dict) -> None:
    """Bars with 95 % CI whiskers: one row of four metric panels per id."""
    fig, axes = plt.subplots(len(env_ids), 4, figsize=(17, 4.2 * len(env_ids)), squeeze=False)
    conds = list(CONDITIONS)
    width = 0.8 / len(POLICY_NAMES)
    colors = {"open-loop": "#d95f02", "odometry-pid": "#7570b3", "ekf-pid": "#1b9e77", "ekf-pid-traction": "#e7298a"}
    for row, env_id in zip(axes, env_ids, strict=True):
        for ax, metric in zip(row, [*METRICS, "success_rate"], strict=True):
            for j, p in enumerate(POLICY_NAMES):
                means = np.array([summaries[(env_id, p, c)][metric]["mean"] for c in conds])
                cis = np.array([summaries[(env_id, p, c)][metric]["ci95"] for c in conds])
                lo = means - cis[:, 0]
                if metric != "success_rate":
                    lo = np.minimum(lo, means * 0.999)  # log axis: a t-interval below 0 is drawn down to the axis
                x = np.arange(len(conds)) + (j - (len(POLICY_NAMES) - 1) / 2) * width
                ax.bar(x, means, width, color=colors.get(p, f"C{j}"), label=p)
                # clip: the Wilson bound for 0 successes is 7e-18, not 0, and errorbar refuses negative lengths
                yerr = np.clip([lo, cis[:, 1] - means], 0.0, None)
                ax.errorbar(x, means, yerr=yerr, fmt="none", ecolor="k", capsize=3, lw=1)
            ax.set_xticks(np.arange(len(conds)), conds)
            ax.set_title(f"{env_id}\n{LABELS[metric]}", fontsize=10)
            if metric == "success_rate":
                ax.set_ylim(0, 1.05)
            else:
                ax.set_yscale("log")
            ax.grid(axis="y", alpha=0.3, which="both")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper right", ncol=len(labels))  # once, clear of the bars
    fig.suptitle("Scripted baselines: means with 95 % confidence intervals (t; Wilson for the success rate)", x=0.35)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=50, help="episodes per id, policy and condition (default 50)")
    ap.add_argument("--confirm-episodes", type=int, default=200,
                    help=f"further seeds for the odometry-pid vs open-loop confirmation on {GOAL_ENV} "
                         "(default 200; 0: skip)")
    ap.add_argument("--seed", type=int, default=10_000, help="first seed (default 10000, held out from tests)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    add_ray_option(ap, "the episode batches", "--workers")
    ap.add_argument("--env", action="append", choices=ENV_IDS, dest="envs",
                    help=f"environment id (repeatable; default both: {', '.join(ENV_IDS)})")
    ap.add_argument("--merge", action="store_true",
                    help="replace only the sections of the ids run in an existing OUT/baselines.md (others kept); "
                         "plot to OUT/baselines-<ids>.png")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    args = ap.parse_args(argv)
    if args.episodes < 2:
        ap.error("--episodes must be >= 2 (confidence intervals need two episodes)")
    env_ids = [e for e in ENV_IDS if e in (args.envs or ENV_IDS)]  # fixed order: Phunopas first
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = "python benchmarks/baselines.py " + " ".join(shlex.quote(a) for a in record_args(argv or sys.argv[1:]))
    t0 = time.time()
    try:
        backend = backend_from_options(max(1, args.workers), args.ray)
    except ValueError as exc:  # BackendError: ray missing, nothing at the address, a bad --jobs/--workers
        raise SystemExit(f"baselines.py: error: {exc}") from None
    runs = run_all(env_ids, args.episodes, args.seed, max(0, args.confirm_episodes), backend)
    eps = {(e, p, c): v for (e, p, c, tag), v in runs.items() if tag == ""}
    confirm = ([runs[(GOAL_ENV, p, LIFT, CONFIRM)] for p in ("open-loop", "odometry-pid")]
               if args.confirm_episodes > 1 and GOAL_ENV in env_ids else [])
    summaries = {k: summarize(v, interval="t") for k, v in eps.items()}  # Student-t, as the header says
    goals = write_markdown(out / "baselines.md", command.strip(), env_ids, summaries, eps, confirm, args.episodes,
                           args.seed, time.time() - t0, merge=args.merge)
    short = "-".join(e.split("-")[1].lower() for e in env_ids)  # OmniPathFollow-Mecanum-v0 → mecanum
    plot(out / (f"baselines-{short}.png" if args.merge else "baselines.png"), env_ids, summaries)
    for env_id in env_ids:
        for cond in conditions(env_id):
            for p in POLICY_NAMES:
                s = summaries[(env_id, p, cond)]
                print(f"{env_id} {cond:16s} {p:13s} rmse {fmt_ci(s['tracking_rmse'])}  "
                      f"final {fmt_ci(s['final_position_error'])}  heading {fmt_ci(s['final_heading_error'])}  "
                      f"success {fmt_ci(s['success_rate'], 2)}")
        g = goals[env_id]
        print(f"{env_id}: ekf-pid / open-loop final position error under slip + lift-off: {g['ratio']:.3f} "
              f"[{g['ratio_ci95'][0]:.3f}, {g['ratio_ci95'][1]:.3f}], one-sided 95 % upper bound {g['upper95']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
