"""Does calibrating make a better controller for the robot? The whole chain, on plants the models were not made from.

Each *plant* is a robot the project never fitted: the separately written event integrator in closed loop
(:class:`omni_gym.analysis.closed_loop.SecondGeneratorPlant`) with one hidden effect of random size and
direction: every library effect that moves the robot (``com_offset``, ``wheel_radius``, ``wheel_geometry``,
``motor_lag``, ``kinetic_friction``, ``wheel_liftoff``, ``roller_gap`` on the omni robot, ``mecanum_lateral`` on
the mecanum one), two causes outside the library (a viscous ``drag`` and a floor ``slope``), and nothing. Two
robot types: ``williams2002`` (three omni wheels) and ``optiodom_omni4`` (four mecanum wheels), both on carpet
with the ``initial`` friction model, the nominal model every plant starts from.

Per plant, as a user would:

1. **Log** a few runs of driving (the second generator's open-loop manoeuvres, 8 runs of 6 s: 48 s) and write
   them as a robot's CSV logs (time, tracked pose, wheel encoder angles; no commands, so a motor's lag behind
   its command is invisible, as it is in such logs).
2. ``omni-gym import csv`` → dataset; ``omni-gym calibrate`` → the kinematic calibration (b) (where it refuses,
   there is no (b): the row says so); ``omni-gym gap`` with its defaults → ``gap``'s model (c).
3. **Controllers**: ``ekf-pid`` on ``OmniPathFollow-Custom-v0`` with each model's kinematics: (a) the nominal
   model, (b) the kinematic calibration, (c) ``gap``'s model.
4. **Evaluate** each through ``omni-gym evaluate --plant second-generator`` on the plant (held-out seeds 10000…,
   the same references for every controller) and on its own model (no plant).

Every task is the same for every model: random waypoints at ``ref_speed`` 0.15 m/s turning in place
(:data:`TASK`, with ``ref_traction`` 0 so that no model's friction set reshapes the reference), 10 s each.

Figures per plant: tracking RMSE on the plant for (a), (b), (c); (c) ÷ (a) and (c) ÷ (b) with 95 % paired
bootstrap intervals over seeds; the effect's *cost* (the nominal controller's RMSE on this plant ÷ on the
robot's nothing-hidden plant, same seeds and references) and how much of it (c) wins back; the sim-to-real
gap |RMSE on the model − RMSE on the plant| ÷ RMSE on the plant. Pooled over the plants whose effect costs at
least 20 %: the share won back and (c) ÷ (a), paired over (plant, seed).

    python benchmarks/sim_to_real.py --jobs 2 --out benchmarks/results          # about 2.5 h on 2 cores
    python benchmarks/sim_to_real.py --jobs 2 --out benchmarks/results --resume  # after an interruption
    python benchmarks/sim_to_real.py --ray HOST:PORT --out benchmarks/results    # plants as Ray tasks on a cluster
    python benchmarks/sim_to_real.py --kinds none com_offset --episodes 2 --out /tmp/s2r  # a quick look

Writes OUT/sim_to_real.md, .json (every plant) and .png (one panel per robot type); each finished plant is
appended to OUT/sim_to_real_runs.jsonl at once, which ``--resume`` reads.

**Agents** (on :data:`AGENT_PLANTS`, both robot types): a residual PPO agent on ``ekf-pid`` (the shipped
``ppo_residual`` hyperparameters, the same fixed budget of :data:`AGENT_STEPS` steps and training seed for every
model) is trained with ``omni-gym train`` on each model's ``OmniPathFollow-Custom-v0`` and evaluated like the
scripted controllers, on the plant and on its own model. A model equal to another (calibrate refused, or ``gap``
returned the nominal model) reuses that model's agent: the same training would give the same agent.

    python benchmarks/sim_to_real.py --jobs 2 --out benchmarks/results --resume --agents-only  # agents only

Not here: tracker effects (``tracker_offset``, ``time_offset``: they change what is logged, not how the robot moves, and
the closed-loop plant models motion only).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from independent_data import hidden_effect  # noqa: E402  (the study's random effect sizes and directions)

from agents.evaluate import paired_bootstrap_ratio  # noqa: E402
from omni_gym.analysis.second_generator import MANOEUVRES, write_second_dataset  # noqa: E402
from omni_gym.parallel import add_ray_option, backend_from_options, parallel_map  # noqa: E402
from omni_gym.physics.effects import REGISTRY  # noqa: E402
from omni_gym.physics.model import SimModel, load_model  # noqa: E402
from omni_gym.record_paths import record_args  # noqa: E402

ROBOTS = ("williams2002", "optiodom_omni4")
KINDS = ("none", "com_offset", "wheel_radius", "wheel_geometry", "motor_lag", "kinetic_friction", "wheel_liftoff",
         "roller_gap", "mecanum_lateral", "drag", "slope")
OUTSIDE = ("drag", "slope")  # causes outside the library: passed to the plant as --plant-extra
ENV = "OmniPathFollow-Custom-v0"
TASK = {"episode_seconds": 10.0, "ref_speed": 0.15, "ref_traction": 0.0}
FIRST_SEED = 10_000  # held out: training uses small seeds, validation 5000…
RUNS, RUN_SECONDS = 8, 6.0  # the logged driving: 48 s
COST_MIN = 0.20  # an effect that costs the nominal controller at least this much more error is one to win back
MODELS = ("nominal", "kinematic", "gap")
AGENT_PLANTS = (("williams2002", "none"), ("williams2002", "com_offset"), ("williams2002", "wheel_radius"),
                ("williams2002", "wheel_liftoff"), ("optiodom_omni4", "none"), ("optiodom_omni4", "wheel_radius"))
AGENT_STEPS = 1_000_000  # one fixed budget for every model: 2.6-4 min of training on a loaded 2-core machine
AGENT = ("--algo", "ppo", "--hyperparams", "ppo_residual", "--seed", "0", "--eval-freq", "0", "--no-progress")


def nominal(robot: str) -> SimModel:
    return load_model(robot, surface="carpet", friction="initial")


def applies(kind: str, model: SimModel) -> bool:
    return kind in ("none", *OUTSIDE) or REGISTRY[kind].applies_to(model.robot)


def plants(kinds=KINDS, robots=ROBOTS, seed0: int = 0) -> list[dict]:
    """One plant per robot and kind, each with its own seed, hidden effect and logged-run settings."""
    out = []
    for robot in robots:
        model = nominal(robot)
        for kind in kinds:
            if not applies(kind, model):
                continue
            seed = seed0 + 1000 * (ROBOTS.index(robot) + 1) + 10 * KINDS.index(kind) + 7
            rng = np.random.default_rng(seed)
            if kind == "slope":
                hidden = {"slope": {"angle": float(rng.uniform(0.02, 0.06)),
                                    "direction": float(rng.uniform(-math.pi, math.pi))}}
            else:
                hidden = hidden_effect(kind, rng, model)
            out.append({"robot": robot, "kind": kind, "seed": seed, "hidden": hidden,
                        "manoeuvre": str(rng.choice(MANOEUVRES)), "noise": 0.001})
    return out


def _cli(*args: str, timeout: float = 3600) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg", "SDL_VIDEODRIVER": "dummy"}
    return subprocess.run([sys.executable, "-m", "omni_gym.cli", *args], capture_output=True, text=True, env=env,
                          timeout=timeout)


def _after(text: str, marker: str) -> str:
    return text.split(marker, 1)[1] if marker in text else text


def plain(text: str) -> str:
    """``text`` with every temporary folder's path cut to its last part (records name no machine's paths)."""
    import re

    text = re.sub(r"/(?:tmp|var/folders)/\S*/([^/\s]+)", r"\1", text)
    return re.sub(r"/(?:tmp|var/folders)\S*", "…", text)  # a path cut short by a note's length


def write_logs(dataset: Path, logs: Path, n_wheels: int) -> list[Path]:
    """The dataset's runs as a robot would log them: time, tracked pose and encoder angles, other column names."""
    logs.mkdir()
    files = []
    for run in sorted((dataset / "runs").glob("*.csv")):
        with run.open() as f:
            rows = list(csv.DictReader(f))
        out = logs / run.name
        with out.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["time", "pose_x", "pose_y", "yaw", *[f"wheel_{i + 1}" for i in range(n_wheels)]])
            for row in rows:
                w.writerow([row["t"], row["x"], row["y"], row["theta"], *[row[f"enc{i + 1}"] for i in range(n_wheels)]])
        files.append(out)
    return files


