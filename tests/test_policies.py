"""Scripted baselines: the PID, the policies, evaluate() and the ``evaluate`` command line.

Seeds: the tests use seeds below 10 000; ``benchmarks/baselines.py`` reports on seeds from 10 000, so
the published table is on episodes no test (or tuning) has looked at.
"""

import functools
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy import stats

from agents.evaluate import bootstrap_ci, evaluate, mean_ci, summarize, wilson_ci
from agents.pid import PathPID, PIDGains
from agents.policies import POLICY_NAMES, make_policy
from agents.rollout import Episode, make_env, run_episode
from omni_gym.cli import main

ENV = "OmniPathFollow-Phunopas-v0"
NO_SLIP = {"surface": "grip", "friction": "initial", "lift_rate": 0.0}
VMAX, WMAX, DT = 0.6, 3.0, 0.01
ZERO_GAINS = PIDGains(0, 0, 0, 0, 0, 0, 0.05, 0, 0)


# --- PID ------------------------------------------------------------------------------------------


def test_pid_sign_conventions():
    """Errors map to body-frame commands with the conventions of docs/conventions.md."""
    pid = PathPID(VMAX, WMAX, DT)
    # Reference ahead along world +x, robot facing +x: drive forward (+vx), no sideways or turning.
    vx, vy, om = pid.update(np.zeros(3), np.array([0.05, 0.0, 0.0]), np.zeros(3))
    assert vx > 0 and abs(vy) < 1e-12 and abs(om) < 1e-12
    # Robot facing world +y (θ = π/2): world +x is the body's right side, −y.
    pid.reset()
    vx, vy, om = pid.update(np.array([0.0, 0.0, math.pi / 2]), np.array([0.05, 0.0, math.pi / 2]), np.zeros(3))
    assert vy < 0 and abs(vx) < 1e-12
    # A reference heading counter-clockwise of the robot's turns it counter-clockwise (ω > 0) ...
    pid.reset()
    assert pid.update(np.zeros(3), np.array([0.0, 0.0, 0.2]), np.zeros(3))[2] > 0
    # ... the short way round across ±π: from 3.1 to −3.1 rad is +0.083 rad, not −6.2.
    pid.reset()
    om = pid.update(np.array([0.0, 0.0, 3.1]), np.array([0.0, 0.0, -3.1]), np.zeros(3))[2]
    assert om == pytest.approx(PIDGains().kp_head * (2 * math.pi - 6.2), rel=1e-3)


def test_pid_feed_forward_rotates_reference_velocity_into_body_frame():
    """With zero gains the output is the reference world velocity in the body frame at mid-period heading."""
    pid = PathPID(VMAX, WMAX, DT, ZERO_GAINS)
    th, ref_vel = 0.7, np.array([0.2, -0.1, 0.5])
    out = pid.update(np.array([1.0, 2.0, th]), np.array([1.3, 2.2, th + 0.4]), ref_vel)
    mid = th + 0.5 * ref_vel[2] * DT
    c, s = math.cos(mid), math.sin(mid)
    np.testing.assert_allclose(out, [c * 0.2 - s * 0.1, -s * 0.2 - c * 0.1, 0.5], atol=1e-12)


def test_pid_saturation_keeps_direction_and_limits():
    pid = PathPID(VMAX, WMAX, DT)
    out = pid.update(np.zeros(3), np.array([3.0, 1.0, 2.0]), np.zeros(3))  # huge error
    assert abs(out[0]) == pytest.approx(VMAX) and abs(out[1]) < VMAX and abs(out[2]) == pytest.approx(WMAX)
    # Direction of the 3:1 world error kept (body frame at the mid-period heading ω·dt/2 = 0.015 rad).
    mid = 0.5 * WMAX * DT
    world = np.array([math.cos(mid) * out[0] - math.sin(mid) * out[1], math.sin(mid) * out[0] + math.cos(mid) * out[1]])
    assert world[1] / world[0] == pytest.approx(1.0 / 3.0, rel=1e-9)
    assert pid.saturated.all()


