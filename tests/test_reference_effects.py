"""The world against the independent reference for the effects the reference implements from their docs:
``motor_lag``, ``kinetic_friction``, ``roller_gap`` and ``wheel_liftoff`` (a fixed lift schedule, replayed in the world
by :class:`~omni_gym.physics.liftoff.ScheduledContactProcess`).

Tolerance: the validation bound of ``tests/test_validation.py``, 1 mm in position and 2 mrad in heading
over a 2 s manoeuvre sampled every 10 ms. The reference's own error is ~1e-10 m (error-controlled stiff
solver, restarted at every command change, roller/gap switch and lift event), so the difference is the world's: its
0.5 ms first-order step (0.16 mm / 1.5 mrad over 2 s in ``benchmarks/results/convergence.md``) and,
for lift-off, switch times rounded up to the next 0.5 ms substep (a load change late by < 0.5 ms at
< 0.5 m/s moves the pose by far less than 0.1 mm). Every test also checks that the effect moves the
reference by more than ten times that bound, so a world or reference that ignored the effect fails.
"""

from __future__ import annotations

import numpy as np
import pytest

from omni_gym.analysis.reference import reference_trajectory
from omni_gym.discrepancy.synthetic.reference_data import lift_schedule
from omni_gym.physics.liftoff import ScheduledContactProcess, contact_cases
from omni_gym.physics.model import SimModel, load_model
from omni_gym.physics.world import World

DT_SAMPLE = 0.01  # s, comparison grid
DURATION = 2.0  # s
POS_TOL = 1e-3  # m (module docstring)
HEAD_TOL = 2e-3  # rad (module docstring)
# Body twists (vx, vy [m/s], ω [rad/s]) held from the given time [s]: the validation's "steps" manoeuvre.
STEPS = [(0.0, (0.2, 0.0, 0.0)), (0.4, (0.0, 0.3, 0.0)), (0.8, (0.1, 0.1, -1.5)),
         (1.2, (-0.3, 0.2, 0.5)), (1.6, (0.0, 0.0, 0.0))]


def _schedule(model: SimModel) -> tuple[np.ndarray, np.ndarray]:
    wm = model.robot.wheel_matrix()
    return np.array([t for t, _ in STEPS]), np.array([wm @ np.asarray(tw) for _, tw in STEPS])


def _world(model: SimModel, times: np.ndarray, commands: np.ndarray,
           events: list[tuple[float, float, np.ndarray]] | None = None) -> np.ndarray:
    """World poses (M, 3) on the 10 ms grid; lift events replayed by a scheduled contact process."""
    world = World(model)
    world.reset()
    if events is not None:
        cases = contact_cases(model.n_wheels)
        idx = [int(np.flatnonzero((cases == m).all(axis=1))[0]) for _, _, m in events]
        world.set_contact_process(0, ScheduledContactProcess(model.n_wheels, [(a, b, c) for (a, b, _), c
                                                                               in zip(events, idx, strict=True)]))
    start = np.rint(times / DT_SAMPLE).astype(int)
    poses = [world.pose[0].copy()]
    for k in range(round(DURATION / DT_SAMPLE)):
        hits = np.flatnonzero(start == k)
        if hits.size:
            world.set_commands(commands[hits[-1]])
        world.step(DT_SAMPLE)
        poses.append(world.pose[0].copy())
    return np.array(poses)


