"""`omni-gym gap` with its command-line defaults on data from a second, separately written integrator.

What users run is validated here: every case writes a dataset with
:func:`omni_gym.analysis.second_generator.write_second_dataset` (an integrator of the documented equations
written apart from the world that ``gap`` fits with: scipy ``solve_ivp`` with events at every roller/gap
and lift switch) and runs ``omni-gym gap DATASET --out REPORT --json`` as a subprocess, with no option.
``--generator reference`` uses the first independent integrator instead
(:mod:`omni_gym.discrepancy.synthetic.reference_data`: random twist steps, Williams robot only).

Cases (:func:`cases`), each with its own seed, over both robot types (``williams2002``: three omni wheels;
``optiodom_omni4``: four mecanum wheels; carpet, ``initial`` friction):

* ``none``: nothing hidden (right: ``none``);
* every library effect that applies to the robot, random size and direction (:func:`hidden_effect`):
  right when it is named first with its parameters within the effect's recovery tolerance;
* ``drag``: a viscous body drag, outside the library (right: ``unexplained``).

Each case draws its run count (3-12), run length (2.5-10 s, at most 40 s of robot time in all),
manoeuvre family (steps with rests, smooth paths, turns in place), tracker noise (0.5-3 mm in x and y,
heading noise 2 mrad per mm) and encoder resolution (512-4096 counts per turn) from its seed. Case i of
category k has seed ``seed0 + 1000·robot + 100·k + i + 1`` whatever ``--kinds`` selects.

One JSON line per case on stdout (flushed: a log shows the progress), then the tables, written to
``--out`` (markdown) with the cases beside it (``.json``).

    python benchmarks/independent_data.py --jobs 2 --out benchmarks/results/independent_data.md
    python benchmarks/independent_data.py --per-kind 1 --kinds none com_offset     # a quick look
    python benchmarks/independent_data.py --jobs 2 --seed0 50000 --out /tmp/held_out.md  # another set
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from omni_gym.analysis.second_generator import MANOEUVRES, write_second_dataset
from omni_gym.discrepancy.synthetic.recovery import TOLERANCES, param_error
from omni_gym.physics.effects import REGISTRY
from omni_gym.physics.model import SimModel, load_model

ROBOTS = ("williams2002", "optiodom_omni4")
# New kinds go at the end: a kind's index sets its cases' seeds (see cases()).
KINDS = ("none", "com_offset", "wheel_radius", "wheel_geometry", "tracker_offset", "time_offset", "drag",
         "motor_lag", "kinetic_friction", "wheel_liftoff", "roller_gap", "mecanum_lateral")
PER_KIND = 3  # cases per effect and robot
PER_NONE = 15  # nothing-hidden cases per robot
MAX_ROBOT_TIME = 40.0  # s of robot time per case (run count x length), to keep the study within hours
ENCODER_COUNTS = (512, 1024, 2048, 4096)


def robot_model(robot: str) -> SimModel:
    """The dataset's nominal model of ``robot`` (carpet, ``initial`` friction: what the generator writes)."""
    return load_model(robot, surface="carpet", friction="initial")


def applies(kind: str, model: SimModel) -> bool:
    """Whether category ``kind`` is a case for ``model``'s robot (an effect must apply to its wheels)."""
    return kind in ("none", "drag") or REGISTRY[kind].applies_to(model.robot)


def _between(rng: np.random.Generator, effect: str, key: str) -> float:
    """A value drawn uniformly between the effect's small and large recovery sizes of ``key``."""
    sizes = REGISTRY[effect].recovery_sizes
    lo, hi = sorted((float(sizes["small"][key]), float(sizes["large"][key])))
    return float(rng.uniform(lo, hi)) if hi > lo else lo


