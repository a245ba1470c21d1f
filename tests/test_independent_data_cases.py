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
    full = {(c["robot"], c["kind"], c["seed"]): c for c in bench.cases()}
    subset = list(bench.cases(("wheel_liftoff", "none"), ("optiodom_omni4",), 2))
    assert [c["seed"] for c in subset] == [1901, 1902, 1001, 1002]
    for c in subset:
        assert c == full[(c["robot"], c["kind"], c["seed"])]
    held_out = list(bench.cases(("motor_lag",), ("williams2002",), 1, seed0=5000))
    assert held_out[0]["seed"] == 5701 and held_out[0]["hidden"] != full[("williams2002", "motor_lag", 701)]["hidden"]


def test_the_study_covers_what_users_meet():
    """At least 80 cases over both robot types, 30 with nothing hidden, every library effect that applies to
    each robot and one outside it; run counts, lengths, noise levels and encoders spread over their ranges."""
    bench = _load()
    all_cases = list(bench.cases())
    assert len(all_cases) >= 80 and sum(c["kind"] == "none" for c in all_cases) >= 30
    for robot in bench.ROBOTS:
        model = bench.robot_model(robot)
        kinds = {c["kind"] for c in all_cases if c["robot"] == robot}
        assert kinds == {n for n, e in REGISTRY.items() if e.applies_to(model.robot)} | {"none", "drag"}, robot
    runs = np.array([c["runs"] for c in all_cases])
    dur = np.array([c["duration"] for c in all_cases])
    noise = np.array([c["position_noise"] for c in all_cases])
    # Lengths reach 8.5 s and more: a case holds at most MAX_ROBOT_TIME (40 s), so 10 s runs come in threes.
    assert runs.min() == 3 and runs.max() >= 11 and dur.min() == 2.5 and dur.max() >= 8.5
    assert np.all(runs * dur <= bench.MAX_ROBOT_TIME + 1e-9)
    assert noise.min() < 0.8e-3 and noise.max() > 2.5e-3
    assert {c["manoeuvre"] for c in all_cases} == {"steps", "smooth", "turns"}
    assert {c["encoder_counts"] for c in all_cases} == set(bench.ENCODER_COUNTS)


def test_new_kinds_draw_sizes_between_the_recovery_sizes():
    bench = _load()
    model = bench.robot_model("williams2002")
    for kind in ("motor_lag", "wheel_liftoff", "roller_gap"):
        sizes = REGISTRY[kind].recovery_sizes
        drawn = [c["hidden"][kind] for c in bench.cases((kind,), ("williams2002",), 20)]
        for key in sizes["small"]:
            lo, hi = sorted((sizes["small"][key], sizes["large"][key]))
            values = np.array([d[key] for d in drawn])
            assert np.all((values >= lo) & (values <= hi)), (kind, key)
            if hi > lo:
                assert np.ptp(values) > 0.5 * (hi - lo), (kind, key)  # random, spread over the range
        for d in drawn:
            REGISTRY[kind].validate(d, model.n_wheels)  # complete, valid parameters (roller_gap: every key, phases)


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


def test_a_stopped_study_resumes_from_its_lines_or_its_json(tmp_path):
    """--resume: results of the same cases are reused, from the printed JSON lines or the written .json list; a
    result whose case settings differ (another generator setting, say) is not, nor one whose gap was killed."""
    import json

    bench = _load()
    todo = list(bench.cases(("none",), ("williams2002",), 2))
    done = [{**todo[0], "generator": "second", "effect": "none", "correct": True},
            {**todo[1], "runs": todo[1]["runs"] + 1, "effect": "none", "correct": True},  # not the same case
            {**todo[1], "generator": "second", "effect": "error (exit -9)", "correct": False}]  # killed: run again
    lines = tmp_path / "log.jsonl"
    lines.write_text("\n".join(json.dumps(r) for r in done) + "\nnot json\n")
    listed = tmp_path / "study.json"
    listed.write_text(json.dumps(done))
    for log in (lines, listed):
        got = bench.previous(log, todo, "second")
        assert [r["seed"] for r in got] == [todo[0]["seed"]], log
    assert bench.previous(lines, todo, "reference") == []
