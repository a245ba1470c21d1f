"""The model-predictive oracle (``agents.oracle``) against the scripted controllers: how well can a robot track?

    python benchmarks/oracle.py [--envs ID ...] [--episodes 50] [--seed 10000] [--sweep-episodes 10]
                                [--workers 2] [--cache FILE] [--episode-seconds S] --out benchmarks/results

Per drivable id and condition (the three of ``benchmarks/baselines.py``), on the same held-out seeds (10000…,
paired: every policy runs the same references, floors, lift-off schedules and sensor noise), the mean
tracking RMSE [mm] of ``ekf-pid``, ``ekf-pid-traction``, the true-state law (k = 2/s), the privileged oracle
(MPPI with the default :class:`agents.oracle.OracleConfig`: 0.5 s horizon, 32 samples, a plan every 5 control
steps) and, in the cells of the students' goals (Phunopas and Mecanum under slip + lift-off, Williams-v1 under
slip), the sensor-only oracle (the same planner from the EKF's estimate). Ratios of mean RMSE with 95 %
paired-bootstrap intervals over seeds, the share of episodes in which the oracle beats ``ekf-pid``, and the
oracle's compute per control step. A sweep of horizon and sample count on Phunopas under slip + lift-off
(``--sweep-episodes`` seeds, the first of the held-out ones). Writes ``oracle.md``, ``oracle.json`` and
``oracle.png`` into ``--out``. The episodes are ``benchmarks/normalised_score.py``'s cells (the same keys): with one
``--cache`` file for both, an interrupted run resumes and the normalised score reuses every episode run here.
"""

from __future__ import annotations

import argparse
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
from normalised_score import TRUE_STATE, Cell, run_all  # noqa: E402

from agents.evaluate import paired_bootstrap_ratio  # noqa: E402
from agents.oracle import NOISY_ORACLE, ORACLE, SENSOR_ORACLE, OracleConfig, oracle_name  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args

ENV_IDS = ("OmniPathFollow-WilliamsPaper-v0", "OmniPathFollow-Williams-v1", "OmniPathFollow-Phunopas-v0",
           "OmniPathFollow-Mecanum-v0")
CONDS = tuple(CONDITIONS)
LAW = TRUE_STATE
SCRIPTED = ("ekf-pid", "ekf-pid-traction")
# The students' goal cells: where the sensor-only oracle is the bound students are judged against.
GOAL_CELLS = {("OmniPathFollow-Phunopas-v0", "slip + lift-off"): "ekf-pid-traction",
              ("OmniPathFollow-Mecanum-v0", "slip + lift-off"): "ekf-pid-traction",
              ("OmniPathFollow-Williams-v1", "slip"): "ekf-pid"}
SWEEP_CELL = ("OmniPathFollow-Phunopas-v0", "slip + lift-off")
SWEEP = [OracleConfig(horizon=h) for h in (0.25, 1.0)] + [OracleConfig(samples=k) for k in (8, 128)]
TIMING_STEPS = 100  # control steps of one robot timed per oracle (after 10 of warm-up)


def cells_for(env_ids, seeds, sweep_seeds, seconds) -> list[Cell]:
    """normalised_score's cells (same keys: one ``--cache`` file serves both benchmarks)."""
    cells = []
    for e in env_ids:
        for c in CONDS:
            for p in (*SCRIPTED, LAW, ORACLE):
                cells.append(Cell(e, p, c, seeds, seconds))
            if (e, c) in GOAL_CELLS:
                cells += [Cell(e, NOISY_ORACLE, c, seeds, seconds), Cell(e, SENSOR_ORACLE, c, seeds, seconds)]
    if SWEEP_CELL[0] in env_ids:
        e, c = SWEEP_CELL
        cells += [Cell(e, oracle_name(cfg), c, sweep_seeds, seconds) for cfg in SWEEP]
    return cells


def step_time(env_id: str, cond: str, config: OracleConfig, seconds: float | None) -> float:
    """Wall time [ms] per control step of the oracle driving one robot (a plan every ``replan`` steps spread
    over them), as on a robot: mean over :data:`TIMING_STEPS` steps after 10 of warm-up, seed 10000."""
    from baselines import conditions

    from agents.oracle import MPPIOracle
    from agents.vector_rollout import make_vector_env

    kw = dict(conditions(env_id)[cond])
    if seconds is not None:
        kw["episode_seconds"] = max(seconds, 1.5)
    env = make_vector_env(env_id, 1, kw, obs_mode="sensors" if config.state == "ekf" else "state")
    obs, _ = env.reset(seed=10_000)
    oracle = MPPIOracle(env, config)
    oracle.reset(obs)
    for k in range(10 + TIMING_STEPS):
        if k == 10:
            t0 = time.perf_counter()
        obs, *_ = env.step(oracle.act(obs))
    env.close()
    return 1e3 * (time.perf_counter() - t0) / TIMING_STEPS


