"""Batched simulation of runs × candidate models in one :class:`~omni_gym.physics.world.World`.

Every robot of the world is one *job*: a run (or a window of it) replayed with its own model. All
robots step together, so the per-substep Python overhead is paid once for the whole batch; fitting
hundreds of parameter candidates on ten runs is one world of thousands of robots.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.discrepancy.data.dataset import Run
from omni_gym.discrepancy.replay.measurement import (
    align_start,
    align_to_start_window,
    centre_start,
    has_tracker_effects,
    measured,
)
from omni_gym.physics.liftoff import ScheduledContactProcess
from omni_gym.physics.model import SimModel
from omni_gym.physics.world import World

FIT_DT = 0.001  # s: physics substep used for fitting (docs/discrepancy.md: vs 0.5 ms, far below tracker noise)


@dataclass
class Job:
    """Replay ``run`` rows k0..k1 (inclusive; k1 = -1 means the last row) with ``model``.

    ``state0`` (optional): pose (3,), geometric-centre world velocity (3,) [m/s, m/s, rad/s],
    wheel angles (n,) [rad] and wheel speeds (n,) [rad/s] at row k0; default: at rest at the run's
    start pose with zero wheel angles (or the run's own ``state0``). ``seed`` draws the wheel_liftoff contact process.
    ``schedule`` (optional): lift events (t_start [s], t_end [s], case) on the job's clock (0 at row
    k0), replayed by :class:`~omni_gym.physics.liftoff.ScheduledContactProcess` instead of the
    random process (used to replay inferred events).
    ``drag`` [N·s/m]: a viscous force −drag·v on the centre of mass (not a library effect: used to
    make data the library cannot explain).
    """

    model: SimModel
    run: Run
    k0: int = 0
    k1: int = -1
    state0: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
    seed: int = 0
    drag: float = 0.0
    schedule: tuple | None = None

    def __post_init__(self) -> None:
        # A run that does not start at rest (a segment of a longer run) carries its start state.
        if self.state0 is None and self.k0 == 0:
            self.state0 = self.run.state0


def simulate_jobs(jobs: list[Job], dt: float = FIT_DT, start_window: float | None = None
                  ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Simulate all jobs in one world; per job (pose (K, 3), wheel angles (K, n)) at rows k0..k1.

    ``start_window`` [s]: a job that replays a whole run from rest is aligned to the run's tracked rows over
    its first ``start_window`` seconds (:func:`~omni_gym.discrepancy.replay.measurement.align_to_start_window`;
    :data:`~omni_gym.discrepancy.replay.measurement.START_WINDOW` for a replay compared with the tracker); None
    (the default): from the start pose as it is (a replay that makes data, or compares two replays)."""
    world = World([j.model for j in jobs], dt=dt)
    B, n = len(jobs), world.n_wheels
    for b, job in enumerate(jobs):
        if job.schedule is not None:
            if job.schedule:
                world.set_contact_process(b, ScheduledContactProcess(n, job.schedule))
        else:
            process = job.model.contact_process(np.random.default_rng(job.seed))
            if process is not None:
                world.set_contact_process(b, process)
    ends = [j.k1 % len(j.run.t) for j in jobs]
    # Start states are measured by the tracker: the centre's comes from the model's measurement effects.
    tracked = [has_tracker_effects(j.model) for j in jobs]
    states0 = [_centre_state0(j) if tr else j.state0 for j, tr in zip(jobs, tracked, strict=True)]
    starts = np.array([(j.run.start_pose if st is None else st[0]) if not tr else st[0]
                       for j, st, tr in zip(jobs, states0, tracked, strict=True)])
    world.reset(starts)
    for b, (job, st) in enumerate(zip(jobs, states0, strict=True)):
        if st is not None:
            _set_state(world, b, job.model, st)
    # Each job's row ticks relative to its own start; the union is the loop's event list.
    ticks = [np.rint((j.run.t[j.k0:e + 1] - j.run.t[j.k0]) / dt).astype(np.int64)
             for j, e in zip(jobs, ends, strict=True)]
    events = np.unique(np.concatenate(ticks))
    E = len(events)
    # Commands holding after each event, per robot (the last row ends a run: wheels commanded to stop).
    cmds = np.zeros((E, B, n))
    rows_at = []  # per job: event index of each of its rows
    for b, (job, tk) in enumerate(zip(jobs, ticks, strict=True)):
        pos = np.searchsorted(events, tk)
        rows_at.append(pos)
        active = np.searchsorted(tk, events, side="right") - 1
        live = active < len(tk) - 1
        cmds[live, b] = job.run.cmd[job.k0 + active[live]]
    pose_ev = np.zeros((E, B, 3))
    ang_ev = np.zeros((E, B, n))
    drag = np.array([j.drag for j in jobs])
    any_drag = bool(np.any(drag > 0))
    for e in range(E):
        pose_ev[e] = world.pose
        ang_ev[e] = world.wheel_angle
        if e == E - 1:
            break
        world.set_commands(cmds[e])
        steps = int(events[e + 1] - events[e])
        if any_drag:
            for _ in range(steps):
                v = world.velocity
                world.ext_force[:, 0] = -drag * v[:, 0]
                world.ext_force[:, 1] = -drag * v[:, 1]
                world.substeps(1)
        else:
            world.substeps(steps)
    poses = [pose_ev[pos, b] for b, pos in enumerate(rows_at)]
    for b, job in enumerate(jobs):
        if tracked[b]:  # what the tracker would report (omni_gym.discrepancy.replay.measurement)
            poses[b] = measured(job.model, job.run.t[job.k0:ends[b] + 1], poses[b])
            # The first row is the tracked start, as in a replay without tracker effects. centre_start
            # is first order in a time offset: a negative delay (the tracker's first row shows the robot
            # |delay| later) would leave the replay shifted by the motion over |delay|. The floor is the
            # same everywhere, so the motion is equivariant under a rigid move of the start: move the
            # whole replay so that its first row is the tracked start.
            target = job.run.start_pose if job.state0 is None else job.state0[0]
            poses[b] = align_start(poses[b], np.asarray(target, dtype=float))
    for b, job in enumerate(jobs):
        if start_window is not None and job.state0 is None and job.k0 == 0:  # a whole run from rest
            poses[b] = align_to_start_window(job.run.t[:ends[b] + 1], job.run.pose[:ends[b] + 1], poses[b],
                                             start_window, job.run.start_weight)
    angles = [ang_ev[pos, b] for b, pos in enumerate(rows_at)]
    return list(zip(poses, angles, strict=True))


