"""World behaviour: determinism, batching, actuation, collisions, lift-off wiring."""

import numpy as np
import pytest

from omni_gym.physics.friction import Surface
from omni_gym.physics.liftoff import ContactProcess
from omni_gym.physics.model import Actuation, SimModel, load_model
from omni_gym.physics.robot import phunopas2018
from omni_gym.physics.world import SWITCH_HORIZON_TICKS, Arena, World, switch_tick


def twist_commands(model, twist):
    return model.robot.wheel_matrix() @ np.asarray(twist, dtype=float)


def test_batched_robots_match_single_robot_bit_for_bit():
    model = load_model("williams2002", "carpet", "roller_gap")
    twists = [(0.3, 0.0, 0.0), (0.0, 0.2, 1.0), (0.1, -0.1, -1.5)]
    singles = []
    for tw in twists:
        w = World(model)
        w.set_commands(twist_commands(model, tw))
        w.step(0.5)
        singles.append(np.concatenate([w.pose[0], w.velocity[0], w.wheel_angle[0]]))
    batch = World(model, n_robots=3)
    batch.set_commands(np.array([twist_commands(model, tw) for tw in twists]))
    batch.step(0.5)
    got = np.concatenate([batch.pose, batch.velocity, batch.wheel_angle], axis=1)
    np.testing.assert_array_equal(got, np.array(singles))


def test_same_inputs_same_result_and_reset_restarts():
    model = load_model("phunopas2018", "paper", "roller_gap")
    w = World(model)
    w.set_commands(twist_commands(model, (0.2, 0.1, 0.5)))
    w.step(0.3)
    first = w.pose.copy()
    w.reset()
    np.testing.assert_array_equal(w.pose, np.zeros((1, 3)))
    w.set_commands(twist_commands(model, (0.2, 0.1, 0.5)))
    w.step(0.3)
    np.testing.assert_array_equal(w.pose, first)


def test_servo_tracks_command_and_respects_torque_limit():
    model = load_model("williams2002", "carpet", "initial")
    act = Actuation(kind="servo")
    w = World(model, actuation=act)
    cmd = twist_commands(model, (0.3, 0.0, 0.0))
    w.set_commands(cmd)
    w.step(0.002)
    # 2 ms after a step command the wheels cannot have reached it: the torque limit bounds the
    # acceleration to (limit + friction torque)/J; the ideal source would be there at once.
    assert np.all(np.abs(w.wheel_speed[0]) < np.abs(cmd))
    limit = (act.torque_limit + model.robot.wheel_radius * model.surface.mu_gap * 20) / act.wheel_inertia
    assert np.all(np.abs(w.wheel_speed[0]) <= limit * 0.002 + 1e-9)
    servo_slip = np.abs(w.slip[0, :, 0]).max()
    w.step(1.0)
    # After 1 s the PI loop has settled: speed error below 1 % of the command (integral action).
    np.testing.assert_allclose(w.wheel_speed[0], cmd, rtol=1e-2)
    ideal = World(model)
    ideal.set_commands(cmd)
    ideal.step(0.002)
    # The ideal source jumps to the command, so its drive slip 2 ms in is larger than the servo's.
    assert np.abs(ideal.slip[0, :, 0]).max() > servo_slip
    ideal.step(1.0)
    # Same steady motion: both robots end within 1 cm (slip only differs in the first tens of ms).
    assert abs(ideal.pose[0, 0] - w.pose[0, 0]) < 0.01


def test_servo_is_stable_on_a_lifted_wheel():
    model = load_model("phunopas2018", "carpet", "initial")
    w = World(model, actuation=Actuation(kind="servo"))
    w.set_contact(0, np.array([True, False, True, True]))
    cmd = twist_commands(model, (0.2, 0.0, 0.0))
    w.set_commands(cmd)
    w.step(1.0)
    # A free wheel has no ground torque: the PI loop brings it to the command exactly (1 % bound).
    np.testing.assert_allclose(w.wheel_speed[0, 1], cmd[1], rtol=1e-2)