def test_pid_anti_windup_integral_stops_growing_under_saturation():
    """Integrators hold while the output is saturated by their error, unwind when the error reverses."""
    e_small, e_big = np.array([0.05, 0.0, 0.05]), np.array([2.0, 0.0, 2.0])
    pid, raw = PathPID(VMAX, WMAX, DT), PathPID(VMAX, WMAX, DT, anti_windup=False)
    for p in (pid, raw):
        for _ in range(20):  # unsaturated: both integrate Ki·e·dt per step
            p.update(np.zeros(3), e_small, np.zeros(3))
    assert not pid.saturated.any()
    before = pid.integral.copy()
    np.testing.assert_allclose(before[[0, 2]], [20 * 2.0 * 0.05 * DT, 20 * 3.0 * 0.05 * DT])
    for _ in range(500):  # 5 s deep in saturation
        pid.update(np.zeros(3), e_big, np.zeros(3))
        raw.update(np.zeros(3), e_big, np.zeros(3))
    assert pid.saturated.all()
    np.testing.assert_array_equal(pid.integral, before)  # frozen: not a single step integrated
    assert raw.integral[0] > 10 * before[0] and raw.integral[2] > 10 * before[2]  # without: winds up
    # Saturated by a large feed-forward while the error points back: that error integrates (unwinds).
    pid.update(np.zeros(3), -e_small, np.array([5.0, 0.0, 10.0]))
    assert pid.saturated.all()
    np.testing.assert_allclose(pid.integral[[0, 2]], before[[0, 2]] - [2.0 * 0.05 * DT, 3.0 * 0.05 * DT])


def test_pid_derivative_filtered_without_kick():
    gains = PIDGains(kp_pos=0, ki_pos=0, kd_pos=1.0, kp_head=0, ki_head=0, kd_head=0, d_tau=0.05)
    pid = PathPID(VMAX, WMAX, DT, gains)
    out = pid.update(np.zeros(3), np.array([0.2, 0.0, 0.0]), np.zeros(3))
    assert np.all(out == 0)  # first step after reset: no derivative kick from the initial error
    # Error growing at 0.1 m/s: the filtered derivative approaches 0.1 as 1 − exp(−t/τ) (discretised).
    for k in range(1, 51):
        out = pid.update(np.zeros(3), np.array([0.2 + 0.1 * k * DT, 0.0, 0.0]), np.zeros(3))
        if k == 1:
            assert out[0] == pytest.approx(0.1 * DT / (0.05 + DT))  # one filter step, not the raw rate
    assert out[0] == pytest.approx(0.1, rel=0.01)  # 10 time constants later


# --- policies on the environment -------------------------------------------------------------------


def test_feed_forward_alone_tracks_a_straight_line_on_grip():
    """Open-loop (feed-forward only) on the no-slip floor follows the 'line' reference.

    Bound: commands are held over each 10 ms period but taken from the reference velocity at its start,
    a zero-order-hold lag of at most v_peak·dt/2 = 0.47 m/s · 5 ms ≈ 2.3 mm while moving (measured
    2.6 mm including the grip floor's tiny slip); it vanishes when the reference stops. A sign, frame or
    scaling error would show as centimetres to metres over the 1.75 m line.
    """
    env = make_env(ENV, {**NO_SLIP, "trajectory": "line", "episode_seconds": 8.0})
    ep = run_episode(env, make_policy("open-loop", env), seed=3, record=True)
    err = np.hypot(*(ep.pose[:, :2] - ep.reference[:, :2]).T)
    path = np.sum(np.hypot(*np.diff(ep.reference[:, :2], axis=0).T))
    assert path > 1.5
    assert err.max() < 0.004
    assert ep.final_position_error < 0.001 and ep.final_heading_error < 0.002 and ep.success


def test_odometry_on_grip_with_noiseless_sensors_stays_within_millimetres():
    """Dead reckoning against the truth on the no-slip floor with sensor_noise=0, over ~2 m of waypoints.

    Encoder quantisation (2048 counts/rev) bounds the position error from each wheel at one count of
    arc, 2π/2048 · 0.05 m = 0.15 mm, without accumulating (the rates are differences of quantised
    angles); the remaining error is the grip floor's slip and the end-of-period twist model. Measured
    ≤ 0.6 mm, 0.2 mrad; the bounds (2 mm, 1 mrad) fail on e.g. the trapezoidal gyro average (a
    3 mrad heading lag) or a wrong frame.
    """
    env = make_env(ENV, {**NO_SLIP, "sensor_noise": 0.0, "episode_seconds": 8.0})
    ep = run_episode(env, make_policy("odometry-pid", env), seed=2, record=True)
    assert np.sum(np.hypot(*np.diff(ep.pose[:, :2], axis=0).T)) > 1.5
    pos = np.hypot(*(ep.pose[:, :2] - ep.estimate[:, :2]).T)
    head = np.abs((ep.pose[:, 2] - ep.estimate[:, 2] + math.pi) % (2 * math.pi) - math.pi)
    assert pos.max() < 0.002 and head.max() < 0.001


