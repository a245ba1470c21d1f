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
from typing import Protocol

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
    check_wheel_commands(path, cmd, wheel_radius)


def check_wheel_commands(path: Path | str, cmd: np.ndarray, wheel_radius: float) -> None:
    """Raise InputError naming ``path`` if a commanded wheel speed ``cmd`` [rad/s] moves the rim (``wheel_radius``
    [m]) faster than :data:`~omni_gym.bounds.PLAUSIBLE_SPEED` (3000 rad/s on a 3 cm wheel: 90 m/s); ``omni-gym
    simulate`` and every dataset run."""
    rim = float(np.max(np.abs(cmd))) * wheel_radius if np.size(cmd) else 0.0
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


# --- Unit mistakes at import: the tracked motion against the wheels' (every importer) ----------------------
# A unit read wrongly scales the tracked motion against the wheel odometry by the unit's factor. The ratio r =
# tracked / wheels is about 1 without slip (0.95 to 1.13 on the shipped OptiOdom sessions) and slip only
# shortens the tracked motion; a ratio within MATCH of a factor below is that factor's mistake (MATCH 1.25 covers
# the shipped sessions' spread with margin and stays far from the next factor: 6.28, 9.55, 10 are 1.05-1.5
# apart, so the message names the candidates that match, never one at random).
MATCH = 1.25
# (factor r, what it means): poses read r times too large (x, y: translation only; theta: rotation only) or
# the wheels read r times too small (translation and rotation alike).
LENGTH_MISTAKES = ((1000.0, "x, y in millimetres read as metres"), (100.0, "x, y in centimetres read as metres"),
                   (10.0, "x, y in millimetres read as centimetres"), (1e-3, "x, y in metres read as millimetres"),
                   (1e-2, "x, y in metres read as centimetres"), (0.1, "x, y in centimetres read as millimetres"))
THETA_MISTAKES = ((180.0 / np.pi, "theta in degrees read as radians"), (np.pi / 180.0, "theta in radians read as "
                                                                                       "degrees"))
WHEEL_MISTAKES = ((60.0 / (2.0 * np.pi), "wheel angles or speeds in rad (rad/s) read as rpm"),
                  (2.0 * np.pi / 60.0, "wheel speeds in rpm read as rad/s"),
                  (180.0 / np.pi, "wheel angles in radians read as degrees"),
                  (np.pi / 180.0, "wheel angles in degrees read as radians"),
                  (2.0 * np.pi, "wheel angles in revolutions read as radians"),
                  (1.0 / (2.0 * np.pi), "wheel angles in radians read as revolutions"))


def _matches(ratio: float, table) -> list[str]:
    return [what for factor, what in table if ratio > 0 and abs(np.log(ratio / factor)) < np.log(MATCH)]


class Run(Protocol):
    """What the unit checks read of a run (``omni_gym.discrepancy.data.dataset.Run`` has it; not imported here:
    the dataset module imports this one)."""

    t: np.ndarray
    pose: np.ndarray
    enc: np.ndarray | None
    cmd: np.ndarray


def wheel_travel_of(run: Run) -> np.ndarray:
    """(K, n) wheel angles [rad] of ``run``: its ``enc`` columns, or the integral of its held commands."""
    if run.enc is not None:
        return np.asarray(run.enc, dtype=float)
    steps = run.cmd[:-1] * np.diff(run.t)[:, None]
    return np.vstack([np.zeros((1, run.cmd.shape[1])), np.cumsum(steps, axis=0)])


def check_import_units(where: str, runs: list[Run], wheel_matrix: np.ndarray, hint: str = "check --units") -> None:
    """Refuse an import whose tracked motion and wheel odometry disagree by a unit's factor (both directions:
    poses too large or too small, wheels too large or too small), naming the likely unit mistake.

    The one plausibility check after unit conversion for every importer (``logs.write_imported``: csv, rosbag2,
    optiodom). ``wheel_matrix`` (n, 3): the nominal model's (:func:`travel`); motion summed over ``runs``. A
    translation ratio outside the travel-ratio bound (``omni_gym.bounds.LOGS``) is refused whatever its cause, a
    rotation ratio outside it on a unit's factor; inside the bound, a run is refused where translation and rotation
    agree on one wheel unit's factor (wheels in rpm read as rad/s give 0.105 on both; slip shortens translation
    and rotation by different amounts, a unit by the same).
    """
    motion = np.zeros(4)
    for run in runs:
        motion += travel(run.t, run.pose, wheel_travel_of(run), wheel_matrix)
    bound = LOGS["travel ratio (tracked / wheels)"]
    # Translation: measured once either side moved (metres read as millimetres leave the tracker almost still);
    # outside the bound it is refused whatever the cause, as the OptiOdom import does.
    r_t = None
    if max(motion[0], motion[1]) >= MIN_MOTION[0]:
        r_t = motion[0] / motion[1] if motion[1] > 0 else np.inf
    # Rotation: slip alone can turn a robot whose wheels give almost no rotation (the Williams robot's slip turns
    # it 0.5 rad in 3 s while its wheels' net rotation stays under 1 mrad), so it is read only where the wheels
    # themselves turned at least a tenth of the least motion (0.05 rad), and refused only on a unit's factor.
    r_r = None
    if motion[2] >= MIN_MOTION[1] or motion[3] >= MIN_MOTION[1]:
        r_r = motion[2] / motion[3] if motion[3] >= 0.1 * MIN_MOTION[1] else None
    wheel_t = _matches(r_t, WHEEL_MISTAKES) if r_t is not None else []
    wheel = [w for w in wheel_t if w in _matches(r_r, WHEEL_MISTAKES)] if r_r is not None else []
    if wheel:  # translation and rotation off by one wheel factor: the wheels (x, y or theta move one only)
        causes = wheel
    else:
        causes = []
        if r_t is not None and not bound.contains(r_t):
            causes = wheel_t + _matches(r_t, LENGTH_MISTAKES) or ["a unit of x, y or the wheels, or the model's wheel "
                                                                  "radius"]
        if r_r is not None and not bound.contains(r_r):
            causes += _matches(r_r, THETA_MISTAKES) + _matches(r_r, WHEEL_MISTAKES)
    if not causes:
        return
    shown = "; ".join(f"tracked {what} {r:.3g} times the wheel odometry's" for what, r in
                      (("translation", r_t), ("rotation", r_r)) if r is not None)
    cause = f"likely {' or '.join(causes)}"
    raise InputError(f"{where}: {shown} (expected about 1 without slip, {bound.within()}): {cause}; {hint}")
