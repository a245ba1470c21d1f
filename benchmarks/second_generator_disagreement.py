"""Disagreement between the second integrator and the world, nothing hidden, noise-free.

    python benchmarks/second_generator_disagreement.py --out benchmarks/results [--seeds 3]

For each robot (``williams2002`` omni, ``optiodom_omni4`` mecanum) on carpet with the ``initial``
friction model (and ``williams2002`` with ``roller_gap``), each manoeuvre family of
:mod:`omni_gym.analysis.second_generator` and each run length (2.5, 5, 10 s), a few seeds: the same
wheel commands (100 Hz rows, from rest at the origin) are integrated by
:func:`omni_gym.analysis.event_integrator.integrate` (LSODA, rtol 1e-8) and replayed by the world
(:func:`omni_gym.physics.replay.simulate_commands`) at dt = 1 ms (the fit's step), 0.5 ms and
0.25 ms. Residuals at every row in gap's units: x, y [mm] and heading × lever [mm] (lever = largest
wheel-centre distance); pooled RMS = sqrt(mean of the three channels' mean squares). Writes
``second_generator_disagreement.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from omni_gym.analysis.event_integrator import build_plant, integrate
from omni_gym.analysis.second_generator import MANOEUVRES, run_commands
from omni_gym.physics.model import load_model
from omni_gym.physics.replay import simulate_commands

CASES = [("williams2002", "initial"), ("optiodom_omni4", "initial"), ("williams2002", "roller_gap")]
LENGTHS = (2.5, 5.0, 10.0)
DTS = (1e-3, 5e-4, 2.5e-4)


def pooled(res: np.ndarray) -> float:
    """sqrt(mean over the three channels of their mean squares) of (K, 3) residuals."""
    return float(np.sqrt(np.mean(np.mean(res ** 2, axis=0))))


def one(robot: str, friction: str, family: str, length: float, seed: int) -> dict:
    model = load_model(robot, surface="carpet", friction=friction)
    rng = np.random.default_rng(seed)
    times, cmd = run_commands(model, family, length, 100.0, rng)
    plant = build_plant(model)
    lever = float(np.max(np.linalg.norm(plant.positions, axis=1)))
    t0 = time.process_time()
    mine = integrate(plant, times, cmd, times)
    cpu = time.process_time() - t0
    row = {"robot": robot, "friction": friction, "manoeuvre": family, "length": length, "seed": seed,
           "cpu_s": cpu, "events": mine.events}
    scale = np.array([1e3, 1e3, 1e3 * lever])
    worlds = {}
    for dt in DTS:
        world = simulate_commands(model, times, cmd, dt=dt)
        worlds[dt] = world[:, :3]
        res = (mine.pose - world[:, :3]) * scale
        row[f"dt{dt * 1e3:g}ms"] = {"pooled_rms_mm": pooled(res), "rms_mm": np.sqrt(np.mean(res ** 2, 0)).tolist(),
                                     "max_mm": np.abs(res).max(0).tolist(),
                                     "final_mm": np.abs(res[-1]).tolist()}
    # gap's estimate of its fitting step's error (fit/fitting.py): Richardson, 2 x (pose at 1 ms - pose at 0.5 ms)
    row["richardson_1ms_mm"] = pooled(2 * (worlds[1e-3] - worlds[5e-4]) * scale)
    # the integrator's own error: against Radau at a 100-fold tighter tolerance (short runs: Radau is slow)
    if length <= 2.5 and seed == 1:
        tight = integrate(plant, times, cmd, times, method="Radau", rtol=1e-10, atol=1e-12)
        row["self_rtol_mm"] = pooled((mine.pose - tight.pose) * scale)
    return row


def table(rows: list[dict]) -> str:
    lines = ["| robot | friction | manoeuvre | length [s] | runs | pooled RMS 1 ms [mm] (max over seeds) | "
             "0.5 ms | 0.25 ms | largest single residual 1 ms [mm] | gap's Richardson estimate at 1 ms [mm] | "
             "integrator: LSODA rtol 1e-8 vs Radau 1e-10 [mm] |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    keys = sorted({(r["robot"], r["friction"], r["manoeuvre"], r["length"]) for r in rows},
                  key=lambda k: ([c[:2] for c in CASES].index(k[:2]), MANOEUVRES.index(k[2]), k[3]))
    for key in keys:
        rs = [r for r in rows if (r["robot"], r["friction"], r["manoeuvre"], r["length"]) == key]

        def fmt(dt: str, rs=rs) -> str:
            v = [r[dt]["pooled_rms_mm"] for r in rs]
            return f"{np.mean(v):.3f} ({max(v):.3f})"
        biggest = max(max(r["dt1ms"]["max_mm"]) for r in rs)
        selfs = [r["self_rtol_mm"] for r in rs if "self_rtol_mm" in r]
        selfe = f"{max(selfs):.1e}" if selfs else "–"
        rich = np.mean([r["richardson_1ms_mm"] for r in rs])
        lines.append(f"| {key[0]} | {key[1]} | {key[2]} | {key[3]:g} | {len(rs)} | {fmt('dt1ms')} | "
                     f"{fmt('dt0.5ms')} | {fmt('dt0.25ms')} | {biggest:.3f} | {rich:.3f} | {selfe} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--lengths", type=float, nargs="*", default=list(LENGTHS))
    parser.add_argument("--cases", type=int, nargs="*", default=list(range(len(CASES))))
    args = parser.parse_args()
    rows = []
    for c in args.cases:
        robot, friction = CASES[c]
        for family in MANOEUVRES:
            for length in args.lengths:
                for seed in range(1, args.seeds + 1):
                    rows.append(one(robot, friction, family, length, seed))
                    r = rows[-1]
                    print(f"{robot} {friction} {family} {length:g}s seed {seed}: pooled "
                          f"{r['dt1ms']['pooled_rms_mm']:.3f} / {r['dt0.5ms']['pooled_rms_mm']:.3f} / "
                          f"{r['dt0.25ms']['pooled_rms_mm']:.3f} mm (1 / 0.5 / 0.25 ms), cpu {r['cpu_s']:.1f} s",
                          flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "second_generator_disagreement.json").write_text(json.dumps(rows, indent=1) + "\n")
    text = ("# Second integrator against the world, nothing hidden, noise-free\n\n"
            "`python benchmarks/second_generator_disagreement.py --out benchmarks/results "
            f"--seeds {args.seeds}`\n\nPooled RMS over the 100 Hz rows of a run, mean over seeds "
            "(largest seed in brackets), in gap's residual units (x, y, heading × lever) [mm].\n\n"
            + table(rows) + "\n")
    (out / "second_generator_disagreement.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
