"""Trained SB3 agents against every scripted baseline, on both path-following ids, batched evaluation.

Ids (``--envs``, default ``OmniPathFollow-Phunopas-v0`` and ``OmniPathFollow-Williams-v1``;
``OmniPathFollow-Mecanum-v0`` on request, without goal rows). On each: the scripted policies of
``--scripted`` (default all: ``agents.policies.POLICY_NAMES``, i.e. open-loop, odometry-pid, ekf-pid,
ekf-pid-traction, and ``feedback-law``, the privileged true-state law of ``agents.feedback_law``, k = 2/s)
and every model of ``--models`` trained on that id (its ``meta.json`` ``env_id``), in the three conditions
of the baseline table (``conditions(id)`` of ``benchmarks/baselines.py``: no slip, slip, slip + lift-off),
on the same seeds for every policy (paired):

* **held-out seeds** (always): random-waypoint paths on seeds ``--seed``… (default 10 000; training used
  seeds 0…n_envs−1 and their continuations, validation 5000…);
* **unseen families** (``--sets held-out unseen``): circle, figure-eight and line paths, never seen in
  training, episode i on family i mod 3, seeds ``--seed`` + ``UNSEEN_OFFSET``….

Evaluation is batched: all episodes of one (id, policy, set, family, condition) run at once as the robots
of one native vector env (:func:`agents.vector_rollout.run_episodes_vector`), which reproduces the
single-environment episodes (bit for bit for open-loop, within 1e-8 m for the EKF policies, see
``tests/test_vector_rollout.py``).

Per metric: mean and 95 % Student-t interval; success rate with its 95 % Wilson interval; lost count.
Each learned agent against ekf-pid and against ekf-pid-traction (privileged agents also against the
feedback law; tracking RMSE): ratio of means with a 95 % paired-bootstrap interval, the share of episodes
in which the agent is better with its 95 % paired-bootstrap interval, and a two-sided paired Wilcoxon test.
Agents trained with a behaviour-cloning warm start (``meta.json`` ``bc_init``) are labelled with its teacher
("BC-initialised from the feedback law" or "... from ekf-pid"). Privileged agents (``obs_mode``
"state": they read the true state) are marked "privileged (upper bound)" everywhere and are never the
"best learned agent": they show the headroom. Goals (held-out seeds):

* Williams-v1, condition "slip" (the id's default; slip + lift-off shown too): the best learned agent's
  tracking RMSE ≤ 0.5 × ekf-pid's and ≤ 0.8 × ekf-pid-traction's; the best scripted or learned policy's
  final position error ≤ 0.2 × open-loop's.
* Phunopas-v0, slip + lift-off: a learned agent's tracking RMSE ≤ 0.8 × ekf-pid's with the two 95 %
  intervals apart.

Writes ``NAME.md`` (``--name``, default ``rl_vs_baselines``; command line first) and ``NAME.png`` (bars
with 95 % whiskers per id, set and condition) into ``--out``; training curves are ``benchmarks/learning_curves.py``.
With ``--cache FILE`` every episode's metrics are kept in a JSON file keyed by (id, policy, a hash of the model's
files, set, condition, seed, overrides) and reused on the next run (e.g. the scripted policies while the
agents train). Usage::

    python benchmarks/rl_vs_baselines.py [--models DIR ...] [--envs ID ...] [--episodes 50] [--seed 10000]
                                         [--sets held-out [unseen]] [--workers 2] [--cache FILE]
                                         [--scripted POLICY ...] [--name STEM]
                                         [--ray [ADDRESS]]
                                         [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import os
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
sys.path.insert(0, str(Path(__file__).resolve().parent))

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from baselines import CONDITIONS, MECANUM_ENV, conditions, fmt_ci, paired_bootstrap_ratio  # noqa: E402
from scipy import stats  # noqa: E402
from tqdm import tqdm  # noqa: E402

from agents.evaluate import METRICS, summarize  # noqa: E402
from agents.policies import POLICY_NAMES  # noqa: E402
from agents.rollout import Episode  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.parallel import Backend, add_ray_option, backend_from_options, parallel_map  # noqa: E402
from omni_gym.record_paths import record_args

PHUNOPAS = "OmniPathFollow-Phunopas-v0"
WILLIAMS = "OmniPathFollow-Williams-v1"
MECANUM = MECANUM_ENV
ENV_IDS = (PHUNOPAS, WILLIAMS, MECANUM)
DEFAULT_ENVS = (PHUNOPAS, WILLIAMS)
LAW = "feedback-law"  # agents.feedback_law.TrueStateFeedback, k = 2/s: privileged (reads the true state), scripted
SCRIPTED = (*POLICY_NAMES, LAW)
SETS = {"held-out": "held-out seeds", "unseen": "unseen families"}
UNSEEN = ("circle", "figure_eight", "line")
UNSEEN_OFFSET = 1000  # unseen-family episodes start at --seed + 1000
SLIP, LIFT = "slip", "slip + lift-off"
BASELINES = ("ekf-pid", "ekf-pid-traction")  # what every learned agent is compared with (privileged ones: + LAW)
PRIVILEGED = "privileged (upper bound)"
LABELS = {"tracking_rmse": "tracking RMSE [m]", "final_position_error": "final position error [m]",
          "final_heading_error": "final heading error [rad]", "success_rate": "success rate"}


@dataclass(frozen=True)
class Batch:
    """One vector env's worth of episodes: the same id, policy, set, path family and condition."""

    env_id: str
    policy: str  # a SCRIPTED entry or a model directory
    eval_set: str  # a SETS value
    cond: str  # a CONDITIONS key
    family: str | None  # None: the id's default (random waypoints)
    seeds: tuple[int, ...]
    overrides: tuple[tuple[str, float], ...]

    def env_kwargs(self) -> dict:
        kw = {**conditions(self.env_id)[self.cond], **dict(self.overrides)}
        if self.family is not None:
            kw["trajectory"] = self.family
        return kw

    def cache_key(self, seed: int) -> str:
        return json.dumps([self.env_id, self.policy, policy_fingerprint(self.policy), self.eval_set, self.cond, seed,
                           list(self.overrides)])


