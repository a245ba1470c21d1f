"""SB3 adapter over the native vector env (``agents.sb3_vec_env.NativeVecEnv``).

The adapter must show an SB3 algorithm exactly what ``DummyVecEnv([Monitor(gym.make(ID)), ...])``
shows it with the same seeds and actions: observations, rewards, dones, ``terminal_observation``,
``TimeLimit.truncated`` and Monitor's episode return and length, compared exactly (the environments
reproduce each other bit for bit, so any tolerance would hide a defect). Only Monitor's ``t`` (wall
time) differs.
"""

from __future__ import annotations

import csv

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.logger import configure  # noqa: E402
from stable_baselines3.common.monitor import Monitor  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize  # noqa: E402

import omni_gym  # noqa: E402, F401  (registers the ids)
from agents.sb3_vec_env import NativeVecEnv, make_native_vec_env  # noqa: E402

PHUNOPAS = "OmniPathFollow-Phunopas-v0"
WILLIAMS = "OmniPathFollow-WilliamsPaper-v0"
# Short episodes and a small lost distance (about 1 cm of tracking error builds up in 20 steps of full
# forward action): the robots whose actions are biased forward terminate, the others are truncated.
SHORT = {"episode_seconds": 0.3, "lost_distance": 0.006, "success_distance": 0.001}  # success below lost
CASES = {
    "state": {},
    "sensors+randomized": {"obs_mode": "sensors", "randomize_friction": (0.7, 1.3), "randomize_lift_rate": (0.0, 2.0)},
    # A TimeLimit shorter than the reference: Gymnasium's TimeLimit on the single env, the native env's
    # own max_episode_steps on the vector.
    "max_episode_steps": {"max_episode_steps": 12},
}


def pair(n: int, kwargs: dict, info_keys="all") -> tuple[NativeVecEnv, DummyVecEnv]:
    kwargs = {**SHORT, **kwargs}
    native = make_native_vec_env(PHUNOPAS, n, info_keys=info_keys, **kwargs)
    dummy = DummyVecEnv([lambda: Monitor(gym.make(PHUNOPAS, **kwargs)) for _ in range(n)])
    return native, dummy


def biased_actions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random actions, robot i pushed forward by 0.5·i (so robot 0 tends to be truncated, the others terminated)."""
    return (rng.uniform(-1.0, 1.0, size=(n, 3)) + 0.5 * np.arange(n)[:, None]).clip(-1, 1).astype(np.float32)


def assert_info_equal(a: dict, b: dict, where: str) -> None:
    assert a.keys() == b.keys(), f"{where}: info keys {sorted(a)} != {sorted(b)}"
    for key in a:
        if key == "episode":
            assert a[key]["r"] == b[key]["r"] and a[key]["l"] == b[key]["l"], f"{where}: {a[key]} != {b[key]}"
            assert isinstance(a[key]["t"], float)
        elif key == "terminal_observation":
            assert a[key].dtype == b[key].dtype == np.float32, where
            assert np.array_equal(a[key], b[key]), f"{where}: terminal_observation differs"
        else:
            assert type(a[key]) is type(b[key]), f"{where}: info[{key!r}] type {type(a[key])} != {type(b[key])}"
            assert np.array_equal(a[key], b[key]), f"{where}: info[{key!r}] {a[key]!r} != {b[key]!r}"


@pytest.mark.parametrize("kwargs", CASES.values(), ids=CASES.keys())
def test_matches_dummy_vec_env_of_monitored_single_envs(kwargs):
    n, n_steps = 3, 70
    native, dummy = pair(n, kwargs)
    assert native.observation_space == dummy.observation_space
    assert native.action_space == dummy.action_space
    assert native.seed(11) == dummy.seed(11)
    obs_n, obs_d = native.reset(), dummy.reset()
    assert obs_n.dtype == obs_d.dtype == np.float32 and np.array_equal(obs_n, obs_d)
    for i in range(n):
        assert_info_equal(native.reset_infos[i], dummy.reset_infos[i], f"reset, env {i}")
    rng = np.random.default_rng(5)
    kinds = {"terminated": 0, "truncated": 0}
    for k in range(n_steps):
        a = biased_actions(rng, n)
        obs_n, rew_n, done_n, info_n = native.step(a)
        obs_d, rew_d, done_d, info_d = dummy.step(a)
        where = f"step {k}"
        assert obs_n.dtype == np.float32 and np.array_equal(obs_n, obs_d), f"{where}: observations"
        assert rew_n.dtype == rew_d.dtype and np.array_equal(rew_n, rew_d), f"{where}: rewards"
        assert done_n.dtype == done_d.dtype and np.array_equal(done_n, done_d), f"{where}: dones"
        assert len(info_n) == n
        for i in range(n):
            assert_info_equal(info_n[i], info_d[i], f"{where}, env {i}")
            if done_n[i]:
                assert_info_equal(native.reset_infos[i], dummy.reset_infos[i], f"{where}, reset info {i}")
                kinds["truncated" if info_n[i]["TimeLimit.truncated"] else "terminated"] += 1
    assert kinds["truncated"] >= 2, kinds
    if "max_episode_steps" not in kwargs:  # 12 steps are too few to drift 6 mm off the reference
        assert kinds["terminated"] >= 2, kinds


def test_default_info_is_what_sb3_reads():
    """Without info_keys, each info holds TimeLimit.truncated, and at an episode's end the terminal observation,
    Monitor's episode and is_success, equal to the DummyVecEnv's."""
    n = 3
    native, dummy = pair(n, {}, info_keys=())
    native.seed(2)
    dummy.seed(2)
    native.reset()
    dummy.reset()
    assert native.reset_infos == [{}] * n
    rng = np.random.default_rng(0)
    ended = 0
    for k in range(40):
        a = biased_actions(rng, n)
        _, _, done, info_n = native.step(a)
        _, _, _, info_d = dummy.step(a)
        for i in range(n):
            keys = {"TimeLimit.truncated", "terminal_observation", "episode", "is_success"} if done[i] else {
                "TimeLimit.truncated"}
            assert info_n[i].keys() == keys, f"step {k}, env {i}"
            assert_info_equal(info_n[i], {key: info_d[i][key] for key in keys}, f"step {k}, env {i}")
            ended += int(done[i])
    assert ended >= 3
    picked, _ = pair(2, {}, info_keys=["tracking_error"])
    picked.reset()
    _, _, _, infos = picked.step(np.zeros((2, 3), dtype=np.float32))
    assert all(info.keys() == {"tracking_error", "TimeLimit.truncated"} for info in infos)


def test_vec_env_sanity():
    """What SB3's env checker asks of an environment, for the vector: spaces, shapes, dtypes, containment."""
    venv = make_native_vec_env(WILLIAMS, 4, episode_seconds=0.1)
    assert venv.num_envs == 4
    obs = venv.reset()
    assert obs.shape == (4, *venv.observation_space.shape) and obs.dtype == venv.observation_space.dtype
    assert all(o in venv.observation_space for o in obs)
    for _ in range(12):  # 10-step episodes: every robot ends one
        actions = np.stack([venv.action_space.sample() for _ in range(4)])
        obs, rewards, dones, infos = venv.step(actions)
        assert obs.shape == (4, *venv.observation_space.shape) and obs.dtype == np.float32
        assert rewards.shape == (4,) and rewards.dtype == np.float32 and np.isfinite(rewards).all()
        assert dones.shape == (4,) and dones.dtype == bool
        assert isinstance(infos, list) and len(infos) == 4 and all(isinstance(i, dict) for i in infos)
        assert all(o in venv.observation_space for o in obs)
        for i in np.flatnonzero(dones):
            assert infos[i]["terminal_observation"] in venv.observation_space
    venv.close()