def evaluate_on(model_path: Path, plant: dict | None, episodes: int, policy: str = "ekf-pid") -> dict:
    """``omni-gym evaluate`` of ``policy`` on ``model_path``'s id on the plant (or on the model itself)."""
    args = ["evaluate", "--policy", policy, "--env", ENV, "--episodes", str(episodes), "--seed", str(FIRST_SEED),
            "--env-kwargs", json.dumps({"model": str(model_path), **TASK}), "--json"]
    if plant is not None:
        args += ["--plant", "second-generator", "--plant-model", str(plant["model"])]
        if plant["extra"]:
            args += ["--plant-extra", json.dumps(plant["extra"])]
    proc = _cli(*args)
    if proc.returncode != 0:
        raise RuntimeError(f"evaluate failed: {proc.stderr.strip()[-400:]}")
    r = json.loads(proc.stdout)
    return {"rmse": r["per_episode"]["tracking_rmse"], "success": r["per_episode"]["success"]}


def run_task(task: tuple[dict, int]) -> dict:
    """:func:`run_plant` of (case, episodes): one backend task (a module-level function the workers import)."""
    return {**run_plant(*task), "episodes": task[1]}


def run_plant(case: dict, episodes: int) -> dict:
    """The chain for one plant (module docstring); every figure in metres."""
    t0 = time.perf_counter()
    robot, hidden = case["robot"], dict(case["hidden"] or {})
    model = nominal(robot)
    library = {k: v for k, v in hidden.items() if k not in OUTSIDE}
    extra = {k: v for k, v in hidden.items() if k in OUTSIDE}
    out = {**case, "models": {}, "notes": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_second_dataset(tmp / "logged", robot=robot, hidden=hidden or None, runs=RUNS, duration=RUN_SECONDS,
                             manoeuvre=case["manoeuvre"], position_noise=case["noise"],
                             heading_noise=2 * case["noise"], seed=case["seed"])
        logs = write_logs(tmp / "logged", tmp / "logs", model.n_wheels)
        (tmp / "nominal.json").write_text(json.dumps(model.to_json()))
        columns = "t=time,x=pose_x,y=pose_y,theta=yaw," + ",".join(
            f"enc{i + 1}=wheel_{i + 1}" for i in range(model.n_wheels))
        proc = _cli("import", "csv", *map(str, logs), "--model", str(tmp / "nominal.json"), "--columns", columns,
                    "--out", str(tmp / "dataset"))
        if proc.returncode != 0:
            raise RuntimeError(f"import failed: {proc.stderr.strip()[-400:]}")
        models = {"nominal": tmp / "nominal.json"}
        proc = _cli("calibrate", str(tmp / "dataset"), "--out", str(tmp / "kinematic.json"))
        if proc.returncode == 0:
            models["kinematic"] = tmp / "kinematic.json"
        else:  # the engineer is left with the nominal model: (b) is (a)
            out["notes"].append("calibrate refused (b = a): " + plain(_after(proc.stderr.strip().splitlines()[-1],
                                                                                "nothing written: "))[:240])
        t_gap = time.perf_counter()
        proc = _cli("gap", str(tmp / "dataset"), "--out", str(tmp / "report"), "--json")
        out["gap_wall_s"] = time.perf_counter() - t_gap
        if proc.returncode != 0:
            raise RuntimeError(f"gap failed: {proc.stderr.strip()[-400:]}")
        result = json.loads(proc.stdout)
        out["gap_effect"], out["gap_effects"] = result["effect"], result["effects"]
        models["gap"] = tmp / "report" / "model.json"
        truth = model.to_json()
        truth["effects"] = library
        (tmp / "truth.json").write_text(json.dumps(truth))
        plant = {"model": tmp / "truth.json", "extra": extra}
        for name, path in models.items():
            out["models"][name] = {"plant": evaluate_on(path, plant, episodes),
                                   "own": evaluate_on(path, None, episodes),
                                   "model": json.loads(path.read_text())}  # kept: agents can be designed on it later
        out["truth"] = {"model": truth, "extra": extra}
    out["wall_s"] = time.perf_counter() - t0
    return out


def run_agent_task(task: tuple[dict, int, int]) -> dict:
    """:func:`run_agents` of (plant record, episodes, steps): one backend task."""
    return run_agents(*task)


def run_agents(record: dict, episodes: int, steps: int) -> dict:
    """A residual agent trained on each of the plant's models (a fixed budget), evaluated on the plant and on its
    own model; ``record`` is the plant's line of the runs log (its models and its truth)."""
    t0 = time.perf_counter()
    out = {k: record[k] for k in ("robot", "kind", "seed")}
    out.update(episodes=episodes, steps=steps, models={})
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "truth.json").write_text(json.dumps(record["truth"]["model"]))
        plant = {"model": tmp / "truth.json", "extra": record["truth"]["extra"]}
        trained: dict[str, str] = {}  # model text → the name whose agent it is
        for name in MODELS:
            if name not in record["models"]:
                continue
            text = json.dumps(record["models"][name]["model"], sort_keys=True)
            if text in trained:  # the same model, seed and budget: the same agent
                out["models"][name] = {**out["models"][trained[text]], "same_as": trained[text]}
                continue
            trained[text] = name
            path = tmp / f"{name}.json"
            path.write_text(text)
            agent = tmp / f"agent-{name}"
            t_train = time.perf_counter()
            proc = _cli("train", *AGENT, "--env", ENV, "--timesteps", str(steps), "--out", str(agent),
                        "--env-kwargs", json.dumps({"model": str(path), **TASK}))
            if proc.returncode != 0:
                raise RuntimeError(f"train failed: {proc.stderr.strip()[-400:]}")
            train_s = time.perf_counter() - t_train
            out["models"][name] = {"plant": evaluate_on(path, plant, episodes, policy=str(agent)),
                                   "own": evaluate_on(path, None, episodes, policy=str(agent)),
                                   "train_s": train_s}
    out["wall_s"] = time.perf_counter() - t0
    return out