@functools.cache
def policy_fingerprint(policy: str) -> str:
    """A scripted policy's name, or the SHA-256 of a model directory's files: a retrained model at the same
    path must not reuse the cached episodes of the old one."""
    if policy in SCRIPTED:
        return policy
    digest = hashlib.sha256()
    for f in sorted(Path(policy).iterdir()):
        if f.is_file() and f.suffix in (".zip", ".pkl", ".json"):
            digest.update(f.name.encode() + b"\0" + f.read_bytes())
    return digest.hexdigest()[:16]


def run_batch(batch: Batch) -> tuple[Batch, list[Episode]]:
    """The batch's episodes, all robots at once (in a worker process or in this one)."""
    from agents.vector_rollout import make_vector_env, run_episodes_vector

    if batch.policy == LAW:
        from agents.feedback_law import TrueStateFeedback

        venv = make_vector_env(batch.env_id, len(batch.seeds), batch.env_kwargs(), obs_mode="state")
        policy = TrueStateFeedback(venv)
    elif batch.policy in POLICY_NAMES:
        from agents.batched.policies import make_vector_policy

        venv = make_vector_env(batch.env_id, len(batch.seeds), batch.env_kwargs())
        policy = make_vector_policy(batch.policy, venv)
    else:
        from agents.sb3_policy import build_vector  # loads torch with one thread (small MLPs)

        venv, policy = build_vector(batch.policy, len(batch.seeds), batch.env_id, batch.env_kwargs())
    try:
        return batch, run_episodes_vector(venv, policy, batch.seeds)
    finally:
        venv.close()


