"""The gated controllers (ekf-pid, then the student once ekf-pid's estimate leaves the path): the threshold chosen on
validation episodes, then every condition on the held-out ones against ekf-pid, ekf-pid-traction and the student.

    python benchmarks/gated.py --out benchmarks/results            # about 10 min on 2 cores
    python benchmarks/gated.py --episodes 4 --validation 4 --out /tmp/g  # a quick look

Per drivable id with a committed student (``agents/models/dagger-student-*``) and the three conditions of
``benchmarks/baselines.py`` (no slip, slip, slip + lift-off):

1. **Selection** (validation seeds 5000…, never the held-out ones): each threshold of :data:`THRESHOLDS` [m]
   gated on the student; the chosen one is the *smallest threshold at which the gated controller stays within
   1.02× ekf-pid on the grip floor of every id* (one threshold for all robots: what holds on three robots is
   likelier to hold on a fourth). The gated model directories (``agents/models/gated-student-*``) carry it.
2. **Held-out** (seeds 10000…, the normalised score's; every policy on the same episodes): mean tracking RMSE
   [mm] of ekf-pid, ekf-pid-traction, the student and the gated controller; gated ÷ each, with 95 % paired
   bootstrap intervals over seeds, the share of episodes better than ekf-pid, and the share in which the
   student drove.

Episodes run as the robots of one native vector env per (id, policy, condition) (``agents.vector_rollout``).
Writes ``gated.md`` and ``gated.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import numpy as np  # noqa: E402
from baselines import conditions  # noqa: E402

from agents.evaluate import paired_bootstrap_ratio  # noqa: E402
from agents.gated import VectorGatedPolicy  # noqa: E402
from agents.vector_rollout import make_vector_env, run_episodes_vector  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args  # noqa: E402

STUDENTS = {"OmniPathFollow-Williams-v1": "dagger-student-williams",
            "OmniPathFollow-Phunopas-v0": "dagger-student-phunopas",
            "OmniPathFollow-Mecanum-v0": "dagger-student-mecanum"}
MODELS = ROOT / "agents" / "models"
THRESHOLDS = (0.002, 0.003, 0.005)  # [m]: 2-5× ekf-pid's estimated error on grip (about 1 mm)
GRIP_LIMIT = 1.02  # the gated controller on grip: at most this × ekf-pid (the goal it is selected for)
SCRIPTED = ("ekf-pid", "ekf-pid-traction")


def run(env_id: str, cond: str, policy: str, seeds: list[int]) -> dict:
    """Per-episode tracking RMSE [m] (and, gated, whether the student drove) of one policy on one condition.
    ``policy``: a scripted name, ``student`` or ``gated:G`` (G the threshold [m])."""
    kw = conditions(env_id)[cond]
    n = len(seeds)
    if policy in SCRIPTED:
        from agents.batched.policies import make_vector_policy

        venv = make_vector_env(env_id, n, kw)
        pol = make_vector_policy(policy, venv)
    else:
        from agents.sb3_policy import build_vector

        venv, pol = build_vector(MODELS / STUDENTS[env_id], n, env_id, kw)
        if policy.startswith("gated:"):
            pol = VectorGatedPolicy(pol, venv, float(policy.split(":", 1)[1]))
    try:
        driven = np.zeros(n, dtype=bool)
        if isinstance(pol, VectorGatedPolicy):
            act = pol.act

            def watch(obs):  # each robot runs one episode: the latch at its end says whether the student drove
                a = act(obs)
                driven[:] |= pol.gate.latched
                return a

            pol.act = watch
        eps = run_episodes_vector(venv, pol, seeds)
    finally:
        venv.close()
    return {"rmse": [e.tracking_rmse for e in eps], "student_drove": driven.tolist()}


def ratio(num, den, seed: int) -> dict:
    num, den = np.asarray(num), np.asarray(den)
    ci, _ = paired_bootstrap_ratio(num, den, np.random.default_rng(seed))
    return {"ratio": float(num.mean() / den.mean()), "ci95": ci, "better": float(np.mean(num < den))}


def select(val: dict) -> tuple[float | None, list[str]]:
    """The smallest threshold within :data:`GRIP_LIMIT` × ekf-pid on every id's grip floor (None: none is)."""
    lines = ["| id | condition | " + " | ".join(f"gated {1e3 * g:.0f} mm ÷ ekf-pid" for g in THRESHOLDS)
             + " | student ÷ ekf-pid |", "|---|---|" + "---|" * (len(THRESHOLDS) + 1)]
    for (env_id, cond), r in val.items():
        base = np.mean(r["ekf-pid"]["rmse"])
        cells = [f"{np.mean(r[f'gated:{g}']['rmse']) / base:.2f}" for g in THRESHOLDS]
        lines.append(f"| {env_id} | {cond} | {' | '.join(cells)} | {np.mean(r['student']['rmse']) / base:.2f} |")
    for g in THRESHOLDS:
        if all(np.mean(r[f"gated:{g}"]["rmse"]) <= GRIP_LIMIT * np.mean(r["ekf-pid"]["rmse"])
               for (_, cond), r in val.items() if cond == "no slip"):
            return g, lines
    return None, lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=50, help="held-out episodes per cell (seeds 10000…)")
    ap.add_argument("--validation", type=int, default=24, help="validation episodes per cell (seeds 5000…)")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    val_seeds = list(range(5000, 5000 + args.validation))
    val = {}
    for env_id in STUDENTS:
        for cond in conditions(env_id):
            val[(env_id, cond)] = {p: run(env_id, cond, p, val_seeds)
                                   for p in ("ekf-pid", "student", *(f"gated:{g}" for g in THRESHOLDS))}
            print(f"gated: validation {env_id} {cond} done, {(time.perf_counter() - t0) / 60:.1f} min",
                  file=sys.stderr, flush=True)
    chosen, val_lines = select(val)
    if chosen is None:
        raise SystemExit(f"gated.py: no threshold keeps the grip floor within {GRIP_LIMIT}× ekf-pid on every id")
    seeds = list(range(10000, 10000 + args.episodes))
    rows = []
    for env_id in STUDENTS:
        for cond in conditions(env_id):
            r = {p: run(env_id, cond, p, seeds) for p in (*SCRIPTED, "student", f"gated:{chosen}")}
            g = r[f"gated:{chosen}"]
            rows.append({"env_id": env_id, "condition": cond,
                         "rmse_mm": {p: 1e3 * float(np.mean(v["rmse"])) for p, v in r.items()},
                         "gated_over": {p: ratio(g["rmse"], r[p]["rmse"], 1 + len(rows)) for p in
                                        (*SCRIPTED, "student")},
                         "student_drove": float(np.mean(g["student_drove"]))})
            print(f"gated: held-out {env_id} {cond} done, {(time.perf_counter() - t0) / 60:.1f} min",
                  file=sys.stderr, flush=True)
    wall = time.perf_counter() - t0
    command = "python benchmarks/gated.py " + " ".join(record_args(argv if argv is not None else sys.argv[1:]))
    text = markdown(rows, val_lines, chosen, command, args, wall)
    write_text_atomic(args.out / "gated.md", text)
    write_text_atomic(args.out / "gated.json", json.dumps({"threshold_m": chosen, "rows": rows}, indent=1) + "\n")
    print(text)
    return 0


