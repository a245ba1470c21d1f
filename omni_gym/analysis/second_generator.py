"""Validation datasets for ``omni-gym gap`` from the second integrator (:mod:`.event_integrator`).

One call, one dataset folder in the format of ``docs/formats.md`` ("Dataset") and its truth file
``DATASET.truth.json`` beside it::

    write_second_dataset("data/check", robot="williams2002", hidden={"com_offset": {"com": [0.01, 0.0]}},
                         runs=4, duration=3.0, manoeuvre="smooth", position_noise=0.001,
                         heading_noise=0.002, encoder_counts=2048, seed=7)

What a run is:

* **Commands.** A body twist (vx, vy [m/s], ω [rad/s], geometric centre, body frame) from the
  manoeuvre family, held per tracker row (a 100 Hz default), turned into wheel speeds by the
  **nominal** wheel matrix, w_i = (v + ω z × p_i)·(d_i + tan γ_i a_i) / r (what the robot's own
  controller would command; the hidden effect is not known to it). Every run starts at rest
  (optionally standing still for ``start_rest`` seconds first) and ends with at least 0.3 s of rest.
  Families: ``steps`` (random twist steps of 0.3-1 s, speed 0.1-0.4 m/s in a random direction and
  |ω| ≤ 1.8 rad/s, one step in five a rest), ``smooth`` (each twist component a sum of three
  sinusoids of 0.1-0.8 Hz scaled to a peak speed 0.2-0.4 m/s and yaw rate 0.8-1.8 rad/s, faded in and
  out over 0.5 s), ``turns`` (turns in place at 1-2 rad/s for 0.5-1.2 s, then 0.3-0.6 s translations
  at 0.15-0.35 m/s, short rests between).
* **Physics.** The nominal model (robot preset, surface, friction) with the hidden physics effect,
  integrated by :func:`.event_integrator.integrate` from rest at the run's start pose (x, y uniform in
  ±0.5 m, θ uniform in [−π, π)). ``wheel_liftoff``: the run's lift switches are drawn by
  :func:`.event_integrator.draw_lift_schedule` and stored in the truth file.
* **Tracker.** Poses at the row times, the tracker effects applied here (``time_offset``: the pose
  stamped t is the one of time t − delay, at rest at the start pose before 0; ``tracker_offset``:
  p + R(θ)·offset and θ + yaw), then white Gaussian noise (std ``position_noise`` [m] in x and y,
  ``heading_noise`` [rad]).
* **Encoders.** The wheel angles read by an incremental encoder of ``encoder_counts`` counts per turn:
  q·(floor((φ + φ0)/q) − floor(φ0/q)), q = 2π/counts, with an unknown start offset φ0 ~ U(0, q) per
  wheel and run (so the reading is 0 at t = 0 and unbiased on average).

Hidden effects: ``None`` or ``{name: params}`` with the parameters of the effect's model-file JSON
(``docs/discrepancy.md``), or ``{"drag": c}`` (c [N·s/m], or ``{"c": c, "c_rot": c_rot}`` with a
yaw drag torque −c_rot·ω [N·m·s]), an effect outside the library. Every random draw comes from one
``numpy.random.default_rng(seed)``, so a seed gives the same bytes.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from omni_gym import outputs
from omni_gym.analysis.event_integrator import (
    TRACKER_EFFECTS,
    build_plant,
    check_effects,
    draw_lift_schedule,
    integrate,
)
from omni_gym.physics.model import SimModel, load_model

ROBOTS = ("williams2002", "optiodom_omni4")
MANOEUVRES = ("steps", "smooth", "turns")
END_REST = 0.3  # s of rest that ends every run


def wheel_matrix(model: SimModel) -> np.ndarray:
    """(n, 3): nominal wheel speeds [rad/s] per body twist (vx, vy [m/s], ω [rad/s]) of the geometric centre."""
    robot = model.robot
    rows = []
    for w in robot.wheels:
        d = np.asarray(w.drive, dtype=float)
        d = d / np.linalg.norm(d)
        a = np.array([-d[1], d[0]])
        s = d + math.tan(w.roller_angle) * a
        px, py = w.position
        rows.append([s[0], s[1], s[0] * (-py) + s[1] * px])
    return np.asarray(rows) / robot.wheel_radius


def _twist_steps(t: np.ndarray, duration: float, rng: np.random.Generator) -> np.ndarray:
    twist = np.zeros((len(t), 3))
    start = 0.0
    while start < duration - END_REST:
        length = rng.uniform(0.3, 1.0)
        if rng.uniform() < 0.2:
            value = np.zeros(3)
        else:
            speed, heading = rng.uniform(0.1, 0.4), rng.uniform(-math.pi, math.pi)
            value = np.array([speed * math.cos(heading), speed * math.sin(heading), rng.uniform(-1.8, 1.8)])
        twist[(t >= start) & (t < start + length)] = value
        start += length
    return twist


def _twist_smooth(t: np.ndarray, duration: float, rng: np.random.Generator) -> np.ndarray:
    twist = np.zeros((len(t), 3))
    for c in range(3):
        freqs = rng.uniform(0.1, 0.8, 3)
        phases = rng.uniform(0.0, 2 * math.pi, 3)
        amps = rng.uniform(0.3, 1.0, 3)
        twist[:, c] = np.sum(amps[:, None] * np.sin(2 * math.pi * freqs[:, None] * t[None, :] + phases[:, None]), 0)
    speed = np.hypot(twist[:, 0], twist[:, 1])
    twist[:, :2] *= rng.uniform(0.2, 0.4) / max(speed.max(), 1e-9)
    twist[:, 2] *= rng.uniform(0.8, 1.8) / max(np.abs(twist[:, 2]).max(), 1e-9)
    moving = duration - END_REST
    fade = 0.5
    ramp = np.clip(np.minimum(t / fade, (moving - t) / fade), 0.0, 1.0)
    return twist * (ramp * ramp * (3 - 2 * ramp))[:, None]  # smoothstep in and out


def _twist_turns(t: np.ndarray, duration: float, rng: np.random.Generator) -> np.ndarray:
    twist = np.zeros((len(t), 3))
    start, turn = 0.0, True
    while start < duration - END_REST:
        if turn:
            length = rng.uniform(0.5, 1.2)
            value = np.array([0.0, 0.0, rng.choice([-1.0, 1.0]) * rng.uniform(1.0, 2.0)])
        else:
            length = rng.uniform(0.3, 0.6)
            speed, heading = rng.uniform(0.15, 0.35), rng.uniform(-math.pi, math.pi)
            value = np.array([speed * math.cos(heading), speed * math.sin(heading), 0.0])
        twist[(t >= start) & (t < start + length)] = value
        start += length
        start += rng.uniform(0.1, 0.3)  # a short rest between
        turn = not turn
    return twist


def manoeuvre_twist(family: str, t: np.ndarray, duration: float, rng: np.random.Generator) -> np.ndarray:
    """(K, 3) body twists held from each row time of ``t`` [s]; zero over the final rest."""
    makers = {"steps": _twist_steps, "smooth": _twist_smooth, "turns": _twist_turns}
    if family not in makers:
        raise ValueError(f"manoeuvre: unknown family {family!r} (known: {', '.join(MANOEUVRES)})")
    twist = makers[family](t, duration, rng)
    twist[t >= duration - END_REST] = 0.0
    return twist


def run_commands(model: SimModel, family: str, duration: float, rate: float,
                 rng: np.random.Generator, start_rest: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(times (K,) [s], wheel commands (K, n) [rad/s]) of one run; the last row (t = duration) ends it.

    ``start_rest`` [s]: the robot stands still that long before the manoeuvre starts.
    """
    rows = int(round(duration * rate))
    t = np.arange(rows + 1) / rate
    twist = manoeuvre_twist(family, t - start_rest, duration - start_rest, rng)
    twist[t < start_rest] = 0.0
    return t, twist @ wheel_matrix(model).T


