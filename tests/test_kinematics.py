"""Kinematics against Phunopas & Inoue (2018), eqs. (1)–(3), and basic identities."""

import numpy as np
import pytest

from omni_gym.physics import kinematics as kin
from omni_gym.physics.robot import RobotSpec, Wheel, optiodom_omni4, phunopas2018, regular, williams2002

R, r = 0.10, 0.05
ALPHAS = np.pi / 4 + np.arange(4) * np.pi / 2


def paper_eq3(theta: float) -> np.ndarray:
    """Eq. (3): world twist (Vx, Vy, θ̇) → wheel speeds, typed in from the paper."""
    return np.array([[-np.sin(theta + a), np.cos(theta + a), R] for a in ALPHAS]) / r


def paper_eq2(theta: float) -> np.ndarray:
    """Eq. (2): J = (r/2)·[−sin(θ+α_i), cos(θ+α_i), 1/(2R)]ᵀ, wheel speeds → world twist."""
    return (r / 2) * np.array([[-np.sin(theta + a), np.cos(theta + a), 1 / (2 * R)] for a in ALPHAS]).T


@pytest.mark.parametrize("theta", [0.0, 0.3, -2.0, np.pi])
def test_four_wheel_matrices_match_paper(theta):
    robot = phunopas2018()
    rng = np.random.default_rng(1)
    for _ in range(5):
        twist_world = rng.normal(size=3)
        twist_body = kin.world_to_body(twist_world, theta)
        w = kin.inverse(robot, twist_body)
        np.testing.assert_allclose(w, paper_eq3(theta) @ twist_world, rtol=1e-12, atol=1e-12)
        # Forward kinematics (least squares) equals the paper's J, in the world frame.
        back = kin.body_to_world(kin.forward(robot, w), theta)
        np.testing.assert_allclose(back, paper_eq2(theta) @ w, rtol=1e-12, atol=1e-12)
        w_any = rng.normal(size=4)
        np.testing.assert_allclose(kin.body_to_world(kin.forward(robot, w_any), theta), paper_eq2(theta) @ w_any,
                                   rtol=1e-12, atol=1e-12)


def test_table1_directions_of_paper():
    """Table 1: 'Forward' (+y in Fig. 1) turns W1 CW, W2 CCW, W3 CCW, W4 CW."""
    w = kin.inverse(phunopas2018(), np.array([0.0, 1.0, 0.0]))
    # With the paper's eq. (3), +y motion gives w ∝ cos(α_i): signs (+, −, −, +).
    np.testing.assert_array_equal(np.sign(w), [1, -1, -1, 1])


def test_forward_inverts_inverse_for_three_wheels():
    robot = williams2002()
    twist = np.array([0.3, -0.1, 1.2])
    np.testing.assert_allclose(kin.forward(robot, kin.inverse(robot, twist)), twist, atol=1e-12)


def test_consistency_residual_detects_slip_only_with_redundancy():
    robot = phunopas2018()
    w = kin.inverse(robot, np.array([0.2, 0.1, 0.5]))
    np.testing.assert_allclose(kin.consistency_residual(robot, w), 0.0, atol=1e-12)
    slipped = w.copy()
    slipped[2] += 1.0  # one wheel spins 1 rad/s faster than the body motion allows
    res = kin.consistency_residual(robot, slipped)
    # The redundant direction of a square layout is (1, -1, 1, -1)/2: the residual is the projection.
    np.testing.assert_allclose(np.abs(res), 0.25, atol=1e-12)
    # Three wheels have no redundant direction: every wheel-speed vector is consistent.
    three = williams2002()
    np.testing.assert_allclose(kin.consistency_residual(three, np.array([1.0, -2.0, 0.5])), 0.0, atol=1e-12)


def test_forward_with_lifted_wheel_uses_remaining_wheels():
    robot = phunopas2018()
    twist = np.array([0.1, 0.2, -0.3])
    w = kin.inverse(robot, twist)
    w[1] = 99.0  # lifted wheel spinning freely: excluded, so it cannot corrupt the estimate
    np.testing.assert_allclose(kin.forward(robot, w, contact=[True, False, True, True]), twist, atol=1e-12)
    with pytest.raises(ValueError, match="do not determine"):
        kin.forward(robot, w, contact=[True, False, True, False])


