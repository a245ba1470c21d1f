"""Normalised tracking score of every scripted policy, the true-state law and each committed agent.

    python benchmarks/normalised_score.py [--envs ID ...] [--models DIR ...] [--episodes 50] [--seed 10000]
                                          [--workers 2] [--cache FILE] [--out benchmarks/results]

score = 100·(RMSE_open − RMSE_policy)/(RMSE_open − RMSE_ekfpid) (``agents.normalised_score``; 0 = open-loop,
100 = ekf-pid), per path-following id and condition (the three conditions of ``benchmarks/baselines.py``:
no slip, slip, slip + lift-off), from the mean tracking RMSE of the same held-out episodes (seeds 10000…,
paired: every policy, anchors included, runs on the same seeds; on ``OmniPathFollow-Mecanum-v0`` the same
floors and lift-off with ``initial`` friction, ``baselines.MECANUM_CONDITIONS``). The interval is the paired
bootstrap of the score over seeds. Policies: ``random`` (uniform actions in [−1, 1], from a Generator seeded by the
episode's seed), the scripted ``open-loop``, ``odometry-pid``, ``ekf-pid``, ``ekf-pid-traction``, the
privileged true-state law (``agents.feedback_law``, k = 2/s) and every model of ``--models`` (default:
``agents/models/*``) on the id it was trained on (its ``meta.json``). Batched: all episodes of one (id,
policy, condition) are the robots of one native vector env (``agents.vector_rollout``), which reproduces
the single-environment episodes of ``omni-gym evaluate --score``. Writes ``normalised_score.md``. Run time
of the whole table (4 ids, 3 conditions, 50 episodes, the 13 committed agents, no cache): 12.7 min on a
shared 2-core machine; ``--envs ID --episodes 4 --episode-seconds 2`` checks one id in under a minute.

``OmniPathFollow-Custom-v0`` is not in the table: its robot, surface and friction all come from the
user's ``model=`` (no canonical model to score); ``omni-gym evaluate --score --env OmniPathFollow-Custom-v0
--env-kwargs '{"model": ...}'`` scores a policy on it.
"""

from __future__ import annotations

import argparse
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

import numpy as np  # noqa: E402
from baselines import CONDITIONS, conditions  # noqa: E402
from tqdm import tqdm  # noqa: E402

from agents.normalised_score import FULL_ANCHOR, NO_INTERVAL, NO_SCORE, ZERO_ANCHOR, score_episodes  # noqa: E402
from agents.oracle import ORACLE, SENSOR_ORACLE, oracle_config  # noqa: E402
from agents.policies import POLICY_NAMES  # noqa: E402
from agents.rollout import Episode  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.parallel import backend_from_options, parallel_map  # noqa: E402
from omni_gym.record_paths import record_args

MECANUM = "OmniPathFollow-Mecanum-v0"
ENV_IDS = ("OmniPathFollow-WilliamsPaper-v0", "OmniPathFollow-Williams-v1", "OmniPathFollow-Phunopas-v0", MECANUM)
RANDOM, TRUE_STATE = "random", "true-state law (k = 2/s)"
SCRIPTED = (RANDOM, *POLICY_NAMES, TRUE_STATE, ORACLE, SENSOR_ORACLE)


class RandomPolicy:
    """Uniform random actions in [−1, 1] for N robots; the Generator is seeded by the batch's seeds."""

    def __init__(self, vec_env, seeds: tuple[int, ...]) -> None:
        self.shape = vec_env.action_space.shape
        self.rng = np.random.default_rng(list(seeds))

    def reset(self, obs, mask=None) -> None:
        """Nothing to reset."""

    def act(self, obs) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, self.shape)


@dataclass(frozen=True)
class Cell:
    env_id: str
    policy: str
    cond: str
    seeds: tuple[int, ...]
    seconds: float | None = None  # episode length override (quick checks); None: the id's 20 s

    def key(self, seed: int) -> str:
        from rl_vs_baselines import policy_fingerprint

        fp = self.policy if self.policy in SCRIPTED or oracle_config(self.policy) else policy_fingerprint(self.policy)
        return json.dumps([self.env_id, self.policy, fp, self.cond, seed, self.seconds])

    def env_kwargs(self) -> dict:
        short = {} if self.seconds is None else {"episode_seconds": self.seconds}
        return {**conditions(self.env_id)[self.cond], **short}


