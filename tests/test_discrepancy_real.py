"""``gap`` end to end on real logs: a small subset of the bundled OptiOdom runs.

Four runs of the training sessions (two clockwise circles, two squares; 220 s of
robot time), fitted within a 20 s budget (one 5 s segment of each run, ``data/segments.py``), one search
step (``max_effects=1``): about a minute on this machine. The full study is
``benchmarks/real_optiodom.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from omni_gym.discrepancy.data.dataset import load_dataset, write_dataset
from omni_gym.discrepancy.data.importers.optiodom import import_optiodom
from omni_gym.discrepancy.workflow import gap
from omni_gym.physics.effects import REGISTRY

DATA = Path(__file__).resolve().parents[1] / "data" / "optiodom-omni3"
RUNS = ("221220201701_run-01", "221220201701_run-02", "221220201953_run-01", "221220201953_run-02")


@pytest.mark.slow  # gap end to end on real OptiOdom logs, as test_discrepancy_real_omni4.py for the mecanum robot
def test_gap_on_four_real_runs_adds_an_effect_and_shrinks_the_heldout_gap(tmp_path):
    """One test, not several sharing a module fixture: pytest-xdist would run the minute-long gap once per
    worker that draws one of them."""
    # On the file's time column: gap's mechanics on real runs, on segments fixed by the data as written. On the
    # tracker's clock (the import's default) the 20 s budget cuts other segments (the rows are 2 % longer), on
    # which wheel_geometry fits at its bounds and is refused as implausible and tracker_offset is unstable
    # across folds (0.18): no effect is added there (measured); the time base has its own tests.
    import_optiodom([DATA / "circular" / "221220201701", DATA / "square" / "221220201953"], tmp_path / "all",
                    time_base="file")
    ds = load_dataset(tmp_path / "all")
    write_dataset(tmp_path / "subset", ds.model_json, ds.description, [r for r in ds.runs if r.name in RUNS])
    # From the dataset's model (the default, auto, starts from the calibration here: it predicts the held-out
    # whole runs better, tests/test_discrepancy_real_omni4.py), so that a library effect is what is searched.
    result = gap(tmp_path / "subset", None, seed=0, progress=False, max_effects=1, fit_budget=20.0, start="nominal")
    # Long real runs are fitted on one segment of each.
    fitted = result["dataset"]["fitted"]
    assert fitted["segmented"] and fitted["fitted_runs"] == 4 and fitted["source_runs"] == 4
    assert fitted["seconds"] <= 20.0 + 1e-9 and fitted["total_seconds"] > 200.0
    # An effect of the library is added to the model...
    assert len(result["effects"]) == 1 and result["effects"][0] in REGISTRY, result["effects"]
    assert result["steps"][0]["status"] in ("named", "partial")
    assert result["effects"][0] in result["model"].get("effects", {})  # model.json carries it
    # ...and the held-out gap shrinks. Measured: wheel_radius, 19.5 -> 9.3 mm beyond noise (52 % removed:
    # kept as a partial step, the answer stays `unexplained` below the 70 % naming rule). A few per cent of
    # geometry error dominates the nominal residual on these runs (kinematic calibration halves the
    # position RMS), so a geometric effect must remove at least half of the gap on held-out segments.
    assert result["gap"]["after"] < 0.5 * result["gap"]["before"], result["gap"]