def hidden_effect(kind: str, rng: np.random.Generator, model: SimModel) -> dict | None:
    """The hidden effect of one case (``{name: params}``; None for ``none``), drawn from ``rng``: sizes a
    robot of this kind plausibly has, in a random direction."""
    n = model.n_wheels
    sign = 1.0 if rng.random() < 0.5 else -1.0
    if kind == "none":
        return None
    if kind == "com_offset":
        size, a = rng.uniform(0.005, 0.025), rng.uniform(-math.pi, math.pi)
        return {kind: {"com": [size * math.cos(a), size * math.sin(a)]}}
    if kind == "wheel_radius":
        scale = np.ones(n)
        scale[rng.integers(n)] = 1.0 + sign * rng.uniform(0.03, 0.06)
        return {kind: {"scale": [float(v) for v in scale]}}
    if kind == "wheel_geometry":
        i, j = rng.choice(n, 2, replace=False)
        distance, mount = np.ones(n), np.zeros(n)
        distance[i] = 1.0 + sign * rng.uniform(0.02, 0.05)
        mount[j] = rng.choice([-1.0, 1.0]) * rng.uniform(0.02, 0.04)
        return {kind: {"distance": [float(v) for v in distance], "mount": [float(v) for v in mount]}}
    if kind == "tracker_offset":
        size, a = rng.uniform(0.01, 0.03), rng.uniform(-math.pi, math.pi)
        return {kind: {"offset": [size * math.cos(a), size * math.sin(a)], "yaw": sign * rng.uniform(0.01, 0.03)}}
    if kind == "time_offset":
        return {kind: {"delay": sign * rng.uniform(0.02, 0.06)}}
    if kind == "drag":
        return {"drag": float(rng.uniform(2.0, 4.0))}
    if kind == "motor_lag":
        return {kind: {"tau": _between(rng, kind, "tau")}}
    if kind == "kinetic_friction":
        return {kind: {"ratio": float(rng.uniform(0.5, 0.75)), "v_s": float(rng.uniform(0.02, 0.05))}}
    if kind == "wheel_liftoff":
        return {kind: {"lift_rate": _between(rng, kind, "lift_rate"),
                       "recover_rate": _between(rng, kind, "recover_rate")}}
    if kind == "roller_gap":
        robot = model.robot
        pitch = 2 * math.pi / robot.rollers
        return {kind: {"mu_gap": _between(rng, kind, "mu_gap"), "roller_fraction": robot.roller_fraction,
                       "phase": [float(v) for v in rng.uniform(0.0, pitch, n)]}}
    if kind == "mecanum_lateral":
        return {kind: {"ratio": float(rng.uniform(0.92, 0.97))}}
    raise ValueError(f"unknown kind {kind!r}")


def cases(kinds: tuple[str, ...] = KINDS, robots: tuple[str, ...] = ROBOTS, per_kind: int | None = None,
          seed0: int = 0) -> Iterator[dict]:
    """The study's cases (module docstring): per robot and kind, ``per_kind`` cases (default
    :data:`PER_KIND`, :data:`PER_NONE` for ``none``), each with its own seed and generator settings."""
    for robot in robots:
        model = robot_model(robot)
        r = ROBOTS.index(robot)
        for kind in kinds:
            if not applies(kind, model):
                continue
            k = KINDS.index(kind)
            for i in range(per_kind or (PER_NONE if kind == "none" else PER_KIND)):
                seed = seed0 + 1000 * r + 100 * k + i + 1
                rng = np.random.default_rng(10_000 + seed)
                runs = int(rng.integers(3, 13))
                duration = float(np.round(rng.uniform(2.5, 10.0), 1))
                duration = max(2.5, min(duration, math.floor(10 * MAX_ROBOT_TIME / runs) / 10))
                noise = float(np.round(rng.uniform(0.5, 3.0), 2)) * 1e-3
                yield {"kind": kind, "robot": robot, "seed": seed, "runs": runs, "duration": duration,
                       "manoeuvre": str(rng.choice(MANOEUVRES)), "position_noise": noise,
                       "heading_noise": 2.0 * noise, "encoder_counts": int(rng.choice(ENCODER_COUNTS)),
                       "hidden": hidden_effect(kind, rng, model)}


def interleaved(todo: list[dict]) -> list[dict]:
    """``todo`` in round-robin order over (robot, category), so that a study stopped part way has covered every
    category about equally."""
    groups: dict[tuple, list[dict]] = {}
    for c in todo:
        groups.setdefault((c["robot"], c["kind"]), []).append(c)
    out = []
    while any(groups.values()):
        for g in groups.values():
            if g:
                out.append(g.pop(0))
    return out


