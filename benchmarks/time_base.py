"""Both real robots: the kinematic calibration on the file's time base against the tracker's, on every held-out
session, through the command line as a user runs it.

OptiOdom's synchronisation resampled each run's motion capture over [gt_ti, gt_tf] (tracker clock) onto the
odometry rows of [odo_ti, odo_tf] (the log's clock); the metadata keeps both windows. On omni4 the tracker
window is 1.06× (circles) to 1.11× (squares) the odometry window, on omni3 1.01–1.02×. ``omni-gym import
optiodom --time-base tracker`` (the default where the windows exist) gives each row the tracker's share of the
run and keeps the logged wheel speeds; ``--time-base file`` is the time column as written. Per robot and time
base::

    omni-gym import optiodom TRAIN_SESSIONS --out TRAIN --time-base B
    omni-gym calibrate TRAIN --out kinematic.json
    omni-gym import optiodom HELDOUT --out HELD --time-base B
    omni-gym score HELD --model kinematic.json --linear-map-from TRAIN --json

Both imports have the same rows and tracked poses, so the position RMS [mm] (open-loop replay from each run's
start pose, mean over the session's runs) is comparable between them. Training and held-out sessions are those
of ``benchmarks/real_optiodom.py``. Also reported: the calibrated wheel diameters and size (l1 + l2 or L) per
time base.

    python benchmarks/time_base.py --out benchmarks/results/time_base.md
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from real_optiodom import ROBOTS, omni_gym  # noqa: E402  (the benchmark's split of sessions; the command line)

from omni_gym.record_paths import record_args  # noqa: E402

BASES = ("file", "tracker")


def robot_rows(name: str, work: Path) -> tuple[list[dict], dict]:
    """Per held-out session: position RMS of the calibration and of the linear map on each time base; and the
    calibrations (time base → calibrate's JSON summary)."""
    robot = ROBOTS[name]
    rows: dict[str, dict] = {}
    calibrations = {}
    for base in BASES:
        train = work / f"{name}_{base}_train"
        omni_gym("import", "optiodom", *[str(robot.data / s) for s in robot.train], "--out", str(train),
                 "--time-base", base)
        kinematic = work / f"{name}_{base}_kinematic.json"
        omni_gym("calibrate", str(train), "--out", str(kinematic))
        calibrations[base] = json.loads(kinematic.read_text())
        for session in robot.heldout:
            held = work / f"{name}_{base}_{session.replace('/', '_')}"
            omni_gym("import", "optiodom", str(robot.data / session), "--out", str(held), "--time-base", base)
            models = json.loads(omni_gym("score", str(held), "--model", str(kinematic), "--linear-map-from",
                                         str(train), "--json"))["models"]
            names = list(models)  # nominal, kinematic, linear map
            row = rows.setdefault(session, {"robot": name, "session": session, "runs": models[names[0]]["runs"]})
            row[base] = {"kinematic": models[names[1]], "linear_map": models[names[2]]}
            print(f"{name} {session} {base}: kinematic {1e3 * models[names[1]]['mean_position_rms']:.1f} mm, "
                  f"linear map {1e3 * models[names[2]]['mean_position_rms']:.1f} mm", flush=True)
    return list(rows.values()), calibrations


def geometry(model: dict) -> str:
    """Wheel diameters [mm] and the wheel-centre size of a calibrated model JSON."""
    scale = model.get("effects", {}).get("wheel_radius", {}).get("scale", [1.0] * len(model["wheels"]))
    d = [2e3 * model["wheel_radius"] * s for s in scale]
    distance = model.get("effects", {}).get("wheel_geometry", {}).get("distance", [1.0] * len(model["wheels"]))
    reach = max(math.hypot(*w["position"]) * f for w, f in zip(model["wheels"], distance, strict=True))
    return f"D {', '.join(f'{v:.1f}' for v in d)} mm; wheel centres {1e3 * reach:.1f} mm from the centre"


def table(rows: list[dict], calibrations: dict, command: str, wall_s: float) -> str:
    lines = [
        "# The log's time base: kinematic calibration on the file's time column against the tracker's clock",
        "",
        f"`{command}` ({wall_s:.0f} s on 2 cores). Per time base: `omni-gym import optiodom … --time-base B`, "
        "`omni-gym calibrate TRAIN`, and per held-out session `omni-gym score HELD --model kinematic.json "
        "--linear-map-from TRAIN --json`. Position RMS [mm]: open-loop replay from each run's start pose, mean "
        "over the session's runs (the same rows and tracked poses on both time bases).",
        "",
        "| robot | held-out session | runs | kinematic, file | kinematic, tracker | tracker ÷ file | "
        "linear map, file | linear map, tracker |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        f, t = r["file"], r["tracker"]
        kf, kt = f["kinematic"]["mean_position_rms"], t["kinematic"]["mean_position_rms"]
        lines.append(f"| {r['robot']} | {r['session']} | {r['runs']} | {1e3 * kf:.1f} | {1e3 * kt:.1f} | "
                     f"{kt / kf:.2f} | {1e3 * f['linear_map']['mean_position_rms']:.1f} | "
                     f"{1e3 * t['linear_map']['mean_position_rms']:.1f} |")
    for robot in dict.fromkeys(r["robot"] for r in rows):
        mine = [r for r in rows if r["robot"] == robot]
        ratios = [r["tracker"]["kinematic"]["mean_position_rms"] / r["file"]["kinematic"]["mean_position_rms"]
                  for r in mine]
        lines += ["", f"**{robot}**: tracker ÷ file {min(ratios):.2f}–{max(ratios):.2f} (mean "
                  f"{sum(ratios) / len(ratios):.2f}) over {len(mine)} held-out sessions. Calibrated on the file's "
                  f"time base: {geometry(calibrations[robot]['file'])}; on the tracker's: "
                  f"{geometry(calibrations[robot]['tracker'])}."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=sorted(ROBOTS))
    parser.add_argument("--out", type=Path, default=None, help="markdown table (and .json beside it)")
    args = parser.parse_args(argv)
    t0 = time.monotonic()
    rows: list[dict] = []
    calibrations: dict = {}
    with tempfile.TemporaryDirectory(prefix="omni-gym-time-base-") as tmp:
        for name in args.robots:
            mine, cal = robot_rows(name, Path(tmp))
            rows += mine
            calibrations[name] = cal
    command = "python benchmarks/time_base.py" + ("" if argv is None and len(sys.argv) == 1 else " " +
                                                   " ".join(record_args(argv if argv is not None else sys.argv[1:])))
    text = table(rows, calibrations, command, time.monotonic() - t0)
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        args.out.with_suffix(".json").write_text(json.dumps({"rows": rows, "calibrations": calibrations}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