def test_odometry_tracks_the_gyro_offset_at_rest_points():
    """The zero-rate offset, refined near the reference's rest points, ends closer to the true bias.

    At reset the offset is one reading (error ~ the 0.005 rad/s white noise). Encoder quantisation
    (2048 counts/rev, at most one count per wheel per rest window of ~0.5 s, i.e. ≈0.002 rad/s of yaw
    rate per window) limits the refinement; over a 20 s path with ~5 rest windows the RMS error is
    measured at 0.0006 rad/s against 0.0037 at reset (12 seeds), so we ask for less than half.
    """
    env = make_env(ENV, NO_SLIP)
    policy = make_policy("odometry-pid", env)
    at_reset, at_end = [], []
    for seed in range(12):
        obs, _ = env.reset(seed=seed)
        policy.reset(obs)
        bias = env.unwrapped.core.sensors.gyro_bias[0]  # ground truth, read by the test only
        at_reset.append(policy.gyro_offset - bias)
        while True:
            obs, _, terminated, truncated, _ = env.step(policy.act(obs))
            if terminated or truncated:
                break
        at_end.append(policy.gyro_offset - env.unwrapped.core.sensors.gyro_bias[0])
    rms = lambda e: math.sqrt(np.mean(np.square(e)))  # noqa: E731
    assert rms(at_end) < 0.5 * rms(at_reset)
    assert rms(at_end) < 0.0015  # below one count per wheel over the shortest rest window


@pytest.mark.parametrize("name", POLICY_NAMES)
def test_policies_give_valid_actions_and_are_deterministic(name):
    env = make_env(ENV, {"episode_seconds": 1.0})
    policy = make_policy(name, env)
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=11)
        policy.reset(obs)
        actions, observations = [], []
        done = False
        while not done:
            a = policy.act(obs)
            assert a.dtype == np.float32 and a.shape == env.action_space.shape and np.all(np.abs(a) <= 1)
            actions.append(a)
            observations.append(obs)
            obs, _, term, trunc, _ = env.step(a)
            done = term or trunc
        runs.append((np.array(actions), np.array(observations)))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    # A fresh policy fed the same observations acts the same: it depends on nothing else.
    fresh = make_policy(name, env)
    fresh.reset(runs[0][1][0])
    np.testing.assert_array_equal(np.array([fresh.act(o) for o in runs[0][1]]), runs[0][0])


def test_make_policy_rejects_bad_input():
    with pytest.raises(ValueError, match="unknown policy"):
        make_policy("pid", make_env(ENV))
    import gymnasium as gym

    with pytest.raises(ValueError, match="obs_mode='sensors'"):
        make_policy("open-loop", gym.make(ENV))


# --- evaluate() -----------------------------------------------------------------------------------


def test_evaluate_is_deterministic_for_a_seed():
    kw = {"episode_seconds": 2.0}
    a = evaluate("ekf-pid", ENV, 3, 5, kw, progress=False)
    b = evaluate("ekf-pid", ENV, 3, 5, kw, progress=False)
    assert a == b
    assert a["seeds"] == [5, 7] and a["per_episode"]["seed"] == [5, 6, 7]
    c = evaluate("ekf-pid", ENV, 3, 6, kw, progress=False)  # shifted seeds: episodes 6, 7 shared
    assert c["per_episode"]["final_position_error"][:2] == a["per_episode"]["final_position_error"][1:]
    assert c != a


def test_episodes_longer_than_the_registered_limit_run_to_the_end():
    """OmniGoToPose-v0 registers 800 steps; episode_seconds=9 must give 900, not a TimeLimit cut at 800."""
    env = make_env("omni_gym:OmniGoToPose-v0", {"episode_seconds": 9.0})
    ep = run_episode(env, make_policy("open-loop", env), seed=0)
    assert ep.steps == 900 and not ep.terminated


def test_confidence_intervals():
    # Wilson score intervals, by hand: (p + z²/2n ± z·√(p(1−p)/n + z²/4n²)) / (1 + z²/n), z = 1.96.
    np.testing.assert_allclose(wilson_ci(0, 10), [0.0, 0.2775], atol=1e-4)
    np.testing.assert_allclose(wilson_ci(5, 10), [0.2366, 0.7634], atol=1e-4)
    np.testing.assert_allclose(wilson_ci(10, 10), [0.7225, 1.0], atol=1e-4)
    x = np.array([0.1, 0.4, 0.2, 0.3, 0.25])
    r = mean_ci(x)
    lo, hi = stats.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=stats.sem(x))
    assert r["mean"] == pytest.approx(0.25) and r["ci95"] == pytest.approx([lo, hi])
    assert mean_ci(np.array([0.3]))["ci95"] is None


