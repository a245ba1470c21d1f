"""Real OptiOdom logs, both robots, as a user runs them: gap's extended model against the kinematic calibration
and a linear wheel-to-twist map, on every held-out session.

Per robot, the command line with its defaults (each run on the tracker's clock, ``docs/formats.md``)::

    omni-gym import optiodom TRAINING_SESSIONS... --out TRAIN
    omni-gym calibrate TRAIN --out kinematic.json
    omni-gym calibrate TRAIN --tracker --out kinematic_tracker.json
    omni-gym gap TRAIN --jobs N --out REPORT                       # timed (skipped with --gap-records)
    omni-gym import optiodom HELDOUT_SESSION --out HELDOUT          # each held-out session on its own
    omni-gym score HELDOUT --model kinematic.json --model REPORT/model.json --model kinematic_tracker.json \\
        --linear-map-from TRAIN --json

Reported per held-out session (``real_optiodom.md``, ``.json``, ``.png``): the mean over its runs of the
whole-run position RMS [mm] (open-loop replay from each run's start pose with its measured wheel speeds,
Euclidean x, y error against motion capture; tracker parts applied) of the nominal model, the kinematic
calibration, the calibration with its tracked frame, gap's extended model and the linear map, each ÷ the
kinematic calibration; the run spread (the extended model's position RMS over the session's runs, and the
per-run refit: the error left after an initial heading offset and a yaw-rate scale fitted to each run, and
the spread of those two, which no model of the robot predicts). Per robot: gap's answer, the effects it named
with their identified values and 5–95 % ranges, its wall time and the calibration's.

    # both robots, gap run on each robot's 24 training runs (about 13 min on 2 cores)
    python benchmarks/real_optiodom.py --jobs 2 --out benchmarks/results
    # gap started from calibrate --tracker's joint fit (about 9 min on 2 cores)
    python benchmarks/real_optiodom.py --start tracker --out benchmarks/results/start_tracker
    # re-score from the gap results an earlier run wrote (real_optiodom_<robot>_gap.json in DIR; 2 min)
    python benchmarks/real_optiodom.py --gap-records benchmarks/results --out DIR

Training and held-out sessions (``data/optiodom-omni3``, ``data/optiodom-omni4``; their READMEs):

* omni3 (three omni wheels): training circular/221220201701 + square/221220201953 (24 runs); held out
  circular/221220201643, …1722, …1726, …1730 and joystick/211220201842 (driven by hand, another day);
* omni4 (four mecanum wheels): training circular/080920201015 + square/080920201810 (24 runs, day 1); held out
  square/080920201715 (day 1), circular/231220200440 and circular/231220200502 (day 2).

Progress on stderr, one line per stage (gap's own progress lines included).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from omni_gym.discrepancy.data.dataset import Run  # noqa: E402
from omni_gym.record_paths import record_args

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Robot:
    """One OptiOdom robot of the benchmark: its data folder, training and held-out sessions."""

    name: str
    title: str
    data: Path
    train: tuple[str, ...]
    heldout: tuple[str, ...]


ROBOTS = {
    "omni3": Robot("omni3", "omni3: three omni wheels", ROOT / "data" / "optiodom-omni3",
                   ("circular/221220201701", "square/221220201953"),
                   ("circular/221220201643", "circular/221220201722", "circular/221220201726",
                    "circular/221220201730", "joystick/211220201842")),
    "omni4": Robot("omni4", "omni4: four mecanum wheels", ROOT / "data" / "optiodom-omni4",
                   ("circular/080920201015", "square/080920201810"),
                   ("square/080920201715", "circular/231220200440", "circular/231220200502")),
}
# The models of each held-out score, in the order `omni-gym score` prints them (nominal first, then each
# --model in the order given, then the linear map).
KEYS = ("nominal", "kinematic", "extended", "kinematic_tracker", "linear_map")
LABELS = {"nominal": "nominal", "kinematic": "kinematic", "extended": "extended (gap)",
          "kinematic_tracker": "calibration + tracked frame", "linear_map": "linear map"}
GOAL = 0.8  # extended ÷ kinematic on every held-out session (the workflow's target)


def say(msg: str) -> None:
    """A stage line on stderr (flushed: visible when piped to a log)."""
    print(f"real_optiodom: {msg}", file=sys.stderr, flush=True)


def cut(run: Run, seconds: float) -> Run:
    """The first ``seconds`` of ``run`` (the last kept row's command is 0: it ends the run)."""
    K = max(int(np.searchsorted(run.t, seconds, side="right")), 2)
    cmd = run.cmd[:K].copy()
    cmd[-1] = 0.0
    return Run(name=run.name, t=run.t[:K].copy(), cmd=cmd, pose=run.pose[:K].copy(),
               enc=None if run.enc is None else run.enc[:K].copy())


def omni_gym(*args: str, stream: bool = False) -> str:
    """Run the command line as a user does; its stdout. ``stream``: its stderr (progress) passes through.
    A failure raises with the command and its stderr."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "omni_gym.cli", *args], stdout=subprocess.PIPE,
                          stderr=None if stream else subprocess.PIPE, text=True, env=env)
    if done.returncode != 0:
        raise RuntimeError(f"omni-gym {' '.join(args)} failed (exit {done.returncode})"
                           + ("" if stream else f": {done.stderr.strip()}"))
    return done.stdout


def named_effects(result: dict) -> list[dict]:
    """The effects gap's model carries on top of its start: name, status, identified parameters and their
    5–95 % bootstrap range (gap's ``steps``)."""
    return [{"effect": s["effect"], "status": s["status"], "params": s["params"],
             "params_5_95": s.get("params_5_95")}
            for s in result.get("steps", []) if s.get("status") in ("named", "partial")]


def gap_result(robot: Robot, train: Path, work: Path, jobs: int, records: Path | None,
               start: str = "auto") -> tuple[dict, str]:
    """gap's result.json on the training dataset (run now, or read from ``records``) and where it came from."""
    if records is not None:
        path = records / f"real_optiodom_{robot.name}_gap.json"
        if not path.is_file():
            raise SystemExit(f"real_optiodom: --gap-records {records}: no {path.name} there")
        return json.loads(path.read_text()), f"the gap result in {path.name} (reused)"
    report = work / f"{robot.name}_report"
    extra = [] if start == "auto" else ["--start", start]  # the default stays the command users run
    args = ["--jobs", str(jobs), *extra]
    say(f"{robot.name}: omni-gym gap on the training runs, {' '.join(args)} (its progress follows)")
    omni_gym("gap", str(train), "--out", str(report), *args, stream=True)
    return json.loads((report / "result.json").read_text()), f"`omni-gym gap TRAIN {' '.join(args)}`"


def robot_record(robot: Robot, work: Path, jobs: int, records: Path | None,
                 start: str = "auto") -> tuple[dict, dict]:
    """One robot's rows and facts (module docstring); and gap's whole result (to keep beside the table)."""
    train = work / f"{robot.name}_train"
    say(f"{robot.name}: importing the training sessions")
    omni_gym("import", "optiodom", *[str(robot.data / s) for s in robot.train], "--out", str(train))
    kinematic, with_frame = work / f"{robot.name}_kinematic.json", work / f"{robot.name}_kinematic_tracker.json"
    t0 = time.monotonic()
    said = omni_gym("calibrate", str(train), "--out", str(kinematic))
    calibrate_s = time.monotonic() - t0
    said_frame = omni_gym("calibrate", str(train), "--tracker", "--out", str(with_frame))
    result, source = gap_result(robot, train, work, jobs, records, start)
    extended = work / f"{robot.name}_extended.json"
    extended.write_text(json.dumps(result["model"]))
    rows = []
    for session in robot.heldout:
        held = work / f"{robot.name}_{session.replace('/', '_')}"
        say(f"{robot.name}: scoring held-out {session}")
        omni_gym("import", "optiodom", str(robot.data / session), "--out", str(held))
        out = json.loads(omni_gym("score", str(held), "--model", str(kinematic), "--model", str(extended),
                                  "--model", str(with_frame), "--linear-map-from", str(train), "--json"))
        names = list(out["models"])
        rows.append({"session": session, **{key: out["models"][n] for key, n in zip(KEYS, names, strict=True)}})
    facts = {"robot": robot.name, "title": robot.title, "train": list(robot.train),
             "calibrate": printed(said), "calibrate_tracker": printed(said_frame),
             "calibrate_wall_s": calibrate_s, "gap": {
                 "source": source, "answer": result["effect"], "why": result["why"],
                 "wall_s": result["work"]["wall_s"], "backend": result["work"].get("backend"),
                 "start": (result.get("start") or {}).get("kind"), "named": named_effects(result)},
             "sessions": rows}
    return facts, result


def printed(stdout: str) -> list[str]:
    """What ``omni-gym calibrate`` said, less the line naming its temporary output file."""
    return [line for line in stdout.splitlines() if line.strip() and not line.startswith("wrote ")]


def ratio(row: dict, key: str) -> float:
    return row[key]["mean_position_rms"] / row["kinematic"]["mean_position_rms"]


def fmt(params: object) -> str:
    """Parameters as text (floats to 4 significant digits)."""
    if isinstance(params, dict):
        return ", ".join(f"{k} {fmt(v)}" for k, v in params.items())
    if isinstance(params, list):
        return "[" + ", ".join(fmt(v) for v in params) + "]"
    return f"{params:.4g}" if isinstance(params, float) else str(params)


def markdown(records: list[dict], command: str, wall_s: float) -> str:
    lines = [f"<!-- made by: {command} -->",
             "# Real OptiOdom logs, both robots: gap's extended model against the kinematic calibration and a "
             "linear map", "",
             f"`{command}` ({wall_s / 60:.1f} min on this 2-core machine). Per robot, every model is fitted on the "
             "two training sessions (24 runs) with the command line's defaults: `omni-gym calibrate TRAIN` "
             "(kinematic), `calibrate TRAIN --tracker` (calibration + tracked frame), `omni-gym gap TRAIN` "
             "(extended: its `model.json`), `score --linear-map-from TRAIN` (a 3 × n wheel-to-twist matrix, "
             "dead-reckoned from each run's encoders). Each held-out session is imported on its own and scored "
             "with `omni-gym score HELDOUT --model … --json`: the position RMS [mm] of each run replayed open loop "
             "from its start pose (tracker parts applied), mean over the session's runs.", "",
             "| robot | held-out session | runs | nominal | kinematic | calibration + tracked frame | extended "
             "(gap) | linear map | + frame ÷ kinematic | extended ÷ kinematic | linear map ÷ kinematic |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for rec in records:
        for r in rec["sessions"]:
            mm = {k: f"{1e3 * r[k]['mean_position_rms']:.1f}" for k in KEYS}
            lines.append(f"| {rec['robot']} | {r['session']} | {r['kinematic']['runs']} | {mm['nominal']} | "
                         f"{mm['kinematic']} | {mm['kinematic_tracker']} | {mm['extended']} | {mm['linear_map']} | "
                         f"{ratio(r, 'kinematic_tracker'):.2f} | **{ratio(r, 'extended'):.2f}** | "
                         f"{ratio(r, 'linear_map'):.2f} |")
    lines += ["", "![held-out sessions ÷ the kinematic calibration](real_optiodom.png)", "", "## Per robot", ""]
    for rec in records:
        ext = [ratio(r, "extended") for r in rec["sessions"]]
        lin = [ratio(r, "linear_map") for r in rec["sessions"]]
        wins = sum(e <= m for e, m in zip(ext, lin, strict=True))
        g = rec["gap"]
        lines += [f"### {rec['title']}", "",
                  f"- **extended ÷ kinematic**: {min(ext):.2f}–{max(ext):.2f} (mean {np.mean(ext):.2f}); goal ≤ "
                  f"{GOAL:g} on every session: **{'met' if max(ext) <= GOAL else 'missed'}**; at or below the "
                  f"linear map on {wins} of {len(ext)} sessions (linear map {min(lin):.2f}–{max(lin):.2f}, mean "
                  f"{np.mean(lin):.2f}).",
                  f"- **gap** ({g['source']}; start: {g['start']}): answer `{g['answer']}` in "
                  f"{g['wall_s']:.0f} s ({g['wall_s'] / 60:.1f} min; {g['backend']}). {g['why'].rstrip('.')}."]
        for n in g["named"]:
            rng = n.get("params_5_95") or {}
            lines.append(f"  - `{n['effect']}` ({n['status']}): {fmt(n['params'])}"
                         + (f"; 5–95 %: {fmt(rng)}" if rng else ""))
        if not g["named"]:
            lines.append("  - no effect named: the extended model is gap's start model")
        lines.append(f"- **`omni-gym calibrate TRAIN`** ({rec['calibrate_wall_s']:.1f} s):")
        lines += [f"  - {line}" for line in rec["calibrate"]]
        lines.append("- **`omni-gym calibrate TRAIN --tracker`**:")
        lines += [f"  - {line}" for line in rec["calibrate_tracker"] if "tracked frame" in line]
        lines += ["", "Run spread (the extended model; per-run refit: the initial heading offset and yaw-rate scale "
                  "that bring each replay closest to its run, which no model of the robot predicts):", "",
                  "| held-out session | runs | position RMS median (min–max) [mm] | sd [mm] | after the per-run "
                  "refit [mm] | heading offsets sd [deg] | yaw scales sd [%] |", "|---|---|---|---|---|---|---|"]
        for r in rec["sessions"]:
            e = r["extended"]
            lines.append(f"| {r['session']} | {e['runs']} | {1e3 * e['median_position_rms']:.1f} "
                         f"({1e3 * e['min_position_rms']:.1f}–{1e3 * e['max_position_rms']:.1f}) | "
                         f"{1e3 * e['std_position_rms']:.1f} | {1e3 * e['mean_refit_position_rms']:.1f} | "
                         f"{np.degrees(e['std_heading_offset']):.2f} | {100 * e['std_yaw_scale']:.2f} |")
        lines.append("")
    lines += ["sd: sample standard deviation over the session's runs (0 for a session of one run). gap's own "
              "records: `real_optiodom_<robot>_gap.json` (its whole `result.json`; `--gap-records` re-scores "
              "from them).", ""]
    return "\n".join(lines)


def plot(records: list[dict], path: Path) -> Path:
    """Each held-out session's models ÷ the kinematic calibration (bars; the 0.8 goal dashed)."""
    rows = [(rec["robot"], r) for rec in records for r in rec["sessions"]]
    keys = ("kinematic_tracker", "extended", "linear_map")
    colors = {"kinematic_tracker": "tab:blue", "extended": "tab:red", "linear_map": "tab:gray"}
    fig, ax = plt.subplots(figsize=(1.2 * len(rows) + 2, 4.2))
    x = np.arange(len(rows))
    for j, k in enumerate(keys):
        ax.bar(x + (j - 1) * 0.27, [ratio(r, k) for _, r in rows], 0.27, color=colors[k], label=LABELS[k])
    ax.axhline(1.0, color="k", lw=1, label="kinematic calibration")
    ax.axhline(GOAL, color="k", lw=1, ls="--", label=f"goal {GOAL:g}")
    ax.set_xticks(x, [f"{name}\n{r['session'].replace('/', chr(10))}" for name, r in rows], fontsize=7)
    ax.set_ylabel("held-out position RMS ÷ kinematic calibration")
    ax.set_title("Real OptiOdom robots, held-out sessions replayed open loop (lower is better)", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    ax.set_ylim(0, 1.35)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_growth(growth: dict, title: str, path: Path) -> Path:
    """Mean position error [mm] against time since each run's start [s], one panel per held-out session:
    ``growth`` maps session -> model -> [(t, error [m]), ...] (``heldout_sessions.py``)."""
    style = {"nominal": ("tab:gray", ":"), "kinematic": ("tab:blue", "--"), "extended": ("tab:green", "-")}
    n = len(growth)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.2), squeeze=False)
    for ax, (name, curves) in zip(axes[0], growth.items(), strict=True):
        for m, pts in curves.items():
            a = np.array(pts)
            ax.plot(a[:, 0], 1e3 * a[:, 1], style[m][1], color=style[m][0], label=m)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("time since start [s]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("mean position error [mm]")
    axes[0][0].legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=sorted(ROBOTS))
    ap.add_argument("--jobs", type=int, default=2, metavar="N", help="gap's local worker processes (default 2)")
    ap.add_argument("--gap-records", type=Path, default=None, metavar="DIR",
                    help="reuse real_optiodom_<robot>_gap.json from DIR instead of running gap")
    ap.add_argument("--start", choices=("auto", "tracker"), default="auto",
                    help="gap's --start (default auto, gap's own default; tracker: from calibrate --tracker's model)")
    ap.add_argument("--out", type=Path, required=True, help="folder of real_optiodom.md, .json, .png")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error(f"--jobs must be at least 1, got {args.jobs}")
    args.out.mkdir(parents=True, exist_ok=True)
    command = " ".join(["python benchmarks/real_optiodom.py", *record_args(sys.argv[1:] if argv is None else argv)])
    t0 = time.monotonic()
    records = []
    with tempfile.TemporaryDirectory(prefix="omni-gym-real-optiodom-") as tmp:
        for name in args.robots:
            facts, result = robot_record(ROBOTS[name], Path(tmp), args.jobs, args.gap_records, args.start)
            records.append(facts)
            target = args.out / f"real_optiodom_{name}_gap.json"
            if args.gap_records is None or target.resolve() != (args.gap_records / target.name).resolve():
                target.write_text(json.dumps(result, indent=1) + "\n")
    text = markdown(records, command, time.monotonic() - t0)
    (args.out / "real_optiodom.md").write_text(text)
    (args.out / "real_optiodom.json").write_text(json.dumps({"command": command, "robots": records},
                                                            indent=1) + "\n")
    plot(records, args.out / "real_optiodom.png")
    say(f"wrote {args.out / 'real_optiodom.md'}, .json and .png")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
