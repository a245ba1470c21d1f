"""Behavioural tests of omni_gym.sensor_bank (the batched sensors of the environments) and its encoder.

Statistical tolerances as in tests/test_sensors.py: a sample std within 5 standard errors
(σ/√(2N)) of σ; the seeds are fixed, so the checks are deterministic.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_gym.envs.core import encode_sensor_obs
from omni_gym.envs.observations import ACC_SCALE, ObsScales, encode_sensors, sensor_layout, sensor_offsets
from omni_gym.sensor_bank import BLOCK_STEPS, SensorBank
from omni_gym.sensors import SensorConfig, SensorSuite

DT = 0.01  # s, the environments' default control period
SE_LIMIT = 5.0  # allowed deviation in standard errors (module docstring)


def motion(k: int, n_robots: int) -> tuple:
    """True states of every robot at sample k: (t, wheel angles, pose, yaw rate, body acceleration),
    different per robot and non-trivial (angles cross many encoder counts, headings cross ±π)."""
    t = k * DT
    j = np.arange(n_robots)[:, None]
    angles = np.array([1.0, -2.0, 0.5]) * t * (1.0 + j) + 0.1 * j
    pose = np.column_stack([0.1 * t + 0.01 * j[:, 0], -0.05 * t * j[:, 0], 3.0 * t + j[:, 0]])
    yaw = 0.3 + 0.1 * np.arange(n_robots)
    acc = np.column_stack([np.full(n_robots, 0.2), -0.1 * np.arange(n_robots)])
    return np.full(n_robots, t), angles, pose, yaw, acc


def bank_run(seeds: list[int], config: SensorConfig, steps: int, scale: float = 1.0) -> list[dict]:
    """Readings of a bank whose robot j is reset from default_rng(seeds[j]), along :func:`motion`."""
    bank = SensorBank(len(seeds), 3)
    for j, s in enumerate(seeds):
        bank.reset(j, np.random.default_rng(s), config, scale)
    out = []
    for k in range(steps):
        bank.measure(*_args(k, len(seeds)))
        out.append({name: getattr(bank, name).copy() for name in ("wheel_angles", "gyro", "compass", "accel", "fix",
                                                                    "has_fix")} | {"gyro_bias": bank.gyro_bias.copy()})
    return out


def _args(k: int, n: int) -> tuple:
    t, angles, pose, yaw, acc = motion(k, n)
    return t, DT, angles, pose, yaw, acc


def test_noiseless_bank_reads_what_the_single_robot_sensors_read():
    config = SensorConfig.noiseless()
    steps = 3 * BLOCK_STEPS  # crosses two block refills
    readings = bank_run([1, 2, 3, 4], config, steps)
    for j in range(4):
        suite = SensorSuite(3, np.random.default_rng(99), config)
        for k in range(steps):
            t, angles, pose, yaw, acc = motion(k, 4)
            r = suite.measure(t[j], DT, angles[j], pose[j], yaw[j], acc[j])
            got = readings[k]
            assert np.array_equal(got["wheel_angles"][j], r.wheel_angles)
            assert got["gyro"][j] == r.gyro and got["compass"][j] == r.compass
            assert np.array_equal(got["accel"][j], r.accel)
            assert got["has_fix"][j] == (r.camera is not None), f"robot {j}, sample {k}: camera schedule"
            if r.camera is not None:
                assert np.array_equal(got["fix"][j], r.camera)
    # 10 Hz camera at 100 Hz samples: a fix at samples 0, 10, 20, ...
    assert [k for k in range(steps) if readings[k]["has_fix"][0]] == list(range(0, steps, 10))


def test_a_robots_readings_do_not_depend_on_the_batch():
    config = SensorConfig()
    steps = 2 * BLOCK_STEPS + 5
    alone = bank_run([7], config, steps)
    # Robot 7's generator as robot 2 of 5; robots 0 and 4 are reset again mid-run and robot 1 is not
    # sampled at every step, which must not change what robot 2 reads.
    bank = SensorBank(5, 3)
    for j, s in enumerate([11, 12, 7, 13, 14]):
        bank.reset(j, np.random.default_rng(s), config)
    for k in range(steps):
        if k == 20:
            bank.reset(0, np.random.default_rng(50), config)
            bank.reset(4, np.random.default_rng(51), config)
        robots = None if k % 3 else np.array([0, 2, 3, 4])
        t, angles, pose, yaw, acc = motion(k, 1)
        big = motion(k, 5)
        rows = [a.copy() for a in big[1:]]
        for a, b in zip(rows, (angles, pose, yaw, acc), strict=True):
            a[2] = b[0]  # robot 2 of the batch moves as the lone robot
        bank.measure(big[0], DT, *rows, robots=robots)
        for name in ("wheel_angles", "gyro", "compass", "accel", "has_fix"):
            assert np.array_equal(getattr(bank, name)[2], alone[k][name][0]), f"sample {k}: {name}"
        if alone[k]["has_fix"][0]:
            assert np.array_equal(bank.fix[2], alone[k]["fix"][0])


def test_noise_distributions_are_the_documented_ones():
    config = SensorConfig(gyro_bias_walk_std=0.0)  # bias then constant: gyro − true − bias is white noise
    n_robots, steps = 2000, 40  # 80,000 samples per noise; the bias std from 2000 robots
    seeds = list(range(n_robots))
    readings = bank_run(seeds, config, steps)
    truth = [motion(k, n_robots) for k in range(steps)]
    bias = readings[0]["gyro_bias"]
    gyro = np.array([r["gyro"] - tr[3] - bias for r, tr in zip(readings, truth, strict=True)])
    compass = np.array([np.angle(np.exp(1j * (r["compass"] - tr[2][:, 2]))) for r, tr in
                        zip(readings, truth, strict=True)])
    accel = np.array([r["accel"] - tr[4] for r, tr in zip(readings, truth, strict=True)])
    fixes = np.array([r["fix"][:, 0:2] - tr[2][:, 0:2] for r, tr in zip(readings, truth, strict=True)
                      if r["has_fix"].all()])

    def assert_std(samples, sigma):
        assert abs(np.std(samples, ddof=1) - sigma) < SE_LIMIT * sigma / math.sqrt(2 * samples.size)

    assert_std(bias, config.gyro_bias_std)
    assert_std(gyro, config.gyro_noise_std)
    assert_std(compass, config.compass_noise_std)
    # Accelerometer: constant bias per robot and axis plus white noise, independent: variances add.
    assert_std(accel, math.hypot(config.accel_bias_std, config.accel_noise_std))
    assert_std(accel - accel.mean(axis=0), config.accel_noise_std * math.sqrt(1 - 1 / steps))
    assert_std(fixes, config.camera_position_std)


def test_noise_scale_multiplies_every_std():
    config = SensorConfig()
    one = bank_run([5, 6], config, BLOCK_STEPS + 3)
    two = bank_run([5, 6], config, BLOCK_STEPS + 3, scale=2.0)
    zero = bank_run([5, 6], config, BLOCK_STEPS + 3, scale=0.0)
    quiet = bank_run([5, 6], SensorConfig.noiseless(), BLOCK_STEPS + 3)
    for k in range(BLOCK_STEPS + 3):
        t, angles, pose, yaw, acc = motion(k, 2)
        # σ·z with the same z: doubling σ doubles each deviation exactly (up to one rounding of the sum).
        assert np.allclose(two[k]["accel"] - acc, 2.0 * (one[k]["accel"] - acc), rtol=1e-9, atol=1e-15)
        assert np.allclose(two[k]["gyro"] - yaw, 2.0 * (one[k]["gyro"] - yaw), rtol=1e-9, atol=1e-15)
        for name in ("wheel_angles", "gyro", "compass", "accel", "has_fix"):
            assert np.array_equal(zero[k][name], quiet[k][name]), name


def test_bank_refuses_a_non_generator_and_a_negative_scale():
    bank = SensorBank(1, 3)
    with pytest.raises(ValueError, match="Generator"):
        bank.reset(0, np.random.RandomState(0), SensorConfig())
    with pytest.raises(ValueError, match="noise_scale"):
        bank.reset(0, np.random.default_rng(0), SensorConfig(), -1.0)


@pytest.mark.parametrize("n_wheels,action_dim", [(3, 3), (4, 4), (6, 3)])
def test_batched_encoder_writes_what_encode_sensors_writes(n_wheels, action_dim):
    rng = np.random.default_rng(n_wheels)
    B, n_samples = 5, 200
    layout = sensor_layout(n_wheels, action_dim)
    scales = ObsScales(wheel_scale=25.0, max_speed=0.6, max_yaw_rate=3.0, arena_half_size=2.0)
    look = np.array([25, 50, 100])
    ref_pose = rng.normal(0.0, 3.0, (B, n_samples, 3))  # some beyond the arena: clipped at ±10
    ref_vel = rng.normal(0.0, 1.0, (B, n_samples, 3))
    enc = rng.normal(0.0, 5.0, (B, n_wheels))
    prev = rng.normal(0.0, 5.0, (B, n_wheels))
    gyro, compass = rng.normal(0.0, 2.0, B), rng.normal(0.0, 4.0, B)
    accel = rng.normal(0.0, 30.0, (B, 2))
    fix = rng.normal(0.0, 1.0, (B, 3))
    has_fix = np.array([True, False, False, True, False])
    step = np.array([0, 0, 7, 3, 60])
    last_fix = rng.normal(0.0, 1.0, (B, 3))
    fix_age = np.array([1.0, 1.0, 0.3, 0.5, 0.995])
    prev_action = rng.uniform(-1, 1, (B, action_dim))
    out = np.zeros((B, layout.size))
    args = [enc, gyro, compass, accel, fix, has_fix, step, DT, prev.copy(), last_fix.copy(), fix_age.copy(),
            ref_pose, ref_vel, look, prev_action,
            np.array([scales.wheel_scale, scales.max_yaw_rate, scales.max_speed, scales.arena_half_size, ACC_SCALE]),
            sensor_offsets(layout), out]
    encode_sensor_obs(np.arange(B), *args)
    new_fix, new_age = args[9], args[10]
    for b in range(B):
        held = fix[b] if has_fix[b] else last_fix[b]
        age = 0.0 if has_fix[b] else (min(fix_age[b] + DT, 1.0) if step[b] > 0 else fix_age[b])
        assert np.array_equal(new_fix[b], held) and new_age[b] == age
        expected = np.zeros(layout.size)
        k = step[b]
        encode_sensors(layout, scales, expected, encoder_rates=(enc[b] - prev[b]) / DT, gyro=gyro[b],
                       compass=compass[b], accel=accel[b], fix=held, fix_age=age, ref_now=ref_pose[b, k],
                       ref_velocity=ref_vel[b, k], ref_lookahead=ref_pose[b, k + look], last_action=prev_action[b])
        assert np.array_equal(out[b], expected), f"robot {b}"
    assert np.array_equal(args[8], enc)  # the encoder angles are kept for the next rate