def test_error_intervals_never_negative():
    """Errors are >= 0: a skewed sample (nine small errors, one lost episode) gives a Student-t interval
    below zero, the bootstrap percentile interval of ``evaluate`` stays inside [min, max] of the data."""
    x = np.array([0.001] * 9 + [1.0])
    assert mean_ci(x)["ci95"][0] < 0  # the defect: a negative bound for an error
    r = bootstrap_ci(x)
    lo, hi = r["ci95"]
    assert x.min() <= lo <= r["mean"] <= hi <= x.max()
    assert r["std"] == pytest.approx(np.std(x, ddof=1))
    assert bootstrap_ci(x) == r  # fixed-seed resampling: a function of the data
    assert bootstrap_ci(np.array([0.3]))["ci95"] is None
    eps = [Episode(seed=i, tracking_rmse=v, final_position_error=v, final_heading_error=v, success=False,
                   terminated=False, steps=1) for i, v in enumerate(x)]
    for m in ("tracking_rmse", "final_position_error", "final_heading_error"):
        assert summarize(eps)[m]["ci95"][0] >= 0
        # The benchmark tables keep their Student-t intervals (their headers say so; their commands reproduce them).
        assert summarize(eps, interval="t")[m] == mean_ci(x)
    with pytest.raises(ValueError, match="interval"):
        summarize(eps, interval="normal")


def test_bootstrap_interval_coverage():
    """The interval covers the true mean at about its nominal 95 %: 400 samples of 30 exponential values
    (skewed, like tracking errors). The percentile bootstrap's known coverage here is about 92-93 %; with
    400 trials the binomial std is 1.3 %, so [0.85, 0.99] fails only for a wrong interval (e.g. a 68 % one
    covers about 67 %)."""
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(400):
        lo, hi = bootstrap_ci(rng.exponential(1.0, size=30), resamples=2000)["ci95"]
        hits += lo <= 1.0 <= hi
    assert 0.85 <= hits / 400 <= 0.99


# --- command line ---------------------------------------------------------------------------------


