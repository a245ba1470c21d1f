"""Timestamped robot logs → dataset runs: the part every general-purpose importer shares.

A robot logs its wheels and its tracked pose as two streams with their own clocks: wheel samples
(angles from encoders, or speeds) at times ``t_w`` and pose samples at times ``t_p``. One run of the dataset
(``docs/formats.md`` "Dataset") is built from them (:func:`make_run`):

* The run's rows are the wheel samples inside the run's time window and inside the pose stream's time
  span (so the first row has a tracked pose); times are shifted so the first row is t = 0.
* With a wheel-**command** stream (speeds [rad/s], what the robot was told), the rows are its samples
  instead, each command held until the next, and ``enc`` the wheel angles interpolated at the row times.
* Wheel **angles** θ_k [rad] (``kind="position"``): the command held from t_k to t_{k+1} is the mean speed
  (θ_{k+1} − θ_k) / (t_{k+1} − t_k) (the wheel's measured motion stands in for the command, as in the OptiOdom
  import); ``enc`` = θ − θ_0. Wheel **speeds** ω_k [rad/s] (``kind="velocity"``): the held command is the
  interval's mean (ω_k + ω_{k+1}) / 2 (trapezoid); ``enc`` its integral. The last row's command is 0.
* The pose [m, m, rad] at each row time is linearly interpolated between the two pose samples around it
  (heading unwrapped first); rows whose neighbouring pose samples are more than ``max_gap`` seconds apart
  (a tracking dropout) are unobserved (empty cells).

:class:`Units` converts a log's units to SI; :func:`write_imported` writes the dataset complete or absent.
Every error is a one-line :class:`~omni_gym.io.InputError` naming the source (file, topic, column).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omni_gym.bounds import FILES
from omni_gym.discrepancy.data.dataset import Run, write_dataset
from omni_gym.discrepancy.data.units import check_import_units, check_run_units
from omni_gym.io import InputError, first_not_increasing
from omni_gym.outputs import Output, check_file_name
from omni_gym.physics.model import SimModel

# --- units ---------------------------------------------------------------------------------------------

LENGTH = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # metres per unit
ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}  # radians per unit (theta)
TIME = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}  # seconds per unit
# Wheel angle: radians per unit; a wheel speed is this per second, except rpm (revolutions per minute).
WHEEL = {"rad": 1.0, "deg": math.pi / 180.0, "rev": 2.0 * math.pi, "rpm": 2.0 * math.pi / 60.0}


@dataclass(frozen=True)
class Units:
    """A log's units as SI factors: ``length`` [m per unit] of x, y; ``angle`` [rad per unit] of theta;
    ``time`` [s per unit] of the time column; ``wheel`` [rad per unit] of wheel angles (a wheel speed is
    wheel units per second, or per minute for ``rpm``); the names as given, for messages."""

    length: float = 1.0
    angle: float = 1.0
    time: float = 1.0
    wheel: float = 1.0
    names: tuple[str, str, str, str] = ("m", "rad", "s", "rad")

    def describe(self) -> str:
        length, angle, time, wheel = self.names
        return f"x, y in {length}, theta in {angle}, time in {time}, wheels in {wheel}"


def parse_units(spec: str | None, option: str = "--units") -> Units:
    """``--units mm,deg`` → :class:`Units`. Tokens, comma-separated, in any order: a length (m, cm, mm),
    an angle (rad, deg: theta, and the wheels unless given), a time (s, ms, us, ns), ``wheel=UNIT``
    (rad, deg, rev, or rpm for speeds). Defaults: m, rad, s. ValueError (one line) naming the token."""
    found: dict[str, str] = {}
    for token in (spec or "").split(","):
        token = token.strip()
        if not token:
            continue
        if token.startswith("wheel="):
            kind, name, table = "wheel", token[6:].strip(), WHEEL
        else:
            kind, name, table = next(((k, token, t) for k, t in (("length", LENGTH), ("angle", ANGLE),
                                                                 ("time", TIME)) if token in t), ("", token, {}))
        if name not in table:
            raise InputError(f"{option}: unknown unit {token!r} (lengths {', '.join(LENGTH)}; angles "
                             f"{', '.join(ANGLE)}; times {', '.join(TIME)}; wheel={'|'.join(WHEEL)})")
        if kind in found:
            raise InputError(f"{option}: two {kind} units ({found[kind]} and {name})")
        found[kind] = name
    length, angle, time = found.get("length", "m"), found.get("angle", "rad"), found.get("time", "s")
    wheel = found.get("wheel", angle)
    return Units(LENGTH[length], ANGLE[angle], TIME[time], WHEEL[wheel], (length, angle, time, wheel))


# --- streams ---------------------------------------------------------------------------------------------


@dataclass
class WheelLog:
    """Wheel samples in the model's wheel order, SI: ``t`` (K,) [s], ``values`` (K, n) wheel angles [rad]
    (``kind`` "position") or speeds [rad/s] ("velocity"); ``where``: the source for messages (file or
    topic); ``names``: each wheel's source (column or joint, with its sign)."""

    t: np.ndarray
    values: np.ndarray
    kind: str
    where: str
    names: tuple[str, ...]


