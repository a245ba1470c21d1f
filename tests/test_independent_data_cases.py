"""benchmarks/independent_data.py's cases: seeds fixed per kind, sizes within each effect's recovery sizes,
and (slow) the new kinds end to end on data from the independent reference integrator."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from benchmark_loader import load_benchmark

from omni_gym.discrepancy.synthetic.recovery import TOLERANCES, nominal_model, param_error
from omni_gym.discrepancy.synthetic.reference_data import write_reference_dataset
from omni_gym.discrepancy.workflow import gap
from omni_gym.physics.effects import REGISTRY

ROOT = Path(__file__).resolve().parents[1]


def _load():
    return load_benchmark("independent_data")


def test_a_subset_of_kinds_repeats_the_full_study_cases():
    bench = _load()
    full = {(c["kind"], c["seed"]): c for c in bench.cases()}
    subset = list(bench.cases(("wheel_liftoff", "none"), 2))
    assert [c["seed"] for c in subset] == [901, 902, 1, 2]
    for c in subset:
        assert c == full[(c["kind"], c["seed"])]
    held_out = list(bench.cases(("motor_lag",), 1, seed0=5000))
    assert held_out[0]["seed"] == 5701 and held_out[0]["hidden"] != full[("motor_lag", 701)]["hidden"]


def test_new_kinds_draw_sizes_between_the_recovery_sizes():
    bench = _load()
    n = nominal_model().n_wheels
    for kind in ("motor_lag", "kinetic_friction", "wheel_liftoff", "roller_gap"):
        sizes = REGISTRY[kind].recovery_sizes
        drawn = [c["hidden"][kind] for c in bench.cases((kind,), 20)]
        for key in sizes["small"]:
            lo, hi = sorted((sizes["small"][key], sizes["large"][key]))
            values = np.array([d[key] for d in drawn])
            assert np.all((values >= lo) & (values <= hi)), (kind, key)
            if hi > lo:
                assert np.ptp(values) > 0.5 * (hi - lo), (kind, key)  # random, spread over the range
        for d in drawn:
            REGISTRY[kind].validate(d, n)  # complete, valid parameters (roller_gap: every key, phases)


@pytest.mark.slow
@pytest.mark.parametrize("kind,hidden", [
    ("motor_lag", {"motor_lag": {"tau": 0.06}}),
    ("kinetic_friction", {"kinetic_friction": {"ratio": 0.65, "v_s": 0.02}}),
])
def test_new_kinds_are_named_right(tmp_path, kind, hidden):
    """A sample of the new categories end to end: named first with parameters within the recovery tolerance."""
    folder = tmp_path / "data"
    write_reference_dataset(folder, nominal_model(), hidden, runs=3, duration=2.5, seed=5)
    result = gap(folder, None, seed=5, progress=False, max_effects=2)
    assert result["effect"] == kind, result["why"]
    err = param_error(kind, hidden[kind], result["params"], nominal_model())
    assert all(err[k] <= TOLERANCES[kind][k] for k in err), (err, result["params"])