def test_walls_stop_the_robot_and_flag_a_collision():
    model = load_model("williams2002", "carpet", "initial")
    # Along body +y the front wheels drive; along x this robot barely moves on carpet (see docs).
    w = World(model, arena=Arena(half_size=0.5, walls=True))
    w.set_commands(twist_commands(model, (0.0, 0.4, 0.0)))
    w.step(3.0)
    y = w.pose[0, 1]
    assert w.collided[0]
    # The disc (radius body_radius) cannot pass the wall at y = 0.5 (5 mm of contact slop allowed).
    assert y < 0.5 - model.robot.body_radius + 0.005
    free = World(model)
    free.set_commands(twist_commands(model, (0.0, 0.4, 0.0)))
    free.step(3.0)
    assert free.pose[0, 1] > 0.6 and not free.collided[0]  # without walls it passes y = 0.5


def test_each_robot_meets_only_its_own_arena_copy_of_an_obstacle():
    model = load_model("phunopas2018", "carpet", "initial")  # symmetric: drives straight
    w = World(model, n_robots=2, arena=Arena(half_size=2.0, obstacles=((0.6, 0.0, 0.1),)))
    w.set_commands(np.array([twist_commands(model, (0.4, 0, 0)), twist_commands(model, (-0.4, 0, 0))]))
    w.step(2.0)
    assert w.collided[0] and not w.collided[1]


def test_contact_process_drives_loads():
    model = load_model("phunopas2018", "carpet", "initial")
    w = World(model)
    w.set_contact_process(0, ContactProcess(4, lift_rate=50.0, recover_rate=50.0, rng=np.random.default_rng(0)))
    seen = set()
    for _ in range(200):
        w.step(0.01)
        seen.add(tuple(w.contact[0]))
        lifted = ~w.contact[0]
        assert np.all(w.loads[0][lifted] == 0.0)
        np.testing.assert_allclose(w.loads[0].sum(), model.robot.mass * model.gravity)
    assert len(seen) >= 4  # at 50 switches/s over 2 s, several distinct cases must appear


def test_world_rejects_bad_commands():
    model = load_model("williams2002")
    w = World(model)
    with pytest.raises(ValueError, match="shape"):
        w.set_commands(np.zeros(4))
    with pytest.raises(ValueError, match="NaN"):
        w.set_commands(np.array([0.0, np.nan, 0.0]))


def test_implicit_step_is_stable_where_explicit_would_not_be():
    """μ = 5 with k = 1000: stiffness N·μ·k·(2/π)/m ≈ 5e4 /s, 25x past explicit Euler's limit at 0.5 ms."""
    robot = phunopas2018()
    # Very high drive friction, roller transverse friction: the wheels act as no-slip constraints.
    model = SimModel(robot=robot, surface=Surface("sticky", 5.0, 0.15, 5.0), friction="initial")
    w = World(model)
    w.set_commands(twist_commands(model, (0.2, 0.0, 0.0)))
    w.step(0.5)
    assert np.all(np.isfinite(w.pose))
    np.testing.assert_allclose(w.velocity[0], [0.2, 0.0, 0.0], atol=1e-3)


def test_robot_reset_mid_run_replays_a_lone_robot_exactly_with_lift_off():
    """Each robot's clock and contact process restart at its own reset (needed for vector autoreset)."""
    model = load_model("phunopas2018", "carpet", "roller_gap")
    cmd = twist_commands(model, (0.2, 0.1, 0.4))

    def process(seed):
        return ContactProcess(4, lift_rate=20.0, recover_rate=20.0, rng=np.random.default_rng(seed))

    lone = World(model)
    lone.set_contact_process(0, process(5))
    lone.reset()
    lone.set_commands(cmd)
    lone_traj = []
    for _ in range(50):
        lone.step(0.01)
        lone_traj.append(np.concatenate([lone.pose[0], lone.contact[0]]))

    batch = World(model, n_robots=2)
    batch.set_contact_process(0, process(1))
    batch.set_contact_process(1, process(2))
    batch.reset()
    batch.set_commands(np.array([cmd, -cmd]))
    batch.step(0.3337)  # robot 1 is reset at an odd global time
    batch.set_contact_process(1, process(5))
    batch.reset(robots=[1])
    batch.set_commands(np.array([cmd, cmd]))
    batch_traj = []
    for _ in range(50):
        batch.step(0.01)
        batch_traj.append(np.concatenate([batch.pose[1], batch.contact[1]]))
    np.testing.assert_array_equal(np.array(batch_traj), np.array(lone_traj))
    assert len({tuple(r[3:]) for r in lone_traj}) > 1  # the contact process did switch meanwhile



