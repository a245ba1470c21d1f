"""``omni-gym score``: how well models predict a dataset's runs (held-out check of a calibrated model).

Every run is replayed **open loop** from its start pose with its commanded wheel speeds, as ``gap``
replays runs, and compared with the tracked poses: the position RMS [m] over the run's tracked rows
(Euclidean x, y error; the measure of ``benchmarks/real_optiodom.py``) and the final position error
[m] at its last tracked row. A model that ``gap`` extended on training sessions is checked this way
on sessions it never saw.

Beside each score, the per-run refit (:mod:`~omni_gym.discrepancy.decide.run_spread`): the initial heading
offset and yaw-rate scale that would bring the replay closest to that run, and the position RMS left
after them: how much of a run's error is run-to-run variation no model of the robot predicts. The summary
gives the spread of the scores over runs (median, min, max, standard deviation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.data.dataset import Dataset, Run
from omni_gym.discrepancy.decide.run_spread import refit_run
from omni_gym.discrepancy.fit.kinematic_calibration import position_rms
from omni_gym.discrepancy.fit.linear_map import LinearMap
from omni_gym.discrepancy.replay.measurement import START_WINDOW
from omni_gym.discrepancy.replay.simulate import FIT_DT, Job, simulate_poses
from omni_gym.discrepancy.replay.start_trust import estimate_start_trust, with_start_trust
from omni_gym.physics.model import SimModel


@dataclass
class RunScore:
    """One run replayed with one model: position RMS and final position error [m] against the tracker;
    the per-run refit's heading offset [rad], yaw-rate scale and the position RMS it leaves [m]."""

    run: str
    model: str
    seconds: float
    position_rms: float
    final_error: float
    heading_offset: float
    yaw_scale: float
    refit_position_rms: float


def final_error(run: Run, poses: np.ndarray) -> float:
    """Position error [m] of ``poses`` (K, 3) at the run's last tracked row."""
    last = int(np.flatnonzero(run.observed)[-1])
    return float(math.hypot(*(run.pose[last, :2] - poses[last, :2])))


def score_models(ds: Dataset, models: dict[str, SimModel], dt: float = FIT_DT,
                 linear_maps: dict[str, LinearMap] | None = None) -> list[RunScore]:
    """Per run and model (run-major order): open-loop replay scores (module docstring). ``linear_maps``:
    baselines scored beside the models (name → :class:`~omni_gym.discrepancy.fit.linear_map.LinearMap`),
    each run dead-reckoned from its encoders with the map.

    ValueError if a model's wheel count differs from the dataset's, or a linear map's run has no encoders.
    """
    for name, m in models.items():
        if m.n_wheels != ds.n_wheels:
            raise ValueError(f"model {name}: {m.n_wheels} wheels, the dataset {ds.path} has {ds.n_wheels}")
    linear_maps = linear_maps or {}
    names = list(models)
    # Replays trust the runs' start poses as gap's do (the same estimate on these runs: replay.start_trust).
    ds = with_start_trust(ds, estimate_start_trust(ds, START_WINDOW, dt))
    poses = simulate_poses([Job(models[n], r) for r in ds.runs for n in names], dt=dt, start_window=START_WINDOW)
    out = []
    for i, run in enumerate(ds.runs):
        replays = [(name, poses[i * len(names) + j]) for j, name in enumerate(names)]
        replays += [(name, lm.predict(run)) for name, lm in linear_maps.items()]
        for name, p in replays:
            refit = refit_run(run.pose, p)
            out.append(RunScore(run.name, name, float(run.t[-1]), position_rms(run.pose, p), final_error(run, p),
                                refit.heading_offset, refit.yaw_scale, refit.position_rms))
    return out


