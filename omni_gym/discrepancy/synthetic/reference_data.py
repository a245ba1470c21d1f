"""Datasets made by an independent implementation: the validation integrator, not the world we fit with.

Every other synthetic dataset of the project comes from :class:`~omni_gym.physics.world.World`, the
simulator the workflow fits with, so a flaw they share (the integration step, the switching of the
friction law) is invisible to the recovery tests. These runs come from
:func:`omni_gym.analysis.reference.reference_trajectory` (scipy's stiff solver, switching times
handled exactly, written independently of the world and its kernel), as a user's data would come from
a real robot: random twist steps, white tracker noise per channel, quantised encoders.

Lift-off (``wheel_liftoff``) is a random process in the world; here each run's realisation is drawn
by :func:`lift_schedule` from the run's seeded generator, with the process documented in
``docs/model.md`` (Normal loads and lift-off), and handed to the reference as a fixed event list.

Default data: 8 runs of about 5 s of random twist steps, white noise of 1 mm in x and y and 2 mrad in
heading, the Williams robot on carpet with the initial friction. Hidden effects: the physics effects
the reference integrator implements (:data:`~omni_gym.analysis.reference.SUPPORTED_EFFECTS`), the
tracker effects (``tracker_offset``, ``time_offset``: applied here, from their documented equations,
by evaluating the reference at the shifted times; not through the workflow's measurement model), and
a viscous drag outside the library (``drag`` [N·s/m]).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from omni_gym.analysis.reference import SUPPORTED_EFFECTS, WheelMotion, reference_trajectory
from omni_gym.discrepancy.data.dataset import Run, write_dataset
from omni_gym.discrepancy.synthetic.synth import COUNTS_PER_REV, RATE
from omni_gym.physics.model import SimModel

NOISE_XY = 0.001  # m: tracker noise in x and y
NOISE_HEADING = 0.002  # rad: tracker noise in heading
TRACKER = ("tracker_offset", "time_offset")  # measurement effects this module applies itself


def twist_steps(model: SimModel, rng: np.random.Generator, duration: float, rate: float = RATE,
                max_speed: float = 0.35, max_yaw_rate: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Times (K,) [s] and wheel commands (K, n) [rad/s] of random body-twist steps.

    Segments of 0.3–1.0 s, each a step to a twist drawn uniformly: speed up to ``max_speed`` [m/s] in
    a random body direction and yaw rate within ±``max_yaw_rate`` [rad/s], one segment in five a stop;
    the last row stops.
    """
    k = int(round(duration * rate)) + 1
    t = np.arange(k) / rate
    twist = np.zeros((k, 3))
    i = 0
    while i < k - 1:
        end = min(k - 1, i + int(rng.integers(int(0.3 * rate), int(1.0 * rate) + 1)))
        if rng.random() >= 0.2:
            v, ang = rng.uniform(0.0, max_speed), rng.uniform(-math.pi, math.pi)
            twist[i:end] = [v * math.cos(ang), v * math.sin(ang), rng.uniform(-max_yaw_rate, max_yaw_rate)]
        i = end
    return t, twist @ model.robot.wheel_matrix().T