@pytest.mark.parametrize("dt", [0.0005, 0.002, 1e-3, 0.1 / 3])
def test_switch_tick_is_the_first_substep_reaching_the_switch(dt):
    """k = switch_tick(s, dt) is the least k >= 0 whose local time k·dt (the float the world hands
    to ``advance``) is >= s, including switch times on, just before and just after a substep and
    far from 0; beyond the horizon, at +inf or NaN there is no switch (None)."""
    rng = np.random.default_rng(0)
    times = [0.0, 5e-324, 1e-300, dt, 0.1, 1.0, 1234.5678, 3.0e7]
    for m in (1, 3, 7, 10**6, 2**40, SWITCH_HORIZON_TICKS - 3):
        on = m * dt
        times += [on, np.nextafter(on, 0.0), np.nextafter(on, np.inf)]
    times += list(rng.uniform(0.0, 1e3, 50)) + list(10.0 ** rng.uniform(-6, 12, 50))
    for s in times:
        k = switch_tick(float(s), dt)
        assert k * dt >= s and (k == 0 or (k - 1) * dt < s), (s, k)
    beyond = SWITCH_HORIZON_TICKS * dt
    for s in (np.nextafter(beyond, np.inf), 2 * beyond, 1e300, np.inf, np.nan):
        assert switch_tick(float(s), dt) is None


def test_rate_zero_means_the_switch_never_comes():
    """lift_rate 0: all wheels stay down. recover_rate 0: a lifted wheel stays up until the robot's
    reset, which puts every wheel down again."""
    model = load_model("phunopas2018", "carpet", "initial")
    w = World(model, n_robots=2)
    w.set_contact_process(0, ContactProcess(4, lift_rate=0.0, recover_rate=5.0, rng=np.random.default_rng(0)))
    w.set_contact_process(1, ContactProcess(4, lift_rate=50.0, recover_rate=0.0, rng=np.random.default_rng(0)))
    w.reset()
    never_lifted, lifted = [], []
    for _ in range(100):
        w.step(0.01)
        never_lifted.append(w.contact[0].all())
        lifted.append(not w.contact[1].all())
    assert all(never_lifted)
    # 50 /s lifts within 0.5 s with probability 1 - e^-25; after that the wheel never comes back.
    assert any(lifted[:50]) and all(lifted[lifted.index(True):])
    w.reset(robots=[1])
    assert w.contact[1].all()


def test_tiny_rates_schedule_no_switch_and_keep_running():
    """Rates so small that the drawn switch lies past the horizon (or 1/rate overflows to inf)
    schedule nothing: reset and stepping return (they used to loop or overflow)."""
    model = load_model("phunopas2018", "carpet", "initial")
    w = World(model, n_robots=3)
    for j, (lift, recover) in enumerate([(1e-30, 5.0), (5e-324, 5.0), (1e3, 1e-300)]):
        w.set_contact_process(j, ContactProcess(4, lift, recover, np.random.default_rng(j)))
    w.reset()
    w.step(0.5)
    assert w.contact[0].all() and w.contact[1].all()
    assert not w.contact[2].all()  # 1000 /s lifted it in the first ms; 1e-300 /s never brings it back
    assert np.all(np.isfinite(w.pose))