def _r(x: dict) -> str:
    return f"{x['ratio']:.2f} [{x['ci95'][0]:.2f}, {x['ci95'][1]:.2f}]"


# The goals these controllers are measured against: (condition, baseline, the largest ratio), per id.
GOALS = {"no slip": ("ekf-pid", {"*": 1.02}),
         "slip": ("ekf-pid", {"OmniPathFollow-Williams-v1": 0.4, "*": 0.7}),
         "slip + lift-off": ("ekf-pid-traction", {"*": 0.7})}


def markdown(rows: list[dict], val_lines: list[str], chosen: float, command: str, args, wall: float) -> str:
    lines = ["# Gated controllers: ekf-pid, then the student once ekf-pid's estimate leaves the path", "",
             f"`{command}`", "",
             "The gate (`agents/gated.py`): the EKF's estimated tracking error, averaged over about 0.5 s; the "
             "student drives for the rest of the episode once the average exceeds the threshold. Mean tracking "
             f"RMSE [mm] over {args.episodes} paired held-out episodes per cell (seeds 10000…); ratios with 95 % "
             "paired bootstrap intervals over seeds; *better*: the share of episodes with a smaller error than "
             "ekf-pid; *student drove*: the share of episodes in which the gate opened.", "",
             f"**Threshold {1e3 * chosen:.0f} mm**, chosen on {args.validation} validation episodes per cell (seeds "
             f"5000…): the smallest of {', '.join(f'{1e3 * g:.0f}' for g in THRESHOLDS)} mm within {GRIP_LIMIT}× "
             "ekf-pid on every grip floor.", "",
             "| id | condition | ekf-pid | ekf-pid-traction | student | gated | gated ÷ ekf-pid | better | "
             "gated ÷ ekf-pid-traction | gated ÷ student | student drove | goal |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        m, o = r["rmse_mm"], r["gated_over"]
        base, limits = GOALS[r["condition"]]
        limit = limits.get(r["env_id"], limits["*"])
        value = o[base]["ratio"]
        ok = value <= limit and (r["condition"] != "no slip" or o[base]["ci95"][1] <= 1.05)
        goal = f"÷ {base} ≤ {limit}" + (" (upper end ≤ 1.05)" if r["condition"] == "no slip" else "")
        lines.append(f"| {r['env_id']} | {r['condition']} | {m['ekf-pid']:.1f} | {m['ekf-pid-traction']:.1f} | "
                     f"{m['student']:.1f} | {m[f'gated:{chosen}']:.1f} | {_r(o['ekf-pid'])} | "
                     f"{o['ekf-pid']['better']:.0%} | {_r(o['ekf-pid-traction'])} | {_r(o['student'])} | "
                     f"{r['student_drove']:.0%} | {goal}: {'**met**' if ok else '**missed**'} |")
    lines += ["", "## Selection (validation episodes)", "", *val_lines, "",
              f"Wall time {wall / 60:.1f} min."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
