"""Gymnasium environments: API checkers, determinism, pickling, vectorisation, validation, episode semantics.

Every comparison between two runs that should be identical (same seed, pickled copy, subprocess, native
vector vs single environments, clipped vs out-of-range actions) is exact: the environments promise bit-for-bit
reproduction, so any tolerance would hide a real defect.
"""

from __future__ import annotations

import functools
import math
import pickle
import re
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

import omni_gym
from omni_gym.envs.observations import LOOK_SCALE, POS_SCALE
from omni_gym.physics.friction import SURFACES
from omni_gym.physics.layout import SP_MASS, WP_MUW
from omni_gym.physics.liftoff import contact_cases

WILLIAMS = "OmniPathFollow-WilliamsPaper-v0"
PHUNOPAS = "OmniPathFollow-Phunopas-v0"
GOTO = "OmniGoToPose-v0"
MECANUM = "OmniPathFollow-Mecanum-v0"  # optiodom_omni4: four mecanum wheels, lift-off as PHUNOPAS
IDS = (WILLIAMS, PHUNOPAS, MECANUM, GOTO)
CUSTOM = "OmniPathFollow-Custom-v0"
# "My robot": five wheels on paper with a calibrated lift-off (the custom id takes everything from it).
CUSTOM_MODEL = omni_gym.load_model("regular5", surface="paper").with_effect(
    "wheel_liftoff", {"lift_rate": 5.0, "recover_rate": 5.0}).to_json()
ID_KWARGS = {CUSTOM: {"model": CUSTOM_MODEL}}  # keywords an id cannot be made without
RANDOMIZE = {"randomize_friction": (0.7, 1.3), "randomize_mass": (0.8, 1.2), "randomize_lift_rate": (0.0, 2.0),
             "randomize_sensor_noise": (0.5, 2.0)}
INFO_KEYS = {"pose", "velocity", "reference_pose", "tracking_error", "heading_error", "slip", "contact", "collided",
             "is_success"}


# --- helpers -------------------------------------------------------------------------------------


