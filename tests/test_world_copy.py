"""``World.copy_robot``: a robot copied into another world (a planner's rollouts) is the same robot.

Bit-exact claims: arenas lie in one binade (``ARENA_BASE``), the body's internal centre of gravity is copied
directly, and the compiled kernel is deterministic, so a copy stepped with the same commands must equal the
source robot in every bit; any tolerance would hide a state variable the copy forgot.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.physics.model import load_model
from omni_gym.physics.world import World

CASES = [("OmniPathFollow-Phunopas-v0", {"surface": "carpet", "lift_rate": 2.0}),
         ("OmniPathFollow-Mecanum-v0", {"surface": "carpet", "lift_rate": 2.0}),
         ("OmniPathFollow-Williams-v1", {"surface": "carpet", "friction": "roller_gap"})]


def _driven(env_id: str, kwargs: dict, steps: int = 37):
    """A 3-robot native vector env after ``steps`` random control steps; its TaskCore."""
    env = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        env.step(rng.uniform(-1, 1, (3, env.single_action_space.shape[0])))
    return env.unwrapped.core


def _same(a: World, j: int, b: World, k: int) -> bool:
    return (np.array_equal(a.pose[j], b.pose[k]) and np.array_equal(a.velocity[j], b.velocity[k])
            and np.array_equal(a.wheels[j], b.wheels[k], equal_nan=True)  # NaN: the gap memo is empty
            and np.array_equal(a.contact[j], b.contact[k]))


@pytest.mark.parametrize(("env_id", "kwargs"), CASES, ids=[c[0] for c in CASES])
def test_a_copy_follows_the_source_bit_for_bit(env_id, kwargs):
    """Robot 1 of a driven env copied into all 4 robots of a planner world (whose clock is elsewhere): 300
    control periods of the same random wheel commands keep every copy equal to the source, lift-off
    switches included (``contacts="copy"``: each copy carries the source's contact process)."""
    core = _driven(env_id, kwargs)
    w = core.world
    plan = World(w.models[0], n_robots=4, dt=w.dt, actuation=w.actuation, arena=w.arena)
    plan.substeps(21)  # another global clock: the copy's local clock must be carried over
    plan.copy_robot(w, 1, contacts="copy")
    rng = np.random.default_rng(1)
    masks = set()
    for _ in range(300):
        cmd = rng.uniform(-20, 20, w.n_wheels)
        w.wheel_cmd[1] = cmd
        plan.wheel_cmd[:] = cmd
        w.substeps(core.cfg.substeps)
        plan.substeps(core.cfg.substeps)
        assert all(_same(w, 1, plan, k) for k in range(4))
        masks.add(w.contact[1].tobytes())
    if kwargs.get("lift_rate"):
        assert len(masks) > 1  # the lift-off process switched during the run (2 /s over 3 s)


def test_a_copy_keeps_an_offset_centre_of_gravity_exact():
    """With a centre of gravity off the body origin, pymunk's position setter adds the rotated offset (one
    rounding); the copy sets the internal centre of gravity itself, so it still follows bit for bit."""
    model = load_model("phunopas2018", "carpet").with_effect("com_offset", {"com": [0.0123, -0.0071]})
    src = World(model, n_robots=2)
    src.reset(np.array([[0.3, -0.2, 0.9], [0.1, 0.1, -2.0]]))
    rng = np.random.default_rng(2)
    for _ in range(50):
        src.set_commands(rng.uniform(-15, 15, src.wheel_cmd.shape))
        src.substeps(20)
    plan = World(model, n_robots=3)
    plan.copy_robot(src, 1)
    assert _same(src, 1, plan, 2)
    for _ in range(200):
        cmd = rng.uniform(-15, 15, src.n_wheels)
        src.wheel_cmd[1] = cmd
        plan.wheel_cmd[:] = cmd
        src.substeps(20)
        plan.substeps(20)
        assert all(_same(src, 1, plan, k) for k in range(3))


def test_hold_keeps_the_lifted_wheels_and_leaves_the_source_alone():
    """``contacts="hold"``: the copy keeps the mask it was given (no process, no switch), and copying does not
    change the source (its next steps equal those of an untouched twin)."""
    core = _driven("OmniPathFollow-Phunopas-v0", {"surface": "carpet", "lift_rate": 2.0})
    twin = _driven("OmniPathFollow-Phunopas-v0", {"surface": "carpet", "lift_rate": 2.0})
    w = core.world
    lifted = np.array([True, False, True, True])
    w.set_contact(0, lifted)
    twin.world.set_contact(0, lifted)
    plan = World(w.models[0], n_robots=2, dt=w.dt, actuation=w.actuation, arena=w.arena)
    plan.copy_robot(w, 0, contacts="hold")
    assert plan.contact_processes == [None, None]
    for _ in range(200):
        plan.substeps(20)
        w.substeps(20)
        twin.world.substeps(20)
        assert np.array_equal(plan.contact, np.tile(lifted, (2, 1)))
    assert _same(w, 0, twin.world, 0) and _same(w, 2, twin.world, 2)


def test_copy_robot_refuses_what_it_cannot_copy():
    a = World(load_model("phunopas2018", "carpet"), n_robots=2)
    with pytest.raises(ValueError, match="wheel count"):
        World(load_model("williams2002", "carpet")).copy_robot(a, 0)
    with pytest.raises(IndexError, match="robot 2 out of range"):
        World(load_model("phunopas2018", "carpet")).copy_robot(a, 2)
    with pytest.raises(ValueError, match="contacts must be"):
        World(load_model("phunopas2018", "carpet")).copy_robot(a, 0, contacts="future")


def test_place_puts_a_robot_where_pose_and_velocity_then_read():
    """``World.place`` takes what ``pose`` and ``velocity`` return (geometric centre, arena frame; world-frame
    velocity): read back to rounding (1e-9 m: positions are stored at 2^20 m, ulp 2.3e-10 m), also with the
    centre of gravity off the centre (where the body's own velocity differs from the centre's by ω × ρ)."""
    model = load_model("phunopas2018", "carpet").with_effect("com_offset", {"com": [0.02, -0.015]})
    w = World(model, n_robots=3)
    poses = np.array([[0.4, -0.3, 2.5], [-1.0, 0.2, -0.7]])
    vels = np.array([[0.3, -0.1, 1.5], [0.0, 0.2, -2.0]])
    w.place([2, 0], poses, vels)
    assert np.allclose(w.pose[[2, 0]], poses, rtol=0, atol=1e-9)
    assert np.allclose(w.velocity[[2, 0]], vels, rtol=0, atol=1e-12)
    assert np.array_equal(w.pose[1], np.zeros(3))  # the others stay
    with pytest.raises(ValueError, match="finite"):
        w.place([1], np.array([[np.nan, 0, 0]]), np.zeros((1, 3)))