def previous(log: Path, todo: list[dict], generator: str) -> list[dict]:
    """The results in ``log`` (the JSON lines an earlier run printed, or the ``.json`` list it wrote beside its
    table) of cases that are in ``todo`` exactly (same robot, category, seed and generator settings) and whose
    ``gap`` finished (a case whose command failed or was killed, ``error (exit N)``, runs again); anything else
    in the file is ignored."""
    want = {(c["robot"], c["kind"], c["seed"]): c for c in todo}
    text = Path(log).read_text(encoding="utf-8")
    try:
        rows = json.loads(text)
    except json.JSONDecodeError:
        rows = None
    if not isinstance(rows, list):
        rows = []
        for line in text.splitlines():
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    out = []
    for r in rows:
        c = want.get((r.get("robot"), r.get("kind"), r.get("seed"))) if isinstance(r, dict) else None
        if c is not None and all(r.get(k) == v for k, v in c.items()) and r.get("generator", "second") == generator \
                and not str(r.get("effect", "")).startswith("error"):
            out.append(r)
    return out


def write_case(case: dict, folder: Path, generator: str = "second") -> None:
    """Write the dataset of ``case`` into ``folder`` with ``generator`` (``second`` or ``reference``)."""
    if generator == "second":
        write_second_dataset(folder, robot=case["robot"], hidden=case["hidden"], runs=case["runs"],
                             duration=case["duration"], manoeuvre=case["manoeuvre"],
                             position_noise=case["position_noise"], heading_noise=case["heading_noise"],
                             encoder_counts=case["encoder_counts"], seed=case["seed"])
        return
    from omni_gym.discrepancy.synthetic.reference_data import write_reference_dataset

    write_reference_dataset(folder, robot_model(case["robot"]), case["hidden"], case["runs"], case["duration"],
                            case["seed"], noise_xy=case["position_noise"], noise_heading=case["heading_noise"],
                            noisy_start=True)


def run(case: dict, generator: str = "second") -> dict:
    """Generate one dataset, run ``omni-gym gap DATASET --out REPORT --json`` (the defaults), score the answer."""
    model = robot_model(case["robot"])
    kind, hidden = case["kind"], case["hidden"]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "data"
        write_case(case, folder, generator)
        t0 = time.perf_counter()
        cmd = [sys.executable, "-m", "omni_gym.cli", "gap", str(folder), "--out", str(Path(tmp) / "report"), "--json"]
        proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"})
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return {**case, "generator": generator, "effect": f"error (exit {proc.returncode})", "effects": [],
                "why": proc.stderr[-300:],
                "nominal_rms_mm": math.nan, "floor_mm": None, "start": "-", "wall_s": wall, "correct": False}
    result = json.loads(proc.stdout)
    g = result["gap"]
    floor = g["noise_components"]["floor"]
    out = {**case, "generator": generator, "effect": result["effect"], "effects": result["effects"],
           "why": result["why"],
           "start": result["start"]["kind"], "nominal_rms_mm": 1e3 * g["rms_before"],
           "floor_mm": None if floor is None else 1e3 * floor, "reduction": g["reduction"], "wall_s": wall,
           "fitted": result.get("params")}
    if kind == "none":
        out["correct"] = result["effect"] == "none"
    elif kind == "drag":
        out["correct"] = result["effect"] == "unexplained"
    else:
        ok = result["effect"] == kind
        if ok:
            err = param_error(kind, hidden[kind], result["params"], model)
            out["param_error"] = err
            ok = all(err[k] <= TOLERANCES[kind][k] for k in err)
        out["correct"] = ok
    return out


def _rate(rows: list[dict]) -> str:
    right = sum(r["correct"] for r in rows)
    return f"{right}/{len(rows)} ({100 * right / len(rows):.0f} %)" if rows else "-"


