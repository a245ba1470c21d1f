"""Unit checks of a dataset run as a whole: rates no wheeled robot reaches mean other units.

Every cell of a run may lie inside its bound (``omni_gym.bounds.FILES``) and the run still be in the
wrong units: positions in millimetres, a heading in degrees, wheel speeds in rpm or °/s. The workflow
then answers with nonsense (a "gap beyond noise" of kilometres). These checks read the rates the
columns imply and refuse a run beyond :data:`~omni_gym.bounds.PLAUSIBLE_SPEED` or
:data:`~omni_gym.bounds.PLAUSIBLE_YAW_RATE`, naming the likely cause.

Tracked rates are measured over baselines of at least :data:`BASELINE` seconds and their median is
compared: tracker noise (σ over 1 s adds about σ·1.4 per second) and a few jumps (a tracker reset)
cannot raise it, while a run in millimetres raises every moving window by a factor of 1000.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from omni_gym.bounds import LOGS, PLAUSIBLE_SPEED, PLAUSIBLE_YAW_RATE
from omni_gym.io import InputError

BASELINE = 1.0  # s: shortest time between the two poses of one rate (the whole run if shorter)


def tracked_rates(t: np.ndarray, pose: np.ndarray) -> tuple[float, float]:
    """Median (speed [m/s], |heading rate| [rad/s]) of the observed poses over baselines of ``BASELINE``.

    ``t`` (K,) [s], ``pose`` (K, 3) with NaN rows where nothing was observed. The heading difference is
    taken as written (not wrapped): a wrapped heading jumps by 2π only now and then, which the median
    ignores. (0, 0) with fewer than two observed poses.
    """
    seen = np.all(np.isfinite(pose), axis=1)
    ts, ps = t[seen], pose[seen]
    if ts.size < 2:
        return 0.0, 0.0
    base = min(BASELINE, float(ts[-1] - ts[0]))
    j = np.searchsorted(ts, ts + base - 1e-12)  # first pose at least `base` later
    i = np.nonzero(j < ts.size)[0]
    j = j[i]
    dt = ts[j] - ts[i]
    speed = np.hypot(ps[j, 0] - ps[i, 0], ps[j, 1] - ps[i, 1]) / dt
    yaw = np.abs(ps[j, 2] - ps[i, 2]) / dt
    return float(np.median(speed)), float(np.median(yaw))


def check_run_units(path: Path, t: np.ndarray, cmd: np.ndarray, pose: np.ndarray, wheel_radius: float) -> None:
    """Raise InputError naming ``path`` and the likely cause if the run's rates are out of reach.

    ``cmd`` (K, n) [rad/s] commanded wheel speeds, ``wheel_radius`` [m] the model's; ``t``, ``pose`` as
    in :func:`tracked_rates`.
    """
    speed, yaw = tracked_rates(t, pose)
    if speed > PLAUSIBLE_SPEED:
        raise InputError(f"{path}: x, y move at {speed:.3g} m/s (median over {BASELINE:g} s), faster than any wheeled "
                         f"robot (> {PLAUSIBLE_SPEED:g} m/s): positions look like millimetres; the format wants metres")
    if yaw > PLAUSIBLE_YAW_RATE:
        raise InputError(f"{path}: theta turns at {yaw:.3g} rad/s (median over {BASELINE:g} s), faster than any "
                         f"wheeled robot (> {PLAUSIBLE_YAW_RATE:g} rad/s): theta looks like degrees; the format wants "
                         "radians")
    rim = float(np.max(np.abs(cmd))) * wheel_radius if cmd.size else 0.0
    if rim > PLAUSIBLE_SPEED:
        raise InputError(f"{path}: commanded wheel speeds reach {rim:.3g} m/s at the rim (r = {wheel_radius:g} m), "
                         f"faster than any wheeled robot (> {PLAUSIBLE_SPEED:g} m/s): w1 … wn look like rpm or "
                         "degrees per second; the format wants rad/s")


def travel(t: np.ndarray, pose: np.ndarray, enc: np.ndarray, wheel_radius: np.ndarray, lever: float
           ) -> tuple[float, float]:
    """(tracked motion [m], wheels' rim travel [m]) of one run over baselines of at least :data:`BASELINE` s.

    Tracked motion per baseline: |Δ(x, y)| + ``lever``·|Δθ| (``lever`` [m]: the wheel-centre radius, so a
    turn on the spot counts as the rim travel it needs); wheel travel: the mean over wheels of
    |Δφ_i|·r_i (``enc`` (K, n) [rad], ``wheel_radius`` (n,) [m]). Only baselines between observed poses
    count. Without slip the two agree within a factor of about 2 (the wheels' drive directions share the
    motion); long baselines make tracker noise negligible.
    """
    seen = np.nonzero(np.all(np.isfinite(pose), axis=1))[0]
    if seen.size < 2:
        return 0.0, 0.0
    picks = [int(seen[0])]
    for k in seen[1:]:
        if t[k] - t[picks[-1]] >= BASELINE:
            picks.append(int(k))
    if len(picks) < 2:
        picks.append(int(seen[-1]))
    idx = np.asarray(picks)
    d = np.diff(pose[idx], axis=0)
    tracked = float(np.sum(np.hypot(d[:, 0], d[:, 1]) + lever * np.abs(d[:, 2])))
    wheels = float(np.sum(np.mean(np.abs(np.diff(enc[idx], axis=0)) * np.asarray(wheel_radius), axis=1)))
    return tracked, wheels


MIN_TRACKED = 0.05  # m: below this much tracked motion a dataset says nothing about scale


def check_travel_scale(where: str, tracked: float, wheels: float, settings: str) -> None:
    """Refuse a dataset whose tracked motion does not match its wheels' travel (``omni_gym.bounds.LOGS``,
    travel ratio): poses in other units, or encoder settings (``settings``, e.g. ``ngear 12, encRes 1024``)
    that make the wheels turn too little or too much. ``where`` names the file(s)."""
    bound = LOGS["travel ratio (tracked / wheels)"]
    if tracked < MIN_TRACKED:
        return
    if wheels <= 0.0:
        raise InputError(f"{where}: the tracker shows {tracked:.3g} m of motion but the wheels never turn "
                         f"({settings}): expected wheel travel comparable to the tracked motion; check ngear and "
                         "encRes")
    ratio = tracked / wheels
    if not bound.contains(ratio):
        cause = ("poses look like millimetres (the format wants metres), or ngear/encRes are too large"
                 if ratio > bound.hi else "ngear/encRes look too small, or the poses are not in metres")
        raise InputError(f"{where}: the tracked motion ({tracked:.3g} m) is {ratio:.3g} times the wheels' rim "
                         f"travel ({wheels:.3g} m; {settings}); expected a ratio {bound.within()}: {cause}")