def lift_cases(n: int) -> np.ndarray:
    """Contact masks (rows, True = on the floor) a lift can produce, as documented (Phunopas & Inoue 2018,
    Table 2, for any n): each single wheel up and, for even n ≥ 4, each diametrically opposite pair up."""
    rows = [np.arange(n) != i for i in range(n)]
    if n % 2 == 0 and n >= 4:
        rows += [(np.arange(n) != i) & (np.arange(n) != i + n // 2) for i in range(n // 2)]
    return np.array(rows)


def lift_schedule(n: int, lift_rate: float, recover_rate: float, t_end: float,
                  rng: np.random.Generator) -> list[tuple[float, float, np.ndarray]]:
    """One realisation of the lift-off process on [0, t_end) [s]: (t_start, t_end, mask) per lift.

    All wheels down for an exponential time of rate ``lift_rate`` [1/s], then one of :func:`lift_cases`
    chosen uniformly for an exponential time of rate ``recover_rate`` [1/s], and so on (a rate of 0:
    that switch never comes). Every draw from ``rng``.
    """
    cases, out, t = lift_cases(n), [], 0.0
    while lift_rate > 0.0:
        t += rng.exponential(1.0 / lift_rate)
        if t >= t_end:
            break
        mask = cases[int(rng.integers(len(cases)))]
        up = t + rng.exponential(1.0 / recover_rate) if recover_rate > 0.0 else math.inf
        out.append((t, min(up, t_end), mask))
        t = up
    return out


def reference_runs(model: SimModel, hidden: dict | None, runs: int, duration: float, seed: int,
                   noise_xy: float = NOISE_XY, noise_heading: float = NOISE_HEADING, noisy_start: bool = False,
                   **twist) -> list[Run]:
    """``runs`` runs of random twist steps integrated by the reference with ``hidden`` effects
    (``{name: params}``, names from :data:`~omni_gym.analysis.reference.SUPPORTED_EFFECTS`; None: the
    nominal model), tracker noise ``noise_xy`` [m] in x and y and ``noise_heading`` [rad] in heading,
    encoders quantised to :data:`~omni_gym.discrepancy.synthetic.synth.COUNTS_PER_REV`. ``noisy_start``: the first
    row is measured with the same noise as the others, as a real tracker's is (default: exact, as in
    ``omni-gym synth``; the workflow takes a run's first pose as its start). Seeded by ``seed``;
    ``twist``: keywords of :func:`twist_steps` (``max_speed``, ``max_yaw_rate``)."""
    true_model = model
    tracker: dict[str, dict] = {}
    drag = 0.0
    for name, params in (hidden or {}).items():
        if name == "drag":
            drag = float(params)
        elif name in TRACKER:
            tracker[name] = params
        elif name not in SUPPORTED_EFFECTS:
            raise ValueError(f"reference_runs: effect {name!r} is not supported by the reference integrator "
                             f"(supported: {[*SUPPORTED_EFFECTS, *TRACKER, 'drag']})")
        else:
            true_model = true_model.with_effect(name, params)
    lift = true_model.effects.get("wheel_liftoff")
    # The lift draws come from a third stream: the manoeuvres and the noise stay those of the same seed.
    r_man, r_noise, r_lift = np.random.default_rng(seed).spawn(3)
    quantum = 2 * math.pi / COUNTS_PER_REV
    delay = float(tracker.get("time_offset", {"delay": 0.0})["delay"])
    out = []
    for i in range(runs):
        t, cmd = twist_steps(model, r_man, duration, **twist)
        # The tracker's row stamped t shows the robot at t - delay (at rest where it started before 0).
        t_seen = np.clip(t - delay, 0.0, t[-1])
        events = None if lift is None else lift_schedule(cmd.shape[1], lift["lift_rate"], lift["recover_rate"],
                                                           float(t[-1]), r_lift)
        ref = reference_trajectory(true_model, t, cmd, t_seen, drag=drag, lift_events=events)  # last row: no time
        truth = ref["pose"]
        if "tracker_offset" in tracker:
            o, yaw = np.asarray(tracker["tracker_offset"]["offset"], dtype=float), tracker["tracker_offset"]["yaw"]
            c, sn = np.cos(truth[:, 2]), np.sin(truth[:, 2])
            truth = np.column_stack([truth[:, 0] + c * o[0] - sn * o[1], truth[:, 1] + sn * o[0] + c * o[1],
                                     truth[:, 2] + yaw])
        pose = truth + r_noise.normal(0.0, 1.0, (len(t), 3)) * np.array([noise_xy, noise_xy, noise_heading])
        if not noisy_start:
            pose[0] = truth[0]  # every run starts at rest, its first pose known exactly
        # Encoders on the robot's clock: the wheel angles (the integral of the commands, lagged with motor_lag).
        tau = float(true_model.effects.get("motor_lag", {"tau": 0.0})["tau"])
        if tau > 0.0:
            motion = WheelMotion(t, cmd, tau)
            angle = np.array([motion.angle(tk) for tk in t])
        else:
            angle = np.vstack([np.zeros(cmd.shape[1]), np.cumsum(cmd[:-1] * np.diff(t)[:, None], axis=0)])
        enc = np.floor(angle / quantum) * quantum
        out.append(Run(name=f"run{i:03d}", t=t, cmd=cmd, pose=pose, enc=enc))
    return out


def write_reference_dataset(folder: str | Path, model: SimModel, hidden: dict | None, runs: int = 8,
                            duration: float = 5.0, seed: int = 0, noise_xy: float = NOISE_XY,
                            noise_heading: float = NOISE_HEADING, noisy_start: bool = False, **twist) -> None:
    """Write :func:`reference_runs` as a dataset folder with the nominal ``model`` (the hidden effects are
    not recorded in it)."""
    data = reference_runs(model, hidden, runs, duration, seed, noise_xy, noise_heading, noisy_start, **twist)
    desc = (f"independent reference data: {runs} runs of {duration:g} s of random twist steps, tracker noise "
            f"{noise_xy:g} m (x, y) and {noise_heading:g} rad (heading), seed {seed}")
    write_dataset(folder, model.to_json(), desc, data)