def make_batches(env_ids: list[str], policies: dict[str, list[str]], sets: list[str], episodes: int, seed: int,
                 overrides: dict) -> list[Batch]:
    """Every batch: per id, policy, set, family (unseen set: one per family) and condition."""
    ov = tuple(sorted(overrides.items()))
    out = []
    for env_id in env_ids:
        for eval_set in sets:
            if eval_set == SETS["held-out"]:
                groups = [(None, tuple(seed + i for i in range(episodes)))]
            else:
                first = seed + UNSEEN_OFFSET
                groups = [(fam, tuple(first + i for i in range(episodes) if i % len(UNSEEN) == k))
                          for k, fam in enumerate(UNSEEN)]
            for cond in CONDITIONS:
                for p in policies[env_id]:
                    out += [Batch(env_id, p, eval_set, cond, fam, seeds, ov) for fam, seeds in groups if seeds]
    return out


def run_all(batches: list[Batch], backend: Backend, cache: Path | None) -> dict:
    """Episodes keyed by (id, policy, set, condition), sorted by seed; cached episodes are reused.

    Batches run on ``backend`` (:mod:`omni_gym.parallel`); an episode is a function of its seed alone,
    so the result is the same on every backend."""
    stored = json.loads(cache.read_text()) if cache is not None and cache.is_file() else {}
    out: dict = {}
    todo = []
    for b in batches:
        key = (b.env_id, b.policy, b.eval_set, b.cond)
        missing = tuple(s for s in b.seeds if b.cache_key(s) not in stored)
        out.setdefault(key, []).extend(Episode(**stored[b.cache_key(s)]) for s in b.seeds if s not in missing)
        if missing:
            todo.append(Batch(b.env_id, b.policy, b.eval_set, b.cond, b.family, missing, b.overrides))
    # Largest first: the pool then ends with short tasks and both workers stay busy.
    todo.sort(key=lambda b: -len(b.seeds))
    bar = tqdm(total=sum(len(b.seeds) for b in todo), desc="episodes", file=sys.stderr, unit="ep")

    def keep(b: Batch, eps: list[Episode]) -> None:
        out[(b.env_id, b.policy, b.eval_set, b.cond)].extend(eps)
        for e in eps:
            stored[b.cache_key(e.seed)] = e.metrics()
        bar.set_postfix_str(f"{b.env_id.split('-')[1]} {label_plain(b.policy)} {b.cond}", refresh=False)
        bar.update(len(eps))

    try:
        parallel_map(run_batch, todo, backend, on_done=lambda _i, r: keep(*r))
    finally:
        bar.close()
        if cache is not None:
            write_text_atomic(cache, json.dumps(stored))
    return {k: sorted(v, key=lambda e: e.seed) for k, v in out.items()}


# --- statistics --------------------------------------------------------------------------------


def values(eps: list[Episode], metric: str) -> np.ndarray:
    return np.array([getattr(e, metric) for e in eps])