def run_cell(cell: Cell) -> tuple[Cell, list[Episode]]:
    """The cell's episodes, all robots at once."""
    from agents.vector_rollout import make_vector_env, run_episodes_vector

    kw = cell.env_kwargs()
    n = len(cell.seeds)
    oracle = oracle_config(cell.policy)
    if oracle is not None:
        from agents.oracle import MPPIOracle

        venv = make_vector_env(cell.env_id, n, kw, obs_mode="sensors" if oracle.state == "ekf" else "state")
        policy = MPPIOracle(venv, oracle)
    elif cell.policy == TRUE_STATE:
        from agents.feedback_law import TrueStateFeedback

        venv = make_vector_env(cell.env_id, n, kw, obs_mode="state")
        policy = TrueStateFeedback(venv)
    elif cell.policy in SCRIPTED:
        from agents.batched.policies import make_vector_policy

        venv = make_vector_env(cell.env_id, n, kw)
        policy = RandomPolicy(venv, cell.seeds) if cell.policy == RANDOM else make_vector_policy(cell.policy, venv)
    else:
        from agents.sb3_policy import build_vector

        venv, policy = build_vector(cell.policy, n, cell.env_id, kw)
    try:
        return cell, run_episodes_vector(venv, policy, cell.seeds)
    finally:
        venv.close()


def run_all(cells: list[Cell], workers: int, cache: Path | None) -> dict:
    """Episodes per (id, policy, condition), sorted by seed; cached episodes reused."""
    stored = json.loads(cache.read_text()) if cache is not None and cache.is_file() else {}
    out: dict = {}
    todo = []
    for c in cells:
        have = [Episode(**stored[c.key(s)]) for s in c.seeds if c.key(s) in stored]
        out[(c.env_id, c.policy, c.cond)] = have
        missing = tuple(s for s in c.seeds if c.key(s) not in stored)
        if missing:
            todo.append(Cell(c.env_id, c.policy, c.cond, missing, c.seconds))
    bar = tqdm(total=len(todo), desc="cells", file=sys.stderr)

    def keep(c: Cell, eps: list[Episode]) -> None:
        out[(c.env_id, c.policy, c.cond)].extend(eps)
        for e in eps:
            stored[c.key(e.seed)] = e.metrics()
        if cache is not None:  # after every cell: an interrupted run keeps what it finished
            write_text_atomic(cache, json.dumps(stored))
        bar.update(1)

    try:
        parallel_map(run_cell, todo, backend_from_options(workers, None), on_done=lambda _i, r: keep(*r))
    finally:
        bar.close()
    return {k: sorted(v, key=lambda e: e.seed) for k, v in out.items()}


def label(policy: str, metas: dict) -> str:
    if policy in metas:
        name = Path(policy).name
        return f"{name} (privileged)" if metas[policy].get("obs_mode") == "state" else name
    return f"{policy} (privileged)" if policy in (TRUE_STATE, ORACLE) else policy


def cell_text(eps: list[Episode], o: list[Episode], e: list[Episode]) -> str:
    s = score_episodes(*([x.tracking_rmse for x in group] for group in (eps, o, e)))
    ci = "" if s.ci95 is None else f" [{s.ci95[0]:.0f}, {s.ci95[1]:.0f}]"
    ci = ci if s.ci_note is None else " (interval not defined †)"  # † explained under the table
    lost = sum(x.terminated for x in eps)
    return (f"{s.score + 0.0:.0f}{ci}".replace("-", "−") + (f", {lost} lost" if lost else "")
            + (" ‡" if s.degenerate else ""))


