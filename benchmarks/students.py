"""The distilled students against ekf-pid, ekf-pid-traction and the oracle bounds, on the held-out episodes.

    python benchmarks/students.py [--students DIR ...] [--episodes 50] [--seed 10000] [--workers 2]
                                 [--cache FILE] [--out benchmarks/results]

Per student (a model directory written by ``python -m agents.distillation``; default the committed
``agents/models/dagger-student-*``) on the id it was trained on, the three conditions of
``benchmarks/baselines.py`` on the normalised score's held-out seeds (10000…, paired: every policy on the same
episodes): mean tracking RMSE [mm] of ekf-pid, ekf-pid-traction, the sensor-only oracle (MPPI from the EKF's
estimate), the privileged oracle and the student; student ÷ ekf-pid, ÷ ekf-pid-traction and ÷ the sensor-only
oracle with 95 % paired-bootstrap intervals over seeds; the share of episodes in which the student beats
ekf-pid(-traction); and the goals (module constant :data:`GOALS`). Episodes are those of
``benchmarks/normalised_score.py`` (its ``Cell``, cache and code path), so a shared ``--cache`` reuses them.
Writes ``students.md``, ``students.json`` and ``students.png``.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import shlex
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from baselines import CONDITIONS  # noqa: E402
from normalised_score import Cell, run_all  # noqa: E402
from oracle import ratio_bars, ratio_text  # noqa: E402

from agents.oracle import ORACLE, SENSOR_ORACLE  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args

CONDS = tuple(CONDITIONS)
BASELINES = ("ekf-pid", "ekf-pid-traction")
# The goal cells: (id, condition) -> (baseline, the ratio to reach, the least share of better episodes).
GOALS = {("OmniPathFollow-Phunopas-v0", "slip + lift-off"): ("ekf-pid-traction", 0.8, 0.6),
         ("OmniPathFollow-Mecanum-v0", "slip + lift-off"): ("ekf-pid-traction", 0.8, 0.6),
         ("OmniPathFollow-Williams-v1", "slip"): ("ekf-pid", 0.5, 0.6)}
BOUND_SLACK = 1.1  # where the sensor-only oracle cannot reach the goal: the student within 1.1x of it
DEFAULT_STUDENTS = "agents/models/dagger-student-*"


def cells_for(metas: dict, seeds, seconds) -> list[Cell]:
    """Every policy's cells on each student's id (``metas``: student folder -> its meta.json)."""
    cells = []
    for s, meta in metas.items():
        e = meta["env_id"]
        for c in CONDS:
            cells += [Cell(e, p, c, seeds, seconds) for p in (*BASELINES, SENSOR_ORACLE, ORACLE, s)]
    return cells


def goal_verdict(row: dict, goal: tuple[str, float, float]) -> dict:
    """Whether the student meets the goal of its cell: ratio and interval below the target and better in
    enough episodes; or, where the sensor-only oracle's own ratio is above the target, within
    :data:`BOUND_SLACK` of that bound."""
    base, target, share = goal
    r = row["ratios"][f"student / {base}"]
    bound = row["ratios"][f"{SENSOR_ORACLE} / {base}"]["ratio"]
    better = row["better"][base]
    if bound <= target:
        met = r["ratio"] <= target and better >= share
        text = (f"student ÷ {base} {r['ratio']:.2f} (goal ≤ {target}), better in {100 * better:.0f} % "
                f"(goal ≥ {100 * share:.0f} %)")
    else:
        s = row["ratios"][f"student / {SENSOR_ORACLE}"]
        met = s["ratio"] <= BOUND_SLACK
        text = (f"the sensor-only oracle reaches only {bound:.2f}× {base}: student ÷ sensor-only oracle "
                f"{s['ratio']:.2f} (goal ≤ {BOUND_SLACK})")
    return {"met": bool(met), "text": text}


def summarise(eps: dict, metas: dict) -> dict:
    rng = np.random.default_rng(0)
    rows = []
    for s, meta in metas.items():
        e = meta["env_id"]
        for c in CONDS:
            r = {p: np.array([x.tracking_rmse for x in eps[(e, p, c)]]) for p in (*BASELINES, SENSOR_ORACLE,
                                                                                  ORACLE, s)}
            row = {"student": Path(s).name, "env_id": e, "condition": c,
                   "rmse_mm": {("student" if p == s else p): 1e3 * float(v.mean()) for p, v in r.items()},
                   "lost": int(sum(x.terminated for x in eps[(e, s, c)])),
                   "better": {b: float(np.mean(r[s] < r[b])) for b in BASELINES}, "text": {}, "ratios": {}}
            for num, den in ((s, "ekf-pid"), (s, "ekf-pid-traction"), (s, SENSOR_ORACLE), (s, ORACLE),
                             (SENSOR_ORACLE, "ekf-pid"), (SENSOR_ORACLE, "ekf-pid-traction"), (ORACLE, "ekf-pid")):
                key = f"{'student' if num == s else num} / {den}"
                row["text"][key], row["ratios"][key] = ratio_text(r[num], r[den], rng)
            if (e, c) in GOALS:
                row["goal"] = goal_verdict(row, GOALS[(e, c)])
            rows.append(row)
    return {"rows": rows}


def markdown(summary: dict, command: str, seeds, wall_s: float, metas: dict) -> str:
    lines = ["# Sensor-only students distilled from the MPPI oracle", "", "```", command, "```", "",
             f"Mean tracking RMSE [mm] over {len(seeds)} paired held-out episodes per cell (seeds {seeds[0]}–"
             f"{seeds[-1]}, the normalised score's; every policy on the same episodes). Students: DAgger on the "
             "privileged oracle's labels (`agents/distillation.py`, docs/agents.md \"Teacher → student\"); they read "
             "the EKF features only. [95 % paired bootstrap over seeds]; 'better': share of episodes in which the "
             f"student's RMSE is below the baseline's. Wall time {wall_s / 60:.1f} min (cached episodes not "
             "counted).", "",
             "| id | condition | ekf-pid | ekf-pid-traction | sensor-only oracle | oracle | student "
             "| student ÷ ekf-pid | student ÷ ekf-pid-traction | student ÷ sensor-only oracle "
             "| better than ekf-pid / -traction | oracle ÷ ekf-pid |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        m = r["rmse_mm"]
        lost = f" ({r['lost']} lost)" if r["lost"] else ""
        lines.append(f"| {r['env_id'].removeprefix('OmniPathFollow-')} | {r['condition']} | {m['ekf-pid']:.1f} | "
                     f"{m['ekf-pid-traction']:.1f} | {m[SENSOR_ORACLE]:.1f} | {m[ORACLE]:.1f} | "
                     f"{m['student']:.1f}{lost} | {r['text']['student / ekf-pid']} | "
                     f"{r['text']['student / ekf-pid-traction']} | {r['text'][f'student / {SENSOR_ORACLE}']} | "
                     f"{100 * r['better']['ekf-pid']:.0f} % / {100 * r['better']['ekf-pid-traction']:.0f} % | "
                     f"{r['text'][f'{ORACLE} / ekf-pid']} |")
    lines += ["", "## Goals", ""]
    for r in summary["rows"]:
        if "goal" in r:
            g = r["goal"]
            lines.append(f"- {r['env_id']}, {r['condition']}: **{'met' if g['met'] else 'missed'}**: {g['text']}")
    lines += ["", "## Training", "", "| student | id | samples | rounds | best round | validation ÷ ekf-pid "
              "(episodes) | wall time [min] |", "|---|---|---|---|---|---|---|"]
    for name, meta in metas.items():
        d = meta["distillation"]
        lines.append(f"| {Path(name).name} | {meta['env_id']} | {d['rounds'][-1]['samples']:,} | "
                     f"{len(d['rounds']) - 1} | {d['best_round']} | {d['best_val_ratio']:.3f} "
                     f"({d['validation_episodes']}) | {meta['wall_time_s'] / 60:.1f} |")
    return "\n".join(lines) + "\n"


def plot(summary: dict, path: Path) -> None:
    ratio_bars(summary["rows"], [("student ÷ ekf-pid", "student / ekf-pid"),
                                 ("student ÷ ekf-pid-traction", "student / ekf-pid-traction"),
                                 ("student ÷ sensor-only oracle", f"student / {SENSOR_ORACLE}"),
                                 ("sensor-only oracle ÷ ekf-pid", f"{SENSOR_ORACLE} / ekf-pid")],
               "DAgger students against the baselines and the sensor-only oracle (95 % paired bootstrap)",
               "mean tracking RMSE ratio\n(below 1: the numerator tracks better)", path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--students", nargs="+", default=None, help=f"model directories (default {DEFAULT_STUDENTS})")
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=10_000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--episode-seconds", type=float, default=None, help="shorter episodes for a quick check")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    students = args.students or sorted(glob.glob(DEFAULT_STUDENTS))
    missing = [s for s in students if not (Path(s) / "meta.json").is_file()]
    if not students or missing:
        ap.error(f"no student model directory at {missing[0] if missing else DEFAULT_STUDENTS}")
    if args.episodes < 2 or args.workers < 1:
        ap.error("need --episodes >= 2 and --workers >= 1")
    seeds = tuple(range(args.seed, args.seed + args.episodes))
    command = "python benchmarks/students.py " + shlex.join(record_args(argv if argv is not None else sys.argv[1:]))
    t0 = time.time()
    metas = {s: json.loads((Path(s) / "meta.json").read_text()) for s in students}
    eps = run_all(cells_for(metas, seeds, args.episode_seconds), args.workers, args.cache)
    summary = summarise(eps, metas)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "students.md", markdown(summary, command, seeds, time.time() - t0, metas))
    write_text_atomic(args.out / "students.json", json.dumps({"command": command, **summary}, indent=1) + "\n")
    plot(summary, args.out / "students.png")
    print(f"wrote {args.out / 'students.md'}, .json, .png", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