def wilcoxon_p(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided paired Wilcoxon signed-rank p-value (1 when every pair is equal: no evidence either way)."""
    if np.all(a == b):
        return 1.0
    return float(stats.wilcoxon(a, b).pvalue)


@dataclass
class Comparison:
    """mean(a)/mean(b) of one metric over paired episodes, its 95 % bootstrap interval and the Wilcoxon p."""

    ratio: float
    ci95: list[float]
    better_share: float  # share of seeds where a < b
    better_ci95: list[float]  # its 95 % paired-bootstrap interval (the same resamples as the ratio's)
    wilcoxon_p: float
    intervals_apart: bool  # a's 95 % t-interval entirely below b's


def compare(a_eps: list[Episode], b_eps: list[Episode], metric: str, summaries_a: dict, summaries_b: dict
            ) -> Comparison:
    a, b = values(a_eps, metric), values(b_eps, metric)
    ci, _ = paired_bootstrap_ratio(a, b, np.random.default_rng(0))  # fixed: same episodes, same interval
    return Comparison(float(a.mean() / b.mean()), ci, float(np.mean(a < b)), share_interval(a, b), wilcoxon_p(a, b),
                      bool(summaries_a[metric]["ci95"][1] < summaries_b[metric]["ci95"][0]))


def share_interval(a: np.ndarray, b: np.ndarray, resamples: int = 10_000) -> list[float]:
    """95 % percentile-bootstrap interval of the share of paired seeds where ``a < b`` (seeds resampled with
    replacement; Generator seeded 0, as the ratio's: the same episodes give the same interval)."""
    better = (np.asarray(a) < np.asarray(b)).astype(float)
    idx = np.random.default_rng(0).integers(0, len(better), size=(resamples, len(better)))
    shares = better[idx].mean(axis=1)
    return [float(np.quantile(shares, 0.025)), float(np.quantile(shares, 0.975))]


# --- report ------------------------------------------------------------------------------------


def label_plain(policy: str) -> str:
    return policy if policy in SCRIPTED else Path(policy).name


def is_privileged(policy: str, metas: dict) -> bool:
    return policy == LAW or (policy in metas and metas[policy].get("obs_mode") == "state")


def is_bc(policy: str, metas: dict) -> bool:
    """Trained with a behaviour-cloning warm start (meta.json ``bc_init``)."""
    return policy in metas and "bc_init" in metas[policy]


def bc_label(policy: str, metas: dict) -> str:
    """"BC-initialised from <teacher>" (models from before the teacher was recorded: the feedback law)."""
    return metas[policy]["bc_init"].get("label", "BC-initialised from the feedback law")


def label(policy: str, metas: dict) -> str:
    name = label_plain(policy) + (f", {bc_label(policy, metas)}" if is_bc(policy, metas) else "")
    return f"{name} ({PRIVILEGED})" if is_privileged(policy, metas) else name


def fmt_cmp(c: Comparison) -> str:
    return f"{c.ratio:.3f} [{c.ci95[0]:.3f}, {c.ci95[1]:.3f}]"


def agents_table(models: list[str], metas: dict) -> list[str]:
    lines = ["| agent | id | algorithm | observation / action | training steps | training wall time | seed | "
             "validation RMSE: untrained → trained |", "|---|---|---|---|---|---|---|---|"]
    for m in models:
        meta = metas[m]
        obs = {"residual-ekf-pid": f"EKF features; residual ±{meta.get('residual_scale')} on ekf-pid",
               "ekf-features": "EKF features; full twist",
               "none": f"{meta.get('obs_mode')} observation; full twist"}.get(meta["wrapper"], meta["wrapper"])
        if is_privileged(m, metas):
            obs += f" — {PRIVILEGED}: reads the true state"
        if is_bc(m, metas):
            obs += f"; {bc_label(m, metas)}, then fine-tuned"
        curve = Path(m) / "curve.csv"
        val = "n/a"
        if curve.is_file():
            d = np.atleast_1d(np.genfromtxt(curve, delimiter=",", names=True))
            if d.dtype.names and "val_tracking_rmse" in d.dtype.names and len(d):
                val = f"{d['val_tracking_rmse'][0]:.4f} → {d['val_tracking_rmse'][-1]:.4f} m"
        lines.append(f"| {label(m, metas)} | {meta.get('env_id')} | {meta['algo'].upper()} | {obs} | "
                     f"{meta.get('timesteps', 0):,} | {meta.get('wall_time_s', 0) / 60:.1f} min | {meta.get('seed')} | "
                     f"{val} |")
    return lines


def best(candidates: list[str], key_eps: dict, metric: str) -> str | None:
    """The candidate with the lowest mean ``metric`` (None if there is none)."""
    scored = [(values(key_eps[p], metric).mean(), p) for p in candidates if p in key_eps]
    return min(scored)[1] if scored else None


def verdict_text(ratio: float, upper: float, goal: float) -> str:
    """met only when the whole 95 % interval lies within the goal; a mean within it alone is said so."""
    if upper <= goal:
        return "met"
    return "not met (mean within the goal, interval not)" if ratio <= goal else "not met"


def goal_williams(cond: str, learned: list[str], scripted: list[str], eps: dict, summ: dict, metas: dict
                  ) -> tuple[list[str], dict]:
    """Williams-v1 goal rows for one condition (held-out seeds)."""
    s = SETS["held-out"]
    k = {p: eps[(WILLIAMS, p, s, cond)] for p in [*learned, *scripted] if (WILLIAMS, p, s, cond) in eps}
    sm = {p: summ[(WILLIAMS, p, s, cond)] for p in k}
    rows, verdict = [], {}
    top = best(learned, k, "tracking_rmse")
    for base, goal in (("ekf-pid", 0.5), ("ekf-pid-traction", 0.8)):
        name = f"best learned agent tracking RMSE ≤ {goal} × {base}"
        if top is None:
            rows.append(f"| {cond} | {name} | no learned agent evaluated | — | **not met** |")
            verdict[name] = False
            continue
        c = compare(k[top], k[base], "tracking_rmse", sm[top], sm[base])
        verdict[name] = c.ci95[1] <= goal
        rows.append(f"| {cond} | {name} | {label(top, metas)}: {fmt_cmp(c)} | {'yes' if c.ci95[1] <= goal else 'no'}"
                    f" | **{verdict_text(c.ratio, c.ci95[1], goal)}** |")
    if "open-loop" not in k:
        return rows, verdict
    top_any = best([*learned, *[p for p in scripted if p != "open-loop"]], k, "final_position_error")
    name = "best scripted or learned policy final position error ≤ 0.2 × open-loop"
    c = compare(k[top_any], k["open-loop"], "final_position_error", sm[top_any], sm["open-loop"])
    verdict[name] = c.ci95[1] <= 0.2
    rows.append(f"| {cond} | {name} | {label(top_any, metas)}: {fmt_cmp(c)} | {'yes' if c.ci95[1] <= 0.2 else 'no'} "
                f"| **{verdict_text(c.ratio, c.ci95[1], 0.2)}** |")
    return rows, verdict


def goal_phunopas(learned: list[str], eps: dict, summ: dict, metas: dict) -> tuple[list[str], dict]:
    """Phunopas-v0 goal rows: every learned agent under slip + lift-off (held-out seeds)."""
    s = SETS["held-out"]
    rows, verdict = [], {}
    base = (PHUNOPAS, "ekf-pid", s, LIFT)
    for m in learned:
        c = compare(eps[(PHUNOPAS, m, s, LIFT)], eps[base], "tracking_rmse", summ[(PHUNOPAS, m, s, LIFT)], summ[base])
        met = c.ratio <= 0.8 and c.intervals_apart
        verdict[label_plain(m)] = met
        rows.append(f"| {LIFT} | {label(m, metas)} tracking RMSE ≤ 0.8 × ekf-pid, 95 % intervals apart | "
                    f"{fmt_cmp(c)}; intervals {'apart' if c.intervals_apart else 'overlap'} | "
                    f"{'yes' if c.ci95[1] <= 0.8 else 'no'} | **{'met' if met else 'not met'}** |")
    if not learned:
        rows.append(f"| {LIFT} | learned tracking RMSE ≤ 0.8 × ekf-pid, 95 % intervals apart | no learned agent "
                    "evaluated | — | **not met** |")
    return rows, verdict


def comparison_rows(env_id: str, models: list[str], sets: list[str], eps: dict, summ: dict, metas: dict) -> list[str]:
    lines = ["| agent | set | condition | vs | ratio of mean tracking RMSE [95 % paired bootstrap] | share of episodes "
             "the agent is better [95 % bootstrap] | Wilcoxon p (two-sided) | 95 % intervals apart |",
             "|---|---|---|---|---|---|---|---|"]
    for m in models:
        bases = [*BASELINES, *([LAW] if is_privileged(m, metas) else [])]
        for s in sets:
            for cond in CONDITIONS:
                for base in bases:
                    a, b = (env_id, m, s, cond), (env_id, base, s, cond)
                    if a not in eps or b not in eps:
                        continue
                    c = compare(eps[a], eps[b], "tracking_rmse", summ[a], summ[b])
                    lines.append(f"| {label(m, metas)} | {s} | {cond} | {base} | {fmt_cmp(c)} | {c.better_share:.2f} "
                                 f"[{c.better_ci95[0]:.2f}, {c.better_ci95[1]:.2f}] | "
                                 f"{c.wilcoxon_p:.2g} | {'yes' if c.intervals_apart else 'no'} |")
    return lines


def condition_tables(env_id: str, policies: list[str], sets: list[str], eps: dict, summ: dict, metas: dict
                     ) -> list[str]:
    lines = []
    for s in sets:
        for cond, kw in conditions(env_id).items():
            traj = f"trajectory {', '.join(UNSEEN)}" if s == SETS["unseen"] else "trajectory waypoints"
            lines += [f"### {s}: {cond} (`{', '.join(f'{k}={v!r}' for k, v in kw.items())}`; {traj})", "",
                      "| policy | tracking RMSE [m] | final position error [m] | final heading error [rad] "
                      "| success rate | lost |", "|---|---|---|---|---|---|"]
            for p in policies:
                r = summ[(env_id, p, s, cond)]
                lost = sum(e.terminated for e in eps[(env_id, p, s, cond)])
                lines.append(f"| {label(p, metas)} | {fmt_ci(r['tracking_rmse'])} | "
                             f"{fmt_ci(r['final_position_error'])} | {fmt_ci(r['final_heading_error'])} | "
                             f"{fmt_ci(r['success_rate'], 2)} | {lost} |")
            lines.append("")
    return lines


def write_markdown(path: Path, command: str, env_ids: list[str], policies: dict, sets: list[str], metas: dict,
                   eps: dict, summ: dict, episodes: int, seed: int, elapsed: float) -> dict:
    models = [m for e in env_ids for m in policies[e] if m not in SCRIPTED]
    set_text = (f"Held-out seeds: random-waypoint paths (the training family) on seeds {seed}–{seed + episodes - 1}."
                + (f" Unseen families: {', '.join(UNSEEN)} in turn on seeds {seed + UNSEEN_OFFSET}–"
                   f"{seed + UNSEEN_OFFSET + episodes - 1}." if SETS["unseen"] in sets else ""))
    lines = [f"# Trained agents vs scripted baselines on {' and '.join(env_ids)}", "", "```", command, "```", "",
             f"{episodes} episodes per id, policy, condition and set (the same seeds for every policy: paired). "
             f"{set_text} Batched evaluation (all episodes of a cell as the robots of one native vector env; "
             "the same episodes as single environments, `tests/test_vector_rollout.py`). Mean and 95 % Student-t "
             "interval per metric; success (within 5 cm and 0.1 rad at the end, not lost) with its 95 % Wilson "
             "interval; lost: episodes ended early (the robot left the reference by more than the id's limit; "
             "their errors are those at that moment). Agents marked "
             f"“{PRIVILEGED}” read the true state: not real-robot controllers, never the “best learned agent”, "
             f"shown as the headroom. Wall time of this run {elapsed / 60:.1f} min (episodes reused from `--cache` "
             "not counted).", ""]
    if models:
        lines += ["## Trained agents", ""] + agents_table(models, metas) + [
            "", "Each agent is evaluated on the id it was trained on. Training wall time is on this 2-core machine, "
            "shared with other jobs (see each model's `meta.json`; curves: `benchmarks/learning_curves.py`).", ""]
    verdicts: dict = {}
    lines += ["## Goals (held-out seeds)", "",
              "| condition | goal | measured: ratio [95 % paired bootstrap] | whole interval within the goal | "
              "verdict |", "|---|---|---|---|---|"]
    for env_id in env_ids:
        learned = [m for m in policies[env_id] if m not in SCRIPTED and not is_privileged(m, metas)]
        if env_id == WILLIAMS:
            lines.append(f"| **{WILLIAMS}** | | | | |")
            for cond in (SLIP, LIFT):
                rows, v = goal_williams(cond, learned, [p for p in POLICY_NAMES if p in policies[env_id]], eps, summ,
                                        metas)
                lines += rows
                verdicts.update({f"{WILLIAMS} | {cond} | {k}": x for k, x in v.items()})
        elif env_id == PHUNOPAS:
            lines.append(f"| **{PHUNOPAS}** | | | | |")
            rows, v = goal_phunopas(learned, eps, summ, metas)
            lines += rows
            verdicts.update({f"{PHUNOPAS} | {LIFT} | {k}": x for k, x in v.items()})
    lines += ["", f"The {WILLIAMS} goal is set for condition “{SLIP}” (the id's default); the “{LIFT}” rows are shown "
              "for comparison. The best learned agent is the non-privileged one with the lowest mean (tracking RMSE, "
              "or final position error for the open-loop goal). A goal is met when the whole 95 % paired-bootstrap "
              "interval of the ratio lies within it (Phunopas: and the agent's and ekf-pid's 95 % intervals are "
              "apart); a mean within the goal whose interval is not is reported as not met, and said so. Tracking "
              "RMSE is the position error only: read the heading column too (an agent that ignores the heading "
              "can have a small position RMSE).", ""]
    for env_id in env_ids:
        env_models = [m for m in policies[env_id] if m not in SCRIPTED]
        lines += [f"## {env_id}", ""]
        if env_models:
            lines += ["### Learned agents vs ekf-pid and ekf-pid-traction (privileged agents also vs the feedback law)",
                      ""]
            lines += comparison_rows(env_id, env_models, sets, eps, summ, metas) + [""]
        lines += condition_tables(env_id, policies[env_id], sets, eps, summ, metas)
    write_text_atomic(path, "\n".join(lines))
    return verdicts


def plot(path: Path, env_ids: list[str], policies: dict, sets: list[str], summ: dict, metas: dict) -> None:
    """Bars with 95 % whiskers: one row of four metric panels per id and set, conditions on the x axis."""
    rows = [(e, s) for e in env_ids for s in sets]
    fig, axes = plt.subplots(len(rows), 4, figsize=(22, 4.3 * len(rows)), squeeze=False)
    conds = list(CONDITIONS)
    for (env_id, s), row in zip(rows, axes, strict=True):
        pols = policies[env_id]
        width = 0.8 / len(pols)
        for ax, metric in zip(row, [*METRICS, "success_rate"], strict=True):
            for j, p in enumerate(pols):
                means = np.array([summ[(env_id, p, s, c)][metric]["mean"] for c in conds])
                cis = np.array([summ[(env_id, p, s, c)][metric]["ci95"] for c in conds])
                lo = means - cis[:, 0]
                if metric != "success_rate":
                    lo = np.minimum(lo, means * 0.999)  # log axis: a t-interval below 0 is drawn to the axis
                x = np.arange(len(conds)) + (j - (len(pols) - 1) / 2) * width
                ax.bar(x, means, width, color=f"C{j % 10}", label=label(p, metas),
                       hatch="//" if is_privileged(p, metas) else None)
                # clip: the Wilson bound for 0 successes is 7e-18, not 0, and errorbar refuses negative lengths
                ax.errorbar(x, means, yerr=np.clip([lo, cis[:, 1] - means], 0.0, None), fmt="none", ecolor="k",
                            capsize=2, lw=1)
            ax.set_xticks(np.arange(len(conds)), conds)
            ax.set_title(f"{env_id}, {s}\n{LABELS[metric]}", fontsize=9)
            if metric == "success_rate":
                ax.set_ylim(0, 1.05)
            else:
                ax.set_yscale("log")
            ax.grid(axis="y", alpha=0.3, which="both")
        row[-1].legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7)  # outside: bars stay visible
    fig.suptitle("Trained agents vs scripted baselines: means with 95 % intervals (t; Wilson for the success rate)")
    fig.tight_layout(rect=(0, 0, 1, 0.98))
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)