def random_actions(env: gym.Env, n: int, seed: int, scale: float = 1.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (scale * rng.uniform(-1.0, 1.0, size=(n, *env.action_space.shape))).astype(np.float32)


def assert_info_equal(a: dict, b: dict, where: str) -> None:
    assert a.keys() == b.keys(), f"{where}: info keys {sorted(a)} != {sorted(b)}"
    for key in a:
        assert np.array_equal(a[key], b[key]), f"{where}: info[{key!r}] {a[key]!r} != {b[key]!r}"


def assert_record_equal(a: tuple, b: tuple, where: str) -> None:
    """Records are (obs, reward, terminated, truncated, info); compared exactly."""
    obs_a, rew_a, term_a, trunc_a, info_a = a
    obs_b, rew_b, term_b, trunc_b, info_b = b
    assert obs_a.dtype == obs_b.dtype, where
    assert np.array_equal(obs_a, obs_b), f"{where}: observations differ\n{obs_a}\n{obs_b}"
    assert rew_a == rew_b, f"{where}: reward {rew_a!r} != {rew_b!r}"
    assert (term_a, trunc_a) == (term_b, trunc_b), f"{where}: flags {(term_a, trunc_a)} != {(term_b, trunc_b)}"
    assert_info_equal(info_a, info_b, where)


def rollout(env: gym.Env, actions: np.ndarray, seed: int | None) -> list[tuple]:
    """reset(seed) then one step per action; an ended episode is followed by an unseeded reset()."""
    obs, info = env.reset(seed=seed)
    records = [(obs, 0.0, False, False, info)]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        records.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            obs, info = env.reset()
            records.append((obs, 0.0, False, False, info))
    return records


def assert_rollouts_equal(ra: list[tuple], rb: list[tuple], label: str) -> None:
    assert len(ra) == len(rb), f"{label}: {len(ra)} != {len(rb)} records (episodes ended at different steps)"
    for k, (a, b) in enumerate(zip(ra, rb, strict=True)):
        assert_record_equal(a, b, f"{label}, record {k}")


def tracking_action(env: gym.Env, obs: np.ndarray, gain: float = 3.0) -> np.ndarray:
    """Feed-forward reference twist plus proportional feedback, from a 'state' observation (twist mode)."""
    cfg = env.unwrapped.cfg
    assert cfg.obs_mode == "state" and cfg.action_mode == "twist"
    layout = env.unwrapped.observation_layout
    err_body = obs[layout["tracking_error_body"]] * POS_SCALE  # m
    err_heading = obs[layout["heading_error"]][0] * math.pi  # rad
    ref_vel = obs[layout["reference_velocity"]]  # body vx, vy / max_speed; yaw rate / max_yaw_rate
    v = ref_vel[0:2] * cfg.max_speed + gain * err_body
    w = ref_vel[2] * cfg.max_yaw_rate + gain * err_heading
    return np.clip(np.array([v[0] / cfg.max_speed, v[1] / cfg.max_speed, w / cfg.max_yaw_rate]), -1, 1).astype(
        np.float32)


# --- 1. API checkers ---------------------------------------------------------------------------


@pytest.mark.parametrize("action_mode", ["wheels", "twist"])
@pytest.mark.parametrize("obs_mode", ["state", "sensors"])
@pytest.mark.parametrize("env_id", (*IDS, CUSTOM))
def test_env_checkers(env_id, obs_mode, action_mode):
    from gymnasium.utils.env_checker import check_env as gym_check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(env_id, obs_mode=obs_mode, action_mode=action_mode, **ID_KWARGS.get(env_id, {}))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gym_check_env(env.unwrapped)
        sb3_check_env(env)
    # Both checkers report soft problems (space bounds, dtypes, seeding, reset info...) as warnings.
    problems = [str(w.message) for w in caught if not issubclass(w.category, (DeprecationWarning,
                                                                           PendingDeprecationWarning))]
    assert problems == []
    obs, _ = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape and obs.dtype == np.float32
    n_wheels = env.unwrapped.core.n_wheels
    assert env.action_space.shape == ((3,) if action_mode == "twist" else (n_wheels,))
    env.close()


# --- 2. determinism ----------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", [PHUNOPAS, MECANUM])
@pytest.mark.parametrize("extra", [{}, RANDOMIZE], ids=["liftoff", "liftoff+randomized"])
def test_same_seed_same_episodes(extra, env_id):
    kwargs = {"obs_mode": "sensors", **extra}
    env_a, env_b = gym.make(env_id, **kwargs), gym.make(env_id, **kwargs)
    actions = random_actions(env_a, 600, seed=123)
    first_a, first_b = rollout(env_a, actions[:300], seed=42), rollout(env_b, actions[:300], seed=42)
    assert_rollouts_equal(first_a, first_b, "seeded run")
    # Unseeded resets continue from each env's own generator, so they must agree too.
    second_a, second_b = rollout(env_a, actions[300:], seed=None), rollout(env_b, actions[300:], seed=None)
    assert_rollouts_equal(second_a, second_b, "after unseeded reset")
    # The same env reseeded replays its first run: nothing leaks from one episode into the next.
    assert_rollouts_equal(rollout(env_a, actions[:300], seed=42), first_a, "reseeded replay")
    # Random actions drive the robot off the path within 300 steps, so resets mid-run were exercised.
    n_ended = sum(r[2] or r[3] for r in first_a + second_a)
    assert n_ended >= 1
    if extra:
        assert env_a.unwrapped.core.models[0] is not env_a.unwrapped.core.base_model


@pytest.mark.parametrize("env_id", (*IDS, CUSTOM))
def test_different_seeds_differ(env_id):
    env_a, env_b = gym.make(env_id, **ID_KWARGS.get(env_id, {})), gym.make(env_id, **ID_KWARGS.get(env_id, {}))
    actions = random_actions(env_a, 30, seed=5)
    ra, rb = rollout(env_a, actions, seed=0), rollout(env_b, actions, seed=1)
    # The first observation already holds the (random) reference look-ahead.
    assert not np.array_equal(ra[0][0], rb[0][0])
    assert not np.array_equal(ra[-1][0], rb[-1][0])
    assert not np.array_equal(ra[-1][4]["reference_pose"], rb[-1][4]["reference_pose"])


# --- 3. pickling -------------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", [PHUNOPAS, MECANUM])
@pytest.mark.parametrize("kwargs", [{"obs_mode": "state"}, {"obs_mode": "sensors", **RANDOMIZE}],
                         ids=["state", "sensors+randomized"])
def test_pickle_round_trip_mid_episode(kwargs, env_id):
    env = gym.make(env_id, **kwargs)
    actions = random_actions(env, 150, seed=9)
    env.reset(seed=3)
    for a in actions[:50]:
        env.step(a)
    copy = pickle.loads(pickle.dumps(env))
    assert copy is not env and copy.unwrapped.core is not env.unwrapped.core
    ra = rollout_continue(env, actions[50:])
    rb = rollout_continue(copy, actions[50:])
    assert_rollouts_equal(ra, rb, "pickled copy")


def rollout_continue(env: gym.Env, actions: np.ndarray) -> list[tuple]:
    records = []
    for a in actions:
        records.append(env.step(a))
        if records[-1][2] or records[-1][3]:
            obs, info = env.reset()  # from the pickled np_random
            records.append((obs, 0.0, False, False, info))
    return records


# --- 4. SB3 subprocess vector env --------------------------------------------------------------


def test_sb3_subproc_vec_env_matches_in_process():
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    # episode_seconds=0.1: 10 steps, so SB3's own auto-reset happens inside the 20 steps, in the subprocess.
    factory = functools.partial(gym.make, f"omni_gym:{PHUNOPAS}", obs_mode="sensors", episode_seconds=0.1)
    pickle.dumps(factory)
    sub = SubprocVecEnv([factory, factory], start_method="spawn")
    try:
        dummy = DummyVecEnv([factory, factory])
        sub.seed(7)
        dummy.seed(7)
        obs_s, obs_d = sub.reset(), dummy.reset()
        assert np.array_equal(obs_s, obs_d)
        assert not np.array_equal(obs_s[0], obs_s[1])  # env i is seeded with 7 + i
        # Plain in-process envs with SB3's reset rule (unseeded reset() right after done) give the float64
        # rewards: DummyVecEnv stores rewards in a float32 buffer while SubprocVecEnv passes the floats through.
        plain = [gym.make(PHUNOPAS, obs_mode="sensors", episode_seconds=0.1) for _ in range(2)]
        for i, env in enumerate(plain):
            assert np.array_equal(env.reset(seed=7 + i)[0], obs_d[i])
        rng = np.random.default_rng(0)
        n_done = 0
        for k in range(20):
            a = rng.uniform(-1, 1, size=(2, *sub.action_space.shape)).astype(np.float32)
            obs_s, rew_s, done_s, info_s = sub.step(a)
            obs_d, rew_d, done_d, info_d = dummy.step(a)
            rew_p = []
            for i, env in enumerate(plain):
                _, r, terminated, truncated, _ = env.step(a[i])
                rew_p.append(r)
                if terminated or truncated:
                    env.reset()
            assert np.array_equal(obs_s, obs_d), f"step {k}"
            assert np.array_equal(rew_s, rew_p), f"step {k}"
            assert np.array_equal(rew_s.astype(np.float32), rew_d), f"step {k}"
            assert np.array_equal(done_s, done_d), f"step {k}"
            for i in range(2):
                assert_info_equal(info_s[i], info_d[i], f"step {k}, env {i}")
            n_done += int(done_s.sum())
        assert n_done >= 2
    finally:
        sub.close()


# --- 5. native vector env vs single envs -------------------------------------------------------


@pytest.mark.parametrize("env_id", [PHUNOPAS, MECANUM])
@pytest.mark.parametrize("kwargs", [{}, {"obs_mode": "sensors"}, {"obs_mode": "sensors", **RANDOMIZE}],
                         ids=["state", "sensors", "sensors+randomized"])
def test_native_vector_env_matches_single_envs(kwargs, env_id):
    n = 4
    kwargs = {"episode_seconds": 0.3, **kwargs}
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(n)]

    assert venv.single_observation_space == singles[0].observation_space
    assert venv.single_action_space == singles[0].action_space
    obs_dim, act_dim = singles[0].observation_space.shape[0], singles[0].action_space.shape[0]
    assert venv.observation_space.shape == (n, obs_dim) and venv.observation_space.dtype == np.float32
    assert venv.action_space.shape == (n, act_dim)
    assert venv.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP

    def check_infos(infos: dict, single_infos: list[dict], where: str) -> None:
        assert INFO_KEYS <= infos.keys()
        for key, value in infos.items():
            assert len(value) == n, f"{where}: infos[{key!r}] has length {len(value)}"
            if key.startswith("_"):
                assert value.dtype == bool and value.all()
            else:
                for i in range(n):
                    assert np.array_equal(value[i], single_infos[i][key]), f"{where}: env {i} info[{key!r}]"

    vobs, vinfos = venv.reset(seed=10)
    first = [env.reset(seed=10 + i) for i, env in enumerate(singles)]
    assert vobs.dtype == np.float32 and vobs in venv.observation_space
    assert np.array_equal(vobs, np.stack([o for o, _ in first]))
    check_infos(vinfos, [info for _, info in first], "reset")

    rng = np.random.default_rng(1)
    pending = [False] * n
    resets = [0] * n
    for k in range(80):
        actions = rng.uniform(-1, 1, size=(n, act_dim)).astype(np.float32)
        vobs, vrew, vterm, vtrunc, vinfos = venv.step(actions)
        expected = []
        for i, env in enumerate(singles):
            if pending[i]:  # NEXT_STEP autoreset: the action is ignored, the reset observation returned
                obs, info = env.reset()
                expected.append((obs, 0.0, False, False, info))
                resets[i] += 1
            else:
                expected.append(env.step(actions[i]))
            pending[i] = expected[i][2] or expected[i][3]
        where = f"step {k}"
        assert vobs.dtype == np.float32 and vrew.shape == vterm.shape == vtrunc.shape == (n,)
        assert np.array_equal(vobs, np.stack([e[0] for e in expected])), f"{where}: observations"
        assert np.array_equal(vrew, [e[1] for e in expected]), f"{where}: rewards"
        assert np.array_equal(vterm, [e[2] for e in expected]), f"{where}: terminated"
        assert np.array_equal(vtrunc, [e[3] for e in expected]), f"{where}: truncated"
        check_infos(vinfos, [e[4] for e in expected], where)
    assert min(resets) >= 1, resets
    venv.close()


