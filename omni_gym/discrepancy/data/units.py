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


def travel(t: np.ndarray, pose: np.ndarray, enc: np.ndarray, wheel_matrix: np.ndarray) -> np.ndarray:
    """Motion of one run over baselines of at least :data:`BASELINE` s, by the tracker and by the wheels:
    [tracked translation [m], wheel-odometry translation [m], tracked rotation [rad], odometry rotation [rad]].

    ``enc`` (K, n) wheel angles [rad]; ``wheel_matrix`` (n, 3): body twist → no-slip wheel speeds
    (:meth:`omni_gym.physics.robot.RobotSpec.wheel_matrix`). Per baseline the body motion is the
    least-squares inverse of the wheels' turn; only baselines between observed poses count. Without slip
    the two agree (slip shortens the tracked motion); long baselines make tracker noise negligible.
    """
    seen = np.nonzero(np.all(np.isfinite(pose), axis=1))[0]
    if seen.size < 2:
        return np.zeros(4)
    picks = [int(seen[0])]
    for k in seen[1:]:
        if t[k] - t[picks[-1]] >= BASELINE:
            picks.append(int(k))
    if len(picks) < 2:
        picks.append(int(seen[-1]))
    idx = np.asarray(picks)
    d = np.diff(pose[idx], axis=0)
    turn = np.angle(np.exp(1j * d[:, 2]))  # a wrapped heading's 2π jumps are no rotation
    turns = np.diff(enc[idx], axis=0)  # (B, n) [rad]
    body = np.linalg.lstsq(np.asarray(wheel_matrix), turns.T, rcond=None)[0].T  # (B, 3): dx, dy [m], dθ [rad]
    return np.array([np.sum(np.hypot(d[:, 0], d[:, 1])), np.sum(np.hypot(body[:, 0], body[:, 1])),
                     np.sum(np.abs(turn)), np.sum(np.abs(body[:, 2]))])


MIN_MOTION = (0.05, 0.5)  # m, rad: below this much motion (tracked and wheels alike) nothing tells a scale


def check_travel_scale(where: str, motion: np.ndarray, settings: str) -> None:
    """Refuse a dataset whose tracked motion does not match its wheels' (``motion``: :func:`travel`, summed
    over runs; ``omni_gym.bounds.LOGS``, travel ratio): poses in other units, or encoder settings
    (``settings``, e.g. ``ngear 12, encRes 1024``) that make the wheels turn too little or too much. ``where``
    names the file(s)."""
    bound = LOGS["travel ratio (tracked / wheels)"]
    for (tracked, wheels), what, unit, least in ((motion[:2], "translation", "m", MIN_MOTION[0]),
                                                 (motion[2:], "rotation", "rad", MIN_MOTION[1])):
        if max(tracked, wheels) < least:  # neither moved enough to tell a scale
            continue
        if wheels <= 0.0:
            raise InputError(f"{where}: the tracker shows {tracked:.3g} {unit} of {what} but the wheels never turn "
                             f"({settings}): expected wheel odometry comparable to the tracked motion; check ngear "
                             "and encRes")
        ratio = tracked / wheels
        if not bound.contains(ratio):
            cause = ("poses in smaller units than the format's (millimetres, degrees), or ngear/encRes too large"
                     if ratio > bound.hi else "poses in larger units than the format's, or ngear/encRes too small")
            raise InputError(f"{where}: the tracked {what} ({tracked:.3g} {unit}) is {ratio:.3g} times the wheel "
                             f"odometry's ({wheels:.3g} {unit}; {settings}); expected a ratio {bound.within()}: "
                             f"{cause}")