def test_regular_generator_and_bad_wheel_count():
    robot = regular(5)
    assert robot.n_wheels == 5
    np.testing.assert_allclose(np.linalg.norm(robot.positions(), axis=1), 0.1)
    for n in (2, 17, 3.5):  # the one wheel-count bound, 3 to 16 (omni_gym.bounds)
        with pytest.raises(ValueError, match="n must be an integer from 3 to 16"):
            regular(n)


# --- mecanum wheels: the OptiOdom omni4 robot --------------------------------------------------------

def optiodom_inverse(l1: float, l2: float) -> np.ndarray:
    """OptiOdom omni4 (Lin et al. 2019): body displacement (dx, dy, dθ) → wheel travels Δ [m], typed in.

    Its least-squares inverse is the dataset's documented forward odometry (checked below).
    """
    c = (l1 + l2) / 2.0
    return np.array([[1.0, -1.0, -c], [-1.0, -1.0, -c], [1.0, 1.0, -c], [-1.0, 1.0, -c]])


def optiodom_forward(l1: float, l2: float) -> np.ndarray:
    """OptiOdom's documented forward odometry Δ → (dx, dy, dθ), typed in from the data README."""
    s = 2.0 * (l1 + l2)
    return np.array([[0.25, -0.25, 0.25, -0.25], [-0.25, -0.25, 0.25, 0.25], [-1 / s, -1 / s, -1 / s, -1 / s]])


@pytest.mark.parametrize(("l1", "l2"), [(0.2, 0.2), (0.205, 0.215), (0.3, 0.1)])
def test_optiodom_omni4_reproduces_the_optiodom_matrix(l1, l2):
    robot = optiodom_omni4(l1, l2)
    # r·W maps a body displacement to wheel travels: OptiOdom's inverse, exactly up to round-off.
    np.testing.assert_allclose(robot.wheel_radius * robot.wheel_matrix(), optiodom_inverse(l1, l2),
                               rtol=0, atol=1e-15)
    # And the least-squares forward kinematics is the dataset's forward formula.
    np.testing.assert_allclose(optiodom_forward(l1, l2) @ optiodom_inverse(l1, l2), np.eye(3), atol=1e-12)
    rng = np.random.default_rng(3)
    travel = rng.normal(size=(6, 4))  # arbitrary, slipping wheel travels included
    np.testing.assert_allclose(kin.forward(robot, travel / robot.wheel_radius), travel @ optiodom_forward(l1, l2).T,
                               rtol=1e-12, atol=1e-12)


def test_optiodom_omni4_equal_diameters_only():
    assert optiodom_omni4(diameters=(0.05,) * 4).wheel_radius == 0.025
    with pytest.raises(ValueError, match="diameters differ"):
        optiodom_omni4(diameters=(0.06, 0.06, 0.061, 0.06))


def test_mecanum_row_is_roller_axis_projection():
    """Row i is u_i·(1, 0, z×p_i)/(r cos γ_i) = (d_i + tan γ_i a_i)·(…)/r, for any roller angle."""
    gamma = 0.4
    wheels = (Wheel((0.1, 0.05), (0.6, 0.8), gamma), Wheel((-0.1, 0.0), (0.0, 1.0)),
              Wheel((0.0, -0.1), (1.0, 0.0), -0.7))
    robot = RobotSpec(name="m", wheels=wheels, wheel_radius=0.04, mass=1.0, inertia=0.01)
    for i, w in enumerate(robot.wheels):
        d = np.array(w.drive)
        a = np.array([-d[1], d[0]])
        e = d + np.tan(w.roller_angle) * a
        px, py = w.position
        np.testing.assert_allclose(robot.wheel_matrix()[i], [e[0], e[1], e @ [-py, px]] / np.float64(0.04), atol=1e-14)


def test_omni_wheel_matrices_unchanged():
    """γ = 0 leaves every omni robot's matrix bit-identical to (d, d·(z × p))/r."""
    for robot in (williams2002(), phunopas2018(), regular(5)):
        p, d = robot.positions(), robot.drives()
        old = np.column_stack([d[:, 0], d[:, 1], d[:, 1] * p[:, 0] - d[:, 0] * p[:, 1]]) / robot.wheel_radius
        np.testing.assert_array_equal(robot.wheel_matrix(), old)
        assert not robot.has_angled_rollers