def test_refusals_and_attributes():
    nxt = gym.make_vec(WILLIAMS, num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="same_step autoreset mode.*autoreset_mode='same_step'"):
        NativeVecEnv(nxt)
    with pytest.raises(ValueError, match="info_keys must be 'all' or a list"):
        make_native_vec_env(WILLIAMS, 2, info_keys="pose")
    with pytest.raises(ValueError, match="sets autoreset_mode='same_step' itself"):
        make_native_vec_env(WILLIAMS, 2, autoreset_mode="next_step")
    venv = make_native_vec_env(WILLIAMS, 3)
    assert venv.get_attr("observation_space") == [venv.observation_space] * 3
    assert venv.get_attr("wheel_scale", indices=[0, 2]) == [venv.venv.unwrapped.wheel_scale] * 2
    assert venv.get_attr("render_mode") == [None] * 3 and venv.render_mode is None
    assert not venv.has_attr("no_such_attribute")
    assert venv.env_is_wrapped(Monitor) == [False] * 3
    config = venv.get_attr("sensor_config")[0]
    venv.set_attr("sensor_config", config)  # every robot: allowed
    with pytest.raises(ValueError, match="share one environment object; set_attr.*indices=None"):
        venv.set_attr("sensor_config", config, indices=[1])
    with pytest.raises(ValueError, match="env_method"):
        venv.env_method("close", indices=0)
    venv.seed(3)
    venv.set_options({"difficulty": 1})
    with pytest.raises(ValueError, match="difficulty"):  # the env takes no reset options and says which key
        venv.reset()
    venv.set_options(None)
    # VecNormalize (SB3's own wrapper) sits on the adapter.
    norm = VecNormalize(venv)
    assert norm.reset().shape == (3, *venv.observation_space.shape)


def test_ppo_smoke(tmp_path):
    """PPO learns on the adapter (a few thousand steps), logs ep_rew_mean and predicts actions of the right shape."""
    venv = make_native_vec_env(WILLIAMS, 4, obs_mode="state", episode_seconds=0.2)  # 20-step episodes
    model = PPO("MlpPolicy", venv, n_steps=128, batch_size=128, n_epochs=2, seed=0, device="cpu")
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(total_timesteps=2048)
    assert model.num_timesteps == 2048
    rows = list(csv.DictReader(open(tmp_path / "progress.csv")))
    assert rows and all(row["rollout/ep_rew_mean"] not in ("", None) for row in rows)
    assert 0.0 < float(rows[-1]["rollout/ep_len_mean"]) <= 20.0
    obs = venv.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (4, 3) and venv.action_space.contains(actions[0])
    single, _ = model.predict(obs[0], deterministic=True)
    assert single.shape == (3,)
