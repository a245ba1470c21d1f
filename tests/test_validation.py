"""Validation of the pymunk world against the independent reference integration (omni_gym.analysis.reference).

The reference integrates the same slip model with an error-controlled stiff solver (rtol 1e-10,
atol 1e-12) and restarts exactly at every command change and roller/rigid-material switch, so its
own error is ~1e-10 m (checked below: LSODA and Radau agree). Every difference between the world
and the reference is therefore the world's error (time step, switch timing, force discretisation).

Bounds for the world (task requirement, default dt = 0.5 ms): over a 2 s manoeuvre the geometric
centre stays within 1 mm of the reference and the heading within 2 mrad, sampled every 10 ms.
1 mm is ~0.1 % of the ~0.8 m travelled in 2 s at 0.4 m/s and 2 mrad ~0.07 % of the 3 rad turned
at 1.5 rad/s: well below what the model itself can claim against a real robot (the paper's
friction coefficients carry a few % uncertainty), so the world's discretisation never matters.

Run with ``-s`` to see the measured errors of every case.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from omni_gym.analysis.reference import reference_trajectory
from omni_gym.physics.friction import Surface
from omni_gym.physics.model import SimModel, load_model
from omni_gym.physics.world import DEFAULT_DT, World

DT_SAMPLE = 0.01  # s, comparison grid (20 world substeps of 0.5 ms)
DURATION = 2.0  # s, length of every manoeuvre
POS_TOL = 1e-3  # m, task bound (see module docstring)
HEAD_TOL = 2e-3  # rad, task bound (see module docstring)

# Body twists (vx [m/s], vy [m/s], ω [rad/s]) of the geometric centre, held from the given time on.
# Within the task's realistic range: |v| ≤ 0.4 m/s, |ω| ≤ 1.5 rad/s. Switch times lie on the 10 ms grid.
MANEUVERS: dict[str, list[tuple[float, tuple[float, float, float]]]] = {
    "translate_x": [(0.0, (0.4, 0.0, 0.0))],
    "translate_y": [(0.0, (0.0, 0.4, 0.0))],
    "rotate": [(0.0, (0.0, 0.0, 1.5))],
    "combined": [(0.0, (0.3, 0.1, 1.0))],
    "start_stop": [(0.0, (0.25, -0.25, 0.8)), (1.0, (0.0, 0.0, 0.0))],
    "steps": [(0.0, (0.2, 0.0, 0.0)), (0.4, (0.0, 0.3, 0.0)), (0.8, (0.1, 0.1, -1.5)),
              (1.2, (-0.3, 0.2, 0.5)), (1.6, (0.0, 0.0, 0.0))],
}

COM_OFFSET = {"com": [0.01, -0.005]}


def _model(robot: str, surface: str, friction: str, com: bool = False) -> SimModel:
    model = load_model(robot, surface, friction)
    return model.with_effect("com_offset", COM_OFFSET) if com else model


def _schedule(model: SimModel, maneuver: str) -> tuple[np.ndarray, np.ndarray]:
    """(switch times (K,), wheel-speed commands (K, n)) of a manoeuvre, via the wheel matrix W."""
    steps = MANEUVERS[maneuver]
    wm = model.robot.wheel_matrix()
    times = np.array([t for t, _ in steps])
    commands = np.array([wm @ np.asarray(tw, dtype=float) for _, tw in steps])
    return times, commands


def _sample_times(duration: float) -> np.ndarray:
    return np.arange(round(duration / DT_SAMPLE) + 1) * DT_SAMPLE


def _run_world(model: SimModel, times: np.ndarray, commands: np.ndarray, duration: float,
               contact: np.ndarray | None = None, dt: float = DEFAULT_DT) -> dict[str, np.ndarray]:
    """World samples on the 10 ms grid; commands applied at their switch times (on the grid)."""
    world = World(model, dt=dt)
    world.reset()
    if contact is not None:
        world.set_contact(0, contact)
    start = np.rint(times / DT_SAMPLE).astype(int)
    assert np.allclose(start * DT_SAMPLE, times), "command switches must lie on the sample grid"
    n_samples = round(duration / DT_SAMPLE)
    poses, vels, angles = [world.pose[0].copy()], [world.velocity[0].copy()], [world.wheel_angle[0].copy()]
    for k in range(n_samples):
        hits = np.flatnonzero(start == k)
        if hits.size:
            world.set_commands(commands[hits[-1]])
        world.step(DT_SAMPLE)
        poses.append(world.pose[0].copy())
        vels.append(world.velocity[0].copy())
        angles.append(world.wheel_angle[0].copy())
    return {"pose": np.array(poses), "velocity": np.array(vels), "wheel_angle": np.array(angles)}


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _errors(world_pose: np.ndarray, ref_pose: np.ndarray) -> tuple[float, float]:
    """(max position error [m], max heading error [rad]) over all samples."""
    pos = np.max(np.hypot(*(world_pose[:, :2] - ref_pose[:, :2]).T))
    head = np.max(np.abs(_wrap(world_pose[:, 2] - ref_pose[:, 2])))
    return float(pos), float(head)


def _compare(label: str, model: SimModel, times: np.ndarray, commands: np.ndarray,
             duration: float = DURATION, contact: np.ndarray | None = None,
             dt: float = DEFAULT_DT) -> tuple[float, float]:
    t_eval = _sample_times(duration)
    ref = reference_trajectory(model, times, commands, t_eval, contact=contact)
    got = _run_world(model, times, commands, duration, contact=contact, dt=dt)
    pos, head = _errors(got["pose"], ref["pose"])
    vel = np.max(np.abs(got["velocity"] - ref["velocity"]), axis=0)
    print(f"\n[validation] {label:45s} {model.robot.name:13s} {model.friction:10s} {model.surface.name:7s} "
          f"pos {pos * 1e3:8.4f} mm  head {head * 1e3:8.4f} mrad  "
          f"(max |dv| {vel[0] * 1e3:.2f}, {vel[1] * 1e3:.2f} mm/s, |dω| {vel[2] * 1e3:.2f} mrad/s)")
    return pos, head


# --- (a) manoeuvres against the reference ---------------------------------------------------------

CASES = [
    pytest.param("williams2002", surface, friction, maneuver, False, id=f"williams2002-{friction}-{surface}-{maneuver}")
    for friction in ("initial", "roller_gap")
    for surface in ("paper", "carpet")
    for maneuver in MANEUVERS
] + [
    pytest.param("phunopas2018", "paper", "roller_gap", "steps", False, id="phunopas2018-roller_gap-paper-steps"),
    pytest.param("phunopas2018", "carpet", "initial", "combined", False, id="phunopas2018-initial-carpet-combined"),
    pytest.param("williams2002", "carpet", "roller_gap", "steps", True, id="williams2002-com-roller_gap-carpet-steps"),
    pytest.param("williams2002", "paper", "initial", "combined", True, id="williams2002-com-initial-paper-combined"),
]


# Mecanum wheels (the optiodom_omni4 preset, rollers at ±45°): the 'initial' friction model only, the
# one that applies to them (roller_gap's rigid material between rollers is an omni-wheel geometry).
CASES += [
    pytest.param("optiodom_omni4", surface, "initial", maneuver, False,
                 id=f"optiodom_omni4-initial-{surface}-{maneuver}")
    for surface in ("paper", "carpet")
    for maneuver in MANEUVERS
] + [
    pytest.param("optiodom_omni4", "carpet", "initial", "steps", True, id="optiodom_omni4-com-initial-carpet-steps"),
]


def test_mecanum_lateral_world_matches_reference():
    """The mecanum_lateral effect (ratio 0.9: radius × 2/1.9, roller angle atan(tan γ / 0.9)) in the world
    and in the reference, which applies it from the documented equations, not from the kernel's numbers."""
    model = _model("optiodom_omni4", "carpet", "initial", False).with_effect("mecanum_lateral", {"ratio": 0.9})
    times, commands = _schedule(model, "combined")
    pos, head = _compare("combined +mecanum_lateral", model, times, commands)
    assert pos <= POS_TOL, f"max position error {pos * 1e3:.3f} mm > 1 mm"
    assert head <= HEAD_TOL, f"max heading error {head * 1e3:.3f} mrad > 2 mrad"
    # The effect itself moves this manoeuvre far more than the tolerance: the check can fail.
    plain = reference_trajectory(_model("optiodom_omni4", "carpet", "initial", False), times, commands,
                                 _sample_times(DURATION))["pose"]
    effect = reference_trajectory(model, times, commands, _sample_times(DURATION))["pose"]
    assert _errors(effect, plain)[0] > 20 * POS_TOL