def _check_number(value, name: str, lo: float, hi: float) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name}: NaN or infinity ({value!r})")
    if not lo <= x <= hi:
        raise ValueError(f"{name}: {x} outside [{lo}, {hi}]")
    return x


def _tracked(pose: np.ndarray, tracker: dict) -> np.ndarray:
    out = pose.copy()
    if "tracker_offset" in tracker:
        ox, oy = tracker["tracker_offset"]["offset"]
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        out[:, 0] += c * ox - s * oy
        out[:, 1] += s * ox + c * oy
        out[:, 2] += float(tracker["tracker_offset"]["yaw"])
    return out


def simulate_run(model: SimModel, hidden: dict, times: np.ndarray, commands: np.ndarray, start_pose,
                 rng: np.random.Generator) -> dict:
    """Noise-free truth of one run: the tracked pose at the row times (tracker effects applied), the
    wheel angles [rad] and the lift schedule. Draws only the lift schedule from ``rng``."""
    physics = {k: v for k, v in hidden.items() if k not in TRACKER_EFFECTS}
    tracker = {k: v for k, v in hidden.items() if k in TRACKER_EFFECTS}
    plant = build_plant(model, physics)
    schedule = draw_lift_schedule(plant, float(times[-1]), rng)
    delay = float(tracker["time_offset"]["delay"]) if "time_offset" in tracker else 0.0
    taken = np.clip(times - delay, 0.0, None)
    samples = np.unique(np.concatenate([times, taken]))
    traj = integrate(plant, times, commands, samples, start_pose=start_pose, lift_schedule=schedule)
    idx_rows = np.searchsorted(samples, times)
    idx_taken = np.searchsorted(samples, taken)
    pose = _tracked(traj.pose[idx_taken], tracker)
    return {"pose": pose, "angles": traj.angles[idx_rows], "lift_schedule": schedule, "events": traj.events}