# --- figures -----------------------------------------------------------------------------------------------


def _mean(x) -> float:
    return float(np.mean(x))


def ratio(num, den, seed: int) -> dict:
    """mean(num) ÷ mean(den) with its 95 % paired bootstrap interval over seeds."""
    ci, _ = paired_bootstrap_ratio(np.asarray(num), np.asarray(den), np.random.default_rng(seed))
    return {"ratio": _mean(num) / _mean(den), "ci95": ci}


def figures(done: list[dict]) -> list[dict]:
    """Per plant: RMSE on the plant per model, ratios, the effect's cost and what (c) wins back, the gaps."""
    base = {r["robot"]: r for r in done if r["kind"] == "none"}
    rows = []
    for r in done:
        m = r["models"]
        a = np.array(m["nominal"]["plant"]["rmse"])
        c = np.array(m["gap"]["plant"]["rmse"])
        row = {"robot": r["robot"], "kind": r["kind"], "seed": r["seed"], "hidden": r["hidden"],
               "gap_effect": r["gap_effect"], "notes": r["notes"],
               "plant": {k: _mean(v["plant"]["rmse"]) for k, v in m.items()},
               "own": {k: _mean(v["own"]["rmse"]) for k, v in m.items()},
               "success": {k: _mean(v["plant"]["success"]) for k, v in m.items()},
               "c_over_a": ratio(c, a, r["seed"])}
        b = m["kinematic"] if "kinematic" in m else m["nominal"]  # refused: the engineer keeps the nominal model
        row["c_over_b"] = ratio(c, np.array(b["plant"]["rmse"]), r["seed"] + 1)
        row["b_refused"] = "kinematic" not in m
        row["sim_to_real_gap"] = {k: abs(row["own"][k] - row["plant"][k]) / row["plant"][k] for k in m}
        none = base.get(r["robot"])
        if none is not None and r["kind"] != "none":
            a0 = np.array(none["models"]["nominal"]["plant"]["rmse"])
            row["cost"] = _mean(a) / _mean(a0) - 1.0
            # Only where there is a loss to win back: below COST_MIN the share divides by noise (+3 % gave −71 %).
            row["won_back"] = ((_mean(a) - _mean(c)) / (_mean(a) - _mean(a0)) if row["cost"] >= COST_MIN else None)
        rows.append(row)
    return rows


