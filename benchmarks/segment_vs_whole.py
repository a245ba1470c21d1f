"""Does the segment score the fit uses rank models as whole-run open-loop drift does? (docs/discrepancy.md)

On the real OptiOdom training sessions of both robots, a family of models around the kinematic calibration
(its own per-wheel diameter and length perturbations of ±0.5–2 %, the nominal model) is scored twice: the
pose SSE over the fit's segments (``gap``'s default budget of 120 s, each segment replayed from the tracked
state), and the mean whole-run open-loop position RMS (``omni-gym score``'s measure). Printed: both per
model and their Spearman rank correlation. Run: ``python benchmarks/segment_vs_whole.py`` (about a minute).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from omni_gym.discrepancy.data.dataset import Dataset
from omni_gym.discrepancy.data.importers.optiodom import nominal_model, read_sessions
from omni_gym.discrepancy.data.segments import FIT_BUDGET, fit_data
from omni_gym.discrepancy.decide.score import heldout_whole_runs
from omni_gym.discrepancy.fit.fitting import Evaluator
from omni_gym.discrepancy.fit.kinematic_calibration import calibrate, calibrated_model
from omni_gym.discrepancy.replay.residuals import run_sse
from omni_gym.discrepancy.synthetic.synth import pose_lever

ROOT = Path(__file__).resolve().parents[1] / "data"
ROBOTS = {"omni3": ("optiodom-omni3", ("circular/221220201701", "square/221220201953")),
          "omni4": ("optiodom-omni4", ("circular/080920201015", "square/080920201810"))}


def family(nominal, cal) -> dict:
    """Models around the calibration: each diameter ±1 %, all diameters ±0.5 %, the length ±1 % and ±2 %."""
    D, L = np.asarray(cal.diameters), cal.L
    out = {"nominal": nominal, "kinematic": cal.model}
    for i in range(len(D)):
        for s in (0.99, 1.01):
            d = D.copy()
            d[i] *= s
            out[f"D{i + 1}x{s:g}"] = calibrated_model(nominal, d, L)
    for s in (0.995, 1.005):
        out[f"Dx{s:g}"] = calibrated_model(nominal, D * s, L)
    for s in (0.98, 0.99, 1.01, 1.02):
        out[f"Lx{s:g}"] = calibrated_model(nominal, D, L * s)
    return out


def main() -> None:
    for robot, (folder, sessions) in ROBOTS.items():
        metas, runs = read_sessions([ROOT / folder / s for s in sessions])
        nominal = nominal_model(metas[0])
        ds = Dataset(None, nominal, nominal.to_json(), "", runs)
        cal = calibrate(runs, nominal)
        models = family(nominal, cal)
        fd = fit_data(ds, FIT_BUDGET)
        res = Evaluator(fd.dataset, pose_lever(nominal)).residuals(list(models.values()))
        n = sum(int(np.isfinite(r).all(axis=1).sum()) for r in res[0])
        seg = [math.sqrt(sum(run_sse(r) for r in per_run) / max(n, 1)) for per_run in res]
        rows = heldout_whole_runs(ds, np.zeros(len(runs), dtype=int), {k: [m] for k, m in models.items()}, models)
        whole = [float(np.mean([r.position_rms[k] for r in rows])) for k in models]
        print(f"{robot}: {fd.describe()}")
        for k, a, b in zip(models, seg, whole, strict=True):
            print(f"  {k:12s} segment pose RMS {1e3 * a:7.2f} mm   whole-run position RMS {1e3 * b:7.1f} mm")
        rho = spearmanr(seg, whole).statistic
        rho_k = spearmanr(seg[1:], whole[1:]).statistic
        print(f"  Spearman rank correlation: {rho:.2f} (all), {rho_k:.2f} (without nominal)")


if __name__ == "__main__":
    main()