def write_markdown(path: Path, command: str, env_ids: list[str], policies: dict, eps: dict, metas: dict,
                   episodes: int, seed: int, elapsed: float) -> None:
    conds = list(CONDITIONS)
    lines = ["# Normalised tracking score: 0 = open-loop, 100 = ekf-pid", "", "```", command, "```", "",
             f"score = 100·(RMSE_open − RMSE_policy)/(RMSE_open − RMSE_ekfpid) from the mean tracking RMSE of "
             f"{episodes} paired held-out episodes per cell (seeds {seed}–{seed + episodes - 1}; every policy, the "
             "anchors included, on the same seeds). Above 100: tracks better than ekf-pid; below 0: worse than "
             "driving the reference open loop. [95 % paired-bootstrap interval over seeds]; 'lost': episodes "
             "ended early (their RMSE is over the steps they ran, so a lost episode's score is flattering). "
             "Privileged policies read the true state (not robot controllers). Any policy: `omni-gym evaluate "
             "--policy P --env ID --episodes 50 --env-kwargs COND --score` (single environments, same episodes). "
             f"Wall time of this run {elapsed / 60:.1f} min (episodes reused from `--cache` not counted). "
             f"†: interval not defined: {NO_INTERVAL}; or {NO_SCORE}.", "",
             "Conditions: " + "; ".join(f"{c}: `{json.dumps(CONDITIONS[c])}`" for c in conds) + ". On the mecanum "
             "id every condition uses `initial` friction (mecanum wheels have no roller-gap model): "
             + "; ".join(f"{c}: `{json.dumps(conditions(MECANUM)[c])}`" for c in conds) + ".", ""]
    for env_id in env_ids:
        lines += [f"## {env_id}", "", "| policy | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
        anchors = {c: (eps[(env_id, ZERO_ANCHOR, c)], eps[(env_id, FULL_ANCHOR, c)]) for c in conds}
        for p in policies[env_id]:
            if all((env_id, p, c) in eps for c in conds):
                lines.append(f"| {label(p, metas)} | "
                             + " | ".join(cell_text(eps[(env_id, p, c)], *anchors[c]) for c in conds) + " |")
        lines.append("| *anchors: mean tracking RMSE open-loop / ekf-pid [m]* | "
                     + " | ".join(f"{np.mean([x.tracking_rmse for x in anchors[c][0]]):.4f} / "
                                  f"{np.mean([x.tracking_rmse for x in anchors[c][1]]):.4f}" for c in conds) + " |")
        lines.append("")
    write_text_atomic(path, "\n".join(lines))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", nargs="+", default=None, help="ids (default: every registered one of " +
                    ", ".join(ENV_IDS) + ")")
    ap.add_argument("--models", nargs="*", default=None, help="model directories (default agents/models/*)")
    ap.add_argument("--policies", nargs="*", default=list(SCRIPTED), help="scripted policies (default all)")
    ap.add_argument("--episodes", type=int, default=50, help="paired episodes per cell (default 50)")
    ap.add_argument("--seed", type=int, default=10_000, help="first seed (default 10000)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--cache", default=None, help="JSON file of episode metrics to reuse and extend")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    ap.add_argument("--episode-seconds", type=float, default=None,
                    help="shorter episodes for a quick check (default: the ids' 20 s; the table uses 20 s)")
    args = ap.parse_args(argv)
    import gymnasium as gym

    import omni_gym  # noqa: F401  (registers the ids)
    from agents.gated import is_gated
    from agents.sb3_policy import read_meta

    env_ids = args.envs or [e for e in ENV_IDS if e in gym.registry]
    bad = [p for p in args.policies if p not in SCRIPTED]
    if args.episodes < 2 or args.seed < 0 or args.workers < 1 or bad:
        ap.error(f"--episodes must be >= 2, --seed >= 0, --workers >= 1 and --policies among {', '.join(SCRIPTED)}")
    # The gated controllers (ekf-pid, then a student) have their own table: benchmarks/gated.py.
    models = args.models if args.models is not None else sorted(str(p) for p in Path("agents/models").iterdir()
                                                                if (p / "meta.json").is_file() and not is_gated(p))
    try:
        metas = {m: read_meta(m) for m in models}
    except ValueError as exc:
        ap.error(str(exc))
    policies = {e: [*(p for p in SCRIPTED if p in args.policies or p in (ZERO_ANCHOR, FULL_ANCHOR)),
                    *(m for m in models if metas[m]["env_id"] == e)] for e in env_ids}
    seeds = tuple(range(args.seed, args.seed + args.episodes))
    cells = [Cell(e, p, c, seeds, args.episode_seconds) for e in env_ids for c in CONDITIONS for p in policies[e]]
    recorded = record_args(argv if argv is not None else sys.argv[1:])
    command = "python benchmarks/normalised_score.py " + shlex.join(recorded)
    t0 = time.time()
    try:
        eps = run_all(cells, args.workers, None if args.cache is None else Path(args.cache))
    except ValueError as exc:
        print(f"normalised_score.py: error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out) / "normalised_score.md"
    write_markdown(out, command.strip(), env_ids, policies, eps, metas, args.episodes, args.seed, time.time() - t0)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
