"""Fitting on a budget: a long dataset is fitted on an even sample of its runs' segments.

Every fitted parameter point replays every run, so the cost of ``omni-gym gap`` grows with the robot
time it fits. Real logs are long (the OptiOdom training sessions: 24 runs, 1325 s), and most of a long
run repeats what its first seconds already show. A dataset with more than ``budget`` seconds of robot
time is therefore fitted on segments: every run is cut into pieces of a few seconds, each replayed
from the tracked state at its start like a multiple-shooting window (smoothed pose and velocity from a
local quadratic fit to the tracker, wheel angles from the encoders, wheel speeds = the held command),
and a sample of the pieces, at most ``budget`` seconds in all, stands in for the runs.

**Every run is sampled.** Runs of one dataset often differ in kind (the OptiOdom sessions alternate
the direction of their circles), and a fit that sees only some kinds is wrong on the others: the first
version sampled every k-th piece in (run, time) order, which on the OptiOdom training sessions drew
only every other run, and the extended model it gave predicted the held-out circles of one direction
2× better and of the other 2–3× worse than the kinematic calibration. So the segment length is
``budget / runs`` (between MIN_SEGMENT and SEGMENT), and pieces are drawn round-robin over the runs:
one piece of every run per round, each run's first piece at a different point of its time (golden-ratio
offsets) and later rounds halfway between (van der Corput offsets), until the budget is spent.

Short replays also keep the world's own integration error small (it grows with the replayed time:
on the OptiOdom runs 2.3 mm RMS over whole 55 s runs at 1 ms against 0.5 ms).

Each segment keeps its source run as its *group*: held-out folds split by source run
(:func:`omni_gym.discrepancy.data.folds.make_folds`), so no fold is scored on a piece of a run it was fitted on.
A dataset within the budget is fitted as it is (``FitData.segmented`` is False).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from omni_gym.discrepancy.data.budget import (  # noqa: F401 -- FIT_BUDGET, MIN_FIT_BUDGET, check_fit_budget: re-exported
    FIT_BUDGET,
    MIN_FIT_BUDGET,
    SEGMENT,
    check_fit_budget,
    segment_seconds,
)
from omni_gym.discrepancy.data.dataset import Dataset, Run
from omni_gym.discrepancy.data.measured_state import local_pose_fit, wheel_angles

MIN_TAIL = 0.5  # shortest tail piece kept, as a share of the segment length
GOLDEN = 0.6180339887498949  # spreads each run's first sampled piece over the run's time


@dataclass
class FitData:
    """The dataset the workflow fits: the runs themselves or segments of them.

    ``groups`` (S,): index of each fitted run's source run in the original dataset; ``seconds`` and
    ``total_seconds``: robot time fitted and in the original dataset [s].
    """

    dataset: Dataset
    groups: np.ndarray
    segmented: bool
    seconds: float
    total_seconds: float
    source_runs: int
    segment: float | None  # segment length [s] (None: whole runs)

    def describe(self) -> str:
        """One line for logs and the report."""
        if not self.segmented:
            return f"all {self.source_runs} runs ({self.seconds:.0f} s of robot time)"
        return (f"{len(self.groups)} segments of at most {self.segment:g} s from {len(set(self.groups.tolist()))} of "
                f"{self.source_runs} runs ({self.seconds:.0f} s of {self.total_seconds:.0f} s of robot time), each "
                "replayed from the tracked state at its start; folds keep each source run whole")

    def to_json(self) -> dict:
        """For ``result.json``: what was fitted."""
        return {"segmented": self.segmented, "fitted_runs": len(self.groups), "source_runs": self.source_runs,
                "seconds": self.seconds, "total_seconds": self.total_seconds,
                "segment_seconds": self.segment, "description": self.describe()}


def fit_data(ds: Dataset, budget: float = FIT_BUDGET, segment: float = SEGMENT) -> FitData:
    """The dataset to fit: ``ds`` itself when its robot time is within ``budget`` [s], else a sample of
    pieces of every run, each budget / runs long (within [MIN_SEGMENT, ``segment``] s), totalling at most
    ``budget`` (module docstring).

    Raises ValueError for a non-positive budget or segment, or when fewer than 2 runs give a piece.
    """
    if not (budget > 0 and segment > 0):
        raise ValueError(f"fit budget and segment length must be positive, got {budget!r} and {segment!r}")
    total = float(sum(r.t[-1] - r.t[0] for r in ds.runs))
    R = len(ds.runs)
    if total <= budget:
        return FitData(ds, np.arange(R), False, total, total, R, None)
    seg = segment_seconds(budget, R, segment)
    per_run = [_pieces(run, seg) for run in ds.runs]
    chosen: list[tuple[int, int]] = []  # (run, piece index)
    taken: list[set[int]] = [set() for _ in per_run]  # piece indices chosen, per run
    seconds = 0.0
    for q in range(max((len(p) for p in per_run), default=0)):
        for ri, pieces in enumerate(per_run):
            left = [j for j in range(len(pieces)) if j not in taken[ri]]
            if not left:
                continue
            # Round q's offset in the run: golden-ratio start per run, then van der Corput steps.
            target = (ri * GOLDEN + _van_der_corput(q)) % 1.0 * len(pieces)
            j = min(left, key=lambda k: (abs(k + 0.5 - target), k))
            length = float(pieces[j].t[-1])
            if seconds + length > budget + 1e-9:
                continue
            chosen.append((ri, j))
            taken[ri].add(j)
            seconds += length
    if len({ri for ri, _ in chosen}) < 2:
        raise ValueError(f"{ds.path}: fewer than 2 runs give a segment of {seg:g} s with a tracked start "
                         f"within the fit budget of {budget:g} s")
    chosen.sort()
    groups = np.array([ri for ri, _ in chosen])
    sub = replace(ds, runs=[per_run[ri][j] for ri, j in chosen])
    return FitData(sub, groups, True, seconds, total, R, seg)


def _pieces(run: Run, segment: float) -> list[Run]:
    """The run cut into consecutive pieces of ``segment`` s (the first from rest, as the run starts; the
    others from the tracked state), keeping those with a usable start and moving wheels."""
    smooth, rate = local_pose_fit(run, half=8)
    ang = wheel_angles(run)
    K = len(run.t)
    out = []
    k0 = 0
    while k0 < K - 2:
        k1 = min(int(np.searchsorted(run.t, run.t[k0] + segment - 1e-9)), K - 1)
        long_enough = run.t[k1] - run.t[k0] >= MIN_TAIL * segment or (k0 == 0 and k1 == K - 1)
        start_ok = k0 == 0 or (run.observed[k0] and np.all(np.isfinite(rate[k0])))
        moves = bool(np.any(run.cmd[k0:k1] != 0.0))
        if long_enough and start_ok and moves and run.observed[k0 + 1:k1 + 1].sum() >= 2:
            out.append(_piece(run, k0, k1, smooth, rate, ang))
        k0 = k1
    return out


def _van_der_corput(q: int) -> float:
    """The q-th point of the base-2 van der Corput sequence in [0, 1): 0, 0.5, 0.25, 0.75, 0.125, …"""
    x, f = 0.0, 0.5
    while q:
        x += f * (q & 1)
        q >>= 1
        f /= 2
    return x


def _piece(run: Run, k0: int, k1: int, smooth: np.ndarray, rate: np.ndarray, ang: np.ndarray) -> Run:
    """Rows k0..k1 of ``run`` as a run on its own clock, starting from the tracked state at k0."""
    sl = slice(k0, k1 + 1)
    state0 = None
    if k0 > 0:
        # Smoothed start pose: a heading error at the start turns the whole segment's path.
        state0 = (smooth[k0].copy(), rate[k0].copy(), ang[k0].copy(), run.cmd[k0 - 1].copy())
    return Run(name=f"{run.name}@{run.t[k0]:.0f}s", t=run.t[sl] - run.t[k0], cmd=run.cmd[sl].copy(),
               pose=run.pose[sl].copy(), enc=None if run.enc is None else run.enc[sl].copy(),
               gyro=None if run.gyro is None else run.gyro[sl].copy(), state0=state0, session=run.session)
