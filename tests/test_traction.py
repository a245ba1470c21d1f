"""Traction limiter (agents/traction.py), its PID hook and the ekf-pid-traction policy."""

import math

import numpy as np
import pytest
from scipy.optimize import linprog

from agents.pid import PIDGains
from agents.policies import make_policy
from agents.rollout import make_env
from agents.traction import LimitedPathPID, TractionLimiter, reference_demand
from omni_gym.analysis.max_force import max_static_force
from omni_gym.envs import ENV_IDS
from omni_gym.envs.config import make_config
from omni_gym.physics.friction import SURFACES
from omni_gym.physics.loads import wheel_loads
from omni_gym.physics.robot import robot_preset

ROBOTS = ("williams2002", "phunopas2018", "optiodom_omni4")  # omni 3 and 4 wheels, mecanum (rollers at ±45°)
DT = 0.01


def _limiter(robot="williams2002", surface="carpet", **kw):
    return TractionLimiter(robot_preset(robot), SURFACES[surface], **kw)


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("surface", ("carpet", "paper", "grip"))
def test_static_set_is_the_max_force_lp(robot, surface):
    """With no yaw acceleration the set's bound along every direction is max_static_force, at any orientation."""
    lim = _limiter(robot, surface)
    r = robot_preset(robot)
    loads = wheel_loads(r.positions(), r.com, r.mass, 9.81)
    for theta in np.linspace(-math.pi, math.pi, 5):
        for phi in np.linspace(0.0, 2.0 * math.pi, 9, endpoint=False):
            u = np.array([math.cos(phi), math.sin(phi)])
            lp = max_static_force(r, SURFACES[surface], float(theta), u, loads=loads)
            c, s = math.cos(theta), math.sin(theta)
            body = (c * u[0] + s * u[1], -s * u[0] + c * u[1])  # the push in the body frame
            # The LP (HiGHS) is exact to its feasibility tolerance, ~1e-9 relative.
            assert lim.max_acceleration(body) * r.mass == pytest.approx(lp, rel=1e-7)


@pytest.mark.parametrize("mode", ("static", "moving"))
@pytest.mark.parametrize("robot", ROBOTS)
def test_limiter_never_exceeds_the_bound(mode, robot):
    """On random twist changes (seeded), every limited change lies inside the set; feasible rows are untouched."""
    lim = _limiter(robot, mode=mode)
    rng = np.random.default_rng(3)
    prev = rng.uniform(-1, 1, size=(2000, 3)) * [0.5, 0.5, 2.0]
    new = prev + rng.normal(size=(2000, 3)) * [0.05, 0.05, 0.5] * rng.uniform(0, 1, size=(2000, 1))
    out, lam = lim.limit(new, prev, DT)
    use = lim.utilisation(lim.accelerations(out, prev, DT), prev)
    steady = lim.utilisation(np.zeros_like(prev), prev)  # >1: the motion alone is outside the set
    ok = steady <= 1.0
    assert np.all(use[ok] <= 1.0 + 1e-9)  # float rounding of the back-solved twist
    np.testing.assert_array_equal(out[~ok], prev[~ok])  # no feasible change exists: hold the twist
    untouched = lam == 1.0
    assert 0 < untouched.sum() < len(lam)  # the sweep exercises both branches
    np.testing.assert_array_equal(out[untouched], new[untouched])


def test_limiter_keeps_the_acceleration_direction_and_ignores_the_pose():
    lim = _limiter()
    prev = np.array([[0.1, 0.2, 0.3]])
    new = np.array([[0.6, -0.4, 3.0]])  # far outside: must be scaled
    out, lam = lim.limit(new, prev, DT)
    assert 0 < lam[0] < 1
    np.testing.assert_allclose(lim.accelerations(out, prev, DT), lam[0] * lim.accelerations(new, prev, DT),
                               rtol=1e-12, atol=1e-12)  # float rounding
    poses = np.array([[0.0, 0.0, th] for th in np.linspace(-3, 3, 7)])
    batch = lim(np.repeat(new, 7, 0), np.repeat(prev, 7, 0), poses, DT)
    np.testing.assert_array_equal(batch, np.repeat(out, 7, 0))  # N rows behave as N = 1, whatever θ


def test_turning_while_moving_straight_needs_no_force():
    """A twist that keeps the world velocity while the heading turns asks for zero translation acceleration."""
    lim = _limiter()
    om = 1.0
    v = np.array([0.0, 0.3])
    half = 0.5 * om * DT
    rot = lambda a: np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])  # noqa: E731
    prev = np.r_[rot(half) @ v, om]  # previous period: mid-heading half a step behind the boundary
    new = np.r_[rot(-half) @ v, om]
    np.testing.assert_allclose(lim.accelerations(new[None], prev[None], DT), 0.0, atol=1e-12)


def test_bad_input_is_one_clear_error():
    with pytest.raises(ValueError, match="margin"):
        _limiter(margin=0.0)
    with pytest.raises(ValueError, match="mode"):
        _limiter(mode="fast")
    with pytest.raises(ValueError, match="contact case"):
        _limiter(contact_cases=[[True, True]])
    with pytest.raises(ValueError, match="dt"):
        _limiter().limit(np.zeros((1, 3)), np.zeros((1, 3)), 0.0)


def test_limited_axes_count_as_saturated_for_anti_windup():
    """A limiter that holds the twist at zero stops the integrators from winding up."""
    pid = LimitedPathPID(lambda t, p, e, dt: np.zeros_like(t), 0.6, 3.0, DT, PIDGains(i_limit_pos=10,
                                                                                      i_limit_head=10))
    for _ in range(100):
        out = pid.update(np.zeros(3), np.array([0.05, 0.02, 0.1]), np.zeros(3))
    np.testing.assert_array_equal(out, 0.0)
    assert pid.saturated.all()
    np.testing.assert_array_equal(pid.integral, 0.0)  # frozen from the first update: the limit acts there already


