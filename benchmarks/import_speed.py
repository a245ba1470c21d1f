"""How long ``omni-gym import rosbag2`` and ``import csv`` take on a 10-minute log.

    python benchmarks/import_speed.py --out benchmarks/results [--minutes 10] [--rate 100]

Writes one rosbag2 recording (MCAP) and one CSV file of ``--minutes`` of a robot driving (wheel joint
positions and a tracked pose, both at ``--rate`` Hz; the motion is a smooth made-up path: the import does
not simulate, so its cost depends only on the message count), then times each import as the command line
runs it (``omni_gym.cli.main``), one after the other in this process. Writes ``import_speed.md`` with the
command, the machine's load average and the seconds per step.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def made_up_log(minutes: float, rate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (K,) [s], wheel angles (K, 3) [rad], pose (K, 3)) of a robot driving slow circles and turns."""
    t = np.arange(0.0, minutes * 60.0, 1.0 / rate)
    theta = 0.3 * np.sin(0.2 * t)
    pose = np.column_stack([0.5 * np.cos(0.1 * t), 0.5 * np.sin(0.1 * t), theta])
    angles = np.column_stack([2.0 * t + np.sin(0.3 * t), -1.5 * t + np.cos(0.2 * t), 1.0 * t])
    return t, angles, pose


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True, help="folder for import_speed.md")
    p.add_argument("--minutes", type=float, default=10.0, help="log length [min]")
    p.add_argument("--rate", type=float, default=100.0, help="joint and pose message rate [Hz]")
    args = p.parse_args(argv)
    from omni_gym.cli import main as cli
    from omni_gym.discrepancy.synthetic.bags import write_bag

    t, angles, pose = made_up_log(args.minutes, args.rate)
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        write_bag(tmp / "bag", [(t, angles, pose)], ["a", "b", "c"], [1.0, 1.0, 1.0], storage="mcap")
        rows["write the bag (rosbags writer)"] = time.perf_counter() - t0
        table = np.column_stack([t, angles, pose]).tolist()
        lines = ["t,a,b,c,x,y,th"] + [",".join(repr(v) for v in row) for row in table]
        (tmp / "log.csv").write_text("\n".join(lines) + "\n")
        t0 = time.perf_counter()
        assert cli(["import", "rosbag2", str(tmp / "bag"), "--model", "williams2002", "--joints", "a,b,c",
                    "--pose-topic", "/tracker/pose", "--out", str(tmp / "ds_bag")]) == 0
        rows["omni-gym import rosbag2"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        assert cli(["import", "csv", str(tmp / "log.csv"), "--model", "williams2002", "--columns",
                    "t=t,x=x,y=y,theta=th,enc1=a,enc2=b,enc3=c", "--out", str(tmp / "ds_csv")]) == 0
        rows["omni-gym import csv"] = time.perf_counter() - t0
    n = len(t)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    text = [f"# Import speed: a {args.minutes:g}-minute log ({n} joint and {n} pose messages)", "",
            f"`python benchmarks/import_speed.py --out {args.out} --minutes {args.minutes:g} --rate {args.rate:g}`; "
            f"load average at the end {load:.1f} (a shared machine: compare within one run).", "",
            "| step | seconds |", "|---|---|"]
    text += [f"| {k} | {v:.1f} |" for k, v in rows.items()]
    (out / "import_speed.md").write_text("\n".join(text) + "\n")
    print("\n".join(text))
    return 0


if __name__ == "__main__":
    sys.exit(main())