def ratio_text(num, den, rng) -> tuple[str, dict]:
    num, den = np.asarray(num), np.asarray(den)
    ci, _ = paired_bootstrap_ratio(num, den, rng)
    r = float(num.mean() / den.mean())
    return f"{r:.2f} [{ci[0]:.2f}, {ci[1]:.2f}]", {"ratio": r, "ci95": ci}


def summarise(eps: dict, env_ids, seeds, sweep_seeds, seconds) -> dict:
    rng = np.random.default_rng(0)
    rmse = {k: np.array([e.tracking_rmse for e in v]) for k, v in eps.items()}
    lost = {k: int(sum(e.terminated for e in v)) for k, v in eps.items()}
    rows = []
    for e in env_ids:
        for c in CONDS:
            names = [*SCRIPTED, LAW, ORACLE] + ([NOISY_ORACLE, SENSOR_ORACLE] if (e, c) in GOAL_CELLS else [])
            r = {p: rmse[(e, p, c)] for p in names}
            row = {"env_id": e, "condition": c, "rmse_mm": {p: 1e3 * float(v.mean()) for p, v in r.items()},
                   "lost": {p: lost[(e, p, c)] for p in names},
                   "oracle_better_than_ekf_pid": float(np.mean(r[ORACLE] < r["ekf-pid"])),
                   "ms_per_step": step_time(e, c, OracleConfig(), seconds), "text": {}, "ratios": {}}
            for num, den in ((ORACLE, "ekf-pid"), (ORACLE, LAW), (ORACLE, "ekf-pid-traction"),
                             (NOISY_ORACLE, ORACLE), (SENSOR_ORACLE, "ekf-pid"), (SENSOR_ORACLE, "ekf-pid-traction"),
                             (SENSOR_ORACLE, ORACLE), (SENSOR_ORACLE, NOISY_ORACLE)):
                if num in r:
                    row["text"][f"{num} / {den}"], row["ratios"][f"{num} / {den}"] = ratio_text(r[num], r[den], rng)
            rows.append(row)
    sweep = []
    if SWEEP_CELL[0] in env_ids:
        e, c = SWEEP_CELL
        n = len(sweep_seeds)
        ekf = rmse[(e, "ekf-pid", c)][:n]  # the first seeds of the table's cells: the sweep's own
        for cfg in [OracleConfig(), *SWEEP]:
            res = rmse[(e, ORACLE, c)][:n] if cfg == OracleConfig() else rmse[(e, oracle_name(cfg), c)]
            text, num = ratio_text(res, ekf, rng)
            sweep.append({"horizon": cfg.horizon, "samples": cfg.samples, "rmse_mm": 1e3 * float(res.mean()),
                          "oracle / ekf-pid": text, "ratio": num, "ms_per_step": step_time(e, c, cfg, seconds)})
    return {"rows": rows, "sweep": sweep}


