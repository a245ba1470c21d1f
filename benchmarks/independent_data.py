"""The workflow on data from an independent implementation (issue 15 item 6): the outcome per seed.

Datasets from :mod:`omni_gym.discrepancy.reference_data` (the validation integrator, white tracker noise
1 mm in x and y and 2 mrad in heading, random twist steps; Williams robot, carpet, initial friction):
nothing hidden (expect ``none``) and a 16 mm centre-of-mass offset in a random direction drawn from
``default_rng(1000 + seed)`` (expect ``com_offset`` within 2 mm). One JSON line per case on stdout,
then the counts.

    python benchmarks/independent_data.py --seeds 1 2 --runs 8 --duration 5
    python benchmarks/independent_data.py --seeds 1 2 3 --runs 4 --duration 3 --noisy-start
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from omni_gym.discrepancy.recovery import TOLERANCES, nominal_model, param_error
from omni_gym.discrepancy.reference_data import write_reference_dataset
from omni_gym.discrepancy.workflow import gap

SIZE = 0.016  # m: the centre-of-mass offset


def run(kind: str, seed: int, runs: int, duration: float, noisy_start: bool) -> dict:
    """Generate one dataset (``kind`` none or com), run ``gap``, score the answer."""
    model = nominal_model()
    hidden, truth = None, None
    if kind == "com":
        a = np.random.default_rng(1000 + seed).uniform(-math.pi, math.pi)
        truth = {"com": [SIZE * math.cos(a), SIZE * math.sin(a)]}
        hidden = {"com_offset": truth}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "data"
        write_reference_dataset(folder, model, hidden, runs, duration, seed, noisy_start=noisy_start)
        t0 = time.perf_counter()
        result = gap(folder, None, seed=seed, progress=False)
        wall = time.perf_counter() - t0
    g = result["gap"]
    out = {"kind": kind, "seed": seed, "runs": runs, "duration": duration, "noisy_start": noisy_start,
           "effect": result["effect"], "why": result["why"], "nominal_rms_mm": 1e3 * g["rms_before"],
           "noise_components_mm": {k: (None if v is None else 1e3 * v) for k, v in g["noise_components"].items()
                                   if k in ("tracker", "integration", "floor")},
           "reduction": g["reduction"], "wall_s": wall}
    if kind == "none":
        out["correct"] = result["effect"] == "none"
    else:
        out["truth"], out["fitted"] = truth, result.get("params")
        ok = result["effect"] == "com_offset"
        if ok:
            err = param_error("com_offset", truth, result["params"], model)["com"]
            out["com_error_mm"] = 1e3 * err
            ok = err <= TOLERANCES["com_offset"]["com"]
        out["correct"] = ok
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--duration", type=float, default=5.0)
    ap.add_argument("--kinds", nargs="+", default=["none", "com"], choices=["none", "com"])
    ap.add_argument("--noisy-start", action="store_true", help="noise on each run's first pose too")
    args = ap.parse_args()
    done = []
    for seed in args.seeds:
        for kind in args.kinds:
            r = run(kind, seed, args.runs, args.duration, args.noisy_start)
            print(json.dumps(r), flush=True)
            done.append(r)
    for kind in args.kinds:
        rs = [r for r in done if r["kind"] == kind]
        print(f"{kind}: right answer in {sum(r['correct'] for r in rs)}/{len(rs)}")


if __name__ == "__main__":
    main()