def simulate_poses(jobs: list[Job], dt: float = FIT_DT, max_batch: int = 1500,
                   start_window: float | None = None,
                   done: Callable[[int, int], None] | None = None) -> list[np.ndarray]:
    """Poses (K, 3) of every job, simulated in worlds of at most ``max_batch`` robots (memory bound);
    ``start_window``: as :func:`simulate_jobs`. ``done(j, m)`` after each world: j of the m worlds simulated
    (progress)."""
    out: list[np.ndarray] = []
    m = -(-len(jobs) // max_batch)
    for j, i in enumerate(range(0, len(jobs), max_batch), 1):
        out += [p for p, _ in simulate_jobs(jobs[i:i + max_batch], dt=dt, start_window=start_window)]
        if done is not None:
            done(j, m)
    return out


def _centre_state0(job: Job) -> tuple:
    """``job``'s start state (pose, velocity, wheel angles, wheel speeds) with the tracked pose and
    velocity turned into the geometric centre's (:func:`~omni_gym.discrepancy.replay.measurement.centre_start`)."""
    n = job.model.n_wheels
    st = job.state0 if job.state0 is not None else (job.run.start_pose, np.zeros(3), np.zeros(n), np.zeros(n))
    pose, vel = centre_start(job.model, st[0], st[1])
    return pose, vel, st[2], st[3]


def _set_state(world: World, b: int, model: SimModel, state0: tuple) -> None:
    """Put robot b into ``state0`` (after reset has placed it at the pose)."""
    _pose, vel, wang, wspd = state0
    theta = _pose[2]
    com = model.com
    c, s = np.cos(theta), np.sin(theta)
    rx, ry = c * com[0] - s * com[1], s * com[0] + c * com[1]
    body = world.bodies[b]
    # pymunk's velocity is the centre of mass's: v_com = v_centre + ω × ρ_com.
    body.velocity = (vel[0] - vel[2] * ry, vel[1] + vel[2] * rx)
    body.angular_velocity = vel[2]
    world.wheel_angle[b] = wang
    world.wheel_speed[b] = wspd


def pose_residual(measured: np.ndarray, simulated: np.ndarray, lever: float) -> np.ndarray:
    """(K, 3) residual measured − simulated in metres: x, y and heading × ``lever`` [m] (NaN where unobserved)."""
    r = measured - simulated
    r[:, 2] = wrap_angle(r[:, 2]) * lever
    return r