def parse(argv: list[str] | None) -> tuple[argparse.Namespace, dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="*", default=[],
                    help="trained model directories (meta.json names the id each is evaluated on)")
    ap.add_argument("--envs", nargs="+", choices=ENV_IDS, default=list(DEFAULT_ENVS),
                    help=f"ids (default {' and '.join(DEFAULT_ENVS)}; {MECANUM} has no goal rows)")
    ap.add_argument("--scripted", nargs="+", choices=SCRIPTED, default=list(SCRIPTED),
                    help=f"scripted policies to run (default all; {LAW}: the privileged true-state law, k = 2/s)")
    ap.add_argument("--name", default="rl_vs_baselines", help="output file stem (default rl_vs_baselines)")
    ap.add_argument("--sets", nargs="+", choices=list(SETS), default=["held-out"],
                    help="evaluation sets (default held-out; 'unseen': circle, figure-eight, line)")
    ap.add_argument("--episodes", type=int, default=50, help="episodes per id, policy, condition and set (default 50)")
    ap.add_argument("--seed", type=int, default=10_000, help="first seed (default 10000)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes, one batch each (default 2)")
    add_ray_option(ap, "the episode batches", "--workers")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    ap.add_argument("--cache", default=None, help="JSON file of episode metrics to reuse and extend")
    ap.add_argument("--episode-seconds", type=float, default=None,
                    help="shorter episodes for a quick check (default: the ids' 20 s; the table uses 20 s)")
    args = ap.parse_args(argv)
    if args.episodes < 2:
        ap.error("--episodes must be >= 2 (confidence intervals need two episodes)")
    if args.seed < 0 or args.workers < 1:
        ap.error("--seed must be >= 0 and --workers >= 1")
    if args.episode_seconds is not None and not (0 < args.episode_seconds <= 600):
        ap.error("--episode-seconds must be in (0, 600]")
    from agents.sb3_policy import read_meta

    metas = {}
    for m in args.models:
        try:
            metas[m] = read_meta(m)
        except ValueError as exc:
            ap.error(str(exc))
        if metas[m].get("env_id") not in ENV_IDS:
            ap.error(f"{m}: trained on {metas[m].get('env_id')!r}; this benchmark evaluates {', '.join(ENV_IDS)}")
    return args, metas


