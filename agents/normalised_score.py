"""The normalised tracking score: 0 = open-loop, 100 = ekf-pid, on the same seeds and condition.

Like the human-normalised scores of RL benchmarks, it puts a policy's tracking RMSE [m] on a scale set by
two reference policies run on the **same** episodes (seeds, reference paths, lift-off schedules, sensor
noise) and the same environment keywords:

    score = 100 · (RMSE_open − RMSE_policy) / (RMSE_open − RMSE_ekfpid)

with RMSE_x the mean over the episodes of each episode's tracking RMSE (:mod:`agents.evaluate`). 0 is
what replaying the reference's twists without feedback gives (``open-loop``), 100 the tuned EKF + PID
(``ekf-pid``); above 100 tracks better than ``ekf-pid``, below 0 worse than not using feedback at all. The
anchors are scripted, need no training and see only sensors, so the scale means the same for every id and
condition and any user can recompute it. They are evaluated again on the policy's own seeds rather than
read from a table: the RMSE of a few episodes varies by ±20 % from seed to seed under slip, and a fixed
anchor would move the score by that much.

The interval resamples the seeds (pairs of three values) with replacement and recomputes the score
(percentile bootstrap, 10 000 resamples from a Generator seeded 0, so the same episodes give the same
interval). Where ekf-pid is not at least 5 % better than open-loop (RMSE_open − RMSE_ekfpid < 0.05·RMSE_open:
a condition where feedback cannot help, or where the EKF's noise costs more than it corrects, e.g. the
Williams robot on a grip floor, open-loop 1.2 mm, ekf-pid 1.4 mm) the scale is degenerate or inverted:
the score is still computed but flagged ``degenerate``, and should not be read.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

ZERO_ANCHOR = "open-loop"  # score 0
FULL_ANCHOR = "ekf-pid"  # score 100
ANCHORS = (ZERO_ANCHOR, FULL_ANCHOR)
DEGENERATE_GAP = 0.05  # ekf-pid better than open-loop by less than this fraction of RMSE_open: no scale
RESAMPLES = 10_000
SEED = 0
# A percentile interval of a ratio that does not contain the ratio itself: the denominator RMSE_open − RMSE_ekfpid
# comes near 0 (or changes sign) in some resamples, so the resampled scores are skewed away from the estimate and
# their percentiles describe those resamples, not the score. Shown instead of the interval.
NO_INTERVAL = ("the bootstrap resamples of the ratio are skewed away from the estimate (its denominator, "
               "RMSE_open − RMSE_ekfpid, comes near 0 in some resamples), so their percentiles do not contain it")
NO_SCORE = "the anchors' mean RMSE are equal, so the score itself is not defined (no scale)"


def normalised_score(rmse_policy: float, rmse_open: float, rmse_ekfpid: float) -> float:
    """100·(rmse_open − rmse_policy)/(rmse_open − rmse_ekfpid) [%]; NaN when the anchors are equal."""
    gap = float(rmse_open) - float(rmse_ekfpid)
    if gap == 0.0:
        return math.nan
    return 100.0 * (float(rmse_open) - float(rmse_policy)) / gap


@dataclass(frozen=True)
class Score:
    """A normalised score with its anchors (mean tracking RMSE [m] over the same episodes)."""

    score: float  # 0 = open-loop, 100 = ekf-pid
    ci95: tuple[float, float] | None  # paired bootstrap over seeds; None for one episode
    rmse_policy: float
    rmse_open: float
    rmse_ekfpid: float
    episodes: int
    degenerate: bool  # ekf-pid not DEGENERATE_GAP better than open-loop
    ci_note: str | None = None  # why there is no interval although there are resamples (NO_INTERVAL)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["ci95"] = None if self.ci95 is None else list(self.ci95)
        d["anchors"] = {"0": ZERO_ANCHOR, "100": FULL_ANCHOR}
        return d

    def text(self) -> str:
        ci = "" if self.ci95 is None else f" [{self.ci95[0]:.1f}, {self.ci95[1]:.1f}]"
        ci = ci if self.ci_note is None else f" (interval not defined: {self.ci_note})"
        warn = (" (ekf-pid is not 5 % better than open-loop here: the scale is degenerate, do not read)"
                if self.degenerate else "")
        return (f"normalised score {self.score:.1f}{ci} over {self.episodes} paired episodes (0 = {ZERO_ANCHOR} "
                f"{self.rmse_open:.4f} m, 100 = {FULL_ANCHOR} {self.rmse_ekfpid:.4f} m, policy "
                f"{self.rmse_policy:.4f} m mean tracking RMSE){warn}")


def score_episodes(policy, open_loop, ekf_pid, resamples: int = RESAMPLES) -> Score:
    """The score of per-episode tracking RMSE [m] ``policy`` against the anchors' on the same seeds.

    The three sequences are aligned by seed (same length, same order). ValueError otherwise.
    """
    p, o, e = (np.asarray(x, dtype=float) for x in (policy, open_loop, ekf_pid))
    if not (p.ndim == o.ndim == e.ndim == 1 and len(p) == len(o) == len(e) and len(p) >= 1):
        raise ValueError(f"score needs three equal, non-empty lists of per-episode RMSE, got lengths "
                         f"{len(np.atleast_1d(p))}, {len(np.atleast_1d(o))}, {len(np.atleast_1d(e))}")
    s = normalised_score(p.mean(), o.mean(), e.mean())
    ci = None
    if len(p) >= 2:
        idx = np.random.default_rng(SEED).integers(0, len(p), size=(resamples, len(p)))
        gap = o[idx].mean(axis=1) - e[idx].mean(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            draws = 100.0 * (o[idx].mean(axis=1) - p[idx].mean(axis=1)) / gap
        draws = draws[np.isfinite(draws)]
        if draws.size:
            lo, hi = np.quantile(draws, [0.025, 0.975])
            ci = (float(lo), float(hi))
    note = None
    if ci is not None and not (ci[0] <= s <= ci[1]):  # an interval that does not hold its own estimate
        ci, note = None, (NO_INTERVAL if math.isfinite(s) else NO_SCORE)
    degenerate = (o.mean() - e.mean()) < DEGENERATE_GAP * o.mean()  # signed: an inverted scale too
    return Score(s, ci, float(p.mean()), float(o.mean()), float(e.mean()), len(p), bool(degenerate), note)


def score_results(result: dict, open_loop: dict, ekf_pid: dict) -> Score:
    """:func:`score_episodes` of three :func:`agents.evaluate.evaluate` results; ValueError if their seeds differ."""
    seeds = result["per_episode"]["seed"]
    for name, other in ((ZERO_ANCHOR, open_loop), (FULL_ANCHOR, ekf_pid)):
        if other["per_episode"]["seed"] != seeds:
            raise ValueError(f"score: {name} ran on other seeds than the policy")
    return score_episodes(*(r["per_episode"]["tracking_rmse"] for r in (result, open_loop, ekf_pid)))
