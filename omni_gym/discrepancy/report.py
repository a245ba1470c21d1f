"""The gap report: ``result.json``, ``report.md`` and its plots, written atomically into REPORT_DIR."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from omni_gym.discrepancy.dataset import Dataset, write_json_atomic
from omni_gym.discrepancy.simulate import Job, simulate_jobs, wrap
from omni_gym.model import SimModel

PLOTTED_RUNS = 4


def write_report(out: Path, result: dict, ds: Dataset, nominal: SimModel, model: SimModel, lever: float,
                 dt: float, plots: bool = True) -> None:
    """Write plots, model.json (the extended model), report.md and result.json (last: a folder with
    result.json is complete)."""
    out.mkdir(parents=True, exist_ok=True)
    figures = _plots(out, result, ds, nominal, model, lever, dt) if plots else []
    write_json_atomic(out / "model.json", result["model"])  # replayable: omni-gym simulate --model
    _write_text_atomic(out / "report.md", markdown(result, figures))
    write_json_atomic(out / "result.json", result)


def _write_text_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def markdown(result: dict, figures: list[str]) -> str:
    """report.md: outcome, gap before/after, ranking, localisation, uncertainty, plots."""
    g = result["gap"]
    mm = 1e3
    lines = [f"# Model-discrepancy report: `{result['effect']}`", "",
             f"Dataset `{result['dataset']['path']}`: {result['dataset']['runs']} runs. "
             f"{result['dataset']['description']}", "",
             f"**Outcome: `{result['effect']}`**: {result['why']}.", ""]
    if result.get("params"):
        lines += [f"Fitted parameters: `{_fmt(result['params'])}`", ""]
    noise = "not estimable (sparse observations)" if g["noise"] is None else f"{mm * g['noise']:.2f} mm"
    lines += ["## Gap on held-out runs", "",
              f"Metric: {g['metric']}. Tracker noise estimate: {noise}.", "",
              "| | nominal | with the effect |", "|---|---|---|",
              f"| gap beyond noise [mm] | {mm * g['before']:.2f} | {mm * g['after']:.2f} |",
              f"| RMS (geometric mean over runs) [mm] | {mm * g['rms_before']:.2f} | {mm * g['rms_after']:.2f} |", "",
              f"Reduction of the gap: {100 * g['reduction']:.0f} %.", "",
              "## Ranking (penalised held-out score, lower is better)", "",
              "| candidate | score | held-out RMS [mm] | beyond noise [mm] | improvement | P(better than nominal) "
              "| stability | parameters |", "|---|---|---|---|---|---|---|---|"]
    for r in result["ranking"]:
        lines.append(f"| {r['effect']} | {r['score']:.0f} | {mm * r['heldout_rms']:.2f} | {mm * r['excess_rms']:.2f} "
                     f"| {100 * r['improvement']:.0f} % | {r['p_better_than_nominal']:.2f} | {r['stability']:.2f} "
                     f"| `{_fmt(r['params'])}` |")
    lines += ["", "Score: Σ_runs n_r·ln(held-out SSE_r / n_r) + p·ln(N) (per-run Gaussian likelihood, BIC penalty; "
              "the nominal model scores {:.0f}). Held-out RMS: geometric mean over runs. Stability: share of bootstrap "
              "resamples of the runs in which the candidate has the best held-out likelihood.".format(
                  result.get("score_nominal", float("nan"))), ""]
    w = result["where"]
    lines += ["## Where the nominal model disagrees", "", f"Method: {w['method']}.", ""]
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
            ratio = "–" if c["ratio"] is None else f"{c['ratio']:.2f}"
            lines.append(f"| {k} | {c['rows']} | {1e6 * c['mean_sq_growth']:.3f} | {1e6 * c['elsewhere']:.3f} "
                         f"| {ratio} |")
    if w.get("wheel_phase"):
        lines += ["", "Modulation of the local error over the roller pitch (max bin / mean; 1 = none): "
                  + ", ".join(f"{k} {v['modulation']:.2f}" for k, v in w["wheel_phase"].items()
                              if v["modulation"] is not None)]
    if w.get("wheels"):
        lines += ["", "| wheel | encoder − command RMS [rad/s] | r·encoder − ground speed RMS [m/s] |", "|---|---|---|"]
        for k, v in w["wheels"].items():
            lines.append(f"| {k} | {_num(v['actuation_rms'])} | {_num(v['rolling_rms'])} |")
    if result.get("uncertainty"):
        u = result["uncertainty"]
        lines += ["", "## Uncertainty", ""]
        if "params_5_95" in u:
            lines += [f"* {k}: [{a:.4g}, {b:.4g}]" for k, (a, b) in u["params_5_95"].items()]
            lines.append(f"* {u['note']}")
        if "noise" in u:
            lines.append(f"* {u['noise']}")
    if figures:
        lines += ["", "## Plots", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"


def _fmt(params: dict) -> str:
    def f(v):
        return [round(float(x), 4) for x in v] if isinstance(v, list) else round(float(v), 4)

    return ", ".join(f"{k}={f(v)}" for k, v in params.items())


def _mm(v: float | None) -> str:
    return "–" if v is None else f"{1e3 * v:.2f}"


def _num(v: float | None) -> str:
    return "–" if v is None else f"{v:.4g}"


def _plots(out: Path, result: dict, ds: Dataset, nominal: SimModel, model: SimModel, lever: float,
           dt: float) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    order = sorted(range(len(ds.runs)), key=lambda i: -(result["where"]["runs"][i]["open_loop_rms"] or 0.0))
    shown = order[:PLOTTED_RUNS]
    runs = [ds.runs[i] for i in shown]
    sims = simulate_jobs([Job(m, r) for m in (nominal, model) for r in runs], dt=dt)
    nom, fit = sims[:len(runs)], sims[len(runs):]
    label = result["effect"] if result["effect"] in nominal.effects or result.get("params") else "nominal"
    files = []
    fig, axes = plt.subplots(1, len(runs), figsize=(4 * len(runs), 4), squeeze=False)
    for ax, run, (pn, _), (pf, _) in zip(axes[0], runs, nom, fit, strict=True):
        ok = run.observed
        ax.plot(run.pose[ok, 0], run.pose[ok, 1], ".", ms=2, color="k", label="measured")
        ax.plot(pn[:, 0], pn[:, 1], "-", color="tab:red", label="nominal")
        ax.plot(pf[:, 0], pf[:, 1], "--", color="tab:blue", label=f"with {label}")
        ax.set_title(run.name)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.axis("equal")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out, "paths.png"))
    fig, axes = plt.subplots(len(runs), 1, figsize=(8, 2.2 * len(runs)), squeeze=False, sharex=True)
    for ax, run, (pn, _), (pf, _) in zip(axes[:, 0], runs, nom, fit, strict=True):
        for p, style, name in ((pn, "-", "nominal"), (pf, "--", f"with {label}")):
            r = run.pose - p
            r[:, 2] = wrap(r[:, 2]) * lever
            ok = np.all(np.isfinite(r), axis=1)
            ax.plot(run.t[ok], 1e3 * np.linalg.norm(r[ok], axis=1), style, label=name)
        ax.set_ylabel(f"{run.name}\n|residual| [mm]")
    axes[-1, 0].set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out, "residuals.png"))
    w = result["where"]
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8))
    names = [r["run"] for r in w["runs"]]
    x = np.arange(len(names))
    ol = [1e3 * (r["open_loop_rms"] or 0) for r in w["runs"]]
    sh = [1e3 * (r["shooting_rms"] or 0) for r in w["runs"]]
    axes[0].bar(x - 0.2, ol, 0.4, label="open loop")
    axes[0].bar(x + 0.2, sh, 0.4, label="multiple shooting")
    axes[0].set_xticks(x, names, rotation=90, fontsize=7)
    axes[0].set_ylabel("RMS residual [mm]")
    axes[0].legend(fontsize=8)
    axes[0].set_title("per run")
    conds = w.get("conditions", {})
    axes[1].bar(list(conds), [c["ratio"] or 0 for c in conds.values()])
    axes[1].axhline(1.0, color="k", lw=0.8)
    axes[1].set_ylabel("local error growth: in / elsewhere")
    axes[1].set_title("per condition")
    for k, v in w.get("wheel_phase", {}).items():
        bins = [np.nan if b is None else 1e6 * b for b in v["bins"]]
        axes[2].plot((np.arange(len(bins)) + 0.5) / len(bins), bins, "o-", label=k)
    axes[2].set_xlabel("wheel angle / roller pitch")
    axes[2].set_ylabel("mean squared growth over 5 rows [mm²]")
    axes[2].set_title("per roller phase")
    if w.get("wheel_phase"):
        axes[2].legend(fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out, "where.png"))
    plt.close("all")
    return files


def _save(fig, out: Path, name: str) -> str:
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".png", dir=out)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=110)
        os.replace(tmp, out / name)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return name