def pooled(done: list[dict], rows: list[dict]) -> dict | None:
    """Over the plants whose effect costs ≥ COST_MIN: the share (c) wins back and (c) ÷ (a), with 95 % bootstrap
    intervals resampling (plant, seed) pairs."""
    costly = {(r["robot"], r["kind"]) for r in rows if r.get("cost") is not None and r["cost"] >= COST_MIN}
    if not costly:
        return None
    base = {r["robot"]: np.array(r["models"]["nominal"]["plant"]["rmse"]) for r in done if r["kind"] == "none"}
    a, c, a0 = [], [], []
    for r in done:
        if (r["robot"], r["kind"]) in costly:
            a += r["models"]["nominal"]["plant"]["rmse"]
            c += r["models"]["gap"]["plant"]["rmse"]
            a0 += list(base[r["robot"]])
    a, c, a0 = map(np.array, (a, c, a0))
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(a), size=(4000, len(a)))
    won = (a[idx].mean(1) - c[idx].mean(1)) / (a[idx].mean(1) - a0[idx].mean(1))
    return {"plants": sorted(f"{rb}/{k}" for rb, k in costly), "pairs": len(a),
            "won_back": float((a.mean() - c.mean()) / (a.mean() - a0.mean())),
            "won_back_ci95": [float(np.quantile(won, 0.025)), float(np.quantile(won, 0.975))],
            "c_over_a": ratio(c, a, 1)}


def _r(x: dict | None) -> str:
    if x is None:
        return "–"
    return f"{x['ratio']:.2f} [{x['ci95'][0]:.2f}, {x['ci95'][1]:.2f}]"


def _hidden(h: dict | None) -> str:
    if not h:
        return "–"
    import re

    text = json.dumps(h, separators=(",", ":")).replace("|", "/")
    return re.sub(r"-?\d+\.\d+(e-?\d+)?", lambda m: f"{float(m.group()):.3g}", text)


INTRO = (
    "Per plant (`benchmarks/sim_to_real.py`, module docstring): 48 s of logged driving → `omni-gym import csv` → "
    "`calibrate` → `gap` (defaults); `ekf-pid` on `{env}` with the kinematics of (a) the nominal model, (b) the "
    "kinematic calibration, (c) `gap`'s model, each evaluated through `omni-gym evaluate --plant second-generator` "
    "on the plant and on its own model: {episodes} held-out episodes of 10 s (seeds {first}…), the same references "
    "for every controller. RMSE in mm; ratios are of mean RMSE with 95 % paired bootstrap intervals over seeds. "
    "*cost*: the nominal controller's RMSE on this plant ÷ on the robot's nothing-hidden plant − 1; *won back*: "
    "(a − c) ÷ (a − a on the nothing-hidden plant), where the cost is at least 20 %; *gap*: |RMSE on the model − "
    "RMSE on the plant| ÷ RMSE on the plant.")


