"""What no model can predict: the per-run heading refit of an open-loop replay.

A replayed run drifts from the tracked one for two kinds of reasons: a model error that repeats from run to
run (what ``gap`` looks for) and run-to-run variation no model of the robot can predict (the floor under each
run, the start heading the tracker reports, a battery that runs down). The second kind shows as a per-run
**initial heading offset** θ₀ [rad] and a per-run **yaw-rate scale** k: the replay's path bent as if the
robot had started θ₀ off and turned k times as fast. Refitting these two per run (what a model that knew
each run's conditions could do) and scoring again says how much of a run's error is of that kind.

The refit bends the replayed path without simulating again: with the replay's poses p(t), heading θ(t) and
its world-frame displacement Δp between rows, the bent path turns each displacement by
δ(t) = θ₀ + (k − 1)(θ(t) − θ(t₀)) about the start, p'(t) = p(t₀) + Σ R(δ) Δp. Exact for a rigid rotation of the
motion; for a yaw-rate scale it keeps the body-frame velocities of the replay (first order in k − 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Bounds of the refit: a heading offset within ±0.5 rad (29°) and a yaw-rate scale within ±50 %; values at
# a bound say that the run differs by more than a heading or a turn rate (the refit then reports the bound).
MAX_HEADING_OFFSET = 0.5
YAW_SCALE_RANGE = (0.5, 1.5)


@dataclass
class RunRefit:
    """The per-run refit of one replay (module docstring): ``heading_offset`` θ₀ [rad], ``yaw_scale`` k and
    the position RMS [m] of the bent replay against the tracker (observed rows, as the plain score)."""

    heading_offset: float
    yaw_scale: float
    position_rms: float


def bend(pose: np.ndarray, heading_offset: float, yaw_scale: float) -> np.ndarray:
    """The replay ``pose`` (K, 3: x, y [m], heading [rad], world frame) bent by a heading offset [rad] and a
    yaw-rate scale about its first row (module docstring); returns the new (K, 3) poses."""
    p = np.asarray(pose, dtype=float)
    dtheta = p[:, 2] - p[0, 2]
    delta = heading_offset + (yaw_scale - 1.0) * dtheta
    step = np.diff(p[:, :2], axis=0)
    mid = 0.5 * (delta[1:] + delta[:-1])  # the turn over each row step, at its middle
    c, s = np.cos(mid), np.sin(mid)
    turned = np.stack([c * step[:, 0] - s * step[:, 1], s * step[:, 0] + c * step[:, 1]], axis=1)
    out = np.empty_like(p)
    out[0, :2] = p[0, :2]
    out[1:, :2] = p[0, :2] + np.cumsum(turned, axis=0)
    out[:, 2] = p[:, 2] + delta
    return out


def refit_run(measured: np.ndarray, replay: np.ndarray) -> RunRefit:
    """The heading offset and yaw-rate scale that bring ``replay`` (K, 3) closest to ``measured`` (K, 3,
    NaN rows not tracked) in position, by least squares over the tracked rows."""
    from scipy.optimize import least_squares

    ok = np.all(np.isfinite(measured), axis=1) & np.all(np.isfinite(replay), axis=1)
    if ok.sum() < 3:
        return RunRefit(math.nan, math.nan, math.nan)

    def residual(x: np.ndarray) -> np.ndarray:
        return (bend(replay, x[0], x[1])[ok, :2] - measured[ok, :2]).ravel()

    lo = [-MAX_HEADING_OFFSET, YAW_SCALE_RANGE[0]]
    hi = [MAX_HEADING_OFFSET, YAW_SCALE_RANGE[1]]
    fit = least_squares(residual, x0=[0.0, 1.0], bounds=(lo, hi), x_scale=[0.05, 0.05])
    e = residual(fit.x).reshape(-1, 2)
    return RunRefit(float(fit.x[0]), float(fit.x[1]), float(math.sqrt(np.mean(np.sum(e**2, axis=1)))))
