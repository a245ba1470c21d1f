"""The batched estimation and control stack (agents/batched/) against the single-robot reference classes.

Every test runs the single classes robot by robot and the batched ones on all robots together, on
real environment episodes (sensors observations, slip, lift-off on the Phunopas robot and on the
four-wheel mecanum robot, the 3-wheel Williams robot), with robots that reset at different steps.

Tolerances: the batched EKF computes the same formulas as OmniEKF but multiplies its small matrices
with explicit loops (numpy: BLAS, another summation order, fused multiply-adds), inverts and
factorises through Cholesky/LDLᵀ (numpy: LU) and regroups the Joseph-form products; each operation
differs in the last bit (relative ~1e-16) and the filter's own contraction keeps the differences from
growing (measured: at most 1.3e-12 over 1000-step episodes). We allow 1e-9, three orders above what
we measure and far below anything that changes a gate or a hysteresis decision, which are compared
exactly. The PID and the policies are element-wise numpy in the same order as the single classes;
only numpy's vectorised cos/sin/arctan2 may differ from the math module's by an ulp, so they get
1e-12 (float64) and, for float32 outputs, 1e-6 (one float32 rounding step near 1 is 6e-8, a flipped
rounding of a value at the features' scale of 10 is 1e-6).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv, VectorEnv

import omni_gym  # noqa: F401  (registers the environments)
from agents.batched import BatchEKF, BatchPathPID, BatchSlipDetector, robot_mask
from agents.batched.policies import VECTOR_POLICY_NAMES, make_vector_policy
from agents.ekf import EKFConfig, OmniEKF
from agents.pid import PathPID
from agents.policies import make_policy
from agents.slip_detector import SlipDetector
from agents.wrappers import EKFFeatures, VectorEKFFeatures
from omni_gym.envs.observations import BatchSensorObsDecoder, SensorObsDecoder

PHUNOPAS = "OmniPathFollow-Phunopas-v0"  # 4 wheels, slip and lift-off
WILLIAMS = "OmniPathFollow-WilliamsPaper-v0"  # 3 wheels, slip
MECANUM = "OmniPathFollow-Mecanum-v0"  # 4 mecanum wheels, slip and lift-off
# Phunopas and WilliamsPaper in `make test-slow` (which CI runs): each costs 30-40 s of `make test`'s 7-minute
# budget on a fresh clone (a cold compile cache); Mecanum (four wheels, slip and lift-off, angled rollers) keeps
# the equivalence in `make test`.
ROBOT_IDS = [pytest.param(PHUNOPAS, marks=pytest.mark.slow), pytest.param(WILLIAMS, marks=pytest.mark.slow), MECANUM]
EKF_TOL = 1e-9  # module docstring: measured differences <= 1.3e-12
PID_TOL = 1e-12  # module docstring: vectorised cos/sin against math's
F32_TOL = 1e-6  # module docstring: float32 outputs


# --- recorded episodes -----------------------------------------------------------------------


def _record(env_id: str, seed: int, steps: int, fault: str) -> tuple[list[np.ndarray], object]:
    """One episode of ``steps`` sensor observations under noisy ekf-pid actions, with a sensor fault.

    Faults force the filter's gates and re-acquisitions: "compass" turns the compass by 1 rad from step
    40 on, "camera" moves the camera fixes by 0.3 m from step 60 on, "gyro" adds 8 rad/s to the gyro for
    steps 30–34, "none" leaves the sensors alone.
    """
    env = gym.make(env_id, obs_mode="sensors")
    policy = make_policy("ekf-pid", env)
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    policy.reset(obs)
    L = env.unwrapped.observation_layout
    sc = env.unwrapped.obs_scales
    out = [obs]
    for t in range(1, steps):
        a = np.clip(policy.act(out[-1]) + rng.normal(0.0, 0.3, 3), -1, 1).astype(np.float32)
        obs, _, terminated, truncated, _ = env.step(a)
        obs = obs.copy()
        if fault == "compass" and t >= 40:
            i = L.starts["compass_sin_cos"]
            th = math.atan2(obs[i], obs[i + 1]) + 1.0
            obs[i], obs[i + 1] = math.sin(th), math.cos(th)
        if fault == "camera" and t >= 60:
            obs[L.starts["camera_fix"]] += 0.3 / sc.arena_half_size
        if fault == "gyro" and 30 <= t < 35:
            obs[L.starts["gyro"]] += 8.0 / sc.max_yaw_rate
        out.append(obs)
        if terminated or truncated:
            break
    return out, env


@pytest.fixture(scope="module", params=ROBOT_IDS)
def streams(request):
    """Per robot a list of episodes (observation lists): 4 robots whose episodes end at different steps."""
    env_id = request.param
    plan = [[(11, 170, "compass"), (12, 90, "none")], [(13, 120, "camera"), (14, 150, "gyro")],
            [(15, 260, "none")], [(16, 60, "gyro"), (17, 80, "camera"), (18, 70, "none")]]
    robots, env = [], None
    for episodes in plan:
        eps = []
        for seed, steps, fault in episodes:
            obs, env = _record(env_id, seed, steps, fault)
            eps.append(obs)
        robots.append(eps)
    return env_id, env, robots


def test_batch_ekf_matches_single_filters(streams):
    env_id, env, robots = streams
    cfg = EKFConfig.for_env(env)
    robot = env.unwrapped.robot
    decode = SensorObsDecoder.for_env(env)
    bdecode = BatchSensorObsDecoder.for_env(env)
    M = len(robots)
    flat = [[(k == 0, o) for ep in eps for k, o in enumerate(ep)] for eps in robots]  # (starts episode, obs)
    T = max(len(f) for f in flat)
    singles = [OmniEKF(robot, cfg) for _ in range(M)]
    batch = BatchEKF(robot, M, cfg)
    seen = {"gyro_reject": 0, "compass_reacquire": 0, "camera_reacquire": 0, "wheel_dropped": 0, "resets": 0}
    gates = singles[0]._gates
    last = [f[0][1] for f in flat]
    for t in range(T):
        starting = np.zeros(M, dtype=bool)
        active = np.zeros(M, dtype=bool)
        for i in range(M):
            if t < len(flat[i]):
                start, o = flat[i][t]
                last[i] = o
                starting[i], active[i] = start, not start
        obs = np.stack(last)
        if starting.any():
            poses = np.stack([decode(obs[i]).ref_pose for i in range(M)])
            batch.reset(starting, poses[starting])
            seen["resets"] += int(starting.sum())
        for i in np.flatnonzero(starting):
            singles[i].reset(decode(obs[i]).ref_pose)
        batch.process(bdecode(obs), 0.01, active)
        for i in np.flatnonzero(active):
            f = singles[i]
            f.process(decode(obs[i]), 0.01)
            seen["gyro_reject"] += f.step_nis["gyro"] > gates["gyro"] and f._rejections["gyro"] > 0
            for name in ("compass", "camera"):
                seen[f"{name}_reacquire"] += f.step_nis.get(name, 0.0) > gates[name] and f._rejections[name] == 0
            seen["wheel_dropped"] += int((~f.wheel_ok).sum())
            nis = [f.step_nis.get(k, np.nan) for k in ("accel", "gyro", "compass", "camera", "wheels_joint")]
            np.testing.assert_allclose(batch.step_nis[i], nis, rtol=EKF_TOL, atol=EKF_TOL, equal_nan=True)
        for i in np.flatnonzero(active | starting):
            f = singles[i]
            np.testing.assert_allclose(batch.x[i], f.x, rtol=EKF_TOL, atol=EKF_TOL, err_msg=f"robot {i} step {t}")
            np.testing.assert_allclose(batch.P[i], f.P, rtol=EKF_TOL, atol=EKF_TOL, err_msg=f"robot {i} step {t}")
            np.testing.assert_allclose(batch.wheel_belief[i], f.wheel_belief, atol=EKF_TOL)
            assert np.array_equal(batch.wheel_ok[i], f.wheel_ok), (i, t)
            assert np.array_equal(batch.wheels_used[i], f.wheels_used), (i, t)
    # The episodes exercised what they are meant to: resets at different steps, gate rejections,
    # re-acquisitions and wheels the detector dropped.
    assert seen["resets"] == sum(len(eps) for eps in robots)
    assert all(v > 0 for v in seen.values()), seen


@pytest.mark.parametrize("env_id", [PHUNOPAS, MECANUM])
def test_batch_slip_detector_matches_single(env_id):
    """Random innovations (slips of several σ on random wheels) through both detectors, robot by robot."""
    robot = gym.make(env_id).unwrapped.robot
    W = robot.wheel_matrix()
    rng = np.random.default_rng(2)
    M, n = 5, W.shape[0]
    singles = [SlipDetector(W, robot.wheel_radius, 0.125) for _ in range(M)]
    batch = BatchSlipDetector(M, W, robot.wheel_radius, 0.125)
    S = np.stack([W @ np.diag([1e-3, 1e-3, 1e-2]) @ W.T + 0.125**2 * np.eye(n)] * M)
    for t in range(200):
        nu = rng.normal(0.0, 0.15, (M, n)) + (rng.random((M, n)) < 0.1) * rng.normal(0, 3.0, (M, n))
        active = rng.random(M) < 0.8
        if t == 100:
            batch.reset([1, 3])
            singles[1].reset()
            singles[3].reset()
        ok = batch.step(nu, S, 0.01, active)
        for i in np.flatnonzero(active):
            singles[i].step(np.zeros(n), nu[i], S[i], 0.0, 1.0, 0.01)
        for i in range(M):
            np.testing.assert_allclose(batch.belief[i], singles[i].belief, atol=EKF_TOL)
            assert np.array_equal(ok[i], singles[i].ok)


def test_batch_pid_matches_single():
    """Random estimates and references (saturating some steps), robots reset at different steps."""
    rng = np.random.default_rng(3)
    M = 6
    singles = [PathPID(0.6, 3.0, 0.01) for _ in range(M)]
    batch = BatchPathPID(M, 0.6, 3.0, 0.01)
    for t in range(300):
        pose = rng.normal(0, 1.0, (M, 3))
        ref = pose + rng.normal(0, 0.1 if t % 50 < 40 else 1.0, (M, 3))  # large errors saturate
        vel = rng.normal(0, 0.3, (M, 3))
        resetting = rng.random(M) < 0.02
        batch.reset(resetting)
        robots = rng.random(M) < 0.9
        out = batch.update(pose, ref, vel, robots)
        for i in range(M):
            if resetting[i]:
                singles[i].reset()
            if robots[i]:
                np.testing.assert_allclose(out[i], singles[i].update(pose[i], ref[i], vel[i]), rtol=PID_TOL,
                                           atol=PID_TOL)
            np.testing.assert_allclose(batch.integral[i], singles[i].integral, rtol=PID_TOL, atol=PID_TOL)
            assert np.array_equal(batch.saturated[i], singles[i].saturated)
    assert batch.saturated.any()


# --- vector policies -------------------------------------------------------------------------

def _run_policy_pair(env_id: str, name: str, num: int, steps: int, limiter=None, single_limit=None):
    """Vector policy on the native vector env vs single policies on single envs; returns the worst differences.

    A small ``lost_distance`` and noisy actions end episodes at different steps (NEXT_STEP autoreset).
    """
    kw = dict(obs_mode="sensors", lost_distance=0.08, max_episode_steps=150)
    venv = gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point", **kw)
    envs = [gym.make(env_id, **kw) for _ in range(num)]
    singles = [make_policy(name, e) for e in envs]
    policy = make_vector_policy(name, venv, limiter=limiter)
    obs, _ = venv.reset(seed=21)
    single_obs = [e.reset(seed=21 + i)[0] for i, e in enumerate(envs)]
    policy.reset(obs)
    for p, o in zip(singles, single_obs, strict=True):
        p.reset(o)
    rng = np.random.default_rng(4)
    autoreset = np.zeros(num, dtype=bool)
    worst, ends = 0.0, set()
    for t in range(steps):
        actions = policy.act(obs)
        single_actions = np.array([p.act(o) for p, o in zip(singles, single_obs, strict=True)])
        if single_limit is not None:
            single_actions = single_limit(single_actions)
        worst = max(worst, float(np.abs(actions - single_actions).max()))
        if policy.estimate is not None:
            est = np.array([p.estimate for p in singles])
            worst = max(worst, float(np.abs(policy.estimate - est).max()))
        sent = np.clip(single_actions + rng.normal(0, 0.4, single_actions.shape), -1, 1).astype(np.float32)
        obs, _, terminated, truncated, _ = venv.step(sent)
        for i in range(num):
            if autoreset[i]:
                single_obs[i] = envs[i].reset()[0]
                singles[i].reset(single_obs[i])
            else:
                single_obs[i] = envs[i].step(sent[i])[0]
        np.testing.assert_array_equal(obs, np.array(single_obs))  # the vector env reproduces the singles
        if autoreset.any():
            policy.reset(obs, autoreset)
        autoreset = terminated | truncated
        if autoreset.any():
            ends.add(t)
    return worst, ends


@pytest.mark.parametrize("env_id", [PHUNOPAS, WILLIAMS, MECANUM])
@pytest.mark.parametrize("name", VECTOR_POLICY_NAMES)
def test_vector_policies_match_single_policies(env_id, name):
    worst, ends = _run_policy_pair(env_id, name, 3, 250)
    assert worst <= F32_TOL
    assert len(ends) >= 2  # episodes ended at two different steps at least


def test_limiter_hook_changes_the_twist():
    """A limiter halving every twist halves the actions (open-loop: twist / scale, no feedback)."""
    calls = []

    def halve(twist, estimate, policy):
        calls.append((twist.shape, estimate.shape))
        return 0.5 * twist

    worst, _ = _run_policy_pair(WILLIAMS, "open-loop", 2, 30, limiter=halve,
                                single_limit=lambda a: (0.5 * a.astype(float)).astype(np.float32))
    assert worst <= F32_TOL
    assert calls and all(c == ((2, 3), (2, 3)) for c in calls)


# --- vector EKF-feature wrapper -----------------------------------------------------------------

KW = dict(obs_mode="sensors", action_mode="twist", lost_distance=0.06, max_episode_steps=100)


class _SameStepVectorEnv(VectorEnv):
    """A SAME_STEP vector env over single envs (Gymnasium's SyncVectorEnv) with the attributes the
    policies read from the native vector env (cfg, robot, kinematics, layout, scales)."""

    def __init__(self, env_id: str, num: int) -> None:
        self.sync = SyncVectorEnv([lambda: gym.make(env_id, **KW) for _ in range(num)],
                                  autoreset_mode=AutoresetMode.SAME_STEP)
        self.num_envs = num
        self.single_observation_space = self.sync.single_observation_space
        self.observation_space = self.sync.observation_space
        self.single_action_space = self.sync.single_action_space
        self.action_space = self.sync.action_space
        self.metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}
        u = self.sync.envs[0].unwrapped
        for key in ("cfg", "robot", "wheel_kinematics", "observation_layout", "obs_scales", "wheel_scale"):
            setattr(self, key, getattr(u, key))

    def reset(self, *, seed=None, options=None):
        return self.sync.reset(seed=seed, options=options)

    def step(self, actions):
        return self.sync.step(actions)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("reward", ["env", "tracking", "squared"])
def test_vector_ekf_features_match_single_wrappers(mode, reward):
    num, env_id = 3, PHUNOPAS
    if mode == AutoresetMode.NEXT_STEP:
        inner = gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point", **KW)
    else:
        inner = _SameStepVectorEnv(env_id, num)
    vec = VectorEKFFeatures(inner, residual_scale=0.8, reward=reward)
    ref = SyncVectorEnv([lambda: EKFFeatures(gym.make(env_id, **KW), 0.8, reward) for _ in range(num)],
                        autoreset_mode=mode)
    o1, _ = vec.reset(seed=7)
    o2, _ = ref.reset(seed=7)
    np.testing.assert_allclose(o1, o2, atol=F32_TOL)
    assert vec.observation_space.shape == ref.observation_space.shape
    rng = np.random.default_rng(5)
    terminations, ends = 0, set()
    for t in range(220):
        a = rng.uniform(-1, 1, (num, 3)).astype(np.float32)
        o1, r1, te1, tr1, i1 = vec.step(a)
        o2, r2, te2, tr2, i2 = ref.step(a)
        np.testing.assert_allclose(o1, o2, atol=F32_TOL, err_msg=f"step {t}")
        np.testing.assert_allclose(r1, r2, rtol=PID_TOL, atol=PID_TOL)
        assert np.array_equal(te1, te2) and np.array_equal(tr1, tr2)
        done = te1 | tr1
        terminations += int(te1.sum())
        if done.any():
            ends.add(t)
        if mode == AutoresetMode.SAME_STEP and done.any():
            assert np.array_equal(i1["_final_obs"], i2["_final_obs"])
            np.testing.assert_allclose(i1["final_obs"][done], np.stack(list(i2["final_obs"][done])), atol=F32_TOL)
    assert terminations >= 2 and len(ends) >= 3  # robots ended (lost, time limit) at different steps


# --- bad input ---------------------------------------------------------------------------------

def test_bad_input_raises_one_line_value_errors():
    robot = gym.make(WILLIAMS).unwrapped.robot
    with pytest.raises(ValueError, match="num must be a positive integer"):
        BatchEKF(robot, 0)
    ekf = BatchEKF(robot, 3)
    with pytest.raises(ValueError, match="poses must have shape"):
        ekf.reset(None, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="robot indices"):
        robot_mask([5], 3)
    with pytest.raises(ValueError, match="robot mask must have shape"):
        robot_mask(np.ones(2, dtype=bool), 3)
    venv = gym.make_vec(WILLIAMS, num_envs=2, vectorization_mode="vector_entry_point", obs_mode="sensors")
    with pytest.raises(ValueError, match="must have shape"):
        BatchSensorObsDecoder.for_env(venv)(np.zeros((2, 5)))
    with pytest.raises(ValueError, match="unknown vector policy"):
        make_vector_policy("nope", venv)
    with pytest.raises(ValueError, match="obs_mode='sensors'"):
        make_vector_policy("ekf-pid", gym.make_vec(WILLIAMS, num_envs=2, vectorization_mode="vector_entry_point"))