def pooled_line(pool: dict | None, plants: str, nominal: str) -> str:
    """The pooled sentence of :func:`pooled`'s figures (or that nothing costs enough to pool)."""
    if pool is None:
        return f"No {plants[:-1]}'s effect costs {nominal} {COST_MIN:.0%} or more: nothing to win back."
    return (f"**Pooled over the {len(pool['plants'])} {plants} whose effect costs {nominal} ≥ {COST_MIN:.0%}** "
            f"({', '.join(pool['plants'])}; {pool['pairs']} paired episodes): (c) wins back {pool['won_back']:.0%} "
            f"[{pool['won_back_ci95'][0]:.0%}, {pool['won_back_ci95'][1]:.0%}] of the loss; (c) ÷ (a) = "
            f"{_r(pool['c_over_a'])}.")


def plant_rows(rows: list[dict]) -> list[str]:
    """The per-plant table (Markdown lines) of :func:`figures`' rows."""
    lines = ["| robot | hidden | gap named | plant RMSE a / b / c | own-model RMSE a / b / c | c ÷ a | c ÷ b | cost | "
             "won back | gap of a / c | success a / b / c |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        p, o, s, g = r["plant"], r["own"], r["success"], r["sim_to_real_gap"]

        def three(d, fmt):
            return " / ".join(fmt(d[k]) if k in d else "–" for k in MODELS)

        cost = "–" if r.get("cost") is None else f"{r['cost']:+.0%}"
        won = "–" if r.get("won_back") is None else f"{r['won_back']:.0%}"
        cb = _r(r["c_over_b"]) + (" †" if r["b_refused"] else "")
        lines.append(f"| {r['robot']} | {r['kind']} `{_hidden(r['hidden'])}` | {r['gap_effect']} | "
                     f"{three(p, lambda v: f'{1e3 * v:.2f}')} | {three(o, lambda v: f'{1e3 * v:.2f}')} | "
                     f"{_r(r['c_over_a'])} | {cb} | {cost} | {won} | "
                     f"{g['nominal']:.0%} / {g['gap']:.0%} | {three(s, lambda v: f'{v:.0%}')} |")
    return lines


def agent_section(done: list[dict], rows: list[dict], pool: dict | None, scripted: list[dict], steps: int) -> list[str]:
    """The agents' table: the same figures as the scripted controllers', and each agent ÷ the ekf-pid designed on
    the same model, on the plant."""
    lines = [f"## Residual agents trained on each model ({steps:,} steps each, the same seed)", "",
             "A residual PPO agent on `ekf-pid` (`omni-gym train --algo ppo --hyperparams ppo_residual`), trained on "
             "each model's `" + ENV + "` with one fixed budget and evaluated as above; (a), (b), (c) now name the "
             "agent trained on that model. *cost* and *won back* use the agent trained on the nominal model on the "
             "robot's nothing-hidden plant.", ""]
    lines += [pooled_line(pool, "agent plants", "the nominal agent"), ""]
    worst = max(rows, key=lambda r: r["c_over_a"]["ratio"])
    lines += [f"Largest (c) ÷ (a): {_r(worst['c_over_a'])} ({worst['robot']} {worst['kind']}). Each model's agent is "
              "one training run of one seed, so a ratio also holds the spread between training runs, which this "
              "table does not measure.", "", *plant_rows(rows)]
    by_plant = {(r["robot"], r["kind"]): r for r in scripted}
    lines += ["", "Agent ÷ `ekf-pid` designed on the same model, on the plant (mean RMSE, 95 % paired interval):", "",
              "| robot | hidden | (a) nominal | (b) kinematic | (c) gap | training time per agent |",
              "|---|---|---|---|---|---|"]
    for r in done:
        s = by_plant[(r["robot"], r["kind"])]
        cells = []
        for name in MODELS:
            if name not in r["models"]:
                cells.append("–")
                continue
            agent = np.array(r["models"][name]["plant"]["rmse"])
            pid = np.array(s["models"][name]["plant"]["rmse"])
            cells.append(_r(ratio(agent, pid, r["seed"] + 2)))
        train = [m["train_s"] for m in r["models"].values() if "train_s" in m]
        lines.append(f"| {r['robot']} | {r['kind']} | {' | '.join(cells)} | {np.median(train) / 60:.1f} min |")
    return lines


def goal_lines(done: list[dict], rows: list[dict], pool: dict | None, agent_done: list[dict] = (),
               jobs: int = 2) -> list[str]:
    """The benchmark's goals, each met or missed with the figure that decides it."""
    def verdict(ok: bool) -> str:
        return "**met**" if ok else "**missed**"

    lines = ["## Goals", ""]
    if pool is not None:
        lo = pool["won_back_ci95"][0]
        lines.append(f"- (c) wins back at least half of what the effects cost, pooled (interval's lower end): "
                     f"{pool['won_back']:.0%} [{lo:.0%}, {pool['won_back_ci95'][1]:.0%}]: {verdict(lo >= 0.5)}")
        hi = pool["c_over_a"]["ci95"][1]
        lines.append(f"- (c) ÷ (a) at most 0.8 pooled over those plants: {_r(pool['c_over_a'])}: {verdict(hi <= 0.8)}")
    worst = max(rows, key=lambda r: r["c_over_a"]["ratio"])
    lines.append(f"- (c) ÷ (a) never above 1.05 on any plant: largest {worst['c_over_a']['ratio']:.2f} "
                 f"({worst['robot']} {worst['kind']}): {verdict(worst['c_over_a']['ratio'] <= 1.05)}")
    none = [r for r in rows if r["kind"] == "none"]
    lines.append("- within 1.05 on the nothing-hidden plants: "
                 + ", ".join(f"{r['robot']} {r['c_over_a']['ratio']:.2f}" for r in none)
                 + f": {verdict(all(r['c_over_a']['ratio'] <= 1.05 for r in none))}")
    named = [r for r in rows if r["kind"] not in ("none", *OUTSIDE) and r["gap_effect"] == r["kind"]]
    over = [r for r in named if r["sim_to_real_gap"]["gap"] > 0.20]
    lines.append(f"- sim-to-real gap of `gap`'s model at most 20 % on every plant where `gap` named the hidden "
                 f"effect: {len(named) - len(over)} of {len(named)}"
                 + "".join(f"; {r['robot']} {r['kind']} {r['sim_to_real_gap']['gap']:.0%} (nominal model "
                           f"{r['sim_to_real_gap']['nominal']:.0%})" for r in over) + f": {verdict(not over)}")
    wall = (sum(r["wall_s"] for r in done) + sum(r["wall_s"] for r in agent_done)) / jobs
    lines.append(f"- the whole benchmark in at most 3 h with `--jobs {jobs}`: about {wall / 3600:.1f} h (the plants' "
                 f"and agents' wall times ÷ {jobs}, on a loaded 2-core machine): {verdict(wall <= 3 * 3600)}")
    accepted = [r for r in done if "kinematic" in r["models"]]
    if accepted:
        worse = [_mean(r["models"]["kinematic"]["plant"]["rmse"]) / _mean(r["models"]["nominal"]["plant"]["rmse"])
                 for r in accepted]
        scales = [v for r in accepted for v in r["models"]["kinematic"]["model"].get("effects", {})
                  .get("wheel_radius", {}).get("scale", [])]
        lines += ["", f"Where `calibrate` accepted a calibration ({len(accepted)} plants: "
                  + ", ".join(f"{r['robot']} {r['kind']}" for r in accepted) + f"), `ekf-pid` on it tracked the plant "
                  f"{min(worse):.1f}–{max(worse):.1f}× worse than on the nominal model"
                  + (f": its kinematics absorb the carpet's slip (wheel radius scales {min(scales):.2f}–"
                     f"{max(scales):.2f})" if scales else "") + "."]
    return lines


def table(done: list[dict], rows: list[dict], pool: dict | None, command: str, episodes: int,
          more: list[str] = ()) -> str:
    lines = ["# Does calibrating make a better controller for the robot? Plants the models were not made from", "",
             f"`{command}`", "",
             INTRO.format(env=ENV, episodes=episodes, first=FIRST_SEED), ""]
    lines += [pooled_line(pool, "plants", "the nominal controller"), ""]
    worst = max((r["c_over_a"]["ratio"] for r in rows), default=math.nan)
    lines += [f"Largest (c) ÷ (a) on any plant: {worst:.2f}.", "", *plant_rows(rows)]
    refused = sum(r["b_refused"] for r in rows)
    lines += ["", f"†: `omni-gym calibrate` refused on {refused} of {len(rows)} plants (values at its search bounds or "
              "dead reckoning far off after the fit: the wheels slip on carpet); the engineer then keeps the nominal "
              "model, so (b) is (a) there."]
    notes = [f"- {r['robot']} {r['kind']}: {plain(n)}" for r in rows for n in r["notes"]]
    if notes:
        lines += ["", "Notes:", "", *notes]
    wall = [r["wall_s"] for r in done]
    lines += ["", f"Wall time per plant: median {np.median(wall) / 60:.1f} min, max {max(wall) / 60:.1f} min "
              f"(gap median {np.median([r['gap_wall_s'] for r in done]):.0f} s)."]
    return "\n".join([*lines, *more]) + "\n"


def plot(rows: list[dict], path: Path, agent_rows: list[dict] = ()) -> None:
    """One panel per robot type: (c) ÷ (a) and (c) ÷ (b) per plant with their 95 % paired intervals, the agents'
    (c) ÷ (a) where agents were trained, the cost of each effect under its name; below 1 the calibrated
    controller tracks the plant better. One legend for both panels, above them (it never hides a point)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    colours = {"c_over_a": "#dd8452", "c_over_b": "#4c72b0", "agent": "#55a868"}
    robots = [rb for rb in ROBOTS if any(r["robot"] == rb for r in rows)]
    fig, axes = plt.subplots(len(robots), 1, figsize=(12, 3.3 * len(robots) + 0.9), squeeze=False)
    for ax, rb in zip(axes[:, 0], robots, strict=True):
        sub = [r for r in rows if r["robot"] == rb]
        x = np.arange(len(sub))
        agents = {r["kind"]: r for r in agent_rows if r["robot"] == rb}
        xa = np.array([i for i, r in enumerate(sub) if r["kind"] in agents])
        if len(xa):
            ag = [agents[sub[i]["kind"]]["c_over_a"] for i in xa]
            ratio = np.array([a["ratio"] for a in ag])
            ax.errorbar(xa + 0.22, ratio, yerr=[ratio - np.array([a["ci95"][0] for a in ag]),
                                                 np.array([a["ci95"][1] for a in ag]) - ratio],
                        fmt="^", color=colours["agent"], capsize=3, zorder=3)
        for dx, key in ((-0.22, "c_over_a"), (0.0, "c_over_b")):
            ratio = np.array([r[key]["ratio"] for r in sub])
            lo = ratio - np.array([r[key]["ci95"][0] for r in sub])
            hi = np.array([r[key]["ci95"][1] for r in sub]) - ratio
            refused = np.array([key == "c_over_b" and r["b_refused"] for r in sub])
            ax.errorbar(x + dx, ratio, yerr=[lo, hi], fmt="none", ecolor=colours[key], capsize=3)
            ax.scatter(x[~refused] + dx, ratio[~refused], color=colours[key], zorder=3)
            ax.scatter(x[refused] + dx, ratio[refused], facecolors="white", edgecolors=colours[key], zorder=3)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.axhline(0.8, color="k", lw=0.6, ls="--")
        costs = ["" if r.get("cost") is None else f"\ncost {r['cost']:+.0%}" for r in sub]
        names = [r["kind"].replace("_", "_\n", 1) if len(r["kind"]) > 11 else r["kind"] for r in sub]
        ax.set_xticks(x, [f"{n}\n→ {r['gap_effect']}{c}" for n, r, c in zip(names, sub, costs, strict=True)],
                      fontsize=7)
        ax.set_ylabel("ratio of mean tracking RMSE\non the plant (< 1: better)")
        ax.set_title(f"{rb}: hidden effect → what gap named, and what the effect costs the nominal ekf-pid",
                     fontsize=9)
        shown = [r[k]["ci95"] for r in sub for k in ("c_over_a", "c_over_b")] + [a["c_over_a"]["ci95"]
                                                                                for a in agents.values()]
        ax.set_ylim(min(0.3, min(c[0] for c in shown) - 0.05), max(1.3, max(c[1] for c in shown) + 0.05))
    handles = [Line2D([], [], ls="", marker="o", color=colours["c_over_a"],
                      label="ekf-pid: (c) on gap's model ÷ (a) on the nominal"),
               Line2D([], [], ls="", marker="o", color=colours["c_over_b"],
                      label="ekf-pid: (c) ÷ (b) on the kinematic calibration"),
               Line2D([], [], ls="", marker="o", markerfacecolor="white", color=colours["c_over_b"],
                      label="(c) ÷ (b) where calibrate refused (b = a)"),
               Line2D([], [], ls="", marker="^", color=colours["agent"],
                      label="residual agent: (c) trained on gap's model ÷ (a) on the nominal")]
    fig.legend(handles=handles, loc="upper center", ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.75 / fig.get_figheight()))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def agents_phase(args: argparse.Namespace, done: list[dict], backend) -> list[dict]:
    """The agents on every plant of :data:`AGENT_PLANTS` already logged: resumed from OUT/sim_to_real_agents.jsonl
    (with ``--resume``, ``--report-only`` or ``--agents-only``), the rest trained now (none with ``--report-only``).
    Each result carries its plant's record, so :func:`figures` reads it like a plant's."""
    log = args.out / "sim_to_real_agents.jsonl"
    plants_ = {(r["robot"], r["kind"]): r for r in done if (r["robot"], r["kind"]) in AGENT_PLANTS}
    got: dict = {}
    if (args.resume or args.report_only or args.agents_only) and log.exists():
        for line in log.read_text().splitlines():
            a = json.loads(line)
            r = plants_.get((a["robot"], a["kind"]))
            if r is not None and a["seed"] == r["seed"] and (a["episodes"], a["steps"]) == (args.episodes,
                                                                                            args.agent_steps):
                got[(a["robot"], a["kind"])] = a
    elif log.exists():
        log.unlink()
    todo = [] if args.report_only else [r for key, r in plants_.items() if key not in got]
    print(f"sim_to_real: agents on {len(todo)} plants ({len(got)} resumed)", file=sys.stderr, flush=True)
    t0 = time.perf_counter()

    def keep(_i: int, a: dict) -> None:
        with log.open("a") as f:
            f.write(json.dumps(a) + "\n")
        got[(a["robot"], a["kind"])] = a
        k, elapsed = len(got), time.perf_counter() - t0
        print(f"sim_to_real: agents {k}/{len(plants_)} plants ({a['robot']} {a['kind']}), {elapsed / 60:.1f} min",
              file=sys.stderr, flush=True)

    if todo:
        parallel_map(run_agent_task, [(r, args.episodes, args.agent_steps) for r in todo], backend, on_done=keep)
    out = []
    for key, r in sorted(plants_.items(), key=lambda kv: (ROBOTS.index(kv[0][0]), KINDS.index(kv[0][1]))):
        if key in got:
            out.append({**r, "models": got[key]["models"], "wall_s": got[key]["wall_s"]})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    ap.add_argument("--episodes", type=int, default=8, help="held-out episodes per controller and plant")
    ap.add_argument("--jobs", type=int, default=1, help="plants run side by side")
    add_ray_option(ap, "the plants", "--jobs")
    ap.add_argument("--seed0", type=int, default=0, help="offset of every plant's seed (0: the committed set)")
    ap.add_argument("--out", type=Path, required=True, help="folder for sim_to_real.md, .json, .png, _runs.jsonl")
    ap.add_argument("--resume", action="store_true", help="skip the plants already in OUT/sim_to_real_runs.jsonl")
    ap.add_argument("--report-only", action="store_true",
                    help="write the table, JSON and plot from the plants already in OUT/sim_to_real_runs.jsonl, "
                         "running none (a study stopped part way; the table says how many plants it covers)")
    ap.add_argument("--agents-only", action="store_true",
                    help="train and evaluate the agents on the plants already logged, running no new plant")
    ap.add_argument("--no-agents", action="store_true", help="the scripted controllers only")
    ap.add_argument("--agent-steps", type=int, default=AGENT_STEPS, help="training steps per agent (one budget)")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "sim_to_real_runs.jsonl"
    todo = plants(tuple(args.kinds), tuple(args.robots), args.seed0)
    done: list[dict] = []
    if (args.resume or args.report_only or args.agents_only) and log.exists():
        keys = {(c["robot"], c["kind"], c["seed"]) for c in todo}
        for line in log.read_text().splitlines():
            r = json.loads(line)
            if (r["robot"], r["kind"], r["seed"]) in keys and r.get("episodes") == args.episodes:
                done.append(r)
    elif log.exists():
        log.unlink()
    seen = {(r["robot"], r["kind"], r["seed"]) for r in done}
    todo = [c for c in todo if (c["robot"], c["kind"], c["seed"]) not in seen]
    missing = len(todo)
    if args.report_only or args.agents_only:
        todo = []
    print(f"sim_to_real: {len(todo)} plants to run ({len(done)} resumed), {args.jobs} at a time", file=sys.stderr,
          flush=True)
    try:
        backend = backend_from_options(max(args.jobs, 1), args.ray)
    except ValueError as exc:  # ray missing, nothing at the address
        raise SystemExit(f"sim_to_real.py: error: {exc}") from None
    t0 = time.perf_counter()
    finished = [0]

    def keep(_i: int, r: dict) -> None:  # as each plant finishes: logged at once (resume), one progress line
        with log.open("a") as f:
            f.write(json.dumps(r) + "\n")
        done.append(r)
        finished[0] += 1
        k, elapsed = finished[0], time.perf_counter() - t0
        print(f"sim_to_real: {k}/{len(todo)} plants ({r['robot']} {r['kind']} → {r['gap_effect']}), "
              f"{elapsed / 60:.1f} min, about {elapsed / k * (len(todo) - k) / 60:.0f} min left", file=sys.stderr,
              flush=True)

    if todo:
        parallel_map(run_task, [(c, args.episodes) for c in todo], backend, on_done=keep)
    done.sort(key=lambda r: (ROBOTS.index(r["robot"]), KINDS.index(r["kind"])))
    if not done:
        raise SystemExit(f"sim_to_real.py: error: no plant of these kinds in {log} with --episodes "
                         f"{args.episodes}; run the plants first (without --report-only or --agents-only)")
    agent_done = [] if args.no_agents else agents_phase(args, done, backend)
    rows = figures(done)
    pool = pooled(done, rows)
    agent_rows = figures(agent_done)
    agent_pool = pooled(agent_done, agent_rows)
    command = "python benchmarks/sim_to_real.py " + " ".join(record_args(argv if argv is not None else sys.argv[1:]))
    more = agent_section(agent_done, agent_rows, agent_pool, done, args.agent_steps) if agent_done else []
    more = [*goal_lines(done, rows, pool, agent_done, max(args.jobs, 1)), "", *more]
    text = table(done, rows, pool, command, args.episodes, more)
    if args.report_only:
        text = text.replace("\n\n", "\n\nRendered from the logs `sim_to_real_runs.jsonl` and "
                            "`sim_to_real_agents.jsonl` beside this table, written by "
                            "`python benchmarks/sim_to_real.py --jobs 2 --out benchmarks/results` (resumed with "
                            "`--resume` where a session ended).\n\n", 1)
    if missing and args.report_only:
        text = text.replace("\n\n", f"\n\n**Partial: {len(done)} of {len(done) + missing} plants** (the others did not "
                            "run; `--resume` runs them).\n\n", 1)
    (args.out / "sim_to_real.md").write_text(text)
    (args.out / "sim_to_real.json").write_text(json.dumps(
        {"plants": rows, "pooled": pool, "agents": {"plants": agent_rows, "pooled": agent_pool}}, indent=1) + "\n")
    plot(rows, args.out / "sim_to_real.png", agent_rows)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
