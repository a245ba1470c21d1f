"""``omni-gym gap``: localise, explain, add the effect, show the gap before and after."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from omni_gym.discrepancy import plausible
from omni_gym.discrepancy.candidates import candidates
from omni_gym.discrepancy.dataset import load_dataset
from omni_gym.discrepancy.decision import RULES, decide
from omni_gym.discrepancy.events import EVENT_METHOD
from omni_gym.discrepancy.finite import finite_json
from omni_gym.discrepancy.fitting import Evaluator, fit_candidate, make_folds, max_ticks, param_intervals
from omni_gym.discrepancy.localise import localise
from omni_gym.discrepancy.outliers import OUTLIER_RULE, drop_outliers, find_outliers
from omni_gym.discrepancy.residuals import count_components, geo_mse
from omni_gym.discrepancy.simulate import FIT_DT
from omni_gym.discrepancy.synth import pose_lever
from omni_gym.outputs import Output
from omni_gym.physics.liftoff import contact_cases

METRIC = ("held-out pose error beyond tracker noise [m]: sqrt(max(0, M - noise^2)), M the geometric mean over runs "
          "(weighted by observed rows) of each run's mean squared residual over x, y and heading x lever; each run is "
          "predicted by a fit that did not see it")


def gap(dataset: str | Path, out: str | Path | None = None, seed: int = 0, folds: int = 3,
        progress: bool | None = None, dt: float = FIT_DT, plots: bool = True, force: bool = False) -> dict:
    """Run the workflow on ``dataset``; write the report folder ``out`` (if given); return the result.

    ``progress``: tqdm bar on stderr (None: only when stderr is a terminal). Same seed, same result.
    ``out`` is checked and locked before the work starts and appears complete or not at all
    (:class:`omni_gym.outputs.Output`): an existing report is refused unless ``force``; a report that
    is, contains or lies inside the dataset is refused.
    """
    if out is None:
        return _gap(dataset, None, seed, folds, progress, dt, plots)
    with Output(Path(out), "dir", force=force, inputs=[dataset], marker="result.json", what="gap report") as tx:
        return _gap(dataset, tx.path, seed, folds, progress, dt, plots)


def _gap(dataset: str | Path, out: Path | None, seed: int, folds: int, progress: bool | None, dt: float,
         plots: bool) -> dict:
    """The workflow of :func:`gap`; the report is written into ``out`` as it is (no transaction)."""
    from tqdm import tqdm

    show = sys.stderr.isatty() if progress is None else progress
    say = _stage_printer(progress is None and not show)  # redirected stderr: one line per stage
    ds = load_dataset(dataset)
    R = len(ds.runs)
    if R < 2:
        raise ValueError(f"{dataset}: needs at least 2 runs (held-out scoring splits by run), got {R}")
    # Said after the checks: a dataset that is refused gives exactly one line (the error).
    say(f"loaded dataset {dataset} ({R} runs)")
    nominal = ds.model
    lever = pose_lever(nominal)
    say(f"checking {R} runs for tracker outliers")
    flagged = find_outliers(ds, lever)
    ds = drop_outliers(ds, flagged)  # flagged rows count as not observed (outliers.py)
    if flagged:
        say(f"{len(flagged)} outlier row(s) excluded: "
            + ", ".join(f"{o.run} row {o.row}" for o in flagged[:5]) + (" ..." if len(flagged) > 5 else ""))
    say("simulating the nominal model")
    ev = Evaluator(ds, lever, dt=dt)
    rng = np.random.default_rng(seed)
    res0, sse0, sigma = ev.nominal_baseline(nominal)
    n_comp = count_components(ds)
    fold_of = make_folds(R, rng, folds)
    cands = candidates(nominal)
    total = 2 + sum(max_ticks(c) + 1 for c in cands)
    fits = []
    with tqdm(total=total, desc="gap: fitting", file=sys.stderr, disable=not show, unit="batch") as bar:
        say("localising")
        where = localise(ds, nominal, lever, res0, dt=dt, sigma=sigma)
        bar.update(1)
        for i, c in enumerate(cands, start=1):
            say(f"fitting candidate {i}/{len(cands)} {c.name}")
            bar.set_postfix_str(c.name)
            done = bar.n + max_ticks(c) + 1
            fits.append(fit_candidate(c, ev, nominal, fold_of, rng, tick=lambda: bar.update(1)))
            bar.update(max(done - bar.n, 0))  # searches that converge early skip their remaining rounds
        say("deciding")
        decision = decide(sse0, fits, n_comp, sigma, rng)
        bar.update(max(total - bar.n, 0))
    by_name = {f.candidate.name: f for f in fits}
    effect = decision["effect"]
    result: dict = {"effect": effect, "why": decision["why"]}
    if "ambiguous_with" in decision:
        result["ambiguous_with"] = decision["ambiguous_with"]
    noise_var = sigma**2 if sigma is not None else 0.0
    N = float(n_comp.sum())
    if effect in by_name:
        fit = by_name[effect]
        model = nominal.with_effect(effect, fit.params_all)
        after_sse = fit.heldout
        result["params"] = fit.params_all
        result["uncertainty"] = {
            "params_5_95": param_intervals(fit, rng),
            "fold_params": fit.fold_params,
            "note": "5-95 % range of the refit over bootstrap resamples of the runs; fold_params are the fits "
                    "each held-out fold was scored with",
        }
    else:
        model = nominal
        after_sse = sse0
        result["params"] = {}
    if sigma is None:
        result.setdefault("uncertainty", {})["noise"] = (
            "tracker noise cannot be estimated (too few consecutive observed rows): gap values include noise, "
            "and a gap left by an effect cannot be told from noise")
    m0, m1 = geo_mse(sse0, n_comp), geo_mse(after_sse, n_comp)
    before = math.sqrt(max(m0 - noise_var, 0.0))
    after = math.sqrt(max(m1 - noise_var, 0.0))
    result["model"] = model.to_json()
    result["gap"] = {"metric": METRIC, "before": before, "after": after,
                     "reduction": 1.0 - after / before if before > 0 else 0.0,
                     "rms_before": math.sqrt(m0), "rms_after": math.sqrt(m1),
                     "pooled_rms_before": math.sqrt(sse0.sum() / N), "pooled_rms_after": math.sqrt(after_sse.sum() / N),
                     "noise": sigma, "heldout_runs": R,
                     "per_run": [{"run": r.name, "fold": int(k), "rms_before": _rms(a, n), "rms_after": _rms(b, n)}
                                 for r, k, a, b, n in zip(ds.runs, fold_of, sse0, after_sse, n_comp, strict=True)]}
    result["ranking"] = decision["ranking"]
    for entry in result["ranking"]:
        f = by_name.get(entry["effect"])
        if f is not None and f.event_fit is not None:
            # The stochastic candidate's inferred lift events (its held-out score counts them).
            entry["n_params_effective"] = f.n_params_eff
            entry["events"] = f.event_fit.to_json([r.name for r in ds.runs], contact_cases(ds.n_wheels))
            if f.event_fit.note:
                entry["events_note"] = f.event_fit.note
        _annotate(entry, decision["nominal_excess_rms"], nominal)
    result["plausibility"] = {
        "flags": [fl.to_json() for fl in plausible.check(effect, result["params"], nominal)],
        "ranges": plausible.ranges_json(),
        "note": "flags: fitted values of the named effect outside a physically plausible range (flagging only, the "
                "fit is not changed); each ranking entry lists its own under 'implausible'",
    }
    result["outliers"] = {"rows": [o.to_json() for o in flagged], "rule": OUTLIER_RULE}
    result["score_nominal"] = decision["score_nominal"]
    result["where"] = where
    result["settings"] = {"seed": seed, "folds": int(fold_of.max()) + 1, "dt": dt, "lever": lever,
                          "liftoff": EVENT_METHOD, "rules": RULES, "robot_runs_simulated": ev.simulated}
    result["dataset"] = {"path": str(dataset), "runs": R, "description": ds.description}
    result, bad = finite_json(result)  # standard JSON: a value that could not be computed is null
    if bad:
        result["non_finite"] = bad
    if out is not None:
        from omni_gym.discrepancy.report import write_report

        say("writing report")
        write_report(Path(out), result, ds, nominal, model, lever, dt, plots=plots)
    return result


def _rms(sse: float, n: int) -> float | None:
    return float(math.sqrt(sse / n)) if n else None


def _annotate(entry: dict, nominal_excess: float, nominal) -> None:
    """Add to a ranking entry the share of the nominal gap beyond noise it removes (the measure the
    decision's 70 % rule uses; ``improvement`` is the MSE reduction of the 5 % rule) and the fitted
    values outside their plausible range, for candidates that beat nominal (the fit of one that does not
    is no evidence of anything, and a lift-off fit without events sits at its null point)."""
    entry["gap_reduction"] = 1.0 - entry["excess_rms"] / nominal_excess if nominal_excess > 0 else 0.0
    flags = plausible.check(entry["effect"], entry["params"], nominal) if entry["beats_nominal"] else []
    entry["implausible"] = [fl.text() for fl in flags]


def _stage_printer(enabled: bool) -> Callable[[str], None]:
    """One line per stage on stderr, flushed (for logs and pipes, where the tqdm bar is off)."""
    def say(message: str) -> None:
        if enabled:
            print(f"gap: {message}", file=sys.stderr, flush=True)
    return say