def _write_folder(folder: Path, model: SimModel, description: str, runs: list[tuple[str, np.ndarray]]) -> None:
    """The dataset folder of ``docs/formats.md``: runs/NAME.csv (t, w1..wn, enc1..encn, x, y, theta), then
    dataset.json {"model", "description"} (written here, not by the workflow's writer: this module sits
    below the discrepancy workflow and relies on the documented format only)."""
    n = model.n_wheels
    header = ["t"] + [f"w{i + 1}" for i in range(n)] + [f"enc{i + 1}" for i in range(n)] + ["x", "y", "theta"]
    (folder / "runs").mkdir(parents=True, exist_ok=True)
    for name, rows in runs:
        outputs.write_csv_atomic(folder / "runs" / f"{name}.csv", header, rows)
    outputs.write_json_atomic(folder / "dataset.json", {"model": model.to_json(), "description": description})


def _digest(folder: Path) -> str:
    h = hashlib.sha256()
    for f in [folder / "dataset.json"] + sorted((folder / "runs").glob("*.csv")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def write_second_dataset(folder, *, robot: str = "williams2002", hidden: dict | None = None, runs: int = 4,
                         duration: float = 3.0, manoeuvre: str = "steps", position_noise: float = 0.001,
                         heading_noise: float = 0.002, encoder_counts: int = 2048, seed: int = 0,
                         surface: str = "carpet", friction: str = "initial", tracker_rate: float = 100.0,
                         start_rest: float = 0.0, force: bool = False) -> Path:
    """Write a dataset folder and ``FOLDER.truth.json`` beside it; return the folder's path.

    ``robot``: ``williams2002`` (3 omni wheels) or ``optiodom_omni4`` (4 mecanum wheels); ``hidden``:
    None or {effect: params} (a library effect, ``tracker_offset``/``time_offset``, or ``drag``);
    ``runs`` 3-12 of ``duration`` 2.5-10 s; ``manoeuvre`` ``steps``/``smooth``/``turns``; noise std
    ``position_noise`` [m] and ``heading_noise`` [rad]; ``encoder_counts`` per wheel turn;
    ``tracker_rate`` [Hz] of the rows; ``start_rest`` [s] at rest before the manoeuvre (0: the robot
    moves from the first row, whose tracked pose is as noisy as any other). Bad input raises a one-line
    ValueError naming it.
    """
    if robot not in ROBOTS:
        raise ValueError(f"robot: unknown robot {robot!r} (known: {', '.join(ROBOTS)})")
    if manoeuvre not in MANOEUVRES:
        raise ValueError(f"manoeuvre: unknown family {manoeuvre!r} (known: {', '.join(MANOEUVRES)})")
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or not 3 <= runs <= 12:
        raise ValueError(f"runs: expected an integer in [3, 12], got {runs!r}")
    duration = _check_number(duration, "duration", 2.5, 10.0)
    position_noise = _check_number(position_noise, "position_noise", 0.0, 0.01)
    heading_noise = _check_number(heading_noise, "heading_noise", 0.0, 0.1)
    tracker_rate = _check_number(tracker_rate, "tracker_rate", 10.0, 1000.0)
    start_rest = _check_number(start_rest, "start_rest", 0.0, 1.0)
    if isinstance(encoder_counts, bool) or not isinstance(encoder_counts, (int, np.integer)) \
            or not 16 <= encoder_counts <= 1 << 20:
        raise ValueError(f"encoder_counts: expected an integer in [16, 1048576], got {encoder_counts!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected an integer >= 0, got {seed!r}")
    model = load_model(robot, surface=surface, friction=friction)
    hidden = dict(hidden or {})
    check_effects(hidden, model)
    if len(hidden) > 1:
        raise ValueError(f"hidden: at most one effect, got {sorted(hidden)}")
    folder = Path(folder)
    truth_path = folder.parent / f"{folder.name}.truth.json"
    rng = np.random.default_rng(seed)
    q = 2 * math.pi / int(encoder_counts)
    run_list, truth_runs = [], []
    for k in range(runs):
        times, commands = run_commands(model, manoeuvre, duration, tracker_rate, rng, start_rest)
        start = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-math.pi, math.pi)])
        sim = simulate_run(model, hidden, times, commands, start, rng)
        pose = sim["pose"].copy()
        pose[:, :2] += rng.normal(0.0, position_noise, (len(times), 2)) if position_noise > 0 else 0.0
        pose[:, 2] += rng.normal(0.0, heading_noise, len(times)) if heading_noise > 0 else 0.0
        phi0 = rng.uniform(0.0, q, model.n_wheels)
        enc = q * (np.floor((sim["angles"] + phi0) / q) - np.floor(phi0 / q))
        name = f"run{k:03d}"
        run_list.append((name, np.column_stack([times, commands, enc, pose])))
        truth_runs.append({"run": name, "start_pose": start.tolist(),
                           "lift_schedule": [{"t": t, "lifted": np.flatnonzero(m).astype(int).tolist()}
                                             for t, m in sim["lift_schedule"]],
                           "integrator_events": sim["events"]})
    description = (f"second generator (omni_gym.analysis.second_generator): {robot} on {surface}, friction "
                   f"{friction}, {runs} runs x {duration:g} s of '{manoeuvre}' manoeuvres, tracker noise "
                   f"{position_noise * 1e3:g} mm / {heading_noise * 1e3:g} mrad at {tracker_rate:g} Hz, "
                   f"{encoder_counts} encoder counts per turn")
    settings = {"robot": robot, "surface": surface, "friction": friction, "runs": int(runs), "duration": duration,
                "manoeuvre": manoeuvre, "position_noise": position_noise, "heading_noise": heading_noise,
                "encoder_counts": int(encoder_counts), "tracker_rate": tracker_rate, "start_rest": start_rest,
                "seed": int(seed)}
    with outputs.Output(folder, "dir", force=force, marker="dataset.json", what="dataset",
                        companions=(truth_path,)) as tx:
        _write_folder(tx.path, model, description, run_list)
        truth = {"generator": "omni_gym.analysis.second_generator", "hidden": _jsonable(hidden),
                 "settings": settings, "seed": int(seed), "runs": truth_runs, "dataset_digest": _digest(tx.path)}
        tx.stage_companion(truth_path, (json.dumps(truth, indent=2) + "\n").encode())
    return folder


def _jsonable(value):
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value