def _bucket_table(done: list[dict], title: str, key, order: list) -> list[str]:
    lines = ["", f"**By {title}**", "", f"| {title} | right | false alarms (nothing hidden) |", "|---|---|---|"]
    for b in order:
        rows = [r for r in done if key(r) == b]
        if rows:
            none = [r for r in rows if r["kind"] == "none"]
            fa = sum(not r["correct"] for r in none)
            lines.append(f"| {b} | {_rate(rows)} | {fa}/{len(none)} |")
    return lines


def table(done: list[dict], command: str, generator: str) -> str:
    """The markdown report: the rate overall, per category and robot, per noise level and run length, the
    false-alarm rate, then one row per case; ``command``: the command line that made it."""
    right = sum(r["correct"] for r in done)
    none = [r for r in done if r["kind"] == "none"]
    fa = [r for r in none if not r["correct"]]
    wall = [r["wall_s"] for r in done]
    source = ("the second integrator, `omni_gym.analysis.second_generator`" if generator == "second" else
              "the reference integrator, `omni_gym.discrepancy.synthetic.reference_data` (noisy first row)")
    lines = ["# Independent data through the command line: the right answer over many cases", "",
             f"`{command}`. Datasets from {source}; each case runs `omni-gym gap DATASET --out REPORT --json` with "
             "the command line's defaults. Right: `none` with nothing hidden, `unexplained` for the drag outside "
             "the library, else the hidden effect named first with its parameters within the effect's recovery "
             "tolerance. Run count, run length, manoeuvre family, tracker noise and encoder resolution vary per "
             "case (`benchmarks/independent_data.py`, module docstring).", "",
             f"**Right answer in {right} of {len(done)} cases ({100 * right / max(len(done), 1):.0f} %)**; "
             f"nothing hidden: `none` in {len(none) - len(fa)} of {len(none)} "
             f"(false alarms {len(fa)}: " + (", ".join(sorted({r['effect'] for r in fa})) or "-") + "). "
             f"Wall time per case: median {np.median(wall):.0f} s, max {max(wall):.0f} s (`gap` in one process, "
             "2-core machine shared with other work).", "",
             "| category | " + " | ".join(ROBOTS) + " | answers given |", "|---|" + "---|" * len(ROBOTS) + "---|"]
    for k in KINDS:
        rows = [r for r in done if r["kind"] == k]
        if not rows:
            continue
        answers: dict[str, int] = {}
        for r in rows:
            answers[r["effect"]] = answers.get(r["effect"], 0) + 1
        per = [_rate([r for r in rows if r["robot"] == rb]) for rb in ROBOTS]
        lines.append(f"| {k} | " + " | ".join(per) + " | "
                     + ", ".join(f"{a} ×{n}" for a, n in sorted(answers.items())) + " |")
    noise_bins = ["0.5-1 mm", "1-2 mm", "2-3 mm"]
    lines += _bucket_table(done, "tracker noise", lambda r: noise_bins[0 if r["position_noise"] < 1e-3 else
                                                                       1 if r["position_noise"] < 2e-3 else 2],
                           noise_bins)
    len_bins = ["2.5-4 s", "4-7 s", "7-10 s"]
    lines += _bucket_table(done, "run length", lambda r: len_bins[0 if r["duration"] < 4 else
                                                                 1 if r["duration"] < 7 else 2], len_bins)
    lines += _bucket_table(done, "manoeuvre", lambda r: r["manoeuvre"], list(MANOEUVRES))
    lines += _bucket_table(done, "run count", lambda r: "3-5" if r["runs"] <= 5 else "6-8" if r["runs"] <= 8
                           else "9-12", ["3-5", "6-8", "9-12"])
    lines += ["", "| category | robot | seed | runs × s | manoeuvre | noise [mm] | counts | hidden | answer (effects) "
              "| parameter error | nominal / floor [mm] | right | wall [s] |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in done:
        err = ", ".join(f"{k} {v:.3g}" for k, v in (r.get("param_error") or {}).items())
        hid = json.dumps(r["hidden"], separators=(",", ":")).replace("|", "/") if r["hidden"] else "-"
        floor = "-" if r["floor_mm"] is None else f"{r['floor_mm']:.2f}"
        lines.append(f"| {r['kind']} | {r['robot']} | {r['seed']} | {r['runs']} × {r['duration']:g} | "
                     f"{r['manoeuvre']} | {1e3 * r['position_noise']:.2f} | {r['encoder_counts']} | `{_round(hid)}` | "
                     f"{r['effect']} ({' + '.join(r['effects']) or '-'}) | {err or '-'} | "
                     f"{r['nominal_rms_mm']:.2f} / {floor} | {'yes' if r['correct'] else '**no**'} | "
                     f"{r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"


def _round(text: str) -> str:
    """Numbers in a JSON string rounded to 4 significant digits (the table stays readable)."""
    import re

    return re.sub(r"-?\d+\.\d+(e-?\d+)?", lambda m: f"{float(m.group()):.4g}", text)


def _command(args: argparse.Namespace) -> str:
    """The command line of this run, with the options that differ from the defaults."""
    parts = ["python benchmarks/independent_data.py", f"--jobs {args.jobs}"]
    if args.resume is not None:
        parts.append(f"--resume {args.resume}")
    if list(args.kinds) != list(KINDS):
        parts.append("--kinds " + " ".join(args.kinds))
    if list(args.robots) != list(ROBOTS):
        parts.append("--robots " + " ".join(args.robots))
    if args.per_kind is not None:
        parts.append(f"--per-kind {args.per_kind}")
    if args.seed0:
        parts.append(f"--seed0 {args.seed0}")
    if args.generator != "second":
        parts.append(f"--generator {args.generator}")
    if args.seeds:
        parts.append("--seeds " + " ".join(str(x) for x in args.seeds))
    if args.out is not None:
        parts.append(f"--out {args.out}")
    return " ".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    ap.add_argument("--per-kind", type=int, default=None, help="cases per category and robot (default: the study's)")
    ap.add_argument("--jobs", type=int, default=1, help="cases run side by side (each gap in one process)")
    ap.add_argument("--seed0", type=int, default=0,
                    help="offset of every case's seed (default 0: the study's own cases; others: held-out sets)")
    ap.add_argument("--generator", choices=("second", "reference"), default="second",
                    help="the independent integrator that writes the data (default: the second one)")
    ap.add_argument("--out", type=Path, default=None, help="markdown table (and .json beside it)")
    ap.add_argument("--resume", type=Path, default=None, metavar="LOG",
                    help="the JSON lines an earlier run of the same cases printed, or the .json it wrote: cases "
                         "found there are not run again (a long study survives an interruption)")
    ap.add_argument("--seeds", type=int, nargs="+", default=None,
                    help="only the study's cases with these seeds (a re-check of chosen cases; the table then "
                         "covers those cases only)")
    args = ap.parse_args()
    todo = interleaved(list(cases(tuple(args.kinds), tuple(args.robots), args.per_kind, args.seed0)))
    if args.seeds:
        unknown = sorted(set(args.seeds) - {c["seed"] for c in todo})
        if unknown:
            ap.error(f"--seeds: no case of this study has seed(s) {unknown}")
        todo = [c for c in todo if c["seed"] in set(args.seeds)]
    done = previous(args.resume, todo, args.generator) if args.resume is not None else []
    seen = {(r["robot"], r["kind"], r["seed"]) for r in done}
    todo = [c for c in todo if (c["robot"], c["kind"], c["seed"]) not in seen]
    print(f"independent_data: {len(todo)} cases to run ({len(done)} from {args.resume}), {args.jobs} at a time",
          file=sys.stderr, flush=True)
    with ProcessPoolExecutor(max(args.jobs, 1)) as pool:
        futures = [pool.submit(run, c, args.generator) for c in todo]
        for fut in as_completed(futures):
            r = fut.result()
            print(json.dumps(r), flush=True)
            done.append(r)
    done.sort(key=lambda r: (ROBOTS.index(r["robot"]), KINDS.index(r["kind"]), r["seed"]))
    text = table(done, _command(args), args.generator)
    print(text)
    if args.out:
        args.out.write_text(text)
        args.out.with_suffix(".json").write_text(json.dumps(done, indent=1) + "\n")


if __name__ == "__main__":
    main()
