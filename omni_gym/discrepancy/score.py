"""``omni-gym score``: how well models predict a dataset's runs (held-out check of a calibrated model).

Every run is replayed **open loop** from its start pose with its commanded wheel speeds, as ``gap``
replays runs, and compared with the tracked poses: the position RMS [m] over the run's tracked rows
(Euclidean x, y error; the measure of ``benchmarks/real_optiodom.py``) and the final position error
[m] at its last tracked row. A model that ``gap`` extended on training sessions is checked this way
on sessions it never saw.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.dataset import Dataset
from omni_gym.discrepancy.kinematic_calibration import position_rms
from omni_gym.discrepancy.simulate import FIT_DT, Job, simulate_poses
from omni_gym.physics.model import SimModel


@dataclass
class RunScore:
    """One run replayed with one model: position RMS and final position error [m] against the tracker."""

    run: str
    model: str
    seconds: float
    position_rms: float
    final_error: float


def score_models(ds: Dataset, models: dict[str, SimModel], dt: float = FIT_DT) -> list[RunScore]:
    """Per run and model (run-major order): open-loop replay scores (module docstring).

    ValueError if a model's wheel count differs from the dataset's.
    """
    for name, m in models.items():
        if m.n_wheels != ds.n_wheels:
            raise ValueError(f"model {name}: {m.n_wheels} wheels, the dataset {ds.path} has {ds.n_wheels}")
    names = list(models)
    poses = simulate_poses([Job(models[n], r) for r in ds.runs for n in names], dt=dt)
    out = []
    for i, run in enumerate(ds.runs):
        last = int(np.flatnonzero(run.observed)[-1])
        for j, name in enumerate(names):
            p = poses[i * len(names) + j]
            out.append(RunScore(run.name, name, float(run.t[-1]), position_rms(run.pose, p),
                                float(math.hypot(*(run.pose[last, :2] - p[last, :2])))))
    return out


def summary(scores: list[RunScore]) -> dict[str, dict]:
    """Per model: mean position RMS and mean final error over the runs [m], and the run count."""
    out: dict[str, dict] = {}
    for name in dict.fromkeys(s.model for s in scores):
        mine = [s for s in scores if s.model == name]
        out[name] = {"runs": len(mine), "mean_position_rms": float(np.mean([s.position_rms for s in mine])),
                     "mean_final_error": float(np.mean([s.final_error for s in mine]))}
    return out
