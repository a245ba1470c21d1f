"""The gap report: ``result.json``, ``report.md`` and its plots, written atomically into REPORT_DIR."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from omni_gym import outputs
from omni_gym.angles import wrap_angle
from omni_gym.discrepancy.data.dataset import Dataset
from omni_gym.discrepancy.fit.plausible import UNITS
from omni_gym.discrepancy.replay.localise import WINDOW
from omni_gym.discrepancy.replay.measurement import START_WINDOW
from omni_gym.discrepancy.replay.simulate import Job, simulate_jobs
from omni_gym.discrepancy.report.finite import dumps_strict
from omni_gym.physics.effects import REGISTRY
from omni_gym.physics.model import SimModel

PLOTTED_RUNS = 4


def write_report(out: Path, result: dict, ds: Dataset, nominal: SimModel, model: SimModel, lever: float,
                 dt: float, plots: bool = True) -> None:
    """Write plots, model.json (the extended model), report.md and result.json into ``out``.

    ``omni-gym gap`` passes the temporary folder of an :class:`omni_gym.outputs.Output`: the report
    folder appears complete, by one rename, or not at all."""
    out.mkdir(parents=True, exist_ok=True)
    figures = _plots(out, result, ds, nominal, model, lever, dt) if plots else []
    # Standard JSON only (allow_nan=False): the workflow has already turned non-finite values into null.
    _write_text_atomic(out / "model.json", dumps_strict(result["model"]) + "\n")  # omni-gym simulate --model
    _write_text_atomic(out / "report.md", markdown(result, figures))
    _write_text_atomic(out / "result.json", dumps_strict(result) + "\n")


def _write_text_atomic(path: Path, text: str) -> None:
    outputs.write_text_atomic(path, text)


def markdown(result: dict, figures: list[str]) -> str:
    """report.md: outcome, what model.json is for (and next steps when nothing was named), how to read
    the numbers, gap before/after, ranking, localisation, outliers, uncertainty, plots."""
    g = result["gap"]
    effect = result["effect"]
    kept = _kept_steps(result)
    named = [effect] + [k["effect"] for k in kept if k["effect"] != effect]
    title = " + ".join(f"`{e}`" for e in named) if effect in [k["effect"] for k in kept] else f"`{effect}`"
    lines = [f"# Model-discrepancy report: {title}", "",
             f"Dataset `{result['dataset']['path']}`: {result['dataset']['runs']} runs. "
             f"{result['dataset']['description']}", ""]
    lines += _fitted_lines(result)
    lines += [f"**Outcome: {_outcome(result, kept)}**: {result['why']}.", ""]
    statuses = (result.get("identifiability") or {}).get("per_effect_status") or {}
    if kept:  # every kept effect's fitted parameters, in the order the search named them
        lines += ["Fitted parameters:", ""]
        for k in kept:
            params = _param_lines(k["effect"], k.get("params") or {}, statuses.get(k["effect"]))
            lines += [f"`{k['effect']}`:", *params] if params else [f"`{k['effect']}`: no fitted parameters"]
        lines += [""]
        lines += _not_measured_lines(result.get("identifiability"))
    elif result.get("params"):
        first = (result.get("effects") or [effect])[0]
        lines += ["Fitted parameters:", ""] + _param_lines(first, result["params"], statuses.get(first)) + [""]
        lines += _not_measured_lines(result.get("identifiability"))
    flags = result.get("plausibility", {}).get("flags", [])
    if flags:
        lines += ["**Implausible fitted values** (flagged, not changed; such a value usually means the effect "
                  "absorbed another error):", ""]
        lines += [f"* ⚠ {f['param']} = {f['value']:.4g}, plausible [{f['lo']:.4g}, {f['hi']:.4g}]: {f['why']}"
                  for f in flags] + [""]
    lines += _steps_lines(result)
    lines += _identifiability_lines(result.get("identifiability"))
    start = result.get("start") or {}
    lines += _model_json_lines(effect, result.get("effects") or [], start.get("kind"), start.get("kept_effects") or [])
    if effect in ("unexplained", "none"):
        lines += _next_steps(result)
    if result.get("non_finite"):
        lines += ["**Values that could not be computed** (non-finite, written as null in result.json): "
                  + ", ".join(f"`{k}`" for k in result["non_finite"][:10])
                  + (" …" if len(result["non_finite"]) > 10 else ""), ""]
    lines += _how_to_read(result)
    noise = "not estimable (sparse observations)" if g["noise"] is None else f"{_mm(g['noise'])} mm"
    lines += ["## Gap on held-out runs", "",
              f"Metric: {g['metric']}. Tracker noise estimate: {noise}"
              + (f"; noise floor subtracted (tracker noise and the fitting step's own integration error): "
                 f"{_mm(g['noise_floor'])} mm." if g.get("noise_floor") is not None else "."), "",
              "| | nominal | reported model (model.json) |", "|---|---|---|",
              f"| gap beyond noise [mm] | {_mm(g['before'])} | {_mm(g['after'])} |",
              f"| RMS (geometric mean over runs) [mm] | {_mm(g['rms_before'])} | {_mm(g['rms_after'])} |", "",
              f"Gap removed by the reported model: {_pct(g['reduction'])}"
              + (" (no effect was added)." if not result.get("params") else "."), ""]
    lines += _heldout_lines(result)
    best = result["ranking"][0] if result["ranking"] else None
    if best is not None and effect in ("unexplained", "none"):
        lines += [f"The best candidate, `{best['effect']}`, would remove {_pct(best.get('gap_reduction'))} of the "
                  f"gap (a named effect needs {_pct(result['settings']['rules']['min_gap_reduction'])}).", ""]
    lines += ["## Ranking (penalised held-out score, lower is better)", "",
              "| candidate | score | held-out RMS [mm] | gap beyond noise [mm] | gap removed | MSE reduction "
              "| P(better than nominal) | stability | parameters |", "|---|---|---|---|---|---|---|---|---|"]
    for r in result["ranking"]:
        warn = " ⚠" if r.get("implausible") else ""
        lines.append(f"| {r['effect']} | {_num0(r['score'])} | {_mm(r['heldout_rms'])} | {_mm(r['excess_rms'])} "
                     f"| {_pct(r.get('gap_reduction'))} | {_pct(r['improvement'])} "
                     f"| {_num2(r['p_better_than_nominal'])} | {_num2(r['stability'])} | `{_fmt(r['params'])}`{warn} |")
    lines += ["", "Score: Σ_runs n_r·ln(held-out SSE_r / n_r) + p·ln(N) (per-run Gaussian likelihood, BIC penalty; "
              f"the nominal model scores {_num0(result.get('score_nominal'))}). Held-out RMS: geometric mean over "
              "runs. Stability: share of bootstrap resamples of the runs in which the candidate has the best held-out "
              "likelihood."]
    implausible = [f"* {r['effect']}: " + "; ".join(r["implausible"]) for r in result["ranking"]
                   if r.get("implausible")]
    if implausible:  # the legend of ⚠ only with the rows it marks, never a heading without its content
        lines += ["", "⚠ marks a fitted value outside its plausible range:", ""] + implausible
    lines += [""] + [f"Not tried, does not apply to this robot: `{k}` ({why})." for k, why in
                     result.get("not_applicable", {}).items()]
    lines += [""] if result.get("not_applicable") else []
    lines += _where_lines(result["where"])
    lines += _outlier_lines(result.get("outliers"))
    if result.get("uncertainty"):
        u = result["uncertainty"]
        lines += ["", "## Uncertainty", ""]
        if "params_5_95" in u:
            lines += [f"* {k}: [{_num(a)}, {_num(b)}]" for k, (a, b) in u["params_5_95"].items()]
            lines.append(f"* {u['note']}")
        if "noise" in u:
            lines.append(f"* {u['noise']}")
    if figures:
        lines += ["", "## Plots", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"


def _kept_steps(result: dict) -> list[dict]:
    """The steps of the search whose effect the reported model keeps (``result["effects"]``), in order."""
    effects = result.get("effects") or []
    return [st for st in result.get("steps", []) if st.get("status") != "end" and st.get("effect") in effects]


def _gap_shares(kept: list[dict]) -> list[float | None]:
    """Share of the initial gap beyond noise (the first kept step's ``gap_before``) each kept step removed:
    (gap before − gap after) / initial gap; None where a gap is missing."""
    first = kept[0].get("gap_before") if kept else None
    out: list[float | None] = []
    for st in kept:
        if "gap_share" in st:  # the result's own (workflow._steps_json); older results: computed alike
            out.append(st["gap_share"])
            continue
        a, b = st.get("gap_before"), st.get("gap_after")
        out.append(None if first is None or a is None or b is None or first <= 0 else (a - b) / first)
    return out


def _outcome(result: dict, kept: list[dict]) -> str:
    """The outcome heading: the answer, and every kept effect with the share of the gap it removed."""
    effect = result["effect"]
    if not kept:
        return f"`{effect}`"
    parts = [f"`{st['effect']}` " + (f"removed {_pct(share)} of the gap beyond noise" if share is not None else
                                     "(its share of the gap could not be computed)")
             for st, share in zip(kept, _gap_shares(kept), strict=True)]
    if effect in [st["effect"] for st in kept]:
        return " + ".join(f"`{st['effect']}`" for st in kept) + f" ({'; '.join(parts)})"
    return f"`{effect}` (after keeping {'; '.join(parts)})"


def _heldout_lines(result: dict) -> list[str]:
    """The model comparison: nominal, kinematic calibration and the reported model side by side, each run
    replayed whole, open loop, by the models fitted without its fold; per session and over all runs."""
    h = result.get("heldout")
    if not h or not h.get("per_session"):
        return []
    st = result.get("start", {})
    names = list(h["mean"]["mean_position_rms"])
    label = {"nominal": "nominal", "kinematic": "kinematic calibration", "extended": "reported model"}
    head = "| session | runs | " + " | ".join(f"{label.get(n, n)} [mm]" for n in names)
    has_kin = "kinematic" in names
    head += " | reported ÷ kinematic |" if has_kin else " |"
    lines = ["## Held-out whole runs (open loop)", "",
             f"Start model: **{st.get('kind', 'nominal')}** ({st.get('why', '')}). Folds by "
             f"{h['folds_by']}: every run is replayed from its start pose, open loop, by the models fitted "
             "without its fold (the kinematic calibration too). Metric: " + h["metric"] + ".", "",
             head, "|---|---|" + "---|" * (len(names) + has_kin)]

    def row(name: str, block: dict) -> str:
        m = block["mean_position_rms"]
        cells = " | ".join(_mm(m[n]) for n in names)
        ratio = (f" | {m['extended'] / m['kinematic']:.2f} |" if has_kin and m["kinematic"] else " |")
        return f"| {name} | {block['runs']} | {cells}{ratio}"

    lines += [row(f"`{b['session']}`" if b["session"] is not None else "(none recorded)", b)
              for b in h["per_session"]]
    lines += [row("**all runs**", h["mean"]), ""]
    d = h.get("drift_check", {})
    if d.get("dropped"):
        lines += [f"Dropped after the search: {', '.join(f'`{e}`' for e in d['dropped'])}: {d['why']} "
                  f"({d['rule']}).", ""]
    elif d:
        lines += [f"Drift check: {d['rule']}; {d['why']}.", ""]
    return lines


def _steps_lines(result: dict) -> list[str]:
    """The staircase of the multi-effect search: one row per step (shown when it went past one step)."""
    steps = result.get("steps", [])
    if len(steps) < 2:
        return []
    lines = ["## Effects, step by step", "",
             "After naming an effect, the workflow adds it to the model (all-run fit) and searches the remaining "
             "gap again. Held-out gap beyond tracker noise before and after each step (staircase.png):", "",
             "| step | answer | gap before [mm] | gap after [mm] | parameters |", "|---|---|---|---|---|"]
    for st in steps:
        lines.append(f"| {st['step']} | `{st['effect']}` | {_mm(st['gap_before'])} | {_mm(st['gap_after'])} "
                     f"| `{_fmt(st.get('params', {}))}` |")
    lines += ["", "; ".join(f"step {st['step']}: {st['why']}" for st in steps) + ".", ""]
    return lines


def _identifiability_lines(ident: dict | None) -> list[str]:
    """What the data determine of the named effects: one line per effect, then confounded pairs."""
    if not ident:
        return []
    lines = ["## What the data determine (identifiability)", "",
             f"{ident['n_identified']} of {ident['n_params']} parameter combinations are identified. "
             "A parameter that is not is one point of a valley the data leave open: do not read it as a measured "
             "physical value.", ""]
    lines += [f"* {line}" for line in ident["per_effect"].values()]
    if ident.get("refit"):
        lines += ["", "The fit was re-done in the identified subspace: directions the data do not determine are held "
                      "at the start model's values and the determined combinations refitted (all runs, and each "
                      "fold's training runs for the held-out scores); `model.json`, the parameters above and the "
                      "held-out tables use these values. The search's values were: "
                  + "; ".join(f"{e} `{_fmt(p)}`" for e, p in ident.get("search_params", {}).items()) + "."]
    if ident["confounded"]:
        lines += ["", "Confounded (|correlation| > 0.9): " + "; ".join(
            f"{c['a']} ~ {c['b']} ({c['correlation']:+.2f})" for c in ident["confounded"][:8]) + "."]
    lines += ["", f"Method: {ident['note']}.", ""]
    return lines


def _not_measured_lines(ident: dict | None) -> list[str]:
    """The warning under the fitted parameters: which of them the data did not determine, and what was done
    with them (identified_fit.py: merged into a determined combination, fixed at the start model's value, or
    left where the search put them)."""
    status = (ident or {}).get("per_effect_status") or {}
    merged = [f"{e}.{p}" for e, st in status.items() for p in st["merged"]]
    fixed = [f"{e}.{p}" for e, st in status.items() for p in st["fixed"]]
    kept = [f"{e}.{p}" for e, st in status.items() for p in st["kept"]]
    loose = [f"{e}.{p}" for e, st in status.items() for p in st.get("loose", {})]
    held = [f"{e}.{p}" for e, st in status.items() for p in st.get("bound_fixed", {})]
    bound = sorted({f"{e}.{p}" for e, st in status.items() for p in [*st["at_bound"], *st.get("bound_cost", {})]})
    parts = []
    if held:
        parts.append("at their fit bound in the search (compensating another error), held at the start model's "
                     "value: " + ", ".join(held))
    if loose:
        parts.append("only loosely determined (not measurements): " + ", ".join(loose))
    if merged:
        parts.append("determined only in combination (their separate values are not measurements): "
                     + ", ".join(merged))
    if fixed:
        parts.append("not determined, fixed at the start model's value: " + ", ".join(fixed))
    if kept:
        parts.append("not determined, left where the search put them (no start value): " + ", ".join(kept))
    if bound:
        parts.append("at the fit bound (the fit wants a value beyond the range, compensating another error; holding "
                     "it at the start model's value predicts held-out runs worse): " + ", ".join(bound))
    if not parts:
        return []
    return ["⚠ **Not every parameter is a measurement** (see \"What the data determine\"): " + "; ".join(parts)
            + ".", ""]


def _param_lines(effect: str, params: dict, status: dict | None = None) -> list[str]:
    """One bullet per fitted parameter, with its unit; with the effect's identifiability ``status``
    (identified_fit.py), a value that is not a measurement says so: at its fit bound (no value: the fit
    wanted one beyond the range), or determined only in combination / loosely."""
    units = UNITS.get(effect, {})
    out = []
    for k, v in params.items():
        if isinstance(v, list):
            val = "[" + ", ".join(_num(x) + _not_measured(status, f"{k}{i + 1}") for i, x in enumerate(v)) + "]"
        else:
            val = _num(v) + _not_measured(status, k)
        out.append(f"* `{k}` = {val} {units.get(k, '')}".rstrip())
    return out


def _not_measured(status: dict | None, dim: str) -> str:
    """The note after a parameter value that is not a measurement (empty for an identified one)."""
    if not status:
        return ""
    if dim in status.get("bound_cost", {}) or dim in status.get("at_bound", []):
        return " = its fit bound (the fit wants a value beyond it: not a measurement)"
    if dim in status.get("bound_fixed", {}):
        return " (start value: the fit put it at its bound)"
    if dim in status.get("fixed", {}):
        return " (start value: not determined by the data)"
    if dim in status.get("loose", {}) or dim in status.get("merged", []) or dim in status.get("kept", {}):
        return " (not determined alone: not a measurement)"
    return ""


def _fitted_lines(result: dict) -> list[str]:
    """How much of the data the fit used: the fit budget's share of the robot time, and the segments."""
    f = result["dataset"].get("fitted", {})
    if not f:
        return []
    budget = result["settings"].get("fit_budget")
    limit = "no limit (`--fit-budget inf`)" if budget is None else f"{budget:g} s"
    if not f.get("segmented"):
        return [f"**Data fitted**: all {f['source_runs']} runs, {f['seconds']:.1f} s of robot time (fit budget "
                f"{limit}: the whole runs fit within it).", ""]
    share = f["seconds"] / f["total_seconds"] if f["total_seconds"] > 0 else None
    return [f"**Data fitted**: {f['seconds']:.0f} s of the {f['total_seconds']:.0f} s of robot time ({_pct(share)}), "
            f"as {f['fitted_runs']} segments of at most {f['segment_seconds']:g} s from {f['source_runs']} runs, "
            f"each replayed from the tracked state at its start (fit budget {limit}; a larger `--fit-budget` fits "
            "more of the data, slower). Every run in the tables below is such a segment.", ""]


def _model_json_lines(effect: str, effects: list[str], start: str | None = None,
                      kept: list[str] | tuple[str, ...] = ()) -> list[str]:
    """What model.json is for (``start``: result.json's ``start.kind``, the model the search began from;
    ``kept``: its ``start.kept_effects``, carried into model.json as they are)."""
    base = {"kinematic": "the kinematic calibration of the runs",
            "tracker": "the kinematic calibration of the runs with the tracked frame"}.get(start, "the nominal model")
    if effect == "kinematic_calibration" and not effects:
        what = "the kinematic calibration of the runs (effective wheel diameters and size), which explains the data"
    elif effect not in ("unexplained", "none"):
        what = f"{base} with the named effect and its fitted parameters added (the extended model)"
    elif effects:
        what = (f"{base} with {' + '.join(effects)} added as fitted, although together they do not "
                "explain the gap (see the outcome)")
    else:
        what = f"{base} unchanged (no effect was named)"
    tracker = [e for e in dict.fromkeys([*kept, *effects]) if e in REGISTRY and REGISTRY[e].kind == "tracker"]
    note = ([f"Tracker (measurement) effects ({', '.join(tracker)}) explain how the data were measured, not how "
             "the robot moves: model.json keeps them under its `tracker` key, which simulators and environments "
             "ignore.", ""] if tracker else [])
    return ["## model.json", "",
            f"`model.json` in this folder is {what}, in the model JSON format (`docs/formats.md`). Use it:", "",
            "* replay wheel commands: `omni-gym simulate --model REPORT/model.json --commands cmds.csv "
            "--out traj.csv`;",
            "* train or evaluate a controller on it: `gym.make(ENV_ID, model=\"REPORT/model.json\")`, or "
            "`omni-gym train`/`omni-gym evaluate` with `--env-kwargs '{\"model\": \"REPORT/model.json\"}'`;",
            "* inspect it: `omni-gym model show REPORT/model.json` (every effect with its parameters and units).", "",
            *note]


def _how_to_read(result: dict) -> list[str]:
    """Definitions of the two percentages and the gap (they measure different things)."""
    rules = result["settings"]["rules"]
    return ["## How to read this report", "",
            "Every error is a held-out error: each run is predicted by a fit that did not see it. M is the "
            "geometric mean over runs (weighted by observed rows) of a run's mean squared pose residual (x, y and "
            "heading × lever, in m²); σ̂ is the tracker noise estimated from the data.", "",
            "* **gap beyond noise** = sqrt(max(0, M − σ̂²)) [mm]: the part of the pose error a model could remove.",
            "* **gap removed** = 1 − gap_after / gap_before: the share of the nominal gap beyond noise that a "
            "model removes. The outcome line and the naming rule use this measure: an effect is named only if it "
            f"removes ≥ {_pct(rules['min_gap_reduction'])} (or leaves the error at the noise level).",
            "* **MSE reduction** (`improvement` in result.json) = 1 − M_candidate / M_nominal: the share of the "
            "mean squared error removed, noise included. A candidate must reach "
            f"≥ {_pct(rules['min_improvement'])} (and be better in ≥ {_pct(rules['significance'])} of run "
            "resamples) to count as better than nominal at all.",
            "* The two differ because one is squared and the other is not: removing 64 % of the gap leaves "
            "(1 − 0.64)² = 13 % of the squared gap, so with little noise the MSE reduction is about 87 %. "
            "Compare gap removed with gap removed, and MSE reduction with MSE reduction.",
            _score_relation(result), ""]


def _score_relation(result: dict) -> str:
    """How the report's gap relates to ``omni-gym score``'s whole-run position error."""
    f = result["dataset"].get("fitted", {})
    if f.get("segmented"):
        return (f"* **This gap and `omni-gym score`**: the errors here are those of segments of at most "
                f"{f['segment_seconds']:g} s, each replayed from the tracked state at its start; `score` replays "
                "every whole run open loop from its first pose, so its position RMS also holds the drift that "
                "builds up over a whole run, which short segments under-weight: expect it to be larger, and check "
                "model.json on whole runs with `omni-gym score DATASET --model REPORT/model.json`.")
    return ("* **This gap and `omni-gym score`**: both replay whole runs open loop; `score` gives each run's "
            "position RMS (x, y, tracker noise included) and their plain mean, while the gap here also counts "
            "heading × lever, takes the geometric mean over runs and removes the noise floor, so the two differ in "
            "size. Use `omni-gym score DATASET --model REPORT/model.json` to check model.json on new runs.")


def _next_steps(result: dict) -> list[str]:
    """Concrete next steps for an ``unexplained`` or ``none`` outcome, from the localisation."""
    w = result["where"]
    g = result["gap"]
    out = ["## Next steps", ""]
    if result["effect"] == "none":
        if g["noise"] is None:
            out += ["* Tracker noise cannot be estimated from these data (too few consecutive tracked rows), so "
                    "`none` means \"no effect could be told from noise\", not \"the model is right\". Track every "
                    "row (≥ 20 consecutive rows per run) and run again."]
        else:
            start = (result.get("start") or {}).get("kind", "nominal")
            out += [f"* The {start} model predicts the held-out runs to within the noise floor "
                    f"({_mm(g['noise_floor'])} mm: tracker noise {_mm(g['noise'])} mm, integration error and the "
                    f"simulator's validated accuracy): nothing to add; `model.json` is the {start} model.",
                    "* If you expected an effect, check the runs excite it: slow wheel turns through the roller pitch "
                    "(roller_gap), command steps (motor_lag), fast slip (kinetic_friction), long straight drives "
                    "(wheel_radius, com_offset), long runs (wheel_liftoff); more and longer runs, or a less noisy "
                    "tracker, make a small effect visible."]
        return out + [""]
    started = (result.get("start") or {}).get("kind") in ("kinematic", "tracker")
    tried = next((r for r in result.get("ranking", []) if r["effect"] == "kinematic_calibration"), None)
    calibrate = f"`omni-gym calibrate {result['dataset']['path']} --out model.json`"
    if result["effect"] == "unexplained" and tried is not None and not started:
        out.append(f"* **Kinematic calibration**: tried beside the library's effects (`kinematic_calibration` in the "
                   f"ranking: held-out RMS {_mm(tried['heldout_rms'])} mm, {_pct(tried.get('gap_reduction'))} of the "
                   f"gap removed); it does not explain the gap either. {calibrate} writes it as a model file.")
    elif result["effect"] == "unexplained" and not started:
        out.append(f"* **Kinematic calibration**: {calibrate} fits the wheel geometry and radii of a slip-free model "
                   "to the logs, in seconds. When the runs barely slip (a grip floor, odometry logs) it can predict "
                   "new runs much better than the nominal model; compare the two with "
                   f"`omni-gym score {result['dataset']['path']} --model model.json` (better: on runs neither has "
                   "seen).")
    runs = sorted((r for r in w["runs"] if r["open_loop_rms"] is not None), key=lambda r: -r["open_loop_rms"])
    ol, sh = w.get("median_open_loop_rms"), w.get("median_shooting_rms")
    if ol is not None and runs:
        shape = "a drift that builds up over a run" if sh is not None and ol > 2 * sh else \
            "a local error (restarting from the measured state does not remove it)"
        out.append(f"* **What the residual looks like**: {shape}; median open-loop RMS {_mm(ol)} mm"
                   + (f" against {_mm(sh)} mm restarted every 0.5 s." if sh is not None else "."))
        out.append("* **Where**: worst runs " + ", ".join(f"{r['run']} ({_mm(r['open_loop_rms'])} mm)"
                                                         for r in runs[:3])
                   + ("; worst windows " + ", ".join(f"{x['run']} {x['t0']:.2f}-{x['t1']:.2f} s"
                                                     for x in w.get("windows", [])[:3]) if w.get("windows") else "")
                   + ". Look at these stretches in residuals.png and in your logs first.")
    hints = {"accelerating": "actuation (a motor lag beyond first order, current or torque limits, a speed "
                             "controller overshooting): log the wheel encoders at the command steps",
             "rotating": "the wheel positions, the inertia or the heading (tracker frame rotation, gyro): "
                         "re-measure the wheel positions and the tracker's heading offset",
             "fast_slip": "the friction law at high slip speed: measure the drive and transverse friction of "
                          "the wheels on this floor (pull test)"}
    for k, c in w.get("conditions", {}).items():
        if c.get("ratio") is not None and c["ratio"] >= 2.0 and k in hints:
            times = f"{c['ratio']:.1f}×" if c["ratio"] < 100 else "more than 100×"
            out.append(f"* The local error grows {times} faster in {k.replace('_', ' ')} rows than in the others "
                       f"(after removing the tracker-noise share, 2σ̂² per row): check {hints[k]}.")
    mod = {k: v["modulation"] for k, v in w.get("wheel_phase", {}).items() if v.get("modulation") is not None}
    if mod and max(mod.values()) >= 2.0:
        k = max(mod, key=mod.get)
        out.append(f"* The error is modulated over the roller pitch ({k} {mod[k]:.1f}× its mean): check the "
                   "rollers of that wheel (worn, stuck or missing rollers, the gap between them).")
    wheels = w.get("wheels", {})
    checks = [("actuation_rms", "its encoder does not follow the command (motor, driver, encoder)"),
              ("rolling_rms", "its rim speed does not match its ground speed (radius, slip, contact)")]
    for key, what in checks[w.get("commands_from_encoders", False):]:  # commands = encoders: no actuation check
        vals = {k: v[key] for k, v in wheels.items() if v.get(key) is not None}
        if len(vals) >= 2:
            k = max(vals, key=vals.get)
            others = float(np.median([v for j, v in vals.items() if j != k]))
            if others > 0 and vals[k] > 2 * others:
                out.append(f"* {k}: {what}; {vals[k]:.3g} against {others:.3g} for the others.")
    if result["ranking"]:
        b = result["ranking"][0]
        out.append(f"* The best library effect, `{b['effect']}`, removes {_pct(b.get('gap_reduction'))} of the gap: "
                   "part of the error may be that effect, the rest another one (the library fits one effect at a "
                   "time).")
    out += ["* **Effects not in the library** that leave such a gap: speed-proportional drag (rolling resistance, "
            "a cable), a floor slope or unevenness (a drift in one world direction), a tracker clock that runs at "
            "another rate than the odometry's, tracker calibration (scale, skew), wheel-speed saturation, two "
            "effects at once.",
            "* **To measure**: the tracker at rest (noise, drift), straight drives at several constant speeds "
            "(drag, slope, radius), the time offset between command and tracker logs; add encoders if the runs "
            "have none.", ""]
    return out


def _where_lines(w: dict) -> list[str]:
    """The localisation section."""
    lines = ["## Where the nominal model disagrees", "", f"Method: {w['method']}.", ""]
    lines += [f"* {s}" for s in w.get("summary", [])]
    if w.get("note"):
        lines.append(f"* {w['note']}")
    lines += ["", "| run | open-loop RMS [mm] | shooting RMS [mm] | end error [mm] |", "|---|---|---|---|"]
    for r in w["runs"]:
        lines.append(f"| {r['run']} | {_mm(r['open_loop_rms'])} | {_mm(r['shooting_rms'])} | {_mm(r['end_error'])} |")
    if w.get("conditions"):
        lines += ["", "| condition | rows | mean squared growth over 5 rows [mm²] | elsewhere [mm²] | ratio |",
                  "|---|---|---|---|---|"]
        for k, c in w["conditions"].items():
            # Four significant digits on both sides, three on the ratio: the ratio can be recomputed from the row
            # (a fixed number of decimals showed a tiny "elsewhere" as 0.000 beside a ratio in the thousands).
            lines.append(f"| {k} | {c['rows']} | {_sig(c['mean_sq_growth'], 1e6, 4)} "
                         f"| {_sig(c['elsewhere'], 1e6, 4)} | {_sig(c['ratio'], 1.0, 3)} |")
    if w.get("wheel_phase"):
        lines += ["", "Modulation of the local error over the roller pitch (max bin / mean; 1 = none): "
                  + ", ".join(f"{k} {v['modulation']:.2f}" for k, v in w["wheel_phase"].items()
                              if v["modulation"] is not None)]
    if w.get("wheels") and w.get("commands_from_encoders"):
        lines += ["", "The wheel commands are the encoder speeds themselves (a log without commanded speeds), so "
                  "encoder − command is not shown (it is round-off).", "",
                  "| wheel | r·encoder − ground speed RMS [m/s] |", "|---|---|"]
        lines += [f"| {k} | {_num(v['rolling_rms'])} |" for k, v in w["wheels"].items()]
    elif w.get("wheels"):
        lines += ["", "| wheel | encoder − command RMS [rad/s] | r·encoder − ground speed RMS [m/s] |", "|---|---|---|"]
        for k, v in w["wheels"].items():
            lines.append(f"| {k} | {_num(v['actuation_rms'])} | {_num(v['rolling_rms'])} |")
    return lines


def _outlier_lines(outliers: dict | None) -> list[str]:
    """The tracker outlier rows and what was done with them."""
    if not outliers:
        return []
    rows = outliers["rows"]
    lines = ["", "## Tracker outliers", "", f"Rule: {outliers['rule']}.", ""]
    if not rows:
        return lines + ["None found."]
    lines += ["| run | CSV row | t [s] | component | deviation [mm] | threshold [mm] |", "|---|---|---|---|---|---|"]
    lines += [f"| {o['run']} | {o['row']} | {o['t']:.3f} | {o['component']} | {_mm(o['deviation'])} "
              f"| {_mm(o['threshold'])} |" for o in rows]
    return lines


def _fmt(params: dict) -> str:
    def f(v):
        if isinstance(v, list):
            return [f(x) for x in v]
        return None if v is None else round(float(v), 4)

    return ", ".join(f"{k}={f(v)}" for k, v in params.items())


def _mm(v: float | None) -> str:
    return "–" if v is None else f"{1e3 * v:.2f}"


def _num(v: float | None) -> str:
    return "–" if v is None else f"{v:.4g}"


def _num0(v: float | None) -> str:
    return "–" if v is None else f"{v:.0f}"


def _num2(v: float | None) -> str:
    return "–" if v is None else f"{v:.2f}"


def _pct(v: float | None) -> str:
    return "–" if v is None else f"{100 * v:.0f} %"


def _sig(v: float | None, scale: float, digits: int) -> str:
    """``scale·v`` to ``digits`` significant digits ("–" for None)."""
    return "–" if v is None else f"{scale * v:.{digits}g}"


def _plots(out: Path, result: dict, ds: Dataset, nominal: SimModel, model: SimModel, lever: float,
           dt: float) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    order = sorted(range(len(ds.runs)), key=lambda i: -(result["where"]["runs"][i]["open_loop_rms"] or 0.0))
    shown = order[:PLOTTED_RUNS]
    runs = [ds.runs[i] for i in shown]
    named = result.get("effects") or []
    # The extended model's curve only when it differs from the nominal one (no effect added: one curve).
    models = (nominal, model) if named else (nominal,)
    sims = simulate_jobs([Job(m, r) for m in models for r in runs], dt=dt, start_window=START_WINDOW)
    curves = [("nominal", "-", "tab:red", sims[:len(runs)])]
    if named:
        curves.append((f"with {' + '.join(named)}", "--", "tab:blue", sims[len(runs):]))
    files = []
    fig, axes = plt.subplots(1, len(runs), figsize=(4 * len(runs), 4), squeeze=False)
    for j, (ax, run) in enumerate(zip(axes[0], runs, strict=True)):
        ok = run.observed
        ax.plot(run.pose[ok, 0], run.pose[ok, 1], ".", ms=2, color="k", label="measured")
        for name, style, color, sim in curves:
            ax.plot(sim[j][0][:, 0], sim[j][0][:, 1], style, color=color, label=name)
        ax.set_title(run.name)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.axis("equal")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out, "paths.png"))
    fig, axes = plt.subplots(len(runs), 1, figsize=(8, 2.2 * len(runs)), squeeze=False, sharex=True)
    for j, (ax, run) in enumerate(zip(axes[:, 0], runs, strict=True)):
        for name, style, color, sim in curves:
            r = run.pose - sim[j][0]
            r[:, 2] = wrap_angle(r[:, 2]) * lever
            ok = np.all(np.isfinite(r), axis=1)
            ax.plot(run.t[ok], 1e3 * np.linalg.norm(r[ok], axis=1), style, color=color, label=name)
        ax.set_ylabel(f"{run.name}\n|residual| [mm]")
    axes[-1, 0].set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out, "residuals.png"))
    w = result["where"]
    names = [r["run"] for r in w["runs"]]
    # The run names stand upright under the first panel (segments: "session_run-03@45s"); the figure grows
    # with the longest, so the axes keep their height and the y-labels stay inside the figure.
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.2 + 0.075 * max((len(n) for n in names), default=0)))
    x = np.arange(len(names))
    ol = [1e3 * (r["open_loop_rms"] or 0) for r in w["runs"]]
    sh = [1e3 * (r["shooting_rms"] or 0) for r in w["runs"]]
    axes[0].bar(x - 0.2, ol, 0.4, label="open loop")
    axes[0].bar(x + 0.2, sh, 0.4, label=f"restarted every {WINDOW:g} s")
    axes[0].set_ylim(0, 1.3 * max(ol + sh + [1e-3]))  # room for the legend above the bars
    axes[0].set_xticks(x, names, rotation=90, fontsize=7)
    axes[0].set_ylabel("RMS residual [mm]")
    axes[0].legend(fontsize=8)
    axes[0].set_title("per run")
    # How fast the model's error grows after a restart from the measured state (over 5 rows), in the rows
    # of each condition divided by the same in all other rows (tracker noise removed): 1 = no difference.
    conds = w.get("conditions", {})
    axes[1].bar([k.replace("_", " ") for k in conds], [c["ratio"] or 0 for c in conds.values()])
    axes[1].axhline(1.0, color="k", lw=0.8)
    axes[1].set_ylabel("error growth in these rows\n÷ in the other rows")
    axes[1].set_title("where the error grows faster (1 = no difference)", fontsize=10)
    for k, v in w.get("wheel_phase", {}).items():
        bins = [np.nan if b is None else 1e6 * b for b in v["bins"]]
        axes[2].plot((np.arange(len(bins)) + 0.5) / len(bins), bins, "o-", label=k)
    axes[2].set_xlabel("wheel angle / roller pitch")
    axes[2].set_ylabel("error growth over 5 rows\n(mean square) [mm²]")
    axes[2].set_title("error growth by roller position", fontsize=10)
    if w.get("wheel_phase"):
        axes[2].legend(fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out, "where.png"))
    if len(result.get("steps", [])) >= 2:
        files.append(_staircase(plt, out, result))
    plt.close("all")
    return files