def summary(scores: list[RunScore]) -> dict[str, dict]:
    """Per model, over the runs: the run count; the mean, median, min, max and standard deviation of the
    position RMS [m]; the mean final error [m]; the mean position RMS left by the per-run refit [m] and the
    standard deviations of its heading offsets [rad] and yaw-rate scales (0 with one run)."""
    out: dict[str, dict] = {}
    for name in dict.fromkeys(s.model for s in scores):
        mine = [s for s in scores if s.model == name]
        rms = np.array([s.position_rms for s in mine])
        ddof = 1 if len(mine) > 1 else 0
        out[name] = {"runs": len(mine), "mean_position_rms": float(np.mean(rms)),
                     "median_position_rms": float(np.median(rms)), "min_position_rms": float(np.min(rms)),
                     "max_position_rms": float(np.max(rms)), "std_position_rms": float(np.std(rms, ddof=ddof)),
                     "mean_final_error": float(np.mean([s.final_error for s in mine])),
                     "mean_refit_position_rms": float(np.nanmean([s.refit_position_rms for s in mine])),
                     "std_heading_offset": float(np.nanstd([s.heading_offset for s in mine], ddof=ddof)),
                     "std_yaw_scale": float(np.nanstd([s.yaw_scale for s in mine], ddof=ddof))}
    return out


@dataclass
class HeldOutRun:
    """One source run replayed whole, open loop, by each compared model of the fold that did not see it.

    ``fold``: the run's held-out fold (-1: the run gave no fitted segment, so no fit saw it; it is
    replayed with the all-run models). ``position_rms`` and ``final_error``: model name → [m].
    """

    run: str
    session: str | None
    fold: int
    seconds: float
    position_rms: dict[str, float]
    final_error: dict[str, float]

    def to_json(self) -> dict:
        return {"run": self.run, "session": self.session, "fold": self.fold, "seconds": self.seconds,
                "position_rms": self.position_rms, "final_error": self.final_error}


def heldout_whole_runs(ds: Dataset, fold_of: np.ndarray, fold_models: dict[str, list[SimModel]],
                       all_models: dict[str, SimModel], dt: float = FIT_DT,
                       start_window: float | None = START_WINDOW) -> list[HeldOutRun]:
    """The drift-aware held-out score: every run of ``ds`` replayed **whole, open loop**, from its start
    pose, with each compared model as fitted without the run's fold: ``fold_models[name][k]`` for a run of
    fold ``fold_of[i] = k``, ``all_models[name]`` for a run no fit saw (fold -1). One simulation per run
    and model, whatever the fit budget: the cost of one search point. ``start_window`` [s]: as
    :func:`~omni_gym.discrepancy.replay.simulate.simulate_jobs`.
    """
    names = list(fold_models)
    jobs = []
    for i, run in enumerate(ds.runs):
        k = int(fold_of[i])
        jobs += [Job(fold_models[n][k] if k >= 0 else all_models[n], run) for n in names]
    poses = simulate_poses(jobs, dt=dt, start_window=start_window)
    out = []
    for i, run in enumerate(ds.runs):
        rms, fin = {}, {}
        for j, n in enumerate(names):
            p = poses[i * len(names) + j]
            rms[n] = position_rms(run.pose, p)
            fin[n] = final_error(run, p)
        out.append(HeldOutRun(run.name, run.session, int(fold_of[i]), float(run.t[-1]), rms, fin))
    return out


def heldout_table(rows: list[HeldOutRun]) -> dict:
    """Per session (in order of appearance; ``null`` where runs record none) and over all runs: the mean
    whole-run position RMS [m] of each model, and each model's ratio to the first one after ``nominal``
    (the start model: the kinematic calibration when there is one)."""
    if not rows:
        return {"per_session": [], "mean": {}}
    names = list(rows[0].position_rms)

    def block(mine: list[HeldOutRun]) -> dict:
        mean = {n: float(np.mean([r.position_rms[n] for r in mine])) for n in names}
        ref = names[1] if len(names) > 1 else names[0]
        return {"runs": len(mine), "seconds": float(sum(r.seconds for r in mine)), "mean_position_rms": mean,
                "ratio_to": ref, "ratio": {n: (mean[n] / mean[ref] if mean[ref] > 0 else None) for n in names}}

    sessions = list(dict.fromkeys(r.session for r in rows))
    return {"per_session": [{"session": s, **block([r for r in rows if r.session == s])} for s in sessions],
            "mean": block(rows)}