@dataclass
class PoseLog:
    """Tracked poses, SI: ``t`` (M,) [s], ``pose`` (M, 3) [m, m, rad]; ``where``: the source."""

    t: np.ndarray
    pose: np.ndarray
    where: str


def check_increasing(t: np.ndarray, where: str, what: str = "message", first: int = 1) -> None:
    """Refuse times that are not finite or not strictly increasing, naming the first bad ``what`` (the first
    sample is number ``first``)."""
    bad = np.nonzero(~np.isfinite(t))[0]
    if bad.size:
        raise InputError(f"{where}: {what} {int(bad[0]) + first}: time is not a finite number")
    k = first_not_increasing(t)
    if k is not None:
        raise InputError(f"{where}: {what} {k + first}: times must be strictly increasing ({t[k]:.9g} s after "
                         f"{t[k - 1]:.9g} s)")


def check_moving(wheels: WheelLog) -> None:
    """Refuse a wheel whose log never changes: a wrong joint or column (the run would say it never turned)."""
    for i, name in enumerate(wheels.names):
        v = wheels.values[:, i]
        still = np.ptp(v) == 0.0 if wheels.kind == "position" else not np.any(v != 0.0)
        if still and len(v) > 1:
            raise InputError(f"{wheels.where}: wheel {i + 1} ({name}) never moves in the log: a wrong joint or "
                             "column name, or that wheel was not logged")


def unwrap_heading(theta: np.ndarray) -> np.ndarray:
    """A heading [rad] made continuous (steps of more than π are taken as wraps)."""
    return np.unwrap(theta)


@dataclass(frozen=True)
class Window:
    """A run's time window [s], relative to the log's first wheel sample; ``end`` may be inf."""

    start: float
    end: float
    name: str


def parse_windows(specs: list[str] | None, option: str = "--window") -> list[Window] | None:
    """``START:END`` [s] (``END`` may be empty: to the end), optionally ``NAME=START:END``; None if none given."""
    if not specs:
        return None
    out = []
    for k, spec in enumerate(specs):
        name, _, span = spec.rpartition("=")
        a, sep, b = span.partition(":")
        try:
            start = float(a) if a.strip() else 0.0
            end = float(b) if b.strip() else math.inf
        except ValueError:
            raise InputError(f"{option} {spec!r}: expected START:END in seconds (e.g. 0:60)") from None
        if not sep or not (math.isfinite(start) and start >= 0 and end > start):
            raise InputError(f"{option} {spec!r}: expected START:END in seconds with 0 <= START < END")
        out.append(Window(start, end, check_file_name(name, "run name", f"{option} {spec!r}") if name
                          else f"run{k:03d}"))
    return out