# --- 6. keyword validation ---------------------------------------------------------------------

BAD_KWARGS = [
    ({"surface": "ice"}, "surface='ice'", ["'paper'", "'carpet'"]),
    ({"obs_mode": "pixels"}, "obs_mode='pixels'", ["'state'", "'sensors'"]),
    ({"action_mode": "torque"}, "action_mode='torque'", ["'wheels'", "'twist'"]),
    ({"friction": "magic"}, "friction='magic'", ["'initial'", "'roller_gap'"]),
    ({"robot": "hexapod"}, "robot='hexapod'", ["'williams2002'", "'phunopas2018'", "regularN"]),
    ({"robot": "regular2"}, "robot='regular2'", ["regularN"]),
    ({"trajectory": "spiral"}, "trajectory='spiral'", ["'waypoints'", "'circle'", "'figure_eight'", "'line'"]),
    ({"task": "goto"}, "trajectory='waypoints'", ["'goto'"]),
    ({"physics_dt": 0.0007}, "physics_dt=0.0007", ["whole number"]),
    ({"physics_dt": 0.005}, "physics_dt=0.005", ["[1e-5, 0.002] s"]),
    ({"control_hz": 0}, "control_hz=0", ["[1, 10000] Hz"]),
    ({"episode_seconds": float("nan")}, "episode_seconds=nan", ["(0, 3600] s"]),
    ({"lift_rate": -1}, "lift_rate=-1", ["in [0, 1000] 1/s"]),
    ({"sensor_noise": -0.5}, "sensor_noise=-0.5", ["[0, 100]"]),
    ({"walls": "yes"}, "walls='yes'", ["True", "False"]),
    ({"obstacles": ((1.0, 0.0, -1.0),)}, "obstacles[0]", ["radius >= 0.001 m"]),
    ({"randomize_mass": (2, 1)}, "randomize_mass=(2, 1)", ["low <= high"]),
    ({"randomize_friction": (0.5,)}, "randomize_friction=(0.5,)", ["(low, high)"]),
    ({"randomize_lift_rate": (-1.0, 1.0)}, "randomize_lift_rate=(-1.0, 1.0)", ["low <= high"]),
    ({"randomize_sensor_noise": (1.0, 11.0)}, "randomize_sensor_noise=(1.0, 11.0)", ["high <= 10"]),
    ({"randomize_sensor_noise": 2.0}, "randomize_sensor_noise=2.0", ["(low, high)"]),
    ({"sufrace": "paper"}, "'sufrace'", ["surface", "obs_mode"]),
    # Values that once hung, overflowed, gave NaN or raised other exceptions.
    ({"control_hz": 1e-300}, "control_hz=1e-300", ["[1, 10000] Hz"]),
    ({"control_hz": 0.001}, "control_hz=0.001", ["[1, 10000] Hz"]),
    ({"max_speed": 1e308}, "max_speed=1e+308", ["[0.001, 10] m/s"]),
    ({"max_yaw_rate": 1e308}, "max_yaw_rate=1e+308", ["[0.001, 100] rad/s"]),
    ({"obstacles": [(1.0, 1.0, 1e308)]}, "obstacles[0]", ["inside the arena"]),
    ({"episode_seconds": 1e308}, "episode_seconds=1e+308", ["(0, 3600] s"]),
    ({"episode_seconds": 0.001}, "episode_seconds=0.001", ["1 to 1000000"]),
    ({"arena_half_size": 1e308}, "arena_half_size=1e+308", ["[0.1, 1000] m"]),
    ({"robot": 5}, "robot=5", ["'williams2002'", "regularN"]),
    ({"robot": ["williams2002"]}, "robot=['williams2002']", ["'williams2002'"]),
    ({"robot": "regular100"}, "robot='regular100'", ["3 <= N <= 16"]),
    ({"robot": "reports/demo/model.json"}, "robot='reports/demo/model.json'", ["model="]),
    ({"obstacles": [1, 2, 3]}, "obstacles[0]=1", ["(x, y, radius)"]),
    ({"obstacles": (1, 2, 3)}, "obstacles[0]=1", ["(x, y, radius)"]),
    ({"obstacles": "abc"}, "obstacles='abc'", ["(x, y, radius)"]),
    ({"obstacles": [("a", 1.0, 0.1)]}, "obstacles[0]=('a', 1.0, 0.1)", ["numbers"]),
    # Tiny rates are valid (tests/test_liftoff_fuzz.py); above 1000 /s they are not.
    ({"lift_rate": 2000.0}, "lift_rate=2000.0", ["in [0, 1000] 1/s"]),
    ({"recover_rate": 1e308}, "recover_rate=1e+308", ["in [0, 1000] 1/s"]),
    ({"sensor_noise": 1e308}, "sensor_noise=1e+308", ["[0, 100]"]),
    ({"success_heading": 4.0}, "success_heading=4.0", ["(0, 3.14159] rad"]),
    # No silent conversion of strings, complex numbers or booleans into numbers.
    ({"max_speed": "0.5"}, "max_speed='0.5'", ["a number"]),
    ({"control_hz": "1_000"}, "control_hz='1_000'", ["a number"]),
    ({"ref_speed": 0.3 + 0j}, "ref_speed=(0.3+0j)", ["a number"]),
    ({"lost_distance": True}, "lost_distance=True", ["a number"]),
    ({"control_hz": 10**400}, "control_hz=1000000", ["[1, 10000] Hz"]),
    ({"obstacles": [(10**400, 0.0, 0.1)]}, "obstacles[0]", ["finite"]),
    ({"randomize_mass": (1, 10**400)}, "randomize_mass", ["low <= high"]),
    ({"randomize_mass": "12"}, "randomize_mass='12'", ["(low, high)"]),
    ({"walls": 1}, "walls=1", ["True", "False"]),
    # An obstacle or a wall at the start pose (the arena centre) would end every episode.
    ({"obstacles": [(0.15, 0.0, 0.1)]}, "obstacles[0]", ["start pose", "body radius 0.1 m"]),
    ({"walls": True, "arena_half_size": 0.1}, "arena_half_size=0.1", ["walls", "start pose"]),
]