@pytest.mark.parametrize(("robot", "surface", "friction", "maneuver", "com"), CASES)
def test_world_matches_reference(robot, surface, friction, maneuver, com):
    model = _model(robot, surface, friction, com)
    times, commands = _schedule(model, maneuver)
    pos, head = _compare(f"{maneuver}{' +com' if com else ''}", model, times, commands)
    assert pos <= POS_TOL, f"max position error {pos * 1e3:.3f} mm > 1 mm"
    assert head <= HEAD_TOL, f"max heading error {head * 1e3:.3f} mrad > 2 mrad"


@pytest.mark.parametrize(("robot", "friction"), [("williams2002", "roller_gap"), ("optiodom_omni4", "initial")])
def test_reference_is_converged(robot, friction):
    """The reference's own error is negligible: two different stiff methods agree to < 1e-8 m / rad.

    Radau (implicit Runge-Kutta, order 5) and LSODA (BDF/Adams) share nothing but the right-hand
    side and the switch times; 1e-8 is 1e-5 of the world bound. Short run (0.5 s, 15 switches)
    to keep Radau's cost down.
    """
    model = _model(robot, "paper", friction)
    times, commands = _schedule(model, "steps")
    t_eval = _sample_times(0.5)
    a = reference_trajectory(model, times, commands, t_eval, method="LSODA")
    b = reference_trajectory(model, times, commands, t_eval, method="Radau")
    if friction == "roller_gap":
        assert len(a["switch_times"]) >= 10
    np.testing.assert_allclose(a["pose"], b["pose"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(a["velocity"], b["velocity"], rtol=0, atol=1e-7)


# --- (b) very high drive friction: kinematic (no-slip) motion --------------------------------------

# Very high grip along the drive direction. The rollers stay free (mu_transverse = 0): an omni wheel
# only rolls "without slip" kinematically if its rollers turn freely; with mu_transverse = 5 too the
# rollers are locked, the layout is over-constrained and the exact model does not follow the
# kinematic twist at all (e.g. a pure x command makes the robot spin about −1.5 rad in 2 s while it
# barely translates). The 'initial' friction model keeps roller contact at every wheel angle.
GRIP = Surface("grip", mu_drive=5.0, mu_transverse=0.0, mu_gap=5.0, k=1000.0)
# Also grips across the wheel (rollers locked): a second stiff surface for world-vs-reference.
LOCKED = Surface("locked", mu_drive=5.0, mu_transverse=5.0, mu_gap=5.0, k=1000.0)


def _kinematic_pose(twist: np.ndarray, t: float) -> np.ndarray:
    """Pose after holding the body twist (vx, vy, ω) for t seconds from the origin (exact)."""
    vx, vy, om = twist
    if om == 0.0:
        return np.array([vx * t, vy * t, 0.0])
    s, c = np.sin(om * t), np.cos(om * t)
    return np.array([(s * vx - (1.0 - c) * vy) / om, ((1.0 - c) * vx + s * vy) / om, om * t])


def _steady_slip_twist(model: SimModel, twist: np.ndarray) -> np.ndarray:
    """Body-twist error (δvx, δvy, δω) of the steady circular motion under GRIP (3 wheels).

    The COM of a robot holding the twist moves on a circle: it needs the centripetal force
    m ω (z × v) and no torque. With mu_transverse = 0 only drive forces f_i act, so
    Σ f_i d_i = m ω (z × v) and Σ f_i (p_i × d_i) = 0 fix f (3 wheels). In the linear part of the
    friction law (k·v_W ≪ 1) f_i = −N_i μ_W (2/π) k v_W,i, so the drive slips are v_W = −f / (N μ_W
    (2/π) k), and the body twist error follows from r·W·δ = v_W.
    """
    robot = model.robot
    p, d = robot.positions(), robot.drives()
    a = np.vstack([d[:, 0], d[:, 1], p[:, 0] * d[:, 1] - p[:, 1] * d[:, 0]])
    vx, vy, om = twist
    f = np.linalg.solve(a, [robot.mass * om * -vy, robot.mass * om * vx, 0.0])
    n_load = robot.mass * model.gravity / robot.n_wheels  # equal loads, centre of mass at the centre
    slip = -f / (n_load * model.surface.mu_drive * (2.0 / np.pi) * model.surface.k)
    return np.linalg.solve(robot.wheel_radius * robot.wheel_matrix(), slip)


@pytest.mark.parametrize("twist", [(0.4, 0.0, 0.0), (0.0, 0.4, 0.0), (0.0, 0.0, 1.5), (0.3, 0.1, 1.0),
                                   (-0.2, 0.3, -1.5)])
def test_high_friction_follows_kinematics(twist):
    """With very high drive grip the world follows the commanded twist.

    The robot starts already moving with the commanded twist (set on the pymunk body), so there is no
    start-up transient — from rest the wheels slip at full friction for ~|v|/(μ g) ≈ 8 ms and leave a
    pose offset of a few mm/mrad that is physical, not an error. What remains is the steady slip
    that carries the centripetal force (:func:`_steady_slip_twist`, ~1e-5 m/s): the exact model
    drifts by at most |δv| T in position plus |v| |δω| T²/2 from the heading drift, and |δω| T in
    heading. The world may add its own error, bounded by the validated 1 mm / 2 mrad. Tolerance =
    2 × the drift estimate (the estimate linearises atan; factor 2 covers that) + world bound.
    """
    model = replace(load_model("williams2002", "paper", "initial"), surface=GRIP)
    tw = np.asarray(twist, dtype=float)
    world = World(model)
    world.reset()
    world.bodies[0].velocity = (tw[0], tw[1])  # at θ = 0 body and world frames coincide; COM at centre
    world.bodies[0].angular_velocity = tw[2]
    world.set_commands(model.robot.wheel_matrix() @ tw)
    world.step(DURATION)
    expected = _kinematic_pose(tw, DURATION)
    delta = _steady_slip_twist(model, tw)
    drift_pos = np.hypot(*delta[:2]) * DURATION + np.hypot(*tw[:2]) * abs(delta[2]) * DURATION**2 / 2.0
    drift_head = abs(delta[2]) * DURATION
    pos = np.hypot(*(world.pose[0, :2] - expected[:2]))
    head = abs(_wrap(world.pose[0, 2] - expected[2]))
    print(f"\n[kinematic] twist {twist}: pos {pos * 1e3:.4f} mm (tol {(2 * drift_pos + POS_TOL) * 1e3:.4f}), "
          f"head {head * 1e3:.4f} mrad (tol {(2 * drift_head + HEAD_TOL) * 1e3:.4f})")
    assert pos <= 2.0 * drift_pos + POS_TOL
    assert head <= 2.0 * drift_head + HEAD_TOL
    # And the exact model itself: within the drift estimate alone (no world error).
    ref = reference_trajectory(model, np.array([0.0]), (model.robot.wheel_matrix() @ tw)[None], np.array([DURATION]),
                               initial_velocity=tw)
    assert np.hypot(*(ref["pose"][0, :2] - expected[:2])) <= 2.0 * drift_pos + 1e-9
    assert abs(ref["pose"][0, 2] - expected[2]) <= 2.0 * drift_head + 1e-9


# The mecanum robot on a floor where nothing slips: drive grip μ 5 along every roller axis, rollers free
# (μ_T = 0). OptiOdom's omni4 matrix, typed in here from the dataset's documentation (wheel travels
# Δ = M·(dx, dy, dθ), c = (l1 + l2)/2, l1 = l2 = 0.2 m), is all the expected motion uses.
OPTIODOM_C = 0.2
OPTIODOM_M = np.array([[1.0, -1.0, -OPTIODOM_C], [-1.0, -1.0, -OPTIODOM_C], [1.0, 1.0, -OPTIODOM_C],
                       [-1.0, 1.0, -OPTIODOM_C]])


def _integrate_kinematics(wheel_speeds: np.ndarray, r: float, t: float, steps: int = 20000) -> np.ndarray:
    """Pose after t seconds at constant wheel speeds by the kinematic matrix alone (classic RK4 on
    ẋ = R(θ)·M⁺·r·w; the body twist is constant, so RK4 at 0.1 ms is exact to ~1e-15 m)."""
    twist = np.linalg.lstsq(OPTIODOM_M, r * wheel_speeds, rcond=None)[0]

    def f(pose):
        c, s = np.cos(pose[2]), np.sin(pose[2])
        return np.array([c * twist[0] - s * twist[1], s * twist[0] + c * twist[1], twist[2]])

    pose, h = np.zeros(3), t / steps
    for _ in range(steps):
        k1 = f(pose)
        k2 = f(pose + 0.5 * h * k1)
        k3 = f(pose + 0.5 * h * k2)
        k4 = f(pose + h * k3)
        pose = pose + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return pose


@pytest.mark.parametrize("twist", [(0.4, 0.0, 0.0), (0.0, 0.4, 0.0), (0.0, 0.0, 1.5), (0.3, 0.1, 1.0),
                                   (-0.2, 0.3, -1.5)])
def test_mecanum_without_slip_follows_the_optiodom_kinematics(twist):
    """Constant wheel speeds on a no-slip floor: the mecanum robot follows the kinematic matrix within 1 mm.

    The wheel speeds come from the typed-in matrix, never from the model; the robot starts already
    moving with the matching twist (from rest the wheels slip for ~|v|/(μ g) ≈ 8 ms, a physical offset).
    What remains is the steady slip that carries the centripetal force m ω |v| (≈ 2.4 N at most here):
    spread over four rollers of stiffness N μ (2/π) k ≈ 3·10⁴ N/(m/s), it is ≲ 1e-4 m/s, ≲ 0.2 mm in 2 s.
    Bound: 1 mm and 2 mrad (the validation bound); at the documented μ ≫ 1 step of 0.25 ms.
    """
    model = replace(load_model("optiodom_omni4", "paper", "initial"), surface=GRIP)
    r = model.robot.wheel_radius
    tw = np.asarray(twist, dtype=float)
    wheel_speeds = OPTIODOM_M @ tw / r
    world = World(model, dt=STIFF_DT)
    world.reset()
    world.bodies[0].velocity = (tw[0], tw[1])  # at θ = 0 body and world frames coincide; COM at centre
    world.bodies[0].angular_velocity = tw[2]
    world.set_commands(wheel_speeds)
    world.step(DURATION)
    expected = _integrate_kinematics(wheel_speeds, r, DURATION)
    pos = np.hypot(*(world.pose[0, :2] - expected[:2]))
    head = abs(_wrap(world.pose[0, 2] - expected[2]))
    print(f"\n[mecanum kinematic] twist {twist}: pos {pos * 1e3:.4f} mm, head {head * 1e3:.4f} mrad")
    assert pos <= POS_TOL, f"position {pos * 1e3:.3f} mm off the kinematics"
    assert head <= HEAD_TOL, f"heading {head * 1e3:.3f} mrad off the kinematics"
    assert np.hypot(*expected[:2]) + abs(expected[2]) > 0.5  # it did move (0.8 m or 3 rad)


# Stiff cases from rest against the reference (same 1 mm / 2 mrad bound). With μ_drive = 5 the
# friction stiffness N·μ·(2/π)·k/m is ~3e4 1/s, dt·λ ~ 15 at the default 0.5 ms: the implicit step stays
# stable but is not accurate from rest there (measured at 0.5 ms: up to 7.8 mm / 121 mrad on the
# locked-roller surface). docs/model.md therefore tells users of μ ≫ 1 to halve the step; these tests
# check that advice: at dt = 0.25 ms the world matches the reference within the usual bound
# (measured ≤ 0.13 mm / 0.39 mrad).
STIFF_DT = 0.25e-3


@pytest.mark.parametrize("surface", [GRIP, LOCKED], ids=lambda s: s.name)
@pytest.mark.parametrize(("robot", "maneuver"), [("williams2002", "translate_x"), ("williams2002", "combined"),
                                                 ("williams2002", "steps"), ("optiodom_omni4", "combined"),
                                                 ("optiodom_omni4", "steps")])
def test_stiff_world_matches_reference_at_the_documented_step(surface, robot, maneuver):
    model = replace(load_model(robot, "paper", "initial"), surface=surface)
    times, commands = _schedule(model, maneuver)
    pos, head = _compare(f"stiff {surface.name} {maneuver}", model, times, commands, dt=STIFF_DT)
    assert pos <= POS_TOL, f"max position error {pos * 1e3:.3f} mm > 1 mm"
    assert head <= HEAD_TOL, f"max heading error {head * 1e3:.3f} mrad > 2 mrad"


# --- (c) frictionless wheels conserve momentum ----------------------------------------------------

FRICTIONLESS = Surface("ice", mu_drive=0.0, mu_transverse=0.0, mu_gap=0.0, k=1000.0)


def _momentum(model: SimModel, pose: np.ndarray, velocity: np.ndarray) -> tuple[np.ndarray, float]:
    """Linear momentum m·V_com and angular momentum about the arena origin I·ω + m·(r_com × V_com)."""
    m, inertia = model.robot.mass, model.robot.inertia
    c, s = np.cos(pose[2]), np.sin(pose[2])
    q = np.array([c * model.com[0] - s * model.com[1], s * model.com[0] + c * model.com[1]])  # R·c
    r_com = pose[:2] + q
    v_com = velocity[:2] + velocity[2] * np.array([-q[1], q[0]])  # v_centre + ω z × (R c)
    return m * v_com, inertia * velocity[2] + m * (r_com[0] * v_com[1] - r_com[1] * v_com[0])


@pytest.mark.parametrize("friction", ["initial", "roller_gap"])
@pytest.mark.parametrize("com", [False, True], ids=["com0", "com_offset"])
def test_frictionless_conserves_momentum(friction, com):
    """With all μ = 0 the wheels exert no force: momentum is conserved whatever the wheels do.

    Zero friction coefficients make every wheel force exactly 0, so velocities must not change at
    all (1e-12) and positions may only carry floating-point round-off: the arena sits far from the
    pymunk origin (~1.6e6 m), where a double resolves u = ulp ≈ 2.3e-10 m, and every substep adds
    v·dt rounded to that grid, a possibly systematic error ≤ u/2 per step and coordinate. Over n
    substeps the COM position is off by ≤ √2 n u/2, so the angular momentum about a fixed point by
    ≤ m |V| √2 n u/2 (≈ 1.5e-7 here; measured 2.5e-8).
    """
    model = replace(_model("williams2002", "paper", friction, com), surface=FRICTIONLESS)
    world = World(model)
    world.reset()
    body = world.bodies[0]
    body.velocity = (0.2, -0.1)  # velocity of the pymunk body's centre of gravity
    body.angular_velocity = 0.7
    world.set_commands(np.array([12.0, -7.0, 5.0]))  # spinning wheels
    world.step(DT_SAMPLE)  # let the world pick the state up, then measure over 1 s
    p0, l0 = _momentum(model, world.pose[0], world.velocity[0])
    angle0 = world.wheel_angle[0].copy()
    world.step(1.0)
    p1, l1 = _momentum(model, world.pose[0], world.velocity[0])
    n_steps = round(1.0 / 0.0005)  # default dt
    ulp = np.spacing(np.max(np.abs(np.array(body.position))))
    l_tol = np.hypot(*p0) * np.sqrt(2.0) * n_steps * ulp / 2.0  # |m V| √2 n u/2
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-12)
    assert abs(l1 - l0) <= l_tol, f"angular momentum changed by {abs(l1 - l0):.3g} > {l_tol:.3g}"
    np.testing.assert_allclose(p0, model.robot.mass * np.array([0.2, -0.1]), rtol=0, atol=1e-12)
    assert np.all(np.abs(world.wheel_angle[0] - angle0) > 1.0)  # the wheels did spin
    # The reference conserves them too (its frictionless motion is exact up to the solver tolerance).
    ref = reference_trajectory(model, np.array([0.0]), np.array([[12.0, -7.0, 5.0]]), np.array([0.0, 1.0]),
                               initial_velocity=np.array([0.2, -0.1, 0.7]))
    (rp0, rl0), (rp1, rl1) = (_momentum(model, ref["pose"][j], ref["velocity"][j]) for j in (0, 1))
    np.testing.assert_allclose(rp1, rp0, rtol=0, atol=1e-9)
    assert abs(rl1 - rl0) <= 1e-9


# --- (d) a lifted wheel exerts no force ------------------------------------------------------------

@pytest.mark.parametrize(("robot", "friction", "lifted"), [("phunopas2018", "roller_gap", 0),
                                                          ("williams2002", "initial", 2),
                                                          ("optiodom_omni4", "initial", 1)])
def test_lifted_wheel_exerts_no_force(robot, friction, lifted):
    """Changing a lifted wheel's command changes nothing but its encoder; the rest matches the reference.

    A lifted wheel carries no load (N = 0) so its force is exactly zero whatever its speed: the pose
    and velocity must be bit-identical between runs that differ only in that wheel's command. Its
    encoder still integrates the ideal wheel speed (exact up to round-off: 1e-9 rad).
    """
    model = load_model(robot, "carpet", friction)
    contact = np.ones(model.n_wheels, dtype=bool)
    contact[lifted] = False
    times, commands = _schedule(model, "steps")
    other = commands.copy()
    other[:, lifted] = [25.0, -40.0, 0.0, 13.0, 8.0]  # arbitrary, including switches
    duration = DURATION
    a = _run_world(model, times, commands, duration, contact=contact)
    b = _run_world(model, times, other, duration, contact=contact)
    np.testing.assert_array_equal(a["pose"], b["pose"])
    np.testing.assert_array_equal(a["velocity"], b["velocity"])
    t = _sample_times(duration)
    for run, cmds in ((a, commands), (b, other)):
        spans = np.clip(np.minimum(np.append(times[1:], np.inf)[None, :], t[:, None]) - times[None, :], 0.0, None)
        np.testing.assert_allclose(run["wheel_angle"], spans @ cmds, rtol=0, atol=1e-9)
    assert not np.allclose(a["wheel_angle"][:, lifted], b["wheel_angle"][:, lifted])
    pos, head = _compare(f"steps, wheel {lifted + 1} lifted", model, times, commands, contact=contact)
    assert pos <= POS_TOL, f"max position error {pos * 1e3:.3f} mm > 1 mm"
    assert head <= HEAD_TOL, f"max heading error {head * 1e3:.3f} mrad > 2 mrad"
