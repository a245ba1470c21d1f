"""Both real robots, every held-out session: the extended model and the calibration with its tracked frame
against two kinematic baselines, through ``omni-gym score`` as a user runs it.

Per robot, the training sessions (those of ``benchmarks/real_optiodom.py``) are imported into one dataset and
each held-out session into its own (the importer's defaults: each run on the tracker's clock); then, per
held-out session::

    omni-gym calibrate TRAIN --out kinematic.json
    omni-gym calibrate TRAIN --tracker --out kinematic_tracker.json
    omni-gym score HELDOUT --model kinematic.json --model EXTENDED --model kinematic_tracker.json \
        --linear-map-from TRAIN --json

with EXTENDED the model of ``gap`` on the same training runs with the command line's defaults (the ``model`` of
``benchmarks/results/heldout_sessions_<robot>_gap.json``: the kinematic calibration competes, and what ``gap``
names is added to it). Reported per session: position RMS [mm] of each model (open-loop replay, mean over
runs), each ÷ the kinematic calibration, and the error left after the per-run heading refit (initial heading
offset and yaw-rate scale: run-to-run variation no model of the robot predicts).

    python benchmarks/linear_map_baseline.py --out benchmarks/results/linear_map_baseline.md
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from real_optiodom import ROBOTS  # noqa: E402  (the benchmark's own split of sessions)


def omni_gym(*args: str) -> str:
    """Run the command line as a user does; its stdout (a failure raises with its stderr)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "omni_gym.cli", *args], capture_output=True, text=True, env=env)
    if done.returncode != 0:
        raise RuntimeError(f"omni-gym {' '.join(args)}: {done.stderr.strip()}")
    return done.stdout


KEYS = ("nominal", "kinematic", "extended", "kinematic_tracker", "linear_map")


def robot_rows(name: str, work: Path) -> list[dict]:
    robot = ROBOTS[name]
    train = work / f"{name}_train"
    omni_gym("import", "optiodom", *[str(robot.data / s) for s in robot.train], "--out", str(train))
    kinematic = work / f"{name}_kinematic.json"
    omni_gym("calibrate", str(train), "--out", str(kinematic))
    with_frame = work / f"{name}_kinematic_tracker.json"
    omni_gym("calibrate", str(train), "--tracker", "--out", str(with_frame))
    results = ROOT / "benchmarks" / "results"
    defaults = work / f"{name}_gap_defaults.json"
    defaults.write_text(json.dumps(json.loads((results / f"heldout_sessions_{name}_gap.json").read_text())["model"]))
    rows = []
    for session in robot.heldout:
        held = work / f"{name}_{session.replace('/', '_')}"
        omni_gym("import", "optiodom", str(robot.data / session), "--out", str(held))
        t0 = time.monotonic()
        out = json.loads(omni_gym("score", str(held), "--model", str(kinematic), "--model", str(defaults),
                                  "--model", str(with_frame), "--linear-map-from", str(train), "--json"))
        models = out["models"]
        names = list(models)  # nominal, kinematic, gap defaults, calibration + tracked frame, linear map
        rows.append({"robot": name, "session": session, "runs": models[names[0]]["runs"],
                     "wall_s": time.monotonic() - t0,
                     **{key: models[n] for key, n in zip(KEYS, names, strict=True)}})
        print(f"{name} {session}: " + ", ".join(f"{k} {1e3 * rows[-1][k]['mean_position_rms']:.1f} mm"
                                                 for k in KEYS), flush=True)
    return rows


def table(rows: list[dict], command: str, wall_s: float) -> str:
    lines = [
        "# Both real robots: the extended model and the calibration with its tracked frame against the kinematic "
        "calibration and a linear wheel-to-twist map",
        "",
        f"`{command}` ({wall_s:.0f} s on 2 cores). Each held-out session imported on its own and scored with "
        "`omni-gym score HELDOUT --model kinematic.json --model EXTENDED --model kinematic_tracker.json "
        "--linear-map-from TRAIN --json`: position RMS [mm], open-loop replay from each run's start pose, mean over "
        "the session's runs. kinematic: `omni-gym calibrate TRAIN`, replayed in the simulator; extended: the model "
        "of `gap TRAIN` with its defaults (`heldout_sessions_<robot>_gap.json`); calibration + tracked frame: "
        "`omni-gym calibrate TRAIN --tracker` (the tracked point's offset and yaw fitted with the kinematics over "
        "whole runs); tracker parts applied by `score`; linear map: 3 × n, fitted on TRAIN, dead-reckoned from "
        "each run's encoders. Refit: the error left after a per-run initial heading offset and yaw-rate scale "
        "(what no model of the robot predicts).",
        "",
        "| robot | held-out session | runs | nominal | kinematic | extended (gap defaults) | calibration + tracked "
        "frame | linear map | extended ÷ kinematic | calibration + frame ÷ kinematic | linear map ÷ kinematic | "
        "calibration + frame, refit | linear map, refit |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        k = r["kinematic"]["mean_position_rms"]
        mm = {key: 1e3 * r[key]["mean_position_rms"] for key in KEYS}
        lines.append(
            f"| {r['robot']} | {r['session']} | {r['runs']} | {mm['nominal']:.1f} | {mm['kinematic']:.1f} | "
            f"{mm['extended']:.1f} | {mm['kinematic_tracker']:.1f} | {mm['linear_map']:.1f} | "
            f"{r['extended']['mean_position_rms'] / k:.2f} | {r['kinematic_tracker']['mean_position_rms'] / k:.2f} | "
            f"{r['linear_map']['mean_position_rms'] / k:.2f} | "
            f"{1e3 * r['kinematic_tracker']['mean_refit_position_rms']:.1f} | "
            f"{1e3 * r['linear_map']['mean_refit_position_rms']:.1f} |")
    for robot in dict.fromkeys(r["robot"] for r in rows):
        mine = [r for r in rows if r["robot"] == robot]
        ratio = {key: [r[key]["mean_position_rms"] / r["kinematic"]["mean_position_rms"] for r in mine]
                 for key in ("extended", "kinematic_tracker", "linear_map")}
        span = {key: f"{min(v):.2f}–{max(v):.2f} (mean {sum(v) / len(v):.2f})" for key, v in ratio.items()}
        wins = sum(e < m for e, m in zip(ratio["kinematic_tracker"], ratio["linear_map"], strict=True))
        lines += ["", f"**{robot}** (÷ kinematic): extended {span['extended']}; calibration + tracked frame "
                  f"{span['kinematic_tracker']}; linear map {span['linear_map']}. The calibration with its tracked "
                  f"frame beats the linear map on {wins} of {len(mine)} sessions."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=sorted(ROBOTS))
    parser.add_argument("--out", type=Path, default=None, help="markdown table (and .json beside it)")
    args = parser.parse_args(argv)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="omni-gym-linear-map-") as tmp:
        rows = [row for name in args.robots for row in robot_rows(name, Path(tmp))]
    command = "python benchmarks/linear_map_baseline.py" + ("" if argv is None and len(sys.argv) == 1 else " " +
                                                             " ".join(argv if argv is not None else sys.argv[1:]))
    text = table(rows, command, time.monotonic() - t0)
    print(text)
    if args.out:
        args.out.write_text(text)
        args.out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
