"""Fitting on a budget (omni_gym.discrepancy.data.segments): long datasets are fitted on segments of their runs,
each replayed from the tracked state at its start; folds split by source run."""

from __future__ import annotations

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import Dataset, write_dataset
from omni_gym.discrepancy.data.folds import make_folds
from omni_gym.discrepancy.data.segments import SEGMENT, fit_data
from omni_gym.discrepancy.replay.simulate import Job, simulate_poses
from omni_gym.discrepancy.synthetic import recovery, synth

RUNS, DURATION = 3, 24.0  # three 24 s runs: two full 10 s segments and a 4 s tail each


@pytest.fixture(scope="module")
def clean_runs():
    """Noise-free runs of the recovery study's nominal model (random twist steps), with encoders."""
    model = recovery.nominal_model()
    runs, _ = synth.synthesize(model, "none", RUNS, 0.0, seed=3, duration=DURATION)
    return model, runs


def _dataset(model, runs) -> Dataset:
    return Dataset(path=None, model=model, model_json=model.to_json(), description="", runs=runs)


def test_within_budget_the_runs_are_fitted_whole(clean_runs):
    model, runs = clean_runs
    fd = fit_data(_dataset(model, runs), budget=RUNS * DURATION + 1)
    assert not fd.segmented
    assert fd.dataset.runs is runs  # the very same runs: results on small datasets do not change
    assert fd.groups.tolist() == list(range(RUNS))


def test_segments_fit_the_budget_and_cover_every_run(clean_runs):
    model, runs = clean_runs
    budget = 40.0
    fd = fit_data(_dataset(model, runs), budget=budget)
    assert fd.segmented
    assert fd.seconds <= budget + 1e-9
    assert len(fd.dataset.runs) == int(budget // SEGMENT)
    # Every run is sampled (runs differ in kind: a fit that sees some runs only is wrong on the others).
    assert set(fd.groups.tolist()) == set(range(RUNS))
    for seg, g in zip(fd.dataset.runs, fd.groups, strict=True):
        assert seg.t[0] == 0.0 and seg.t[-1] <= SEGMENT + 1e-9
        src = runs[g]
        # Every row of the segment is a row of its source run (same commands and poses, shifted clock).
        K = len(seg.t)
        starts = [k for k in range(len(src.t) - K + 1)
                  if np.array_equal(src.pose[k:k + K], seg.pose) and np.array_equal(src.cmd[k:k + K], seg.cmd)]
        assert starts, f"{seg.name}: not a slice of {src.name}"
        np.testing.assert_allclose(src.t[starts[0]:starts[0] + K] - src.t[starts[0]], seg.t, atol=1e-9)


def test_many_runs_get_shorter_segments_one_from_each(clean_runs):
    """Budget / runs sets the segment length: with a 12 s budget for 3 runs each run gives one 4 s piece,
    and the pieces start at different times of their runs."""
    model, runs = clean_runs
    fd = fit_data(_dataset(model, runs), budget=12.0)
    assert sorted(fd.groups.tolist()) == list(range(RUNS))
    assert all(s.t[-1] <= 4.0 + 1e-9 for s in fd.dataset.runs)
    assert fd.segment == 4.0 and fd.seconds <= 12.0 + 1e-9
    assert len({s.name.split("@")[1] for s in fd.dataset.runs}) > 1, [s.name for s in fd.dataset.runs]


def test_a_segment_replayed_from_its_start_state_follows_its_run(clean_runs):
    """The start state (tracked pose and velocity, encoder angles, held command) puts the replay on the
    run's path: with the true model and a noise-free tracker the segment's residual stays small."""
    model, runs = clean_runs
    fd = fit_data(_dataset(model, runs), budget=40.0)
    moving = [s for s in fd.dataset.runs if s.state0 is not None]
    assert moving, "expected segments that start moving"
    sims = simulate_poses([Job(model, s) for s in moving])
    for seg, pose in zip(moving, sims, strict=True):
        err = np.hypot(*(pose[:, :2] - seg.pose[:, :2]).T)
        # Measured: 0.45 and 0.11 mm. The start velocity comes from a quadratic fit over ±8 rows (0.16 s)
        # that spans command steps, so it is slightly off where the twist jumps; 2 mm would be a start
        # state in the wrong frame or a wheel-speed/angle mix-up (those give tens of mm over 10 s).
        assert float(np.max(err)) < 2e-3, f"{seg.name}: max position error {1e3 * float(np.max(err)):.2f} mm"


def test_folds_keep_a_source_run_together():
    rng = np.random.default_rng(0)
    groups = np.array([0, 0, 1, 1, 1, 2, 3, 3, 4, 5])
    folds = make_folds(len(groups), rng, 3, groups=groups)
    for g in np.unique(groups):
        assert len(set(folds[groups == g].tolist())) == 1, f"segments of run {g} split across folds"
    assert set(folds.tolist()) == {0, 1, 2}
    # One group per run gives exactly the plain per-run folds (the workflow passes groups 0..R-1 for a
    # dataset within the budget, whose results must not change).
    assert np.array_equal(make_folds(6, np.random.default_rng(0), 3),
                          make_folds(6, np.random.default_rng(0), 3, groups=np.arange(6)))


def test_gap_refuses_a_bad_fit_budget(clean_runs, tmp_path, capsys):
    model, runs = clean_runs
    data = tmp_path / "data"
    write_dataset(data, model.to_json(), "clean", runs)
    for bad in ("0", "-5", "nan"):
        code = main(["gap", str(data), "--out", str(tmp_path / f"r{bad}"), "--fit-budget", bad])
        err = capsys.readouterr().err.strip()
        assert code != 0
        assert "--fit-budget" in err and len(err.splitlines()) == 1, err
        assert not (tmp_path / f"r{bad}").exists()