def test_large_batch_matches_lone_robots_bit_for_bit():
    model = load_model("phunopas2018", "carpet", "roller_gap")
    rng = np.random.default_rng(4)
    twists = rng.uniform(-1, 1, size=(64, 3)) * [0.3, 0.3, 1.5]
    batch = World(model, n_robots=64, parallel=True)  # the threaded kernel, as large batches use
    assert batch.parallel and not World(model).parallel
    batch.set_commands(np.array([model.robot.wheel_matrix() @ tw for tw in twists]))  # same arithmetic as alone
    batch.step(0.2)
    for j in (0, 17, 63):
        lone = World(model)
        lone.set_commands(model.robot.wheel_matrix() @ twists[j])
        lone.step(0.2)
        np.testing.assert_array_equal(batch.pose[j], lone.pose[0])
        np.testing.assert_array_equal(batch.wheel_angle[j], lone.wheel_angle[0])


@pytest.mark.parametrize("actuation", ["ideal", "servo"])
def test_mixed_omni_and_mecanum_batch_matches_lone_robots_bit_for_bit(actuation):
    """Omni and mecanum robots share one batch (and the threaded kernel): each robot's arithmetic is its own."""
    models = [load_model("phunopas2018", "carpet", "roller_gap"), load_model("optiodom_omni4", "carpet")] * 2
    act = Actuation(actuation)
    twists = [(0.3, 0.0, 0.0), (0.0, 0.3, 0.0), (0.1, -0.1, -1.5), (0.2, 0.2, 1.0)]
    batch = World(models, actuation=act, parallel=True)
    batch.set_commands(np.array([twist_commands(m, tw) for m, tw in zip(models, twists, strict=True)]))
    batch.step(0.2)
    for j, (m, tw) in enumerate(zip(models, twists, strict=True)):
        lone = World(m, actuation=act)
        lone.set_commands(twist_commands(m, tw))
        lone.step(0.2)
        np.testing.assert_array_equal(batch.pose[j], lone.pose[0])
        np.testing.assert_array_equal(batch.wheel_speed[j], lone.wheel_speed[0])
    # The mecanum robot commanded sideways moved sideways, though its drives all point along ±x.
    assert batch.pose[1, 1] > 0.01 and abs(batch.pose[1, 0]) < 1e-6


@pytest.mark.parametrize("parallel", [False, True])
def test_compiled_substep_loop_matches_python_calls_bit_for_bit(parallel):
    """World.substeps runs read, kernel, write and pymunk step in one compiled call (run_substeps in physics/kernel.py);
    the same calls made one by one from Python, robots driven into the walls (so pymunk's collision
    callback fires inside the compiled loop), give the same bits and the same collision flags."""
    from omni_gym.physics.kernel import substep, substep_parallel

    model = load_model("williams2002", "carpet", "roller_gap")  # drives along body y (see the walls test)
    worlds = [World(model, n_robots=3, arena=Arena(0.4, walls=True), parallel=parallel) for _ in range(2)]
    cmds = np.array([twist_commands(model, tw) for tw in [(0.0, 0.4, 0.0), (0.0, -0.4, 0.0), (0.0, 0.3, 0.3)]])
    compiled, by_hand = worlds
    for w in worlds:
        w.set_commands(cmds)
    compiled.substeps(3000)
    kernel = substep_parallel if parallel else substep
    batch = by_hand._batch
    by_hand.space.step(0.0)
    for _ in range(3000):
        batch.read()
        kernel(by_hand.dt, batch.states, by_hand.wheels, by_hand.sp, by_hand.wp, by_hand.ext_force, batch.forces,
               by_hand.slip)
        batch.write()
        batch.step(by_hand.dt)
    assert compiled.collided.all()  # every robot reached a wall within 1.5 s
    np.testing.assert_array_equal(compiled.collided, by_hand.collided)
    for name in ("pose", "velocity", "wheels", "slip"):
        np.testing.assert_array_equal(getattr(compiled, name), getattr(by_hand, name), err_msg=name)