@pytest.mark.parametrize(("kwargs", "names", "allowed"), BAD_KWARGS, ids=[str(c[0]) for c in BAD_KWARGS])
def test_bad_kwargs_rejected(kwargs, names, allowed):
    with pytest.raises(ValueError, match=re.escape(names)) as excinfo:
        gym.make(WILLIAMS, **kwargs)
    message = str(excinfo.value)
    for value in allowed:
        assert value in message, f"{message!r} does not mention {value!r}"
    assert "\n" not in message


# 255 arenas of 2 km (2048 m apart) fill the 2^19 m of one space; 65535 of the smallest (8 m apart).
@pytest.mark.parametrize(("kwargs", "names"), [({"obs_mode": "pixels"}, "obs_mode='pixels'"),
                                               ({"sufrace": "paper"}, "'sufrace'"),
                                               ({"num_envs": 0}, "num_envs=0"),
                                               ({"num_envs": 2.5}, "num_envs=2.5"),
                                               ({"num_envs": 4.0}, "num_envs=4.0"),
                                               ({"num_envs": True}, "num_envs=True"),
                                               ({"num_envs": "2"}, "num_envs='2'"),
                                               ({"num_envs": 10**12}, "num_envs=1000000000000"),
                                               ({"num_envs": 256, "arena_half_size": 1000}, "num_envs=256"),
                                               ({"max_episode_steps": 0}, "max_episode_steps=0")])
def test_bad_kwargs_rejected_by_vector_env(kwargs, names):
    kwargs = {"num_envs": 2, **kwargs}
    with pytest.raises(ValueError, match=re.escape(names)):
        gym.make_vec(PHUNOPAS, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("env_kwargs", ['{"robot": 5}', '{"episode_seconds": 1e308}', '{"arena_half_size": 1e308}',
                                        '{"obstacles": [1, 2, 3]}', '{"control_hz": 1e-300}'])
def test_cli_bad_env_kwargs_one_line_exit_2(env_kwargs, capsys):
    from omni_gym.cli import main

    argv = ["evaluate", "--policy", "ekf-pid", "--env", GOTO, "--episodes", "1", "--seed", "0",
            "--env-kwargs", env_kwargs]
    assert main(argv) == 2
    err = capsys.readouterr().err
    key = env_kwargs.split('"')[1]
    assert err.startswith("omni-gym: error: ") and key in err and err.count("\n") == 1, err


def test_numpy_scalars_accepted_as_python_values():
    numpy_kwargs = {"max_speed": np.float32(0.6), "episode_seconds": np.int64(1), "walls": np.bool_(True),
                    "obstacles": np.array([[1.0, 0.5, 0.1]]), "randomize_mass": np.array([0.9, 1.1]),
                    "surface": np.str_("paper")}
    plain_kwargs = {"max_speed": float(np.float32(0.6)), "episode_seconds": 1, "walls": True,
                    "obstacles": ((1.0, 0.5, 0.1),), "randomize_mass": (0.9, 1.1), "surface": "paper"}
    env_np, env_plain = gym.make(WILLIAMS, **numpy_kwargs), gym.make(WILLIAMS, **plain_kwargs)
    assert env_np.unwrapped.cfg == env_plain.unwrapped.cfg
    # Stored as Python types: the config pickles and prints as plain numbers.
    cfg = env_np.unwrapped.cfg
    assert type(cfg.max_speed) is float and type(cfg.walls) is bool and type(cfg.obstacles[0][0]) is float
    actions = random_actions(env_np, 20, seed=3)
    assert_rollouts_equal(rollout(env_np, actions, seed=np.int64(4)), rollout(env_plain, actions, seed=4), "numpy")
    venv = gym.make_vec(WILLIAMS, num_envs=np.int64(2), vectorization_mode="vector_entry_point", **numpy_kwargs)
    assert np.array_equal(venv.reset(seed=np.int64(3))[0], venv.reset(seed=3)[0])
    assert np.array_equal(venv.reset(seed=[np.int64(3), np.int64(4)])[0], venv.reset(seed=3)[0])


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True, [1, 2]])
def test_bad_reset_seed_rejected(seed):
    env = gym.make(WILLIAMS)
    with pytest.raises(ValueError, match=re.escape("seed")):
        env.reset(seed=seed)
    venv = gym.make_vec(WILLIAMS, num_envs=2, vectorization_mode="vector_entry_point")
    if not isinstance(seed, list):
        with pytest.raises(ValueError, match=re.escape("seed")):
            venv.reset(seed=seed)
    with pytest.raises(ValueError, match=re.escape("seed")):
        venv.reset(seed=[0, -1])