def test_cli_evaluate_json():
    proc = subprocess.run([sys.executable, "-m", "omni_gym.cli", "evaluate", "--policy", "open-loop", "--env", ENV,
                           "--episodes", "2", "--seed", "0", "--env-kwargs", '{"episode_seconds": 1.0}', "--json"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    for key in ("policy", "env_id", "env_kwargs", "episodes", "seeds", "tracking_rmse", "final_position_error",
                "final_heading_error", "success_rate", "terminated_rate", "per_episode"):
        assert key in data
    assert data["env_kwargs"] == {"episode_seconds": 1.0} and data["episodes"] == 2
    for m in ("tracking_rmse", "final_position_error", "final_heading_error"):
        lo, hi = data[m]["ci95"]
        assert lo <= data[m]["mean"] <= hi
    assert 0 <= data["success_rate"]["ci95"][0] <= data["success_rate"]["mean"] <= data["success_rate"]["ci95"][1]


def test_cli_evaluate_table(capsys):
    assert main(["evaluate", "--policy", "odometry-pid", "--env", "OmniGoToPose-v0", "--episodes", "2", "--seed", "0",
                 "--env-kwargs", '{"episode_seconds": 1.0}']) == 0
    out = capsys.readouterr().out
    for label in ("tracking_rmse", "final_position_error", "final_heading_error", "success rate", "95% CI"):
        assert label in out


BAD_CLI = {
    "unknown_policy": (["--policy", "pid", "--env", ENV, "--episodes", "1", "--seed", "0"], "unknown policy 'pid'"),
    "missing_model": (["--policy", "no/such/model.zip", "--env", ENV, "--episodes", "1", "--seed", "0"],
                      "no/such/model.zip"),
    "bad_json": (["--policy", "open-loop", "--env", ENV, "--episodes", "1", "--seed", "0", "--env-kwargs", "{x"],
                 "--env-kwargs: not valid JSON"),
    "json_not_object": (["--policy", "open-loop", "--env", ENV, "--episodes", "1", "--seed", "0", "--env-kwargs",
                         "[1]"], "must be a JSON object"),
    "unknown_env": (["--policy", "open-loop", "--env", "NoSuchEnv-v0", "--episodes", "1", "--seed", "0"],
                    "unknown environment id 'NoSuchEnv-v0'"),
    "not_omni_env": (["--policy", "open-loop", "--env", "CartPole-v1", "--episodes", "1", "--seed", "0"],
                     "not an omni-gym environment"),
    "zero_episodes": (["--policy", "open-loop", "--env", ENV, "--episodes", "0", "--seed", "0"],
                      "--episodes must be an integer in [1, 100000], got 0"),
    "negative_seed": (["--policy", "open-loop", "--env", ENV, "--episodes", "1", "--seed", "-1"],
                      "--seed must be an integer in [0, 9007199254740992], got -1"),
    "bad_env_kwarg": (["--policy", "open-loop", "--env", ENV, "--episodes", "1", "--seed", "0", "--env-kwargs",
                       '{"surface": "ice"}'], "invalid surface='ice'"),
    "state_obs": (["--policy", "ekf-pid", "--env", ENV, "--episodes", "1", "--seed", "0", "--env-kwargs",
                   '{"obs_mode": "state"}'], "obs_mode='sensors'"),
}


@pytest.mark.parametrize("case", sorted(BAD_CLI))
def test_cli_evaluate_bad_input_one_line_exit_2(case, capsys):
    args, expected = BAD_CLI[case]
    assert main(["evaluate", *args]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("omni-gym: error: ") and expected in lines[0], captured.err
    assert captured.out == ""


# --- the baselines under slip and lift-off ----------------------------------------------------------

# Paired design: the same seed gives every policy the same reference, lift-off schedule and sensor
# noise, so per-seed differences cancel the episode-to-episode spread (which is large: whether a wheel
# lifts near the end decides much of the final error). One-sided Wilcoxon signed-rank test, α = 0.01.
# Count: 30 episodes of 8 s. A pilot on seeds 90 000–90 039 (not used here) gave ekf-pid a lower final
# error than odometry-pid / open-loop on 93 % / 90 % of seeds; bootstrap resamples of 30 of those
# pilot episodes gave p < 0.01 in 100 % of 2000 draws (99th percentile of p: 8e-5 and 3e-4), so the
# verdict does not hinge on the seeds. Runtime ≈ 30 × (0.25 + 0.25 + 0.65) s ≈ 35 s on one core.
STAT_EPISODES, STAT_SEED, STAT_SECONDS = 30, 1000, 8.0
ALPHA = 0.01


@functools.cache
def _final_errors(policy: str) -> np.ndarray:
    r = evaluate(policy, ENV, STAT_EPISODES, STAT_SEED, {"episode_seconds": STAT_SECONDS}, progress=False)
    return np.array(r["per_episode"]["final_position_error"])


def test_ekf_pid_beats_odometry_pid_and_open_loop_under_slip_and_liftoff():
    """OmniPathFollow-Phunopas-v0 defaults (carpet, roller-gap friction, lift-off 0.5 /s), 8 s episodes."""
    ekf, odo, ol = _final_errors("ekf-pid"), _final_errors("odometry-pid"), _final_errors("open-loop")
    for other, name in ((odo, "odometry-pid"), (ol, "open-loop")):
        p = stats.wilcoxon(ekf, other, alternative="less").pvalue
        assert p < ALPHA, f"ekf-pid vs {name}: p = {p:.3g}, medians {np.median(ekf):.4f} vs {np.median(other):.4f}"
        assert np.median(ekf) < 0.5 * np.median(other)  # and by a margin that matters, not just significantly


@pytest.mark.xfail(strict=True, reason=(
    "odometry-pid does not beat open-loop here: the wheels are velocity-controlled, so the encoders read the "
    "commanded wheel speeds whether a wheel grips, slips or hangs in the air; encoder odometry integrates the "
    "commands (what open-loop assumes) and cannot see the translational slip that dominates the final error. "
    "Its only extra information is the gyro heading (offset refined at rest points): it cuts the final heading "
    "error (0.052 -> 0.038 rad, 100 seeds) but not the position error (0.163 vs 0.169 m, Wilcoxon p = 0.72). "
    "strict: if this starts passing, the sensors, actuation or policy changed and the baseline report needs a look."))
def test_odometry_pid_beats_open_loop_under_slip_and_liftoff():
    p = stats.wilcoxon(_final_errors("odometry-pid"), _final_errors("open-loop"), alternative="less").pvalue
    assert p < ALPHA, f"p = {p:.3g}"
