"""Reference tables of the environments."""

import numpy as np
import pytest

from omni_gym.envs.config import make_config
from omni_gym.envs.references import _sample_rest_to_rest, draw_reference
from omni_gym.trajectories import QuinticWaypoints


def test_compiled_waypoint_sampler_matches_quintic_waypoints():
    rng = np.random.default_rng(0)
    wp = rng.uniform(-1, 1, size=(6, 3))
    durations = rng.uniform(0.5, 3.0, size=5)
    t = np.arange(0, durations.sum() + 1.0, 0.01)
    pose, vel = np.empty((len(t), 3)), np.empty((len(t), 3))
    _sample_rest_to_rest(wp, durations, t, pose, vel)
    ref_pose, ref_vel, _ = QuinticWaypoints(wp, segment_durations=durations).sample(t)
    # Same polynomial in two algebraic forms: agreement to rounding (1e-12 of unit-sized values).
    np.testing.assert_allclose(pose, ref_pose, atol=1e-12)
    np.testing.assert_allclose(vel, ref_vel, atol=1e-12)


@pytest.mark.parametrize("family", ["waypoints", "circle", "figure_eight", "line", "goto"])
def test_references_start_at_rest_at_the_origin_and_are_smooth(family):
    task = "goto" if family == "goto" else "path"
    cfg = make_config(task=task, trajectory=family)
    n = cfg.episode_steps + 101
    pose, vel = draw_reference(cfg, np.random.default_rng(1), n)
    assert pose.shape == vel.shape == (n, 3)
    np.testing.assert_allclose(pose[0, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(vel[0], 0.0, atol=1e-12)  # every family starts at rest
    # Velocity is the derivative of the pose: central differences at 100 Hz agree to O(dt²·jerk).
    dt = 1.0 / cfg.control_hz
    fd = (pose[2:] - pose[:-2]) / (2 * dt)
    np.testing.assert_allclose(fd, vel[1:-1], atol=5e-3)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    assert speed.max() < 2.0 * cfg.ref_speed + 1e-9  # quintic peaks are 1.875x the mean speed
    assert np.all(np.abs(pose[:, :2]) <= cfg.arena_half_size)  # stays in the arena


def test_reference_draws_are_seeded():
    cfg = make_config()
    a = draw_reference(cfg, np.random.default_rng(5), 500)[0]
    b = draw_reference(cfg, np.random.default_rng(5), 500)[0]
    c = draw_reference(cfg, np.random.default_rng(6), 500)[0]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_sensor_observation_decodes_to_physical_units():
    import gymnasium as gym

    import omni_gym  # noqa: F401
    from omni_gym.envs.observations import SensorObsDecoder

    env = gym.make("OmniPathFollow-Phunopas-v0", obs_mode="sensors", sensor_noise=0.0, lift_rate=0.0)
    decode = SensorObsDecoder.for_env(env)
    obs, info = env.reset(seed=3)
    for _ in range(30):
        obs, _, _, _, info = env.step(np.array([0.3, -0.2, 0.4]))
    s = decode(obs)
    core = env.unwrapped.core
    # Noiseless sensors: reference and compass come back to float32 precision (1e-6 of their scale).
    np.testing.assert_allclose(s.ref_pose[:2], info["reference_pose"][:2], atol=1e-5)
    assert abs(np.angle(np.exp(1j * (s.compass - info["pose"][2])))) < 1e-5  # compass is wrapped
    assert abs(s.gyro - info["velocity"][2]) < 1e-4 * 3.0
    np.testing.assert_allclose(s.last_action, [0.3, -0.2, 0.4], atol=1e-6)
    # Encoder rates are the quantised angle change over 10 ms: within one count per period of the truth.
    quantum = 2 * np.pi / 2048
    true_rates = core.world.wheel_speed[0]
    assert np.all(np.abs(s.encoder_rates - true_rates) <= quantum / 0.01 + 1e-3)


def test_turn_before_separates_turns_from_translations():
    """ref_turn="before": the heading never changes while the reference translates."""
    during, before = make_config(ref_turn="during"), make_config(ref_turn="before")
    for seed in range(5):
        n = before.episode_steps + 1
        pose_d, _ = draw_reference(during, np.random.default_rng(seed), n)
        pose_b, vel_b = draw_reference(before, np.random.default_rng(seed), n)
        speed = np.hypot(vel_b[:, 0], vel_b[:, 1])
        assert np.all((speed == 0.0) | (vel_b[:, 2] == 0.0))  # rest-to-rest pieces: exactly one moves at a time
        assert np.max(np.abs(vel_b[:, 2])) <= 1.0 + 1e-9  # peak yaw rate as in "during" (rounding)
        assert pose_b[0, 2] == pose_d[0, 2]  # same draws: both start facing the same first segment
    with pytest.raises(ValueError, match="ref_turn"):
        make_config(ref_turn="after")
