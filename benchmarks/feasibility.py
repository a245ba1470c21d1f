"""Can the wheels transmit what the default references of the path-following ids ask for?

For every ``OmniPathFollow-*`` id, draw the default reference from seeds 0..S−1 (the environments'
distribution, ``agents.traction.reference_demand``), turn it into the open-loop body twists and measure
the share of the traction set each period's twist change uses (Williams et al. 2002, Sec. IV-B; the set
and the two modes are described in ``agents/traction.py`` and ``docs/agents.md``):

* static: the max-force LP (every wheel on a roller, loads as the physics computes them);
* moving: the drive boxes only, around the transverse friction the current motion draws.

Writes DIR/feasibility.md.

    .venv/bin/python benchmarks/feasibility.py [--out benchmarks/results] [--seeds 200]
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.traction import MODES, TractionLimiter, reference_demand  # noqa: E402
from omni_gym.envs import ENV_IDS  # noqa: E402
from omni_gym.envs.config import make_config  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args

COLUMNS = ("peak_speed", "peak_accel", "peak_yaw_rate", "peak_yaw_accel", "utilisation", "steady_utilisation")


def rows(seeds: int) -> list[tuple[str, str, dict[str, tuple[float, float]]]]:
    """(id, mode, column → (median over seeds, max over seeds)) for every path-following id and mode."""
    out = []
    for env_id, (kwargs, _) in ENV_IDS.items():
        if not env_id.startswith("OmniPathFollow"):
            continue
        cfg = make_config(**kwargs)
        model = cfg.base_model()
        for mode in MODES:
            lim = TractionLimiter(model.robot, model.surface, mode=mode, com=model.com)
            demands = [reference_demand(cfg, lim, s) for s in range(seeds)]
            stats = {c: (float(np.median([getattr(d, c) for d in demands])),
                         float(np.max([getattr(d, c) for d in demands]))) for c in COLUMNS}
            out.append((env_id, mode, stats))
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--seeds", type=int, default=200)
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error(f"--seeds must be >= 1, got {args.seeds}")
    table = rows(args.seeds)
    lines = [
        "# Feasibility of the default references (Williams et al. 2002, Sec. IV-B)",
        "",
        f"Produced by: `.venv/bin/python benchmarks/feasibility.py {shlex.join(record_args(sys.argv[1:]))}`",
        "",
        f"Default reference of each path-following id on seeds 0–{args.seeds - 1}, as open-loop body twists at the",
        "control rate. Each cell: median over seeds / max over seeds of the per-episode peak. *utilisation*: the",
        "largest share of the traction set a period's twist change asks for (≤ 1 feasible); *steady*: the share",
        "the motion alone asks for (moving mode). Speeds in m/s, accelerations in m/s², yaw in rad/s, rad/s².",
        "",
        "| id | mode | peak speed | peak accel | peak yaw rate | peak yaw accel | utilisation | steady |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for env_id, mode, s in table:
        cells = " | ".join(f"{s[c][0]:.3f} / {s[c][1]:.3f}" for c in COLUMNS)
        lines.append(f"| {env_id} | {mode} | {cells} |")
    path = Path(args.out)
    path.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path / "feasibility.md", "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