def test_reset_options_refused_not_ignored():
    env = gym.make(WILLIAMS)
    venv = gym.make_vec(WILLIAMS, num_envs=2, vectorization_mode="vector_entry_point")
    for reset in (env.reset, venv.reset):
        with pytest.raises(ValueError, match=r"unsupported reset option\(s\) 'start_pose'; supported: none"):
            reset(seed=0, options={"start_pose": (1.0, 0.0, 0.0)})
        with pytest.raises(ValueError, match="must be None or a dict"):
            reset(seed=0, options=[1])
    # None and an empty dict are the same as no options.
    assert np.array_equal(env.reset(seed=0, options={})[0], env.reset(seed=0)[0])
    assert np.array_equal(venv.reset(seed=0, options=None)[0], venv.reset(seed=0)[0])


def test_obstacle_just_clear_of_the_start_pose_is_accepted():
    # Williams body radius 0.1 m: a disc of 0.1 m at 0.21 m leaves 1 cm; standing still, nothing collides.
    env = gym.make(WILLIAMS, obstacles=[(0.21, 0.0, 0.1)])
    env.reset(seed=0)
    _, _, terminated, _, info = env.step(np.zeros(3, dtype=np.float32))
    assert not terminated and not info["collided"]


def test_recover_rate_zero_keeps_a_lifted_wheel_up():
    # lift_rate 50 /s: P(no lift within 1 s) = e^-50; the seed is fixed anyway.
    env = gym.make(PHUNOPAS, lift_rate=50.0, recover_rate=0.0, lost_distance=1e4, episode_seconds=1.0)
    env.reset(seed=0)
    lifted = []
    for _ in range(100):
        lifted.append(not env.step(np.zeros(3, dtype=np.float32))[4]["contact"].all())
    first = lifted.index(True)
    assert all(lifted[first:])


def test_diverged_simulation_raises_instead_of_returning_nan():
    # Within the bounds nothing diverges (tests/test_env_fuzz.py); a corrupted state stands in for a bug.
    env = gym.make(WILLIAMS)
    env.reset(seed=0)
    env.unwrapped.core.world.bodies[0].velocity = (math.nan, 0.0)
    with pytest.raises(FloatingPointError, match=re.escape("robot(s) [0]")):
        env.step(np.zeros(3, dtype=np.float32))


# --- 7. invalid and out-of-range actions -------------------------------------------------------


def test_non_real_and_misshapen_actions_rejected_state_untouched():
    env, ref = gym.make(PHUNOPAS, obs_mode="sensors"), gym.make(PHUNOPAS, obs_mode="sensors")
    actions = random_actions(env, 6, seed=1)
    env.reset(seed=5)
    ref.reset(seed=5)
    good = actions[0]
    bad = [(good.astype(complex) + 1j, "real numbers"), (good[None, :], "shape (3,)"), (good[:2], "shape (3,)"),
           (np.array(["a", "b", "c"]), "real numbers"), ([True, False, True], "real numbers"),
           ([[1.0], [1.0, 2.0]], "shape (3,)"), (None, "real numbers")]
    for action, message in bad:
        with pytest.raises(ValueError, match=re.escape(message)):
            env.step(action)
    for k, a in enumerate(actions):  # a list of Python floats is a valid action too
        assert_record_equal(env.step(a.tolist()), ref.step(a), f"step {k} after the refused actions")
    venv = gym.make_vec(PHUNOPAS, num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    for action in (good, np.stack([good, good]).astype(complex), np.zeros((2, 4))):
        with pytest.raises(ValueError, match="action"):
            venv.step(action)
    venv.step(np.stack([good, good]))



@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("action_mode", ["twist", "wheels"])
def test_non_finite_action_rejected_state_untouched(action_mode, bad):
    kwargs = {"obs_mode": "sensors", "action_mode": action_mode, "episode_seconds": 1.0}
    env, ref = gym.make(PHUNOPAS, **kwargs), gym.make(PHUNOPAS, **kwargs)
    actions = random_actions(env, 40, seed=4, scale=0.5)
    env.reset(seed=11)
    ref.reset(seed=11)
    for a in actions[:10]:
        env.step(a)
        ref.step(a)
    core = env.unwrapped.core
    before = (core.step_count.copy(), core.obs.copy(), core.world.tick, core.world.wheel_cmd.copy())
    poisoned = actions[10].copy()
    poisoned[1] = bad
    with pytest.raises(ValueError, match="NaN or infinity"):
        env.step(poisoned)
    assert np.array_equal(core.step_count, before[0]) and np.array_equal(core.obs, before[1])
    assert core.world.tick == before[2] and np.array_equal(core.world.wheel_cmd, before[3])
    # Continuing matches an env that never saw the bad action (including every noise draw).
    for k, a in enumerate(actions[10:]):
        assert_record_equal(env.step(a), ref.step(a), f"step {10 + k} after the bad action")


@pytest.mark.parametrize("action_mode", ["twist", "wheels"])
def test_out_of_range_action_is_clipped(action_mode):
    kwargs = {"obs_mode": "sensors", "action_mode": action_mode, "episode_seconds": 0.5}
    env, ref = gym.make(PHUNOPAS, **kwargs), gym.make(PHUNOPAS, **kwargs)
    wild = random_actions(env, 50, seed=6, scale=5.0)
    wild[0, :] = 5.0  # the exact case of the docs
    wild[1, :] = -5.0
    assert (np.abs(wild) > 1).mean() > 0.5
    clipped = np.clip(wild, -1.0, 1.0)
    assert_rollouts_equal(rollout(env, wild, seed=2), rollout(ref, clipped, seed=2), "clipped vs out-of-range")


# --- 8. episode semantics ----------------------------------------------------------------------


def check_info_layout(env: gym.Env, info: dict) -> None:
    n = env.unwrapped.core.n_wheels
    assert INFO_KEYS <= info.keys()
    assert np.shape(info["pose"]) == (3,) and np.shape(info["reference_pose"]) == (3,)
    assert np.shape(info["slip"]) == (n, 2)
    assert np.shape(info["contact"]) == (n,) and np.asarray(info["contact"]).dtype == bool
    assert isinstance(info["tracking_error"], float) and isinstance(info["collided"], bool)
    # tracking_error is the planar distance pose → reference; 1e-12 m absorbs the rounding of hypot vs sqrt.
    distance = math.hypot(*(np.asarray(info["reference_pose"][:2]) - info["pose"][:2]))
    assert info["tracking_error"] == pytest.approx(distance, abs=1e-12)


# Williams on carpet: the roller gaps make it crawl along its body x axis (≈ 0.02 m/s at full command, the
# paper's effect), so a naive feed-forward + P controller cannot follow every random path there; on paper it can.
# lost_distance=1.0: this test is about when truncation happens, and with lift-off the naive controller's worst
# error (≈ 0.4 m on some seeds) comes close to the default 0.5 m; termination has its own tests below.
@pytest.mark.parametrize(("env_id", "extra"), [(WILLIAMS, {"surface": "paper"}), (PHUNOPAS, {"lost_distance": 1.0}),
                                               (GOTO, {"lost_distance": 1.0}), (PHUNOPAS, {"episode_seconds": 0.5}),
                                               (MECANUM, {"lost_distance": 1.0})],
                         ids=["williams-paper", "phunopas", "goto", "phunopas-0.5s", "mecanum"])
def test_truncation_at_end_of_reference(env_id, extra):
    env = gym.make(env_id, obs_mode="state", action_mode="twist", **extra)
    cfg = env.unwrapped.cfg
    n_steps = cfg.episode_steps
    assert n_steps == int(round(cfg.episode_seconds * cfg.control_hz))
    obs, info = env.reset(seed=21)
    check_info_layout(env, info)
    assert info["tracking_error"] == 0.0  # the robot starts on the reference
    errors = []
    for k in range(1, n_steps + 1):
        obs, reward, terminated, truncated, info = env.step(tracking_action(env, obs))
        errors.append(info["tracking_error"])
        assert not terminated, f"step {k}: tracking controller lost (error {info['tracking_error']:.3f} m)"
        assert truncated == (k == n_steps), f"step {k} of {n_steps}: truncated={truncated}"
    check_info_layout(env, info)
    # The final reference pose is the last sample of the table, not a wrapped or clamped index.
    assert np.array_equal(info["reference_pose"], env.unwrapped.core.ref_pose[0, n_steps])
    # The controller really tracks (mean error measured <= 0.075 m over several seeds), so the absence of
    # termination is not an accident of a huge lost_distance.
    assert np.mean(errors) < 0.15
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3, dtype=np.float32))


