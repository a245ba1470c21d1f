"""gap's candidate fits as tasks finer than a candidate (omni_gym.discrepancy.fit.fit_tasks), and the work record.

A round of a fit is cut into chunk tasks of contiguous jobs; put back together they give the one-batch
residuals bit for bit (a robot's simulation does not depend on the other robots of its world). ``gap`` on
two local worker processes gives the serial result bit for bit, and both runs' ``work`` records (tasks,
total work, critical path, reachable speed-up) are consistent. No timing is asserted: the seconds are
measured on a shared machine; only their sums and orderings, which hold whatever they are.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from benchmark_loader import load_benchmark

from omni_gym.discrepancy import workflow
from omni_gym.discrepancy.data.dataset import load_dataset
from omni_gym.discrepancy.fit import candidates
from omni_gym.discrepancy.fit.candidates import candidates as library
from omni_gym.discrepancy.fit.fit_tasks import WORKERS, FitShared, chunk_task, chunks, reachable_speedup
from omni_gym.discrepancy.fit.fitting import Evaluator
from omni_gym.discrepancy.synthetic.recovery import nominal_model
from omni_gym.discrepancy.synthetic.synth import pose_lever, write_synthetic
from omni_gym.parallel import Backend

# Three candidates: a plain LM fit, a valley search, and the stochastic one (lift events: its own jobs).
FITTED = ("motor_lag", "com_offset", "wheel_liftoff")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("fit_tasks") / "data"
    write_synthetic(folder, nominal_model(), 'motor_lag:{"tau": 0.08}', 3, 0.001, 5, 1.5)
    return folder


def test_chunks_put_together_equal_one_batch_bit_for_bit(dataset) -> None:
    ds = load_dataset(dataset)
    ev = Evaluator(ds, pose_lever(ds.model))
    assert ev.has_windows()  # the shooting case is exercised too
    rng = np.random.default_rng(1)
    models = [ds.model.with_effect(c.name, c.params(rng.random(c.n_params)))
              for c in library(ds.model) if c.name in ("roller_gap", "motor_lag", "com_offset")]
    shared = FitShared(ev, np.zeros(len(ds.runs), dtype=int))
    for shooting in (False, True):
        whole = ev.residuals(models, shooting)
        # 2 s of robot time per chunk: runs of 1.5 s, so chunks cut between the runs of one model.
        parts = chunks(ev, models, shooting, robot_s=2.0)
        n_jobs = len(models) * ev.jobs_per_model(shooting)
        assert len(parts) > len(models)  # finer than a parameter point
        assert [p.lo for p in parts] == [0] + [p.hi for p in parts[:-1]] and parts[-1].hi == n_jobs  # a partition
        flat = [r for p in parts for r in chunk_task(shared, p).residuals]
        again = ev.assemble(len(models), flat, shooting)
        for a, b in zip(whole, again, strict=True):
            for x, y in zip(a, b, strict=True):
                assert np.array_equal(x, y, equal_nan=True)


def test_a_chunk_holds_at_most_its_robot_time_unless_one_job_is_longer(dataset) -> None:
    ds = load_dataset(dataset)
    ev = Evaluator(ds, pose_lever(ds.model))
    models = [ds.model] * 5
    jobs = ev.jobs(models)
    for robot_s in (0.5, 3.0, 7.0):
        for p in chunks(ev, models, False, robot_s=robot_s):
            seconds = sum(float(j.run.t[j.k1] - j.run.t[j.k0]) for j in jobs[p.lo:p.hi])
            assert seconds <= robot_s or p.hi - p.lo == 1


def _gap(dataset: Path, backend: Backend, mp: pytest.MonkeyPatch) -> dict:
    mp.setattr(workflow, "candidates", lambda m: [c for c in candidates.candidates(m) if c.name in FITTED])
    return workflow.gap(dataset, None, progress=False, plots=False, max_effects=1, backend=backend)


@pytest.fixture(scope="module")
def runs(dataset) -> dict[str, dict]:
    mp = pytest.MonkeyPatch()
    try:
        return {"serial": _gap(dataset, Backend(), mp), "jobs2": _gap(dataset, Backend(jobs=2), mp)}
    finally:
        mp.undo()


def test_two_workers_give_the_serial_result_bit_for_bit(runs) -> None:
    serial, parallel = (json.dumps({k: v for k, v in r.items() if k != "work"}, sort_keys=True)
                        for r in runs.values())
    assert serial == parallel
    assert runs["serial"]["effect"] == "motor_lag"  # a real answer, not an empty search


def test_work_record_is_consistent(runs) -> None:
    for name, result in runs.items():
        work = result["work"]
        steps = work["steps"]
        assert len(steps) == 1 and work["tasks"] == sum(s["tasks"] for s in steps)
        for s in steps:
            fits = s["fits"]
            assert sorted(f["candidate"] for f in fits) == sorted(FITTED)  # one record per candidate fit
            assert s["tasks"] == sum(f["tasks"] for f in fits)
            assert s["total_work_s"] == pytest.approx(sum(f["total_s"] for f in fits) + s["decide_s"], rel=1e-9)
            assert s["critical_path_s"] == pytest.approx(max(f["critical_path_s"] for f in fits) + s["decide_s"],
                                                         rel=1e-9)
            assert s["max_task_s"] <= s["critical_path_s"] <= s["total_work_s"]
            for f in fits:
                assert 1 <= f["rounds"] <= f["tasks"]
                assert f["max_task_s"] <= f["critical_path_s"] - f["driver_s"] + 1e-12 <= f["work_s"] + 1e-12
                assert f["total_s"] == pytest.approx(f["work_s"] + f["driver_s"], rel=1e-9)
                if name == "serial":
                    assert f["tasks"] == f["rounds"]  # in this process a round is one batch
        assert work["total_work_s"] == pytest.approx(work["serial_s"] + sum(s["total_work_s"] for s in steps),
                                                     rel=1e-9)
        assert work["critical_path_s"] == pytest.approx(
            work["serial_s"] + sum(s["critical_path_s"] for s in steps), rel=1e-9)
        assert work["critical_path_s"] <= work["total_work_s"]
        assert work["driver_cpu_s"] >= work["serial_s"]  # the serial part is the driver's, outside the steps
        speedup = [work["reachable_speedup"][str(w)] for w in WORKERS]
        assert speedup[0] == pytest.approx(1.0)
        assert all(a <= b + 1e-12 for a, b in zip(speedup, speedup[1:], strict=False))  # more workers never reach less
        assert all(s <= w + 1e-9 for s, w in zip(speedup, WORKERS, strict=True))
        assert speedup[-1] <= work["total_work_s"] / work["critical_path_s"] + 1e-9
    # The rounds are the fits' own (the same searches on every backend); only their tasks differ.
    rounds = [{f["candidate"]: f["rounds"] for f in r["work"]["steps"][0]["fits"]} for r in runs.values()]
    assert rounds[0] == rounds[1]
    serial, parallel = (r["work"]["steps"][0] for r in runs.values())
    assert parallel["tasks"] > serial["tasks"]  # finer than a round on the parallel backend


def test_reachable_speedup_is_the_critical_path_bound() -> None:
    assert reachable_speedup(100.0, 10.0, 1) == 1.0
    assert reachable_speedup(100.0, 10.0, 4) == 4.0  # total / W still above the critical path
    assert reachable_speedup(100.0, 10.0, 32) == 10.0  # the critical path bounds it
    assert reachable_speedup(0.0, 0.0, 8) == 1.0  # no work: nothing to gain


def test_work_json_and_the_scaling_table_of_a_known_record() -> None:
    """One step of 100 s of work with a 10 s critical path, 10 s of serial driver work around it."""

    from omni_gym.discrepancy.fit.fit_tasks import FitWork, StepWork, work_json

    fit = FitWork("a")
    for _ in range(9):  # 9 rounds of ten 1-s tasks: 90 s of work, a 9 s chain
        fit.add_round([1.0] * 10)
    fit.driver_s = 1.0  # chain 10 s
    other = FitWork("b")
    other.add_round([9.0])  # one 9-s task: shorter than a's chain
    step = StepWork(fits=[fit, other], decide_s=0.0)
    assert (step.tasks, step.total_s, step.critical_path_s, step.max_task_s) == (91, 100.0, 10.0, 9.0)
    work = work_json([step], serial_s=10.0, wall_s=60.0, backend="2 local processes")
    assert work["steps"][0]["reachable_speedup"] == {"1": 1.0, "2": 2.0, "4": 4.0, "8": 8.0, "16": 10.0, "32": 10.0}
    # Whole run: 110 s of work; with 16 workers 10 s serial + 10 s critical path.
    assert work["reachable_speedup"]["16"] == pytest.approx(110.0 / 20.0)
    assert work["reachable_speedup"]["2"] == pytest.approx(110.0 / 60.0)
    scaling = load_benchmark("scaling")
    table = scaling.gap_work_table({"work": work}, "cmd")
    assert "| step 1 | 91 | 100.0 | 10.0 | 9.00 | 1.00 | 2.00 | 4.00 | 8.00 | 10.00 | 10.00 |" in table
    assert "| whole run (serial part 10.0 s) | 91 | 110.0 | 20.0 | |" in table and "**5.50**" in table
    assert "wall time 60.0 s on 2 local processes" in table
