"""Held-out sessions of both real robots: nominal / kinematic / extended, and how the error grows.

For one robot: the training sessions imported together; the kinematic calibration fitted on them; the
extended model of a ``gap`` report on the same training runs (its ``model.json`` and ``result.json``);
every held-out session replayed **whole, open loop**, from each run's start pose, by the three models.
Printed and written (``heldout_sessions_<robot>.md/.json/.png``): per session the mean position RMS
[mm] of each model and extended ÷ kinematic; the named effects with their identified parameters (and
5–95 % bootstrap ranges, plausibility flags); the per-session error growth: mean Euclidean position
error [mm] against time since the run's start (1 s bins), one panel per session.

    python benchmarks/heldout_sessions.py --robot omni3 --gap-report REPORT_DIR --out DIR

``REPORT_DIR``: the folder ``omni-gym gap`` wrote for the robot's training dataset (``omni-gym import
optiodom`` of the TRAIN sessions below). A few seconds: no fit is run here.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
from real_optiodom import ROBOTS, named_effects, plot_growth  # noqa: E402  (benchmarks/ is on sys.path as a script)

from omni_gym.discrepancy.data.dataset import Run  # noqa: E402
from omni_gym.discrepancy.data.importers.optiodom import nominal_model, read_sessions  # noqa: E402
from omni_gym.discrepancy.fit.kinematic_calibration import calibrate, position_rms  # noqa: E402
from omni_gym.discrepancy.replay.measurement import START_WINDOW
from omni_gym.discrepancy.replay.simulate import FIT_DT, Job, simulate_poses  # noqa: E402
from omni_gym.io import read_json  # noqa: E402
from omni_gym.physics.model import SimModel  # noqa: E402

MODELS = ("nominal", "kinematic", "extended")
BIN = 1.0  # s: error-growth bins


def load(robot: str) -> tuple[SimModel, list[Run], dict[str, list[Run]]]:
    """Nominal model, training runs and the held-out sessions' runs (name → runs) of ``robot``."""
    spec = ROBOTS[robot]  # the two-robot benchmark's split of sessions
    metas, runs = read_sessions([spec.data / s for s in spec.train])
    sessions = {s: read_sessions([spec.data / s])[1] for s in spec.heldout}
    return nominal_model(metas[0]), runs, sessions


