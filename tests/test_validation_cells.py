"""Validation cells and seeds (``agents.validation``): what model selection is measured on.

The cells are derived from the training keywords, so a change of the training distribution changes what
is validated; the seeds must stay apart from the benchmarks' held-out 10 000+ for any episode count the
command line allows (``--eval-episodes`` <= 1000).
"""

from __future__ import annotations

from agents.train import load_hyperparams
from agents.validation import LIFT_RATE, VALIDATION_SEED, episodes_per_cell, validation_cells, validation_seeds


def test_cells_cover_every_training_floor_with_and_without_lift_off():
    kw = load_hyperparams("ppo", "OmniPathFollow-Mecanum-v0", "ppo_features_bc_skip")["env_kwargs"]
    cells = validation_cells(kw)
    assert cells == [{"surface": "grip", "friction": "initial", "lift_rate": 0.0},
                     {"surface": "grip", "friction": "initial", "lift_rate": LIFT_RATE},
                     {"surface": "carpet", "friction": "initial", "lift_rate": 0.0},
                     {"surface": "carpet", "friction": "initial", "lift_rate": LIFT_RATE}]


def test_without_randomisation_the_training_conditions_are_the_one_cell():
    kw = {"obs_mode": "state", "surface": "carpet", "lift_rate": 0.2, "randomize_mass": [0.8, 1.2]}
    assert validation_cells(kw) == [{"surface": "carpet", "lift_rate": 0.2}]
    assert validation_cells({"randomize_floor": ["grip"]}) == [{"surface": "grip"}]  # no friction given


def test_episodes_are_spread_and_seeds_stay_apart_from_the_held_out_ones():
    assert [episodes_per_cell(100, n) for n in (1, 2, 3, 4)] == [100, 50, 34, 25]
    assert episodes_per_cell(1, 4) == 1
    seeds = validation_seeds(episodes_per_cell(1000, 1))
    assert seeds[0] == VALIDATION_SEED and len(set(seeds)) == 1000 and max(seeds) < 10_000