def _errors(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    pos = float(np.max(np.hypot(*(a[:, :2] - b[:, :2]).T)))
    head = float(np.max(np.abs((a[:, 2] - b[:, 2] + np.pi) % (2 * np.pi) - np.pi)))
    return pos, head


def _check(model: SimModel, effect: SimModel, events=None) -> None:
    times, commands = _schedule(model)
    t_eval = np.arange(round(DURATION / DT_SAMPLE) + 1) * DT_SAMPLE
    ref = reference_trajectory(effect, times, commands, t_eval, lift_events=events)["pose"]
    plain = reference_trajectory(model, times, commands, t_eval)["pose"]
    pos, head = _errors(_world(effect, times, commands, events), ref)
    moved = _errors(ref, plain)
    print(f"\n[reference effects] {list(effect.effects)}: world - reference {pos * 1e3:.4f} mm, {head * 1e3:.4f} mrad; "
          f"effect moves the pose {moved[0] * 1e3:.1f} mm, {moved[1] * 1e3:.1f} mrad")
    assert pos <= POS_TOL, f"position {pos * 1e3:.3f} mm off the reference"
    assert head <= HEAD_TOL, f"heading {head * 1e3:.3f} mrad off the reference"
    assert moved[0] > 10 * POS_TOL or moved[1] > 10 * HEAD_TOL, "the effect barely moves the pose: the test is blind"


@pytest.mark.parametrize("robot", ["williams2002", "optiodom_omni4"])
def test_motor_lag_matches_the_world(robot):
    model = load_model(robot, "carpet", "initial")
    _check(model, model.with_effect("motor_lag", {"tau": 0.08}))


@pytest.mark.parametrize("robot", ["williams2002", "optiodom_omni4"])
def test_kinetic_friction_matches_the_world(robot):
    model = load_model(robot, "carpet", "initial")
    _check(model, model.with_effect("kinetic_friction", {"ratio": 0.6, "v_s": 0.02}))


def test_kinetic_friction_with_the_gap_model_matches_the_world():
    model = load_model("williams2002", "paper", "roller_gap")
    _check(model, model.with_effect("kinetic_friction", {"ratio": 0.6, "v_s": 0.02}))


@pytest.mark.parametrize("friction", ["initial", "roller_gap"])
def test_roller_gap_effect_matches_the_world(friction):
    """The effect's own μ'', roller share and per-wheel phases, on a nominal model without and with the gap model."""
    model = load_model("williams2002", "carpet", friction)
    _check(model, model.with_effect("roller_gap", {"mu_gap": 0.5, "roller_fraction": 0.8, "phase": [0.1, 0.9, 0.4]}))


@pytest.mark.parametrize("robot", ["williams2002", "optiodom_omni4"])
def test_lift_events_match_the_world(robot):
    """A drawn schedule with lifts (a diagonal pair for the four-wheeled robot) and a centre-of-mass offset,
    so the loads of the wheels left down redistribute by static balance."""
    model = load_model(robot, "carpet", "initial").with_effect("com_offset", {"com": [0.01, -0.005]})
    events = [(0.25, 0.55, contact_cases(model.n_wheels)[1]), (0.93, 1.31, contact_cases(model.n_wheels)[-1])]
    _check(model, model.with_effect("wheel_liftoff", {"lift_rate": 0.5, "recover_rate": 5.0}), events)


def test_motor_lag_wheel_speed_is_the_documented_first_order_lag():
    """Wheel speeds from rest follow c (1 − e^{−t/τ}) after a step (closed form typed here), angles its integral."""
    model = load_model("williams2002", "carpet", "initial").with_effect("motor_lag", {"tau": 0.05})
    c = np.array([3.0, -2.0, 1.0])
    t = np.array([0.0, 0.02, 0.05, 0.2])
    out = reference_trajectory(model, np.array([0.0]), c[None], t)
    np.testing.assert_allclose(out["wheel_speed"], c * (1 - np.exp(-t / 0.05))[:, None], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["wheel_angle"], c * (t - 0.05 * (1 - np.exp(-t / 0.05)))[:, None],
                               rtol=0, atol=1e-12)


def test_lift_schedule_follows_the_documented_rates():
    """Mean number of lifts and mean lifted time over many draws: lift_rate / (1 + lift_rate / recover_rate) lifts
    per second (renewal: mean cycle 1/lift + 1/recover) and 1/recover_rate per lift, within 3 standard errors."""
    rng = np.random.default_rng(3)
    lift, recover, t_end = 2.0, 10.0, 50.0
    events = lift_schedule(4, lift, recover, t_end, rng)
    durations = np.array([b - a for a, b, _ in events])[:-1]  # the last may be cut at t_end
    expected = t_end / (1 / lift + 1 / recover)
    assert abs(len(events) - expected) < 3 * np.sqrt(expected)
    assert abs(durations.mean() - 1 / recover) < 3 * (1 / recover) / np.sqrt(len(durations))
    masks = np.array([m for _, _, m in events])
    assert set(masks.sum(axis=1)) == {2, 3}  # one wheel or a diagonal pair up, never all down
    assert all(b0 <= a1 for (_, b0, _), (a1, _, _) in zip(events[:-1], events[1:], strict=True))


def test_reference_refuses_what_it_does_not_integrate():
    model = load_model("williams2002", "carpet", "initial")
    with pytest.raises(ValueError, match="lift_events"):
        reference_trajectory(model.with_effect("wheel_liftoff", {"lift_rate": 1.0, "recover_rate": 5.0}),
                             np.array([0.0]), np.ones((1, 3)), np.array([0.0, 0.1]))
    gapped = load_model("williams2002", "carpet", "roller_gap").with_effect("motor_lag", {"tau": 0.05})
    with pytest.raises(NotImplementedError, match="motor_lag"):
        reference_trajectory(gapped, np.array([0.0]), np.ones((1, 3)), np.array([0.0, 0.1]))