def error_growth(run: Run, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bin index (k,), position error [m] (k,)) of the run's tracked rows."""
    ok = run.observed
    e = np.hypot(*(run.pose[ok, :2] - pose[ok, :2]).T)
    return (run.t[ok] // BIN).astype(int), e


def study(robot: str, gap_dir: Path) -> dict:
    """The per-session table, the named effects and the error-growth curves (module docstring)."""
    nominal, train, sessions = load(robot)
    cal = calibrate(train, nominal)
    result = json.loads((gap_dir / "result.json").read_text())
    extended = SimModel.from_json(read_json(gap_dir / "model.json"), where=str(gap_dir / "model.json"))
    models = {"nominal": nominal, "kinematic": cal.model, "extended": extended}
    table, growth = [], {}
    for name, runs in sessions.items():
        poses = simulate_poses([Job(models[m], r) for r in runs for m in MODELS], dt=FIT_DT, start_window=START_WINDOW)
        rms = {m: [] for m in MODELS}
        curves: dict[str, dict[int, list[float]]] = {m: {} for m in MODELS}
        for i, run in enumerate(runs):
            for j, m in enumerate(MODELS):
                p = poses[i * len(MODELS) + j]
                rms[m].append(position_rms(run.pose, p))
                bins, e = error_growth(run, p)
                for b in np.unique(bins):
                    curves[m].setdefault(int(b), []).append(float(np.mean(e[bins == b])))
        mean = {m: float(np.mean(v)) for m, v in rms.items()}
        table.append({"session": name, "runs": len(runs), "seconds": float(sum(r.t[-1] for r in runs)),
                      "mean_position_rms": mean, "extended_over_kinematic": mean["extended"] / mean["kinematic"],
                      "per_run": {m: [float(x) for x in v] for m, v in rms.items()}})
        growth[name] = {m: [[(b + 0.5) * BIN, float(np.mean(v))] for b, v in sorted(c.items())]
                        for m, c in curves.items()}
    flags = result.get("plausibility", {}).get("flags", [])
    named = [{**n, "implausible": [f for f in flags if f.get("effect") == n["effect"]]} for n in named_effects(result)]
    return {"robot": robot, "train_runs": len(train), "kinematic": cal.to_json(), "gap_answer": result["effect"],
            "gap_start": result.get("start", {}).get("kind") or result.get("start", {}).get("model"),
            "named": named, "gap_heldout": result.get("heldout"), "sessions": table, "growth": growth}


def markdown(rec: dict) -> str:
    k = rec["kinematic"]
    lines = [f"# Held-out sessions, {rec['robot']}", "",
             f"Training: {rec['train_runs']} runs. Kinematic calibration: D = "
             f"[{', '.join(f'{1e3 * d:.2f}' for d in k['diameters'])}] mm, {k['size_name']} = {1e3 * k['L']:.2f} mm. "
             f"gap (start: {rec['gap_start']}): answer `{rec['gap_answer']}`.", "",
             "| held-out session | runs | nominal [mm] | kinematic [mm] | extended [mm] | extended ÷ kinematic |",
             "|---|---|---|---|---|---|"]
    for s in rec["sessions"]:
        m = s["mean_position_rms"]
        lines.append(f"| `{s['session']}` | {s['runs']} | {1e3 * m['nominal']:.1f} | {1e3 * m['kinematic']:.1f} "
                     f"| {1e3 * m['extended']:.1f} | {s['extended_over_kinematic']:.2f} |")
    lines += ["", "Position RMS: each run replayed whole, open loop, from its start pose with its measured wheel "
              "speeds; Euclidean x, y error against motion capture over the tracked rows; mean over the session's "
              "runs. Every model is fitted on the training runs only.", "", "Named effects (on top of the "
              f"{rec['gap_start']} model):", ""]
    if not rec["named"]:
        lines.append("* none: the extended model is the start model")
    for n in rec["named"]:
        rng = n.get("params_5_95") or {}
        lines.append(f"* `{n['effect']}` ({n['status']}): `{json.dumps(n['params'])}`"
                     + (f"; 5–95 %: `{json.dumps(rng)}`" if rng else "")
                     + ("; ⚠ implausible: " + ", ".join(f["param"] for f in n["implausible"])
                        if n["implausible"] else ""))
    h = rec.get("gap_heldout") or {}
    if h.get("per_session"):
        lines += ["", f"gap's own held-out check on the training sessions (folds by {h.get('folds_by')}, whole runs):",
                  "", "| fold session | nominal [mm] | kinematic [mm] | extended [mm] |", "|---|---|---|---|"]
        for s in h["per_session"]:
            m = s["mean_position_rms"]
            lines.append(f"| `{s['session']}` | {1e3 * m['nominal']:.1f} | "
                         f"{1e3 * m.get('kinematic', math.nan):.1f} | {1e3 * m['extended']:.1f} |")
    lines += ["", f"![error growth](heldout_sessions_{rec['robot']}.png)", ""]
    return "\n".join(lines)


def plot(rec: dict, out: Path) -> Path:
    """Mean position error against time, one panel per held-out session (``real_optiodom.plot_growth``)."""
    return plot_growth(rec["growth"], f"{rec['robot']}: held-out sessions, whole runs open loop (models fitted on "
                       "the training runs)", out / f"heldout_sessions_{rec['robot']}.png")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", choices=tuple(ROBOTS), required=True)
    ap.add_argument("--gap-report", type=Path, required=True, help="folder of omni-gym gap on the training runs")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rec = study(args.robot, args.gap_report)
    plot(rec, args.out)
    (args.out / f"heldout_sessions_{args.robot}.json").write_text(json.dumps(rec, indent=1, allow_nan=False) + "\n")
    text = markdown(rec)
    (args.out / f"heldout_sessions_{args.robot}.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