@pytest.mark.parametrize("gamma", [np.pi / 2, -1.1, np.nan])
def test_roller_angle_beyond_bound_is_refused(gamma):
    wheels = (Wheel((0.1, 0.0), (0.0, 1.0), gamma), Wheel((-0.1, 0.0), (0.0, 1.0)), Wheel((0.0, -0.1), (1.0, 0.0)))
    with pytest.raises(ValueError, match="wheel 1 roller_angle must be in"):
        RobotSpec(name="bad", wheels=wheels, wheel_radius=0.03, mass=1.0, inertia=0.01)


# --- a model's effective kinematics (effective_kinematics) -----------------------------------------


def _model(robot, surface="grip", friction="initial", **effects):
    from omni_gym.physics.friction import SURFACES
    from omni_gym.physics.model import SimModel

    return SimModel(robot, SURFACES[surface], friction, effects=effects)


def test_effective_kinematics_without_kinematic_effects_is_the_robots_own_bit_for_bit():
    """No effect, or effects that leave the no-slip rolling constraint alone (centre of mass, motor lag,
    friction): the robot's own matrix and radius, bit for bit (so kinematics="model" changes nothing)."""
    for robot in (williams2002(), phunopas2018(), optiodom_omni4()):
        for effects in ({}, {"com_offset": {"com": [0.01, -0.02]}, "motor_lag": {"tau": 0.02},
                             "kinetic_friction": {"ratio": 0.8, "v_s": 0.01}}):
            k = kin.effective_kinematics(_model(robot, **effects))
            np.testing.assert_array_equal(k.wheel_matrix(), robot.wheel_matrix())
            assert k.wheel_radius == robot.wheel_radius and k.n_wheels == robot.n_wheels


def test_effective_kinematics_divides_each_row_by_its_wheels_radius_scale():
    """A wheel whose effective rolling radius is s × nominal turns 1/s as fast for the same body twist;
    the radius controllers get is the mean effective one."""
    robot = optiodom_omni4()
    scale = np.array([1.07, 1.072, 1.0699, 1.086])
    k = kin.effective_kinematics(_model(robot, wheel_radius={"scale": scale.tolist()}))
    np.testing.assert_allclose(k.wheel_matrix() * scale[:, None], robot.wheel_matrix(), rtol=1e-12)
    assert k.wheel_radius == pytest.approx(robot.wheel_radius * scale.mean(), rel=1e-12)


def test_effective_kinematics_of_wheel_geometry_is_the_moved_robots_matrix():
    """wheel_geometry moves wheel i to distance_i·p_i and yaws its drive by mount_i: the effective matrix is
    the nominal matrix of a robot built with those wheels (an independent construction)."""
    robot = williams2002()
    distance, mount = [1.0, 1.04, 0.98], [0.0, 0.03, -0.02]
    k = kin.effective_kinematics(_model(robot, "carpet", "roller_gap",
                                        wheel_geometry={"distance": distance, "mount": mount}))
    moved = []
    for w, s, m in zip(robot.wheels, distance, mount, strict=True):
        c, si = np.cos(m), np.sin(m)
        moved.append(Wheel((s * w.position[0], s * w.position[1]),
                           (c * w.drive[0] - si * w.drive[1], si * w.drive[0] + c * w.drive[1])))
    np.testing.assert_allclose(k.wheel_matrix(), robot.with_changes(wheels=tuple(moved)).wheel_matrix(),
                               rtol=1e-12, atol=1e-12)


def test_effective_kinematics_of_mecanum_lateral_splits_the_radius_by_direction():
    """mecanum_lateral (docs in its module): along the rolling direction the body moves r_lon = 2r/(1 + ratio)
    per wheel radian, sideways r_lat = ratio·r_lon (45° rollers); the optiodom_omni4 wheels drive along body x."""
    robot, ratio, v = optiodom_omni4(), 0.95, 0.2
    k = kin.effective_kinematics(_model(robot, mecanum_lateral={"ratio": ratio}))
    r_lon = robot.wheel_radius * 2.0 / (1.0 + ratio)
    np.testing.assert_allclose(np.abs(k.wheel_matrix() @ [v, 0.0, 0.0]), v / r_lon, rtol=1e-12)
    np.testing.assert_allclose(np.abs(k.wheel_matrix() @ [0.0, v, 0.0]), v / (ratio * r_lon), rtol=1e-12)
