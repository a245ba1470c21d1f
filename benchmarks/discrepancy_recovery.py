"""Recovery table of the model-discrepancy workflow.

For every library effect x size x tracker noise x seed: synthesize a dataset with the effect hidden
(Williams robot, carpet, initial friction as the nominal model), run ``omni-gym gap`` on it, and
record the named effect, the parameter error against the truth, the held-out gap reduction and the
wall time. Null (``none``) and out-of-library (viscous drag -> ``unexplained``) rows too, and the
wall time of one 10-run x 5 s dataset per effect (its budget: 2 minutes on 2 cores).

    # the committed table (also `make bench-discrepancy`):
    python benchmarks/discrepancy_recovery.py --seeds 2 --runs 6 --duration 3 --jobs 2 --out benchmarks/results
    python benchmarks/discrepancy_recovery.py --seeds 1 --runs 4 --duration 2.5   # quick look
    # re-run the rows of some effects (e.g. a new one) and merge them into the committed table:
    python benchmarks/discrepancy_recovery.py --seeds 2 --runs 6 --duration 3 --jobs 2 --effects wheel_geometry
    # the cases as Ray tasks (a fresh local Ray with --jobs CPUs, or the cluster at ADDRESS; same table):
    python benchmarks/discrepancy_recovery.py --seeds 2 --runs 6 --duration 3 --ray [ADDRESS]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from omni_gym.discrepancy.synthetic.recovery import NOISES, SIZES, TOLERANCES, run_case
from omni_gym.parallel import add_ray_option, backend_from_options, parallel_map


def _case(args: tuple) -> dict:
    hidden, size, params, noise, seed, runs, duration = args
    out = run_case(hidden, params, noise, seed, runs, duration)
    out["size"] = size
    out["runs"] = runs
    out["duration"] = duration
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--runs", type=int, default=6)
    ap.add_argument("--duration", type=float, default=3.0)
    ap.add_argument("--jobs", type=int, default=2, help="local worker processes (with --ray: the local Ray's CPUs)")
    add_ray_option(ap, "the cases", "--jobs")
    ap.add_argument("--no-budget", action="store_true", help="skip the 10-run x 5 s timing rows")
    ap.add_argument("--budget-only", action="store_true",
                    help="run only the timing rows (of --effects, or of the effects that have one) and replace them "
                         "in the committed OUT/discrepancy_recovery.{json,md}, keeping the sweep rows")
    ap.add_argument("--effects", default=None, metavar="NAME[,NAME...]",
                    help="run only these library effects' rows (sweep and budget) and merge them into the "
                         "committed OUT/discrepancy_recovery.json, replacing their old rows")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    effects = list(SIZES) if args.effects is None else args.effects.split(",")
    unknown = [e for e in effects if e not in SIZES]
    if unknown:
        raise SystemExit(f"--effects: unknown effect(s) {', '.join(unknown)}; library: {', '.join(SIZES)}")
    cases = [(e, size, SIZES[e][size], noise, 100 + s, args.runs, args.duration)
             for e in effects for size in ("small", "large") for noise in NOISES for s in range(args.seeds)]
    if args.effects is None:
        cases += [("none", "-", None, noise, 100 + s, args.runs, args.duration) for noise in NOISES
                  for s in range(args.seeds)]
        cases += [("viscous_drag", "c=4", {"c": 4.0}, noise, 100 + s, args.runs, args.duration) for noise in NOISES
                  for s in range(args.seeds)]
    budget = [] if args.no_budget else [(e, "large", SIZES[e]["large"], 0.001, 7, 10, 5.0) for e in effects]
    if args.budget_only:
        if args.no_budget:
            raise SystemExit("discrepancy_recovery.py: error: --budget-only and --no-budget exclude each other")
        old = json.loads((out / "discrepancy_recovery.json").read_text())
        if args.effects is None:  # the effects whose timing row the committed table has
            budget = [c for c in budget if any(r["hidden"] == c[0] for r in old.get("budget", []))]
        _replace_budget_rows(out, old, [_timed(c, k, len(budget)) for k, c in enumerate(budget, start=1)])
        return
    try:
        backend = backend_from_options(args.jobs, args.ray)
    except ValueError as exc:  # BackendError: ray missing, nothing at the address, a bad --jobs/--workers
        raise SystemExit(f"discrepancy_recovery.py: error: {exc}") from None
    t0 = time.perf_counter()
    finished = [0]

    def progress(i: int, result: dict) -> None:  # one line per case as it finishes (also when piped)
        finished[0] += 1
        hidden, size, _, noise, seed = cases[i][:5]
        print(f"[{finished[0]}/{len(cases)} {(time.perf_counter() - t0) / 60:.1f} min] {hidden} {size} "
              f"{noise * 1e3:g} mm seed {seed}: {result['named']}", file=sys.stderr, flush=True)

    print(f"{len(cases)} cases on {backend.describe()}, then {len(budget)} timed budget rows", file=sys.stderr,
          flush=True)
    results = parallel_map(_case, cases, backend, on_done=progress)  # in the order of the cases, any backend
    sweep_wall = time.perf_counter() - t0
    # Budget rows one at a time: each is timed alone on the machine (2 cores).
    timed = [_timed(c, k, len(budget)) for k, c in enumerate(budget, start=1)]
    runs_note = [f"full sweep: {sweep_wall / 60:.1f} min on {backend.describe()}"]
    if args.effects is not None:
        old = json.loads((out / "discrepancy_recovery.json").read_text())
        keep = [r for r in old["sweep"] if r["hidden"] not in effects]
        # The library's order: the merged rows sit where their effect sits in SIZES; null and drag last.
        order = {e: i for i, e in enumerate([*SIZES, "none", "viscous_drag"])}
        results = sorted(keep + results, key=lambda r: order.get(r["hidden"], len(order)))
        timed = sorted([r for r in old.get("budget", []) if r["hidden"] not in effects] + timed,
                       key=lambda r: order.get(r["hidden"], len(order)))
        runs_note = old.get("runs_note", ["full sweep: see the git history of this table"]) + [
            f"rows of {', '.join(effects)} re-run with --effects: {sweep_wall / 60:.1f} min on {backend.describe()}"]
    (out / "discrepancy_recovery.json").write_text(
        json.dumps({"sweep": results, "budget": timed, "runs_note": runs_note}, indent=1))
    write_table(out, results, timed, args, runs_note)


def _timed(case: tuple, k: int, n: int) -> dict:
    """One budget row, run alone in this process (its wall time is the row's figure)."""
    row = _case(case)
    print(f"[budget {k}/{n}] {case[0]}: {row['wall_s']:.0f} s", file=sys.stderr, flush=True)
    return row


def _budget_line(r: dict) -> str:
    return f"| {r['hidden']} | {r['named']} | {r['reduction']:.2f} | {r['wall_s']:.1f} |"


def _replace_budget_rows(out: Path, old: dict, timed: list[dict]) -> None:
    """--budget-only: the new timing rows replace their effects' rows in the json and in the table's budget
    section (the sweep rows and every note of the table stay as they are)."""
    new = {r["hidden"]: r for r in timed}
    budget = [new.pop(r["hidden"], r) for r in old.get("budget", [])] + list(new.values())
    old["budget"] = budget
    old["runs_note"] = [*old.get("runs_note", []), f"timing rows of {', '.join(r['hidden'] for r in timed)} re-run "
                        "with --budget-only"]
    md = (out / "discrepancy_recovery.md").read_text().split("\n")
    rows = {r["hidden"]: _budget_line(r) for r in budget}
    head = md.index("| effect | named | gap reduction | wall [s] |")
    end = head + 2
    while end < len(md) and md[end].startswith("| "):
        end += 1
    md[head + 2:end] = list(rows.values())
    (out / "discrepancy_recovery.json").write_text(json.dumps(old, indent=1))
    (out / "discrepancy_recovery.md").write_text("\n".join(md))


def _fmt_err(effect: str, rows: list[dict]) -> str:
    errs = [r["param_error"] for r in rows if "param_error" in r]
    if not errs:
        return "–"
    keys = TOLERANCES[effect]
    return ", ".join(f"{k} {np.median([e[k] for e in errs]):.3g} (tol {keys[k]:g})" for k in keys)


def write_table(out: Path, results: list[dict], timed: list[dict], args, runs_note: list[str]) -> None:
    lines = ["# Discrepancy workflow: recovery of hidden effects", "",
             f"`python benchmarks/discrepancy_recovery.py --seeds {args.seeds} --runs {args.runs} "
             f"--duration {args.duration:g} --jobs {args.jobs}"
             + (f" --effects {args.effects}" if args.effects else "")
             + f"` on {platform.machine()} ({os.cpu_count()} cores, "
             "shared with other work while it ran).", "",
             f"Nominal model: Williams robot, carpet, initial friction. Each case: {args.runs} runs of "
             f"{args.duration:g} s (random steps, ramps, rotations, diagonal moves at 50 Hz), tracker noise σ on x, y "
             "(σ/lever on heading), encoders quantised; `gap` with seed = data seed. Parameter errors: median over "
             "the correctly named cases (units: see `TOLERANCES` in `omni_gym/discrepancy/synthetic/recovery.py`). "
             "Gap reduction: 1 − after/before of the held-out gap beyond noise (median; min in brackets).", "",
             "| effect | size | noise [mm] | correct name | other answers | parameter error (median) | params in tol "
             "| gap reduction median [min] | wall [s] |",
             "|---|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple, list[dict]] = {}
    for r in results:
        groups.setdefault((r["hidden"], r["size"], r["noise"]), []).append(r)
    for (e, size, noise), rows in groups.items():
        n = len(rows)
        ok = sum(r["correct"] for r in rows)
        others = sorted({r["named"] for r in rows if not r["correct"]})
        red = [r["reduction"] for r in rows if r["correct"]]
        red_s = f"{np.median(red):.2f} [{min(red):.2f}]" if red and e in SIZES else "–"
        tol = [r.get("params_ok") for r in rows if r["correct"] and e in SIZES]
        tol_s = f"{sum(bool(t) for t in tol)}/{len(tol)}" if tol else "–"
        lines.append(f"| {e} | {size} | {1e3 * noise:g} | {ok}/{n} | {', '.join(others) or '–'} | "
                     f"{_fmt_err(e, rows) if e in SIZES else '–'} | {tol_s} | {red_s} | "
                     f"{np.mean([r['wall_s'] for r in rows]):.1f} |")
    lib = [r for r in results if r["hidden"] in SIZES]
    lines += ["", f"Library effects: correct name in {sum(r['correct'] for r in lib)}/{len(lib)} cases; "
              f"null: `none` in {sum(r['correct'] for r in results if r['hidden'] == 'none')}/"
              f"{sum(r['hidden'] == 'none' for r in results)}; viscous drag: `unexplained` in "
              f"{sum(r['named'] == 'unexplained' for r in results if r['hidden'] == 'viscous_drag')}/"
              f"{sum(r['hidden'] == 'viscous_drag' for r in results)}. Wall time: {'; '.join(runs_note)}."]
    if timed:
        lines += ["", "## Budget: one dataset of 10 runs x 5 s (σ = 1 mm, large size), run alone", "",
                  "| effect | named | gap reduction | wall [s] |", "|---|---|---|---|"]
        for r in timed:
            lines.append(_budget_line(r))
    (out / "discrepancy_recovery.md").write_text("\n".join(lines) + "\n")
    _plot(out, groups)


def _plot(out: Path, groups: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [k for k in groups if k[0] in SIZES]
    labels = [f"{e}\n{s} {1e3 * n:g}mm" for e, s, n in keys]
    rate = [np.mean([r["correct"] for r in groups[k]]) for k in keys]
    red = [np.median([r["reduction"] for r in groups[k] if r["correct"]] or [0.0]) for k in keys]
    fig, ax = plt.subplots(figsize=(max(8, 0.55 * len(keys)), 4))
    x = np.arange(len(keys))
    ax.bar(x - 0.2, rate, 0.4, label="correct-name rate")
    ax.bar(x + 0.2, red, 0.4, label="held-out gap reduction (median)")
    ax.axhline(0.9, color="k", lw=0.8, ls="--")
    ax.axhline(0.7, color="gray", lw=0.8, ls=":")
    ax.set_xticks(x, labels, rotation=90, fontsize=7)
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "discrepancy_recovery.png", dpi=110)


if __name__ == "__main__":
    main()
