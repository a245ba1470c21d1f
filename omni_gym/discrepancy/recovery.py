"""Recovery study: hide an effect in synthetic data, run the workflow, compare with the truth.

Shared by ``tests/test_discrepancy_recovery.py`` and ``benchmarks/discrepancy_recovery.py`` so that
both measure the same thing: the named effect, the parameter error and the held-out gap reduction.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from omni_gym.discrepancy.synth import write_synthetic
from omni_gym.discrepancy.workflow import gap
from omni_gym.physics.model import SimModel, load_model

# Two sizes of every library effect on the Williams robot (carpet, initial friction): "large" is
# the default of omni-gym synth (roller_gap: the paper's carpet values), "small" about half of it.
# roller_gap's size is the rigid-material coefficient mu'' (roller fraction 0.9, random phases).
SIZES: dict[str, dict[str, dict]] = {
    "roller_gap": {"small": {"mu_gap": 0.4}, "large": {"mu_gap": 0.56}},  # carpet: mu' 0.25 / 0.15
    "kinetic_friction": {"small": {"ratio": 0.75, "v_s": 0.02}, "large": {"ratio": 0.6, "v_s": 0.02}},
    "com_offset": {"small": {"com": [0.008, -0.005]}, "large": {"com": [0.015, -0.01]}},
    "wheel_radius": {"small": {"scale": [1.0, 0.97, 1.0]}, "large": {"scale": [1.0, 0.94, 1.02]}},
    "motor_lag": {"small": {"tau": 0.04}, "large": {"tau": 0.08}},
    "wheel_liftoff": {"small": {"lift_rate": 0.4, "recover_rate": 5.0},
                      "large": {"lift_rate": 1.0, "recover_rate": 5.0}},
}
NOISES = (0.001, 0.003)  # m: a motion-capture tracker, and a camera tracker

# Documented parameter tolerances (docs/discrepancy.md), per effect: the largest error that still
# counts as "recovered". Errors are measured by :func:`param_error`.
TOLERANCES = {
    "roller_gap": {"mu_gap": 0.1, "roller_fraction": 0.03, "phase": 0.1},  # phase: share of the pitch
    "kinetic_friction": {"ratio": 0.05, "v_s": 0.3},  # v_s: relative
    "com_offset": {"com": 0.002},  # m
    "wheel_radius": {"scale": 0.01},
    "motor_lag": {"tau": 0.2},  # relative
    "wheel_liftoff": {"lift_rate": 1.0, "recover_rate": 1.0},  # |ln(fit/true)|: a factor e
}


def nominal_model() -> SimModel:
    """The nominal model of the study: the Williams robot on carpet with the paper's initial friction."""
    return load_model("williams2002", surface="carpet", friction="initial")


def param_error(effect: str, truth: dict, fitted: dict, model: SimModel) -> dict[str, float]:
    """Per parameter group, the error of ``fitted`` against ``truth`` (units as in :data:`TOLERANCES`)."""
    if effect == "roller_gap":
        pitch = 2 * math.pi / model.robot.rollers
        d = np.mod(np.asarray(fitted["phase"]) - np.asarray(truth["phase"]) + pitch / 2, pitch) - pitch / 2
        return {"mu_gap": abs(fitted["mu_gap"] - truth["mu_gap"]),
                "roller_fraction": abs(fitted["roller_fraction"] - truth["roller_fraction"]),
                "phase": float(np.max(np.abs(d)) / pitch)}
    if effect == "kinetic_friction":
        return {"ratio": abs(fitted["ratio"] - truth["ratio"]), "v_s": abs(fitted["v_s"] / truth["v_s"] - 1)}
    if effect == "com_offset":
        return {"com": float(np.hypot(*(np.asarray(fitted["com"]) - truth["com"])))}
    if effect == "wheel_radius":
        return {"scale": float(np.max(np.abs(np.asarray(fitted["scale"]) - truth["scale"])))}
    if effect == "motor_lag":
        return {"tau": abs(fitted["tau"] / truth["tau"] - 1)}
    if effect == "wheel_liftoff":
        return {k: abs(math.log(fitted[k] / truth[k])) for k in ("lift_rate", "recover_rate")}
    return {}


def run_case(hidden: str, params: dict | None, noise: float, seed: int, runs: int, duration: float,
             workdir: str | Path | None = None, observe: str = "all") -> dict:
    """Synthesize one dataset, run ``gap`` on it, and score the answer against the truth."""
    import json

    model = nominal_model()
    spec = hidden if params is None else f"{hidden}:{json.dumps(params)}"
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        folder = Path(tmp) / "data"
        truth = write_synthetic(folder, model, spec, runs, noise, seed, duration, observe)
        t0 = time.perf_counter()
        result = gap(folder, None, seed=seed, progress=False)
        wall = time.perf_counter() - t0
    named = result["effect"]
    out = {"hidden": hidden, "noise": noise, "seed": seed, "named": named, "correct": named == hidden,
           "reduction": result["gap"]["reduction"], "before": result["gap"]["before"],
           "after": result["gap"]["after"], "wall_s": wall, "truth": truth["params"],
           "fitted": result.get("params", {}), "ambiguous_with": result.get("ambiguous_with"),
           "uncertainty": result.get("uncertainty")}
    if named == hidden and hidden in TOLERANCES:
        err = param_error(hidden, truth["params"], result["params"], model)
        out["param_error"] = err
        out["params_ok"] = all(err[k] <= TOLERANCES[hidden][k] for k in err)
    return out