def main(argv: list[str] | None = None) -> int:
    args, metas = parse(argv)
    env_ids = [e for e in ENV_IDS if e in args.envs]  # fixed order: Phunopas first
    skipped = [m for m in args.models if metas[m]["env_id"] not in env_ids]
    for m in skipped:
        print(f"note: {m} was trained on {metas[m]['env_id']}, not in --envs: skipped", file=sys.stderr)
    policies = {e: [*[m for m in args.models if metas[m]["env_id"] == e], *args.scripted] for e in env_ids}
    sets = [SETS[s] for s in SETS if s in args.sets]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    recorded = record_args(argv or sys.argv[1:])
    command = "python benchmarks/rl_vs_baselines.py " + " ".join(shlex.quote(a) for a in recorded)
    overrides = {} if args.episode_seconds is None else {"episode_seconds": args.episode_seconds}
    t0 = time.time()
    batches = make_batches(env_ids, policies, sets, args.episodes, args.seed, overrides)
    try:
        backend = backend_from_options(args.workers, args.ray)
        eps = run_all(batches, backend, None if args.cache is None else Path(args.cache))
    except ValueError as exc:  # a model that does not fit its environment, bad env kwargs: one line
        print(f"rl_vs_baselines.py: error: {exc}", file=sys.stderr)
        return 2
    elapsed = time.time() - t0
    summ = {k: summarize(v, interval="t") for k, v in eps.items()}  # Student-t, as the header says
    if any(b not in args.scripted for b in BASELINES):
        print(f"rl_vs_baselines.py: error: --scripted must include {' and '.join(BASELINES)}", file=sys.stderr)
        return 2
    verdicts = write_markdown(out / f"{args.name}.md", command.strip(), env_ids, policies, sets, metas, eps, summ,
                              args.episodes, args.seed, elapsed)
    plot(out / f"{args.name}.png", env_ids, policies, sets, summ, metas)
    for key, met in verdicts.items():
        print(f"{key}: {'met' if met else 'not met'}")
    print(f"wall time {elapsed / 60:.1f} min; wrote {out / (args.name + '.md')} and {out / (args.name + '.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