@pytest.mark.parametrize(("env_id", "lost_distance"), [(WILLIAMS, None), (PHUNOPAS, None), (GOTO, None),
                                                       (PHUNOPAS, 0.2), (MECANUM, None)])
def test_terminates_when_lost(env_id, lost_distance):
    kwargs = {"obs_mode": "state", "action_mode": "twist"}
    if lost_distance is not None:
        kwargs["lost_distance"] = lost_distance
    env = gym.make(env_id, **kwargs)
    limit = env.unwrapped.cfg.lost_distance
    obs, info = env.reset(seed=8)
    # Full speed sideways (body y: the Williams robot crawls along body x on carpet), on the side away from where
    # the reference is heading (its 1 s look-ahead point; body = world frame at t = 0).
    ahead = obs[env.unwrapped.observation_layout["lookahead[2]"]][0:2] * LOOK_SCALE
    assert abs(ahead[1]) > 1e-3
    action = np.array([0.0, -np.sign(ahead[1]), 0.0], dtype=np.float32)
    for k in range(1, 301):
        obs, reward, terminated, truncated, info = env.step(action)
        check_info_layout(env, info)
        if terminated:
            break
        assert info["tracking_error"] <= limit, f"step {k}: error {info['tracking_error']} without termination"
    assert terminated, f"never lost after 3 s at full speed (error {info['tracking_error']:.3f} m)"
    assert not truncated and not info["collided"]
    assert info["tracking_error"] > limit


@pytest.mark.parametrize("env_id", [WILLIAMS, PHUNOPAS, MECANUM])
def test_terminates_on_wall_collision(env_id):
    # lost_distance far beyond the arena so the wall, not the tracking error, ends the episode.
    env = gym.make(env_id, walls=True, arena_half_size=0.5, lost_distance=10.0, action_mode="twist")
    half = env.unwrapped.cfg.arena_half_size
    radius = env.unwrapped.core.robot.body_radius
    obs, info = env.reset(seed=1)
    assert not info["collided"]
    action = np.array([0.0, 1.0, 0.0], dtype=np.float32)  # body y: fast for both robots (see above)
    for k in range(1, 301):
        obs, reward, terminated, truncated, info = env.step(action)
        if terminated:
            break
        assert not info["collided"], f"step {k}: collided without termination"
    assert terminated and not truncated
    assert info["collided"] and info["tracking_error"] <= 10.0
    # The robot's disc touches the nearest wall (the start heading follows the reference, so any wall):
    # allow 2 cm for the wall's own thickness/penetration slop.
    gap = half - np.max(np.abs(info["pose"][:2]))
    assert gap == pytest.approx(radius, abs=0.02)


# --- 9. registration ---------------------------------------------------------------------------


