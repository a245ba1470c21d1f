"""Recovery study: hide an effect in synthetic data, run the workflow, compare with the truth.

Shared by ``tests/test_discrepancy_recovery.py`` and ``benchmarks/discrepancy_recovery.py`` so that
both measure the same thing: the named effect, the parameter error and the held-out gap reduction.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from omni_gym.discrepancy.synthetic.synth import write_synthetic
from omni_gym.discrepancy.workflow import gap
from omni_gym.physics.effects import REGISTRY
from omni_gym.physics.model import SimModel, load_model

# Two sizes of every library effect on the Williams robot (the mecanum robot for a mecanum-only effect;
# carpet, initial friction), from the effect
# library (omni_gym.physics.effects): "large" is about the default of omni-gym synth, "small" about half.
SIZES: dict[str, dict[str, dict]] = {name: e.recovery_sizes for name, e in REGISTRY.items()}
NOISES = (0.001, 0.003)  # m: a motion-capture tracker, and a camera tracker

# Documented parameter tolerances (docs/discrepancy.md), per effect: the largest error that still
# counts as "recovered". Errors are measured by :func:`param_error` (units: each effect's module).
TOLERANCES = {name: e.tolerances for name, e in REGISTRY.items()}


def nominal_model(effect: str | None = None) -> SimModel:
    """The nominal model of the study: the Williams robot on carpet with the paper's initial friction; for
    an ``effect`` that does not apply to it (``mecanum_lateral``: mecanum wheels only) the four-wheeled
    mecanum robot of the OptiOdom logs (``optiodom_omni4``) on the same carpet and friction."""
    model = load_model("williams2002", surface="carpet", friction="initial")
    if effect in REGISTRY and not REGISTRY[effect].applies_to(model.robot):
        return load_model("optiodom_omni4", surface="carpet", friction="initial")
    return model


def param_error(effect: str, truth: dict, fitted: dict, model: SimModel) -> dict[str, float]:
    """Per parameter group, the error of ``fitted`` against ``truth`` (units as in :data:`TOLERANCES`)."""
    if effect not in REGISTRY:
        return {}
    return REGISTRY[effect].param_error(truth, fitted, model)


def run_case(hidden: str, params: dict | None, noise: float, seed: int, runs: int, duration: float,
             workdir: str | Path | None = None, observe: str = "all", max_effects: int = 1) -> dict:
    """Synthesize one dataset, run ``gap`` on it, and score the answer against the truth.

    One effect is hidden, so the study scores the first answer; ``max_effects`` = 1 (the default) skips
    the search for further effects (``tests/test_discrepancy_multi.py`` covers that search)."""
    import json

    model = nominal_model(hidden)
    spec = hidden if params is None else f"{hidden}:{json.dumps(params)}"
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        folder = Path(tmp) / "data"
        truth = write_synthetic(folder, model, spec, runs, noise, seed, duration, observe)
        t0 = time.perf_counter()
        result = gap(folder, None, seed=seed, progress=False, max_effects=max_effects)
        wall = time.perf_counter() - t0
    named = result["effect"]
    out = {"hidden": hidden, "noise": noise, "seed": seed, "named": named, "correct": named == hidden,
           "reduction": result["gap"]["reduction"], "before": result["gap"]["before"],
           "after": result["gap"]["after"], "wall_s": wall, "truth": truth["params"],
           "fitted": result.get("params", {}), "ambiguous_with": result.get("ambiguous_with"),
           "effects": result["effects"],
           "uncertainty": result.get("uncertainty")}
    if named == hidden and hidden in TOLERANCES:
        err = param_error(hidden, truth["params"], result["params"], model)
        out["param_error"] = err
        out["params_ok"] = all(err[k] <= TOLERANCES[hidden][k] for k in err)
    return out