def markdown(summary: dict, command: str, seeds, wall_s: float, sweep_n: int) -> str:
    cfg = OracleConfig()
    lines = ["# The model-predictive oracle: how well can a slipping robot track?", "", "```", command, "```", "",
             f"Mean tracking RMSE [mm] over {len(seeds)} paired held-out episodes per cell (seeds {seeds[0]}–"
             f"{seeds[-1]}; every policy on the same episodes). Oracle: MPPI planning with the simulator itself "
             f"from the true state (`agents/oracle.py`; horizon {cfg.horizon:g} s, {cfg.samples} samples, a plan every "
             f"{cfg.replan} control steps, rollouts = the true-state law plus smooth corrections). Ratios: of mean "
             "RMSE, [95 % paired bootstrap over seeds]. 'better': share of "
             "episodes in which the oracle's RMSE is below ekf-pid's. Compute: wall time per control step of the "
             f"oracle driving one robot (as on a robot; mean over {TIMING_STEPS} steps, a plan every "
             f"{OracleConfig().replan} of them; one core of this 2-core machine). Lost episodes (tracking error beyond "
             "`lost_distance` or a wall) end early; their RMSE is over the steps they ran.", ""]
    lines += ["| id | condition | ekf-pid | ekf-pid-traction | law | oracle | oracle ÷ ekf-pid | oracle ÷ law | "
              "better | lost (ekf-pid / oracle) | oracle ms/step |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        m, t = r["rmse_mm"], r["text"]
        lines.append(f"| {r['env_id'].removeprefix('OmniPathFollow-')} | {r['condition']} | {m['ekf-pid']:.1f} | "
                     f"{m['ekf-pid-traction']:.1f} | {m[LAW]:.1f} | {m[ORACLE]:.1f} | {t[ORACLE + ' / ekf-pid']} | "
                     f"{t[ORACLE + ' / ' + LAW]} | {100 * r['oracle_better_than_ekf_pid']:.0f} % | "
                     f"{r['lost']['ekf-pid']} / {r['lost'][ORACLE]} | {r['ms_per_step']:.1f} |")
    lines += ["", "## What estimation costs and what control costs (the goal cells of the students)", "",
              "The same planner from three start states: the true one (oracle), the true one plus the sensors' "
              "noise at every step (camera σ on the pose, gyro σ on ω), and the EKF's estimate (sensor-only; all "
              "wheels assumed down). The baseline is the scripted controller the students must beat.", "",
              "| id | condition | baseline | baseline [mm] | oracle | true + noise | sensor-only | "
              "sensor-only ÷ baseline | true + noise ÷ oracle | sensor-only ÷ true + noise |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        goal = GOAL_CELLS.get((r["env_id"], r["condition"]))
        if goal is None:
            continue
        m, t = r["rmse_mm"], r["text"]
        lines.append(f"| {r['env_id'].removeprefix('OmniPathFollow-')} | {r['condition']} | {goal} | {m[goal]:.1f} | "
                     f"{m[ORACLE]:.1f} | {m[NOISY_ORACLE]:.1f} | {m[SENSOR_ORACLE]:.1f} | "
                     f"{t[SENSOR_ORACLE + ' / ' + goal]} | {t[NOISY_ORACLE + ' / ' + ORACLE]} | "
                     f"{t[SENSOR_ORACLE + ' / ' + NOISY_ORACLE]} |")
    if summary["sweep"]:
        lines += ["", f"## Horizon and samples ({SWEEP_CELL[0]}, {SWEEP_CELL[1]}, {sweep_n} episodes)", "",
                  "| horizon [s] | samples | RMSE [mm] | oracle ÷ ekf-pid | ms/step |", "|---|---|---|---|---|"]
        for s in summary["sweep"]:
            lines.append(f"| {s['horizon']:g} | {s['samples']} | {s['rmse_mm']:.1f} | {s['oracle / ekf-pid']} | "
                         f"{s['ms_per_step']:.1f} |")
    lines += ["", f"Wall time of this run: {wall_s / 60:.1f} min (cells reused from `--cache` not counted)."]
    return "\n".join(lines) + "\n"


def ratio_bars(rows: list[dict], keys: list[tuple[str, str]], title: str, ylabel: str, path: Path,
               width: float | None = None) -> None:
    """A bar per (legend name, ``row["ratios"]`` key) and row (id and condition on the axis), with its 95 %
    interval; a row without the key has no bar. Written to ``path``."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 4.5))
    labels = [f"{r['env_id'].removeprefix('OmniPathFollow-')}\n{r['condition']}" for r in rows]
    x = np.arange(len(rows))
    w = width or 0.8 / len(keys)
    for k, (name, key) in enumerate(keys):
        vals = [r["ratios"].get(key) for r in rows]
        xs = [xi + (k - (len(keys) - 1) / 2) * w for xi, v in zip(x, vals, strict=True) if v is not None]
        ys = [v["ratio"] for v in vals if v is not None]
        err = np.array([[v["ratio"] - v["ci95"][0], v["ci95"][1] - v["ratio"]] for v in vals if v is not None]).T
        if ys:
            ax.bar(xs, ys, w, yerr=err, capsize=2, label=name)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(x, labels, fontsize=7, rotation=45, ha="right")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot(summary: dict, path: Path) -> None:
    ratio_bars(summary["rows"], [("oracle ÷ ekf-pid", f"{ORACLE} / ekf-pid"), ("oracle ÷ law", f"{ORACLE} / {LAW}"),
                                 ("sensor-only oracle ÷ ekf-pid", f"{SENSOR_ORACLE} / ekf-pid")],
               "The MPPI oracle against ekf-pid and the true-state law (95 % paired-bootstrap intervals)",
               "mean tracking RMSE ratio\n(below 1: the oracle tracks better)", path, width=0.27)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", nargs="+", default=list(ENV_IDS), choices=ENV_IDS)
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=10_000)
    ap.add_argument("--sweep-episodes", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--episode-seconds", type=float, default=None, help="shorter episodes for a quick check")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    if not 2 <= args.sweep_episodes <= args.episodes or args.workers < 1:
        ap.error("need 2 <= --sweep-episodes <= --episodes and --workers >= 1")
    seeds = tuple(range(args.seed, args.seed + args.episodes))
    sweep_seeds = seeds[:args.sweep_episodes]
    cells = cells_for(args.envs, seeds, sweep_seeds, args.episode_seconds)
    command = "python benchmarks/oracle.py " + shlex.join(record_args(argv if argv is not None else sys.argv[1:]))
    t0 = time.time()
    eps = run_all(cells, args.workers, args.cache)
    summary = summarise(eps, args.envs, seeds, sweep_seeds, args.episode_seconds)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "oracle.md", markdown(summary, command, seeds, time.time() - t0, len(sweep_seeds)))
    write_text_atomic(args.out / "oracle.json", json.dumps({"command": command, **summary}, indent=1) + "\n")
    plot(summary, args.out / "oracle.png")
    print(f"wrote {args.out / 'oracle.md'}, .json, .png", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
