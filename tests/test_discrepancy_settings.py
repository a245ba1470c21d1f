"""The discrepancy workflow's settings (omni_gym.discrepancy.settings) are recorded in full in result.json,
so that a report can be reproduced from itself, and the values a caller passes are the values used.

The dataset is small (3 runs of 1.5 s at 50 Hz) and only the motor_lag candidate is fitted (monkeypatched
library), which keeps each gap run to seconds.
"""

import pytest

from omni_gym.discrepancy import workflow
from omni_gym.discrepancy.settings import DecisionRules, EventSearchSettings, FitSettings, GapSettings


def test_result_json_records_every_setting_and_a_changed_one(lag_dataset, only_motor_lag):
    default = workflow.gap(lag_dataset, None, progress=False, plots=False)
    rec = default["settings"]
    # The values every committed report was made with (the module constants before the settings objects).
    assert rec["fit"]["iterations"] == 6 and rec["fit"]["fold_iterations"] == 4 and rec["fit"]["low_dim_starts"] == 4
    assert rec["event_search"]["grid_dt"] == 0.05 and rec["event_search"]["durations"] == [0.05, 0.1, 0.2, 0.4]
    assert rec["event_search"]["dev_rows"] == 10 and rec["event_search"]["case_alpha"] == 0.01
    assert rec["rules"]["min_gap_reduction"] == 0.7 and rec["rules"]["n_boot"] == 400
    # In full: every field of every stage, and read back they are the defaults.
    assert GapSettings.from_json(rec) == GapSettings()
    assert set(rec["event_search"]) == {"grid_dt", "durations", "refine", "refine_ol", "open_loop_rounds",
                                        "window_events", "add_rounds", "add_level", "add_top", "case_alpha",
                                        "max_lifted_share", "skip_factor", "seq_max_events", "seq_ahead",
                                        "seq_horizon", "dev_rows", "dev_level"}
    assert rec["fit"]["identified_iterations"] == 4

    changed = GapSettings(fit=FitSettings(iterations=1, valley_rounds=1),
                          event_search=EventSearchSettings(grid_dt=0.1),
                          rules=DecisionRules(min_gap_reduction=0.6))
    other = workflow.gap(lag_dataset, None, progress=False, plots=False, settings=changed)
    assert other["settings"]["fit"]["iterations"] == 1 and other["settings"]["fit"]["valley_rounds"] == 1
    assert other["settings"]["event_search"]["grid_dt"] == 0.1
    assert other["settings"]["rules"]["min_gap_reduction"] == 0.6
    assert GapSettings.from_json(other["settings"]) == changed
    # The changed rounds were the ones used: one LM iteration and one valley round simulate fewer robot-runs
    # than six and three (a search that converged early would tie, not exceed).
    assert other["settings"]["robot_runs_simulated"] < rec["robot_runs_simulated"]


def test_unknown_recorded_setting_is_refused_by_name():
    with pytest.raises(ValueError, match=r"^settings\.fit\.iteration: unknown setting"):
        GapSettings.from_json({"fit": {"iteration": 3}})