def test_registered_ids_from_fresh_interpreter(tmp_path):
    steps = {env_id: kwargs_steps[1] for env_id, kwargs_steps in omni_gym.ENV_IDS.items()}
    assert steps == {WILLIAMS: 2000, "OmniPathFollow-Williams-v1": 2000, PHUNOPAS: 2000, MECANUM: 2000, GOTO: 800}
    code = (
        "import sys\n"
        "import gymnasium as gym\n"
        "assert 'omni_gym' not in sys.modules\n"
        f"for env_id, steps in {steps!r}.items():\n"
        "    env = gym.make('omni_gym:' + env_id)\n"
        "    assert env.spec.max_episode_steps == steps, (env_id, env.spec.max_episode_steps)\n"
        "    env.reset(seed=0)\n"
        "    env.step(env.action_space.sample())\n"
        "print('ok')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("ok")


@pytest.mark.parametrize("env_id", (*IDS, CUSTOM))
def test_spec_max_episode_steps_matches_reference(env_id):
    env = gym.make(env_id, **ID_KWARGS.get(env_id, {}))
    assert env.spec.max_episode_steps is not None
    assert env.spec.max_episode_steps == env.unwrapped.cfg.episode_steps == gym.spec(env_id).max_episode_steps
    assert env.spec.vector_entry_point is not None


# --- 10. domain randomisation ------------------------------------------------------------------


def test_randomisation_draws_new_model_each_reset():
    env = gym.make(PHUNOPAS, episode_seconds=0.1, **RANDOMIZE)
    core = env.unwrapped.core
    nominal = SURFACES["carpet"]
    base_mass = core.base_model.robot.mass
    scales, masses, lifts = [], [], []
    for k in range(10):
        env.reset(seed=99 if k == 0 else None)
        model = core.models[0]
        s = model.surface.mu_drive / nominal.mu_drive
        assert 0.7 <= s <= 1.3
        # One scale on every coefficient (1e-12 relative: the products round differently).
        assert model.surface.mu_transverse / nominal.mu_transverse == pytest.approx(s, rel=1e-12)
        assert model.surface.mu_gap / nominal.mu_gap == pytest.approx(s, rel=1e-12)
        assert 0.8 * base_mass <= model.robot.mass <= 1.2 * base_mass
        # The physics uses the drawn model, not just the bookkeeping.
        assert core.world.models[0] is model
        assert np.all(core.world.wp[0, :, WP_MUW] == model.surface.mu_drive)
        assert core.world.sp[0, SP_MASS] == model.robot.mass
        proc = core.world.contact_processes[0]
        assert proc is not None and 0.0 <= proc.lift_rate <= 2.0
        scales.append(s)
        masses.append(model.robot.mass)
        lifts.append(proc.lift_rate)
    assert len(set(scales)) == len(set(masses)) == len(set(lifts)) == 10
    # Without randomisation every episode keeps the nominal model.
    plain = gym.make(PHUNOPAS, episode_seconds=0.1)
    for k in range(3):
        plain.reset(seed=k)
        assert plain.unwrapped.core.models[0].surface == nominal


def test_sensor_noise_randomisation_scales_each_robots_noise():
    kwargs = {"obs_mode": "sensors", "episode_seconds": 0.5}
    env = gym.make(PHUNOPAS, randomize_sensor_noise=(0.5, 2.0), **kwargs)
    core = env.unwrapped.core
    nominal = core.sensor_config
    factors = []
    for k in range(8):
        env.reset(seed=4 if k == 0 else None)
        s = core.sensor_noise_scale[0]
        assert 0.5 <= s <= 2.0
        # Every noise std of the robot's sensors, and nothing else, is scaled (the products as the bank forms them).
        assert core.sensors.std[0, 0] == nominal.gyro_noise_std * s
        assert core.sensors.std[0, 5] == nominal.camera_heading_std * s
        assert core.sensors.quantum[0] == 2 * math.pi / nominal.counts_per_rev
        factors.append(s)
    assert len(set(factors)) == 8
    # A factor of 0 gives the noiseless observations; the draw comes after every other draw of the reset,
    # so the first episode's physics is that of the env without the keyword.
    actions = random_actions(env, 60, seed=8)
    quiet = rollout(gym.make(PHUNOPAS, sensor_noise=0.0, **kwargs), actions, seed=21)
    zeroed = rollout(gym.make(PHUNOPAS, randomize_sensor_noise=(0.0, 0.0), **kwargs), actions, seed=21)
    ends = [i for i, r in enumerate(quiet) if r[2] or r[3]]
    first = (ends[0] + 1) if ends else len(quiet)
    assert_rollouts_equal(zeroed[:first], quiet[:first], "noise factor 0 vs sensor_noise=0")
    # In state mode the keyword draws the same factor, so observations and physics agree across modes.
    state_a = rollout(gym.make(PHUNOPAS, randomize_sensor_noise=(0.5, 2.0), episode_seconds=0.5), actions, seed=21)
    state_b = rollout(gym.make(PHUNOPAS, randomize_sensor_noise=(0.5, 2.0), **kwargs), actions, seed=21)
    assert [r[4]["pose"].tolist() for r in state_a] == [r[4]["pose"].tolist() for r in state_b]


@pytest.mark.parametrize(("env_id", "extra"), [(WILLIAMS, {"surface": "paper"}), (PHUNOPAS, {}), (MECANUM, {})])
def test_contact_mask_changes_with_lift_off(env_id, extra):
    env = gym.make(env_id, **extra)  # full 20 s episode (Williams on paper: trackable, see the truncation test)
    lift_rate = env.unwrapped.cfg.lift_rate
    obs, info = env.reset(seed=17)
    masks = [info["contact"]]
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(tracking_action(env, obs))
        masks.append(info["contact"])
        done = terminated or truncated
    assert truncated and len(masks) == env.unwrapped.cfg.episode_steps + 1
    masks = np.array(masks)
    changes = int(np.any(masks[1:] != masks[:-1], axis=1).sum())
    if lift_rate > 0:
        # Lift events at 0.5/s over 20 s: ~10 expected (each giving 2 changes); P(none) = e^-10, seed fixed.
        assert changes >= 2 and not masks.all()
        assert masks[0].all()  # every episode starts with all wheels down
        # Only the paper's contact cases occur: all down, one wheel up, or a diagonal pair up.
        cases = {tuple(c) for c in contact_cases(env.unwrapped.core.n_wheels)}
        assert {tuple(m) for m in masks} <= cases
    else:
        assert changes == 0 and masks.all()


# --- the custom id, renamed ids, Gymnasium's own checks --------------------------------------------


def test_custom_id_takes_robot_floor_and_liftoff_from_the_model():
    env = gym.make(CUSTOM, model=CUSTOM_MODEL)
    u = env.unwrapped
    assert u.robot.n_wheels == 5 and u.cfg.base_model().surface == SURFACES["paper"]
    assert u.cfg.contact_rates() == (5.0, 5.0)  # the model's wheel_liftoff effect
    # Without the effect no wheel ever lifts: the keyword default is 0, not the Phunopas ids' 0.5 /s.
    plain = omni_gym.load_model("regular5", surface="paper").to_json()
    calm = gym.make(CUSTOM, model=plain)
    assert calm.unwrapped.cfg.contact_rates()[0] == 0.0
    calm.reset(seed=0)
    for a in random_actions(calm, 300, seed=1, scale=0.3):
        _, _, terminated, truncated, info = calm.step(a)
        assert info["contact"].all()
        if terminated or truncated:
            calm.reset()
    # With the effect, wheels do lift within 3 s (the robot leaves all-down at 5 /s: P(no lift) = e^-15).
    env.reset(seed=0)
    lifted = False
    for a in random_actions(env, 300, seed=1, scale=0.3):
        _, _, terminated, truncated, info = env.step(a)
        lifted |= not info["contact"].all()
        if terminated or truncated:
            env.reset()
    assert lifted


def test_mecanum_id_defaults_and_the_mecanum_robot_on_an_omni_id():
    """The mecanum id: optiodom_omni4 on carpet with the initial friction model and the Phunopas lift-off.
    The omni-wheel ids pass friction='roller_gap', which mecanum wheels refuse: a one-line error naming the
    keyword and the fix, from the single and the vector env alike; with friction='initial' it works."""
    cfg = gym.make(MECANUM).unwrapped.cfg
    model = cfg.base_model()
    assert model.robot.name == "optiodom_omni4" and model.robot.has_angled_rollers
    assert model.surface == SURFACES["carpet"] and model.friction == "initial"
    assert cfg.contact_rates() == (0.5, 5.0) == (omni_gym.envs.LIFT_OFF["lift_rate"],
                                                 omni_gym.envs.LIFT_OFF["recover_rate"])
    message = "invalid friction='roller_gap' for robot='optiodom_omni4'"
    for make in (lambda **kw: gym.make(PHUNOPAS, **kw),
                 lambda **kw: gym.make_vec(WILLIAMS, num_envs=2, vectorization_mode="vector_entry_point", **kw),
                 lambda **kw: gym.make(MECANUM, friction="roller_gap", **kw)):
        with pytest.raises(ValueError, match=re.escape(message)) as err:
            make(robot="optiodom_omni4")
        assert "\n" not in str(err.value) and "friction='initial'" in str(err.value)
    env = gym.make(PHUNOPAS, robot="optiodom_omni4", friction="initial")
    assert env.unwrapped.robot.n_wheels == 4 and env.unwrapped.robot.has_angled_rollers
    env.reset(seed=0)
    env.step(env.action_space.sample())


@pytest.mark.parametrize(("kwargs", "message"), [
    ({}, "OmniPathFollow-Custom-v0 needs model="),
    ({"model": CUSTOM_MODEL, "robot": "williams2002"}, "invalid robot='williams2002' for OmniPathFollow-Custom-v0"),
    ({"model": CUSTOM_MODEL, "surface": "carpet"}, "invalid surface='carpet' for OmniPathFollow-Custom-v0"),
])
def test_custom_id_needs_a_model_and_refuses_what_it_defines(kwargs, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        gym.make(CUSTOM, **kwargs)
    with pytest.raises(ValueError, match=re.escape(message)):
        gym.make_vec(CUSTOM, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)


def test_custom_id_is_deterministic_pickles_and_vectorises_exactly():
    kwargs = {"model": CUSTOM_MODEL, "obs_mode": "sensors", "episode_seconds": 0.5}
    env_a, env_b = gym.make(CUSTOM, **kwargs), gym.make(CUSTOM, **kwargs)
    actions = random_actions(env_a, 120, seed=3)
    ra = rollout(env_a, actions, seed=7)
    assert_rollouts_equal(ra, rollout(env_b, actions, seed=7), "custom id, same seed")
    env_a.reset(seed=7)
    for a in actions[:20]:
        env_a.step(a)
    clone = pickle.loads(pickle.dumps(env_a))
    for a in actions[20:40]:
        assert_record_equal(env_a.step(a), clone.step(a), "custom id, pickled mid-episode")
    n = 3
    venv = gym.make_vec(CUSTOM, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(CUSTOM, **kwargs) for _ in range(n)]
    vobs, _ = venv.reset(seed=10)
    assert np.array_equal(vobs, np.stack([env.reset(seed=10 + i)[0] for i, env in enumerate(singles)]))
    for k in range(40):  # 0.4 s, inside the 0.5 s episode: no autoreset to align
        batch = random_actions(singles[0], n, seed=100 + k)
        vobs, vrew, _, _, _ = venv.step(batch)
        steps = [env.step(batch[i]) for i, env in enumerate(singles)]
        assert np.array_equal(vobs, np.stack([s[0] for s in steps]))
        assert np.array_equal(vrew, np.array([s[1] for s in steps]))


def test_old_williams_id_names_its_new_name_and_the_new_names_make_without_warnings():
    with pytest.raises(ValueError, match=r"OmniPathFollow-Williams-v0 was renamed OmniPathFollow-WilliamsPaper-v0.*"
                                         r"OmniPathFollow-Williams-v1 is a different task") as err:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # Gymnasium's version hint comes first
            gym.make("OmniPathFollow-Williams-v0")
    assert isinstance(err.value, gym.error.Error)
    for env_id in (WILLIAMS, "OmniPathFollow-Williams-v1", MECANUM, CUSTOM):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no "out of date, consider upgrading" for any current id
            gym.make(env_id, **ID_KWARGS.get(env_id, {})).close()


@pytest.mark.parametrize("mode", [3, 1.5, b"human", ["rgb_array"]])
def test_render_mode_that_is_not_a_string_is_a_one_line_value_error(mode):
    # gym.make looks the mode up in metadata["render_modes"] before our constructor runs.
    with pytest.raises(ValueError, match=r"^invalid render_mode=.*; allowed values: None, 'rgb_array', 'human'$"):
        gym.make(PHUNOPAS, render_mode=mode)


@pytest.mark.parametrize(("env_id", "kwargs", "names"), [
    (PHUNOPAS, {"lost_distance": 0.01, "success_distance": 0.05}, ["lost_distance=0.01", "success_distance=0.05"]),
    (PHUNOPAS, {"kinematics": "model"}, ["kinematics='model'", "model="]),
    (PHUNOPAS, {"trajectory": "circle", "ref_turn": "before"}, ["ref_turn='before'", "trajectory='circle'"]),
    (GOTO, {"ref_turn": "during"}, ["ref_turn='during'", "task='goto'"]),
    (GOTO, {"ref_heading": "tangent"}, ["ref_heading='tangent'", "task='goto'"]),
])
def test_contradicting_keywords_are_refused_naming_both(env_id, kwargs, names):
    """Keywords that contradict each other are refused in one line that names them, instead of one silently
    winning (an episode that ends lost before it can succeed; a reference option the task ignores)."""
    with pytest.raises(ValueError) as err:
        gym.make(env_id, **kwargs)
    msg = str(err.value)
    assert "\n" not in msg and all(n in msg for n in names), msg
