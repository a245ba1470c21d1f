"""Held-out folds: which runs each fit sees and which it is scored on (a partition of the data).

K folds by run (:func:`make_folds`), runs of one group (the segments of one source run,
:mod:`omni_gym.discrepancy.data.segments`) kept in one fold, or by recording session where the dataset
records several (:func:`source_folds`). Fold k's fit sees only the other folds' runs and is scored on
the runs of fold k (:mod:`omni_gym.discrepancy.fit.fitting`, :mod:`omni_gym.discrepancy.decide.decision`).
"""

from __future__ import annotations

import numpy as np


def make_folds(n_runs: int, rng: np.random.Generator, k: int = 3, groups: np.ndarray | None = None) -> np.ndarray:
    """(R,) fold index of each run: K = min(k, R) folds of near-equal size, seeded order.

    ``groups`` (R,) (optional): runs of one group (segments of one source run,
    :mod:`omni_gym.discrepancy.data.segments`) share a fold, so no fold is scored on a piece of a run it
    was fitted on; the folds are then near-equal in groups.
    """
    if groups is not None:
        ids, inverse = np.unique(np.asarray(groups), return_inverse=True)
        return make_folds(len(ids), rng, k)[inverse]
    k = min(k, n_runs)
    order = rng.permutation(n_runs)
    folds = np.empty(n_runs, dtype=int)
    folds[order] = np.arange(n_runs) % k
    return folds


def source_folds(n_runs: int, rng: np.random.Generator, k: int = 3, sessions: list[str] | None = None) -> np.ndarray:
    """(R,) fold of each source run of a dataset (whole runs, before segmenting).

    Without ``sessions`` (None): :func:`make_folds` by run. With ``sessions`` (R,) (the runs' recording
    sessions, at least two distinct): folds split by session, never within one, so every fold is scored
    on sessions its fit never saw: leave-one-session-out when there are at most ``k`` sessions, else K
    folds of near-equal session counts (grouped K-fold, seeded order). Sessions are numbered in order of
    first appearance, so the folds do not depend on how the ids sort.
    """
    if sessions is None:
        return make_folds(n_runs, rng, k)
    if len(sessions) != n_runs:
        raise ValueError(f"sessions: {len(sessions)} entries for {n_runs} runs")
    ids = np.array([list(dict.fromkeys(sessions)).index(s) for s in sessions])
    n_sessions = int(ids.max()) + 1
    if n_sessions <= k:
        return ids  # leave one session out
    return make_folds(n_runs, rng, k, groups=ids)