def make_run(name: str, wheels: WheelLog, pose: PoseLog, wheel_radius: float, window: Window | None = None,
             max_gap: float = 0.25, session: str | None = None, commands: WheelLog | None = None) -> Run:
    """One dataset run from a wheel stream and a pose stream (mapping in the module docstring).

    ``window`` [s] relative to the wheel stream's first sample (None: all of it); ``max_gap`` [s]: pose samples
    further apart than this do not interpolate (the rows between are unobserved); ``wheel_radius`` [m]: the
    model's, for the units check. ``commands``: a wheel-command stream (speeds [rad/s], each held until the
    next): the rows are then its samples, ``w`` its values, and ``enc`` the wheel angles interpolated linearly
    at the row times (``wheels`` of kind "position"; None for wheel speeds). InputError naming the source on
    bad input.
    """
    t_w = wheels.t
    t0_log = float(t_w[0])
    lo, hi = max(float(pose.t[0]), t0_log), float(pose.t[-1])
    if commands is not None:
        hi = min(hi, float(t_w[-1]))  # the wheel angles must cover every row
    if window is not None:
        lo, hi = max(lo, t0_log + window.start), min(hi, t0_log + window.end)
    rows_from = wheels if commands is None else commands
    t_r = rows_from.t
    keep = (t_r >= lo) & (t_r <= hi)
    where = f"{rows_from.where} and {pose.where}" + (f", window {window.name}" if window else "")
    if np.count_nonzero(keep) < 2:
        what = "wheel samples" if commands is None else "wheel commands"
        raise InputError(f"{where}: fewer than two {what} where the pose is tracked "
                         f"({what} {t_r[0] - t0_log:.3f}…{t_r[-1] - t0_log:.3f} s, pose "
                         f"{pose.t[0] - t0_log:.3f}…{pose.t[-1] - t0_log:.3f} s of the log)")
    t = t_r[keep]
    v = rows_from.values[keep]
    K, n = v.shape
    dt = np.diff(t)
    cmd = np.zeros((K, n))
    enc: np.ndarray | None = np.zeros((K, n))
    if commands is not None:
        cmd[:-1] = v[:-1]
        if wheels.kind == "position":
            angles = np.column_stack([np.interp(t, t_w, wheels.values[:, i]) for i in range(n)])
            enc = angles - angles[0]
        else:
            enc = None
    elif wheels.kind == "position":
        with np.errstate(over="ignore", invalid="ignore"):  # absurd values: refused below, not warned about
            cmd[:-1] = np.diff(v, axis=0) / dt[:, None]
            enc = v - v[0]
    else:
        with np.errstate(over="ignore", invalid="ignore"):
            mean = 0.5 * (v[1:] + v[:-1])
            cmd[:-1] = mean
            enc[1:] = np.cumsum(mean * dt[:, None], axis=0)
    for what, values in (("wheel speed", cmd), ("wheel angle", enc)):
        bad = np.nonzero(~np.all(np.isfinite(values), axis=1))[0] if values is not None else []
        if len(bad):
            raise InputError(f"{where}: at t = {t[bad[0]] - t[0]:.6g} s: the {what} overflows (not a finite number; "
                             "absurd wheel values or times too close together)")
    heading = FILES["theta"]  # held as logged: unwrapping folds a corrupt 99999 rad cell into a small jump
    raw = pose.pose[:, 2]
    bad = np.nonzero(np.isfinite(raw) & ((raw < heading.lo) | (raw > heading.hi)))[0]
    if bad.size:
        raise InputError(f"{where}: at t = {pose.t[bad[0]] - pose.t[0]:.6g} s: theta {heading.describe()}, got "
                         f"{raw[bad[0]]:.6g} (a corrupt cell or another unit)")
    th = unwrap_heading(raw)
    rows = np.column_stack([np.interp(t, pose.t, pose.pose[:, 0]), np.interp(t, pose.t, pose.pose[:, 1]),
                            np.interp(t, pose.t, th)])
    j = np.clip(np.searchsorted(pose.t, t), 1, len(pose.t) - 1)
    exact = pose.t[j - 1] == t
    gap = (pose.t[j] - pose.t[j - 1] > max_gap) & ~exact & (pose.t[j] != t)
    rows[gap] = np.nan
    t = t - t[0]
    run = Run(name=name, t=t + 0.0, cmd=cmd + 0.0, pose=rows, enc=None if enc is None else enc + 0.0, session=session)
    check_run_bounds(run, where)
    check_run_units(where, run.t, run.cmd, run.pose, wheel_radius)  # type: ignore[arg-type]  # named in the message
    return run


def check_run_bounds(run: Run, where: str) -> None:
    """Hold every column to its bound (``omni_gym.bounds.FILES``); InputError naming the source and the time."""
    checks = (("run duration (t)", run.t, FILES["t"]), ("wheel speed", run.cmd, FILES["w1 … wn"]),
              ("wheel angle", run.enc, FILES["enc1 … encn"]), ("x, y", run.pose[:, :2], FILES["x, y"]),
              ("theta", run.pose[:, 2], FILES["theta"]))
    for what, values, bound in checks:
        if values is None:
            continue
        arr = np.asarray(values, dtype=float).reshape(len(run.t), -1)
        bad = np.nonzero(np.any(np.isfinite(arr) & ((arr < bound.lo) | (arr > bound.hi)), axis=1))[0]
        if bad.size:
            k = int(bad[0])
            raise InputError(f"{where}: at t = {run.t[k]:.3f} s of run {run.name}: {what} "
                             f"{bound.describe()}, got {np.max(np.abs(arr[k])):.4g}")


def wheel_radius_of(model_json: dict) -> float:
    """The nominal model's wheel radius [m] (for the units check)."""
    return float(model_json["wheel_radius"])


def write_imported(out: str | Path, inputs: list[Path], force: bool, build: Callable[[], tuple[dict, str, list[Run]]],
                   hint: str = "check --units") -> None:
    """Write the dataset folder ``out`` complete or absent (:class:`omni_gym.outputs.Output`, as ``omni-gym
    synth``): ``build()`` reads the logs under the output's lock and returns (model JSON, description, runs).
    The runs' tracked motion is checked against their wheels' for a unit mistake
    (:func:`~omni_gym.discrepancy.data.units.check_import_units`; ``hint`` ends the message)."""
    with Output(Path(out), "dir", force=force, inputs=inputs, marker="dataset.json", what="dataset") as tx:
        model_json, description, runs = build()
        names = [check_file_name(r.name, "run name", str(out)) for r in runs]
        dup = next((n for n in names if names.count(n) > 1), None)
        if dup is not None:
            raise InputError(f"two runs are named {dup!r}; give each window or file its own name")
        where = str(inputs[0]) if len(inputs) == 1 else f"{len(inputs)} inputs ({inputs[0]}, …)"
        wheel_matrix = SimModel.from_json(model_json, where="nominal model").robot.wheel_matrix()
        check_import_units(where, runs, wheel_matrix, hint)  # every importer: unit mistakes, both directions
        write_dataset(tx.path, model_json, description, runs)
