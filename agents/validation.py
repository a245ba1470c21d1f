"""Where trained agents are validated (model selection): seeds and cells apart from the benchmarks.

A training run keeps the policy that scores best on its validation episodes, so those episodes must be many
(30 episodes picked noise: gains of 0.57–0.87× on them became 1.04–1.40× on held-out ones, docs/agents.md)
and must cover what the agent was trained for. :func:`validation_cells` spreads them over every floor the
training randomises (``randomize_floor``), each without and with lift-off when the training randomises the
lift-off rate, with every other randomisation off (the id's nominal model). Seeds start at
:data:`VALIDATION_SEED` in every cell; training uses small seeds (or ``agents.distillation.TRAIN_SEED``) and
the benchmarks 10 000 and up, so no validation episode is a held-out one.
"""

from __future__ import annotations

import math

from omni_gym.envs.config import parse_floors

VALIDATION_SEED = 5000  # validation episodes; training envs use small seeds, benchmarks 10 000+
VALIDATION_EPISODES = 100  # default number of validation episodes (spread over the cells)
LIFT_RATE = 0.5  # [1/s] lift-off rate of the cells with lift-off: the benchmarks' slip + lift-off condition


def validation_cells(train_kwargs: dict) -> list[dict]:
    """Env keywords of the validation cells of a run trained with ``train_kwargs``.

    The training keywords without the ``randomize_*`` ones (and ``obs_mode``), then per training floor
    (``randomize_floor`` entries "surface:friction", or the run's own floor) one cell, or two (lift-off rate
    0 and :data:`LIFT_RATE`) when ``randomize_lift_rate`` is set.
    """
    base = {k: v for k, v in train_kwargs.items() if not k.startswith("randomize_") and k != "obs_mode"}
    floors = parse_floors(train_kwargs.get("randomize_floor")) or [None]
    lifts = [0.0, LIFT_RATE] if train_kwargs.get("randomize_lift_rate") else [None]
    cells = []
    for floor in floors:
        kw = dict(base)
        if floor is not None:
            kw["surface"] = floor.surface
            if floor.friction is not None:
                kw["friction"] = floor.friction
        for lift in lifts:
            cells.append(kw if lift is None else {**kw, "lift_rate": lift})
    return cells


def episodes_per_cell(episodes: int, cells: int) -> int:
    """Episodes per cell so that all cells together hold at least ``episodes``."""
    return max(1, math.ceil(int(episodes) / max(1, int(cells))))


def validation_seeds(per_cell: int) -> list[int]:
    """The seeds of one cell's validation episodes (the same in every cell: paired across cells)."""
    return [VALIDATION_SEED + i for i in range(int(per_cell))]


def cell_episodes(venvs, policies) -> list[list]:
    """Each cell's validation episodes (:class:`agents.rollout.Episode`): the robots of native vector env
    ``venvs[c]`` from :func:`validation_seeds`, driven by the vector actor ``policies[c]``."""
    from agents.vector_rollout import run_episodes_vector

    return [run_episodes_vector(venv, policy, validation_seeds(int(venv.num_envs)))
            for venv, policy in zip(venvs, policies, strict=True)]