def test_robots_split_among_spaces_match_one_space_bit_for_bit():
    """A threaded world without obstacles gives each thread its own pymunk space (physics/kernel.py:
    run_substeps_spaces); with lift-off switches splitting the runs, every robot matches the same robot
    in a one-space world (built with one numba thread), bit for bit."""
    import numba

    model = load_model("phunopas2018", "carpet", "roller_gap")
    rng = np.random.default_rng(7)
    cmds = rng.uniform(-15.0, 15.0, size=(96, 4))

    def run() -> World:
        w = World(model, n_robots=96, parallel=True)
        for j in (3, 50, 95):
            w.set_contact_process(j, ContactProcess(4, 20.0, 40.0, np.random.default_rng(j)))
        w.set_commands(cmds)
        w.substeps(300)
        return w

    threads = numba.get_num_threads()
    split = run()
    numba.set_num_threads(1)
    try:
        single = run()
    finally:
        numba.set_num_threads(threads)
    assert len(single.spaces) == 1
    if threads > 1:
        assert len(split.spaces) == min(threads, 3)  # 96 robots, at least 32 per space
    for name in ("pose", "velocity", "wheels", "slip", "contact"):
        np.testing.assert_array_equal(getattr(split, name), getattr(single, name), err_msg=name)
    assert not split.contact[[3, 50, 95]].all()  # the switches happened


def test_split_world_pickles_and_resumes_bit_for_bit():
    """A world split among spaces (threaded, no obstacles) gathers its bodies for pickling and resumes exactly."""
    import pickle

    w = World(load_model("phunopas2018", "carpet", "roller_gap"), n_robots=96, parallel=True)
    w.set_commands(np.random.default_rng(0).uniform(-10.0, 10.0, (96, 4)))
    w.substeps(50)
    copy = pickle.loads(pickle.dumps(w))
    assert len(copy.spaces) == len(w.spaces)
    w.substeps(100)
    copy.substeps(100)
    for name in ("pose", "velocity", "wheels"):
        np.testing.assert_array_equal(getattr(copy, name), getattr(w, name), err_msg=name)


@pytest.mark.parametrize("actuation", ["ideal", "servo"])
def test_kernel_gap_memo_changes_no_bit_and_set_model_forgets_it(actuation):
    """The kernel reuses the rigid-material measure of the last substep's end angle (layout WH_GAP_*).
    A world that forgets it before every substep gives the same bits, also across a set_model that
    changes the gap width but not the phase (the memo's angle would still match: set_model must clear it)."""
    from omni_gym.physics.layout import WH_GAP_AT

    base = load_model("phunopas2018", "carpet", "roller_gap")
    wider = base.with_effect("roller_gap", {"mu_gap": 0.6, "roller_fraction": 0.8, "phase": [0.0, 0.1, 0.2, 0.3]})
    narrow = wider.with_effect("roller_gap", {"mu_gap": 0.6, "roller_fraction": 0.95, "phase": [0.0, 0.1, 0.2, 0.3]})
    cmds = np.array([twist_commands(base, (0.2, 0.1, 0.8)), twist_commands(base, (-0.1, 0.3, -0.5))])
    memo, fresh = (World(wider, n_robots=2, actuation=Actuation(actuation)) for _ in range(2))
    for w in (memo, fresh):
        w.set_commands(cmds)
    for k in range(600):
        if k == 300:
            for w in (memo, fresh):
                w.set_model(1, narrow)
        memo.substeps(1)
        fresh.wheels[:, :, WH_GAP_AT] = np.nan
        fresh.substeps(1)
    for name in ("pose", "velocity", "wheels", "slip"):
        a, b = getattr(memo, name), getattr(fresh, name)
        if name == "wheels":
            a, b = a[:, :, :WH_GAP_AT], b[:, :, :WH_GAP_AT]
        np.testing.assert_array_equal(a, b, err_msg=name)
