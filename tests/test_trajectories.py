"""Behavioural tests of omni_gym.trajectories.

Finite-difference tolerances: a central difference (f(t+h) − f(t−h))/2h has truncation error
h²/6·max|f'''| plus rounding ≈ ε·max|f|/h (ε ≈ 2.2e-16). With h = 1e-4 s and the smooth, O(1)-sized
trajectories used here (third derivatives ≲ 100 in SI units) that is ≲ 2e-7 + 1e-11, so 1e-5 leaves
a wide margin while a wrong derivative (a dropped factor, a missing chain-rule term) is off by O(1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_gym.physics.kinematics import forward
from omni_gym.physics.robot import phunopas2018, regular, williams2002
from omni_gym.trajectories import (
    Circle,
    FigureEight,
    Quintic,
    QuinticWaypoints,
    StepVelocity,
    StraightLine,
    Trajectory,
    integrate_constant_twist,
    random_waypoints,
)

H = 1e-4  # s, finite-difference step (see module docstring)
FD_TOL = 1e-5  # see module docstring

ROBOTS = [williams2002(), phunopas2018(), regular(5)]


def central_difference(f, t: np.ndarray) -> np.ndarray:
    """(f(t+H) − f(t−H)) / 2H for an array-valued f(t) of shape (..., 3)."""
    return (f(t + H) - f(t - H)) / (2 * H)


def assert_derivatives_consistent(traj: Trajectory, t: np.ndarray) -> None:
    """Velocity is the time derivative of pose and acceleration that of velocity (central differences)."""
    np.testing.assert_allclose(central_difference(traj.pose, t), traj.velocity(t), atol=FD_TOL)
    np.testing.assert_allclose(central_difference(traj.velocity, t), traj.acceleration(t), atol=FD_TOL)


# --- quintic -------------------------------------------------------------------------------------

START, GOAL, T = np.array([0.2, -0.5, 0.3]), np.array([1.4, 0.7, -1.2]), 2.5


def test_quintic_coefficients_satisfy_boundary_conditions() -> None:
    # Evaluate the polynomial from the published coefficients directly (independent of sample()).
    q = Quintic(START, GOAL, T)
    for k in range(3):
        p = q.coefficients[k]
        v, a = np.polyder(p), np.polyder(p, 2)
        assert np.polyval(p, 0.0) == pytest.approx(START[k], abs=1e-12)
        assert np.polyval(p, T) == pytest.approx(GOAL[k], abs=1e-12)
        for d in (v, a):  # values O(1): 1e-12 allows rounding of the five-term Horner sum only
            assert np.polyval(d, 0.0) == pytest.approx(0.0, abs=1e-12)
            assert np.polyval(d, T) == pytest.approx(0.0, abs=1e-12)


def test_quintic_sample_boundaries_and_hold() -> None:
    q = Quintic(START, GOAL, T)
    pose, vel, acc = q.sample(np.array([-1.0, 0.0, T, T + 3.0]))
    np.testing.assert_allclose(pose, [START, START, GOAL, GOAL], atol=1e-12)
    np.testing.assert_array_equal(vel, 0.0)
    np.testing.assert_array_equal(acc, 0.0)
    # Just inside the interval the polynomial itself must be near rest: |Ṡ| ≤ 30|Δ|/T·(ε/T)² and
    # |S̈| ≤ 60|Δ|/T²·(ε/T) for ε = 1e-6 s, i.e. < 1e-10 and < 1e-4 here.
    _, vel, acc = q.sample(np.array([1e-6, T - 1e-6]))
    assert np.all(np.abs(vel) < 1e-10) and np.all(np.abs(acc) < 1e-4)


def test_quintic_derivatives_match_finite_differences() -> None:
    q = Quintic(START, GOAL, T)
    assert_derivatives_consistent(q, np.linspace(0.01, T - 0.01, 101))


def test_quintic_peak_speed_is_15_over_8_distance_over_duration() -> None:
    q = Quintic(START, GOAL, T)
    t = np.linspace(0.0, T, 10_001)  # odd count: T/2 is a grid point
    speed = np.abs(q.velocity(t))
    np.testing.assert_allclose(speed.max(axis=0), 15 / 8 * np.abs(GOAL - START) / T, rtol=1e-12)
    assert np.all(t[speed.argmax(axis=0)] == pytest.approx(T / 2))


def test_quintic_is_monotone_and_symmetric() -> None:
    q = Quintic(START, GOAL, T)
    t = np.linspace(0.0, T, 501)
    pose = q.pose(t)
    assert np.all(np.diff(pose, axis=0) * np.sign(GOAL - START) >= -1e-15)  # no overshoot
    # Point symmetry about the midpoint: S(t) + S(T−t) = S₀ + S₁.
    np.testing.assert_allclose(pose + pose[::-1], np.broadcast_to(START + GOAL, pose.shape), atol=1e-12)


def test_quintic_shortest_turn() -> None:
    q = Quintic((0, 0, 3.0), (0, 0, -3.0), 1.0, shortest_turn=True)
    assert q.goal_pose[2] == pytest.approx(2 * math.pi - 3.0)  # +0.28 rad rather than −6 rad
    assert Quintic((0, 0, 3.0), (0, 0, -3.0), 1.0).goal_pose[2] == -3.0


def test_sample_is_vectorised_over_any_shape() -> None:
    q = Quintic(START, GOAL, T)
    t = np.linspace(0, T, 20).reshape(4, 5)
    for part, scalar in zip(q.sample(t), q.sample(1.0), strict=True):
        assert part.shape == (4, 5, 3)
        assert scalar.shape == (3,)
    np.testing.assert_array_equal(q.pose(t)[1, 2], q.pose(t[1, 2]))


# --- quintic waypoints ---------------------------------------------------------------------------

WAYPOINTS = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.5], [1.0, 1.5, 0.5], [0.0, 0.0, 2.0]])


def test_waypoints_pass_through_each_at_rest() -> None:
    traj = QuinticWaypoints(WAYPOINTS, segment_durations=[1.0, 2.0, 1.5])
    assert traj.duration == pytest.approx(4.5)
    times = np.array([0.0, 1.0, 3.0, 4.5, 10.0])
    pose, vel, acc = traj.sample(times)
    np.testing.assert_allclose(pose, np.vstack([WAYPOINTS, WAYPOINTS[-1]]), atol=1e-12)
    np.testing.assert_allclose(vel, 0.0, atol=1e-12)
    np.testing.assert_allclose(acc, 0.0, atol=1e-12)


def test_waypoints_derivatives_consistent_across_joints() -> None:
    # The grid straddles the joints at t = 1 and t = 3: velocity and acceleration are continuous
    # there (both zero), so central differences across a joint still agree.
    traj = QuinticWaypoints(WAYPOINTS, segment_durations=[1.0, 2.0, 1.5])
    assert_derivatives_consistent(traj, np.linspace(0.01, 4.49, 301))


def test_waypoints_speed_sets_peak_linear_speed() -> None:
    traj = QuinticWaypoints(WAYPOINTS, speed=0.4, yaw_rate=10.0)  # large yaw limit: speed binds
    t = np.linspace(0.0, traj.duration, 20_001)
    vel = traj.velocity(t)
    assert np.hypot(vel[:, 0], vel[:, 1]).max() == pytest.approx(0.4, rel=1e-6)  # grid resolution
    lengths = np.hypot(*np.diff(WAYPOINTS[:, :2], axis=0).T)
    assert traj.duration == pytest.approx(15 / 8 * lengths.sum() / 0.4)


def test_waypoints_yaw_rate_limit_for_pure_rotation() -> None:
    traj = QuinticWaypoints([[0, 0, 0], [0, 0, 3.0]], speed=1.0, yaw_rate=0.5)
    t = np.linspace(0.0, traj.duration, 2001)
    assert np.abs(traj.velocity(t)[:, 2]).max() == pytest.approx(0.5, rel=1e-9)


# --- step velocity -------------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda r: r.name)
@pytest.mark.parametrize(("direction", "heading"), [((1, 0), 0.0), ((0, 1), 0.0), ((1, -1), 0.7),
                                                    ((-2, 1), -2.5)])
def test_step_straight_line_reaches_requested_distance(robot, direction, heading) -> None:
    step = StepVelocity.straight_line(robot, 1.2, 3.0, heading=heading, direction=direction,
                                      start_position=(0.5, -0.5))
    u = np.asarray(direction, dtype=float) / np.hypot(*direction)
    end = step.pose(step.duration)
    np.testing.assert_allclose(end[:2], [0.5, -0.5] + 1.2 * u, atol=1e-12)
    assert end[2] == pytest.approx(heading, abs=1e-12)
    # The path is the straight segment: every sample lies on the line (zero cross product).
    rel = step.pose(np.linspace(0, 3.0, 31))[:, :2] - [0.5, -0.5]
    np.testing.assert_allclose(rel[:, 0] * u[1] - rel[:, 1] * u[0], 0.0, atol=1e-12)


def test_step_wheel_commands_switch_on_and_off() -> None:
    robot = williams2002()
    step = StepVelocity([2.0, -1.0, 3.0], 1.5, robot)
    cmds = step.wheel_commands(np.array([-0.1, 0.0, 1.49, 1.5, 2.0]))
    np.testing.assert_array_equal(cmds, [[0, 0, 0], [2, -1, 3], [2, -1, 3], [0, 0, 0], [0, 0, 0]])
    # The reference's feed-forward wheel speeds reproduce the command (3 wheels: W is invertible).
    np.testing.assert_allclose(step.wheel_speeds(robot, np.array([0.3, 1.2])), [[2, -1, 3]] * 2, atol=1e-12)


def test_step_with_rotation_matches_numerical_integration() -> None:
    # Closed form vs RK4 integration of ṗ = R(θ)·v, θ̇ = ω (RK4 error ~ (dt·ω)⁴ ≈ 1e-12 here).
    robot = williams2002()
    step = StepVelocity([10.0, 6.0, 14.0], 2.0, robot, start_pose=(0.3, 0.1, 0.4))
    vx, vy, w = forward(robot, step.wheel_speeds_cmd)
    assert abs(w) > 1.0  # a genuinely curved path

    def f(state: np.ndarray) -> np.ndarray:
        c, s = math.cos(state[2]), math.sin(state[2])
        return np.array([c * vx - s * vy, s * vx + c * vy, w])

    state, dt = np.array([0.3, 0.1, 0.4]), 1e-3
    for _ in range(2000):
        k1 = f(state)
        k2 = f(state + dt / 2 * k1)
        k3 = f(state + dt / 2 * k2)
        k4 = f(state + dt * k3)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(step.pose(2.0), state, atol=1e-9)
    assert_derivatives_consistent(step, np.linspace(0.01, 1.99, 51))


def test_constant_twist_is_continuous_at_zero_yaw_rate() -> None:
    t = np.linspace(0.0, 5.0, 11)
    straight = integrate_constant_twist(np.array([0.0, 0.0, 0.5]), np.array([0.3, -0.1, 0.0]), t)
    nearly = integrate_constant_twist(np.array([0.0, 0.0, 0.5]), np.array([0.3, -0.1, 1e-12]), t)
    assert np.all(np.isfinite(nearly))
    np.testing.assert_allclose(nearly, straight, atol=1e-11)  # deviation O(v·ω·t²) ≈ 1e-11
    c, s = math.cos(0.5), math.sin(0.5)
    np.testing.assert_allclose(straight[-1, :2], 5.0 * np.array([c * 0.3 + s * 0.1, s * 0.3 - c * 0.1]))


def test_step_holds_pose_outside_interval() -> None:
    step = StepVelocity([1.0, 1.0, 1.0], 1.0, williams2002(), start_pose=(1.0, 2.0, 0.0))
    pose, vel, _ = step.sample(np.array([-1.0, 1.0, 5.0]))
    np.testing.assert_array_equal(pose[0], [1.0, 2.0, 0.0])
    np.testing.assert_array_equal(pose[1], pose[2])
    np.testing.assert_array_equal(vel, 0.0)


# --- geometric paths -----------------------------------------------------------------------------


@pytest.mark.parametrize("clockwise", [False, True])
def test_circle_radius_speed_and_tangent_heading(clockwise: bool) -> None:
    circ = Circle((1.0, -2.0), radius=0.8, period=4.0, phase=0.3, clockwise=clockwise, laps=2)
    assert circ.duration == 8.0
    t = np.linspace(0.0, circ.duration, 401)
    pose, vel, acc = circ.sample(t)
    np.testing.assert_allclose(np.hypot(pose[:, 0] - 1.0, pose[:, 1] + 2.0), 0.8, rtol=1e-12)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    np.testing.assert_allclose(speed, 2 * math.pi * 0.8 / 4.0, rtol=1e-12)
    np.testing.assert_allclose(np.hypot(acc[:, 0], acc[:, 1]), speed**2 / 0.8, rtol=1e-12)  # v²/r
    # Tangent heading: body x axis along the velocity.
    np.testing.assert_allclose(np.cos(pose[:, 2]) * vel[:, 0] + np.sin(pose[:, 2]) * vel[:, 1], speed,
                               rtol=1e-12)
    assert np.sign(circ.velocity(0.0)[2]) == (-1 if clockwise else 1)
    assert_derivatives_consistent(circ, t)
    # Periodic: same position after one period, heading advanced by ±2π (unwrapped).
    np.testing.assert_allclose(circ.pose(4.0)[:2], circ.pose(0.0)[:2], atol=1e-12)
    assert circ.pose(4.0)[2] - circ.pose(0.0)[2] == pytest.approx(-2 * math.pi if clockwise else 2 * math.pi)


def test_circle_constant_heading() -> None:
    circ = Circle((0, 0), 1.0, 5.0, heading=0.4)
    pose, vel, acc = circ.sample(np.linspace(0, 5, 50))
    np.testing.assert_array_equal(pose[:, 2], 0.4)
    np.testing.assert_array_equal(vel[:, 2], 0.0)
    np.testing.assert_array_equal(acc[:, 2], 0.0)


@pytest.mark.parametrize("clockwise", [False, True])
def test_figure_eight_tangent_heading_is_continuous_and_aligned(clockwise: bool) -> None:
    fig = FigureEight((0.5, 0.5), half_width=1.2, period=12.0, clockwise=clockwise)
    t = np.linspace(0.0, 12.0, 12_001)
    pose, vel, _ = fig.sample(t)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    assert speed.min() > 0.1  # the Gerono lemniscate never stops at constant parameter rate
    np.testing.assert_allclose(np.cos(pose[:, 2]) * vel[:, 0] + np.sin(pose[:, 2]) * vel[:, 1], speed,
                               rtol=1e-10)
    # Continuity: no step bigger than max|θ̇|·dt (plus 1e-9 rounding); a 2π branch jump would fail.
    assert np.max(np.abs(np.diff(pose[:, 2]))) <= np.abs(vel[:, 2]).max() * (t[1] - t[0]) + 1e-9
    np.testing.assert_allclose(pose[-1], pose[0], atol=1e-9)  # closed, net turning zero
    assert_derivatives_consistent(fig, np.linspace(0.05, 11.95, 200))


def test_figure_eight_shape() -> None:
    fig = FigureEight((0.0, 0.0), half_width=2.0, period=10.0, heading=0.0)
    pose = fig.pose(np.linspace(0, 10, 4001))
    # The extremes (φ = π/4, π/2, ... ↔ t = 1.25, 2.5, ...) are grid points, so only rounding remains.
    assert pose[:, 0].max() == pytest.approx(2.0, abs=1e-12)
    assert pose[:, 0].min() == pytest.approx(-2.0, abs=1e-12)
    assert np.abs(pose[:, 1]).max() == pytest.approx(1.0, abs=1e-12)  # (a/2)·sin 2φ
    np.testing.assert_allclose(fig.pose(5.0)[:2], [0.0, 0.0], atol=1e-12)  # crosses the centre mid-lap


@pytest.mark.parametrize("heading", [0.3, "tangent"])
def test_straight_line(heading) -> None:
    line = StraightLine((0.0, 1.0), (2.0, -1.0), 4.0, heading=heading)
    expected_heading = 0.3 if heading == 0.3 else -math.pi / 4
    t = np.linspace(0.0, 4.0, 401)
    pose, vel, _ = line.sample(t)
    np.testing.assert_allclose(pose[:, 2], expected_heading)
    np.testing.assert_allclose(pose[:, 0] + pose[:, 1], 1.0, atol=1e-12)  # on the line x + y = 1
    np.testing.assert_allclose(line.pose(4.0), [2.0, -1.0, expected_heading], atol=1e-12)
    np.testing.assert_allclose(np.hypot(vel[:, 0], vel[:, 1]).max(), 15 / 8 * math.sqrt(8) / 4.0, rtol=1e-12)
    assert_derivatives_consistent(line, t[1:-1])


# --- random waypoints ----------------------------------------------------------------------------


def test_random_waypoints_bounds_separation_and_determinism() -> None:
    wp = random_waypoints(np.random.default_rng(3), 50, 2.0, margin=0.25, min_separation=0.5)
    assert wp.shape == (50, 3)
    assert np.all(np.abs(wp[:, :2]) <= 1.75)
    assert np.all(np.hypot(*np.diff(wp[:, :2], axis=0).T) >= 0.5)
    assert np.all((wp[:, 2] > -math.pi) & (wp[:, 2] <= math.pi))
    np.testing.assert_array_equal(wp, random_waypoints(np.random.default_rng(3), 50, 2.0, margin=0.25,
                                                       min_separation=0.5))
    assert not np.allclose(wp, random_waypoints(np.random.default_rng(4), 50, 2.0, margin=0.25,
                                                min_separation=0.5))


def test_random_waypoints_start_and_tangent_heading() -> None:
    wp = random_waypoints(np.random.default_rng(0), 6, 1.0, heading="tangent", start=(0.1, 0.2, 0.3))
    np.testing.assert_array_equal(wp[0], [0.1, 0.2, 0.3])
    steps = np.diff(wp[:, :2], axis=0)
    np.testing.assert_allclose(wp[1:, 2], np.arctan2(steps[:, 1], steps[:, 0]))
    traj = QuinticWaypoints(wp, speed=0.5)  # usable directly as a trajectory
    np.testing.assert_allclose(traj.pose(traj.duration), wp[-1], atol=1e-12)


# --- bad inputs ----------------------------------------------------------------------------------


@pytest.mark.parametrize(("make", "name"), [
    (lambda: Quintic(START, GOAL, 0.0), "duration"),
    (lambda: Quintic([0, np.nan, 0], GOAL, 1.0), "start_pose"),
    (lambda: Quintic(START, [1.0, 2.0], 1.0), "goal_pose"),
    (lambda: QuinticWaypoints(WAYPOINTS), "segment_durations"),
    (lambda: QuinticWaypoints(WAYPOINTS, [1.0, 1.0]), "segment_durations"),
    (lambda: QuinticWaypoints(WAYPOINTS, [1.0, -1.0, 1.0]), "segment_durations"),
    (lambda: QuinticWaypoints(WAYPOINTS[:1], speed=1.0), "waypoints"),
    (lambda: QuinticWaypoints([[0, 0, 0], [0, 0, 0]], speed=1.0), "waypoints"),
    (lambda: QuinticWaypoints(WAYPOINTS, speed=-1.0), "speed"),
    (lambda: StepVelocity([1.0, 2.0], 1.0, williams2002()), "wheel_speeds"),
    (lambda: StepVelocity([1.0, 2.0, 3.0], 1.0, "williams2002"), "robot"),
    (lambda: StepVelocity.straight_line(williams2002(), -1.0, 1.0), "distance"),
    (lambda: StepVelocity.straight_line(williams2002(), 1.0, 1.0, direction=(0, 0)), "direction"),
    (lambda: Circle((0, 0), -1.0, 1.0), "radius"),
    (lambda: Circle((0, 0), 1.0, 1.0, heading="inward"), "heading"),
    (lambda: FigureEight(period=np.inf), "period"),
    (lambda: StraightLine((0, 0), (0, 0), 1.0, heading="tangent"), "heading"),
    (lambda: random_waypoints(np.random, 3, 1.0), "rng"),
    (lambda: random_waypoints(np.random.default_rng(0), 3, 1.0, margin=1.0), "margin"),
    (lambda: random_waypoints(np.random.default_rng(0), 3, 1.0, min_separation=5.0), "min_separation"),
    (lambda: Quintic(START, GOAL, 1.0).sample([0.0, np.nan]), "t"),
])
def test_bad_inputs_raise_naming_the_argument(make, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        make()