def _staircase(plt, out: Path, result: dict) -> str:
    """Held-out gap beyond noise [mm] after each step of the multi-effect search."""
    steps = result["steps"]
    labels = ["nominal"] + [f"+ {st['effect']}" for st in steps if st.get("params") is not None]
    values = [steps[0]["gap_before"]] + [st["gap_after"] for st in steps if st.get("params") is not None]
    fig, ax = plt.subplots(figsize=(1.8 * len(labels) + 2, 3.5))
    x = np.arange(len(labels))
    ax.step(x, [1e3 * (v or 0.0) for v in values], where="mid", color="tab:blue")
    ax.plot(x, [1e3 * (v or 0.0) for v in values], "o", color="tab:blue")
    ax.set_xticks(x, labels)
    ax.set_ylabel("held-out gap beyond noise [mm]")
    ax.set_ylim(bottom=0)
    last = steps[-1]
    ended = {"none": "then the search found no further effect (none)",
             "unexplained": "then a gap remains that no candidate explains (unexplained)"}
    how = (ended.get(last["effect"], f"then {last['effect']}") if last.get("params") is None
           else "stopped at --max-effects, a random effect, or the last candidate")
    ax.set_title(f"Held-out gap left after each effect added;\n{how}", fontsize=10)
    fig.tight_layout()
    return _save(fig, out, "staircase.png")


def _save(fig, out: Path, name: str) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    outputs.write_bytes_atomic(out / name, buf.getvalue())
    return name