def test_policy_matches_ekf_pid_without_slip():
    """On the no-slip floor the references and the PID's corrections are far inside the set: same actions."""
    kw = {"surface": "grip", "friction": "initial", "lift_rate": 0.0, "episode_seconds": 3.0}
    env = make_env("OmniPathFollow-WilliamsPaper-v0", kw)
    actions = []
    for name in ("ekf-pid", "ekf-pid-traction"):
        policy = make_policy(name, env)
        obs, _ = env.reset(seed=4)
        policy.reset(obs)
        acts, done = [], False
        while not done:
            a = policy.act(obs)
            acts.append(a)
            obs, _, term, trunc, _ = env.step(a)
            done = term or trunc
        actions.append(np.array(acts))
    np.testing.assert_array_equal(actions[0], actions[1])


@pytest.mark.parametrize("env_id", [e for e in ENV_IDS if e.startswith("OmniPathFollow")])
def test_default_references_are_within_the_static_bound(env_id):
    """benchmarks/feasibility.py on a few seeds: the default references use under a third of the LP bound."""
    cfg = make_config(**ENV_IDS[env_id][0])
    model = cfg.base_model()
    lim = TractionLimiter(model.robot, model.surface, com=model.com)
    for seed in range(5):
        # Measured ≤ 0.23 over 200 seeds (benchmarks/results/feasibility.md); a third leaves room for draws.
        assert reference_demand(cfg, lim, seed).utilisation < 1 / 3


@pytest.mark.parametrize("surface", ("paper", "carpet"))
def test_moving_set_of_a_mecanum_robot_matches_the_slip_law(surface):
    """"moving" mode on the mecanum preset against a computation written here from the wheel law alone.

    For a steady twist v, each wheel turning without slip (w = W·v) rolls its floor roller at
    v_T = (u − r·w·d)·f (docs/model.md: u the wheel-centre velocity, d the drive, f = z × e the free
    direction of the roller axis e = cos γ·d + sin γ·a); the rolling friction −μ'_T·N·(2/π)·atan(k·v_T)
    along f gives a wrench w_T about the centre of mass. Its utilisation is the smallest s with w_T in
    s·{Σ t_i·g_i : |t_i| ≤ 1}, g_i = μ'_W·N_i·(e_i, ρ_i × e_i): a linear program, solved here with HiGHS.
    """
    robot, surf = robot_preset("optiodom_omni4"), SURFACES[surface]
    lim = TractionLimiter(robot, surf, mode="moving")
    loads = wheel_loads(robot.positions(), robot.com, robot.mass, 9.81)
    r = robot.wheel_radius
    rng = np.random.default_rng(5)
    twists = rng.uniform(-1, 1, size=(12, 3)) * [0.4, 0.4, 1.5]
    twists[0] = [0.3, 0.0, 0.0]  # straight ahead: the rollers of this layout do not roll
    twists[1] = [0.0, 0.3, 0.0]  # sideways: every roller rolls at √2·|v|
    for v in twists:
        w_T = np.zeros(3)
        gens = []
        for i, wheel in enumerate(robot.wheels):
            p = np.array(wheel.position)
            d = np.array(wheel.drive)
            a = np.array([-d[1], d[0]])
            g = wheel.roller_angle
            e = math.cos(g) * d + math.sin(g) * a
            f = np.array([-e[1], e[0]])
            u = v[:2] + v[2] * np.array([-p[1], p[0]])
            w = float(robot.wheel_matrix()[i] @ v)  # no-slip wheel speed [rad/s]
            assert (u - r * w * d) @ e == pytest.approx(0.0, abs=1e-12)  # indeed no slip along e
            vt = (u - r * w * d) @ f
            force = -surf.mu_transverse * loads[i] * (2 / math.pi) * math.atan(surf.k * vt) * f
            w_T += [force[0], force[1], p[0] * force[1] - p[1] * force[0]]
            gens.append(surf.mu_drive * loads[i] * np.array([e[0], e[1], p[0] * e[1] - p[1] * e[0]]))
        G = np.array(gens).T  # (3, n)
        n = G.shape[1]
        # min s  s.t.  G t = w_T,  −s ≤ t_i ≤ s  (variables t_1..t_n, s).
        res = linprog(np.r_[np.zeros(n), 1.0],
                      A_ub=np.block([[np.eye(n), -np.ones((n, 1))], [-np.eye(n), -np.ones((n, 1))]]),
                      b_ub=np.zeros(2 * n), A_eq=np.c_[G, np.zeros(3)], b_eq=w_T,
                      bounds=[(None, None)] * n + [(0, None)], method="highs")
        assert res.status == 0
        # HiGHS is exact to its feasibility tolerance (~1e-9 relative); 1e-7 leaves room for the facet sums.
        assert lim.utilisation(np.zeros((1, 3)), v[None])[0] == pytest.approx(res.x[-1], rel=1e-7, abs=1e-9)
    # The two named cases: straight ahead draws nothing; sideways draws the rolling friction of every wheel.
    assert lim.utilisation(np.zeros((1, 3)), twists[:1])[0] == pytest.approx(0.0, abs=1e-12)
    assert lim.utilisation(np.zeros((1, 3)), twists[1:2])[0] > 0.5 * surf.mu_transverse / surf.mu_drive
