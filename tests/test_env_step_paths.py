"""The single environment's per-robot shortcuts (``TaskCore.info``, ``TaskCore.outcome``) agree with the
batched arrays the vector environment returns, value for value and type for type."""

import numpy as np

from omni_gym.envs.config import make_config
from omni_gym.envs.core import TaskCore


def test_info_and_outcome_match_the_batched_arrays():
    cfg = make_config(walls=True, arena_half_size=0.6, lift_rate=2.0)
    core = TaskCore(cfg, 4)
    rng = np.random.default_rng(0)
    for j in range(4):
        core.reset_robot(j, rng)
    core.observe()
    seen = {"terminated": set(), "success": set()}
    for _ in range(150):
        core.advance(np.full((4, 3), [1.0, -1.0, 0.5]) * np.array([[1], [0.3], [-1], [0]]))
        core.observe()
        infos = core.infos()
        rewards, terminated, truncated = core.rewards(), core.terminated(), core.truncated()
        for j in range(4):
            info = core.info(j)
            assert set(info) == set(infos)
            for key, value in info.items():
                if np.ndim(infos[key][j]) == 0:
                    assert type(value) is type(infos[key][j].item()), key  # Python scalars, as before
                    assert value == infos[key][j].item(), key
                else:
                    np.testing.assert_array_equal(value, infos[key][j], err_msg=key)
            assert core.outcome(j) == (float(rewards[j]), bool(terminated[j]), bool(truncated[j]))
            seen["terminated"].add(bool(terminated[j]))
            seen["success"].add(info["is_success"])
    # Both branches of each flag were exercised (robots driven off their references into the walls).
    assert seen["terminated"] == {False, True} and seen["success"] == {False, True}


def test_threaded_observation_matches_serial_bit_for_bit():
    """A core whose world is threaded (256 robots and more) observes with the threaded loop; it writes the
    same bits as the serial one."""
    from omni_gym.envs.core import observe_state, observe_state_parallel

    core = TaskCore(make_config(), 300)
    assert core.world.parallel and core._observe_state is observe_state_parallel
    assert TaskCore(make_config(), 4)._observe_state is observe_state
    rng = np.random.default_rng(1)
    for j in range(300):
        core.reset_robot(j, rng)
    core.advance(rng.uniform(-1.0, 1.0, (300, 3)))
    core.observe()
    world = core.world
    outs = []
    for fn in (observe_state, observe_state_parallel):
        obs, err, true, reward = (np.full_like(a, np.nan) for a in (core._state_obs, core.err, core.true, core.reward))
        fn(world._state_view, world.origins, world.sp, core.ref_pose, core.ref_vel, core.step_count, core.look,
           core.prev_action, core.scales, core._state_offsets, obs, err, true, reward)
        outs.append((obs, err, true, reward))
    for serial, threaded in zip(*outs, strict=True):
        np.testing.assert_array_equal(serial, threaded)
    np.testing.assert_array_equal(outs[0][0], core.obs)
