"""Native vector env autoreset modes: ``same_step`` gives the same episodes as ``next_step``, bit for bit.

With the same seeds each robot's episodes are identical in both modes; the ``same_step`` stream only
skips the ``next_step`` stream's autoreset steps (whose action is ignored) and hands the ended step's
observation and infos over in ``info["final_obs"]`` / ``info["final_info"]``. Comparisons are exact: the
environment promises bit-for-bit reproduction.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.envs.vector import OmniPathVectorEnv

PHUNOPAS = "OmniPathFollow-Phunopas-v0"
# Short episodes (20 steps) and a small lost distance (the robot accelerates slowly: about 1 cm of tracking
# error after 20 steps of full forward action): within 80 steps every robot ends three episodes or more,
# the robots that drift (events() biases robot i's actions by 0.5·i) by termination, robot 0 by truncation.
SHORT = {"episode_seconds": 0.2, "lost_distance": 0.006, "success_distance": 0.001}  # success below lost


def make(mode, n: int = 3, **kwargs) -> gym.vector.VectorEnv:
    return gym.make_vec(PHUNOPAS, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                        **{**SHORT, **kwargs})


def rows(infos: dict, i: int) -> dict:
    return {k: v[i] for k, v in infos.items() if not k.startswith("_") and k not in ("final_obs", "final_info")}


def events(venv, n_steps: int, seed: int) -> list[list[tuple]]:
    """Per robot: ("reset", obs, info) and ("step", obs, reward, terminated, truncated, info) events.

    Robot i draws its actions from its own generator, one per action it actually takes (not on a
    next_step autoreset step), so both modes give each robot the same action sequence.
    """
    n = venv.num_envs
    rngs = [np.random.default_rng(100 + i) for i in range(n)]
    same = venv.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    obs, infos = venv.reset(seed=seed)
    out = [[("reset", obs[i], rows(infos, i))] for i in range(n)]
    pending = np.zeros(n, dtype=bool)
    for _ in range(n_steps):
        actions = np.zeros((n, 3), dtype=np.float32)
        for i in range(n):
            if not pending[i]:
                actions[i] = rngs[i].uniform(-1.0, 1.0, size=3) + 0.5 * i  # robot 0 stays closer
        obs, rew, term, trunc, infos = venv.step(actions)
        for i in range(n):
            if pending[i]:  # next_step: this step is robot i's reset
                assert rew[i] == 0.0 and not term[i] and not trunc[i]
                out[i].append(("reset", obs[i], rows(infos, i)))
            elif same and (term[i] or trunc[i]):
                assert infos["_final_obs"][i] and infos["_final_info"][i]
                out[i].append(("step", infos["final_obs"][i], rew[i], term[i], trunc[i],
                               rows(infos["final_info"], i)))
                out[i].append(("reset", obs[i], rows(infos, i)))
            else:
                out[i].append(("step", obs[i], rew[i], term[i], trunc[i], rows(infos, i)))
        pending = (term | trunc) if not same else pending
    return out


def assert_event_equal(a: tuple, b: tuple, where: str) -> None:
    assert a[0] == b[0], f"{where}: {a[0]} != {b[0]}"
    assert a[1].dtype == b[1].dtype == np.float32, where
    assert np.array_equal(a[1], b[1]), f"{where}: observations differ\n{a[1]}\n{b[1]}"
    assert a[2:-1] == b[2:-1], f"{where}: reward/flags {a[2:-1]} != {b[2:-1]}"
    ia, ib = a[-1], b[-1]
    assert ia.keys() == ib.keys(), where
    for key in ia:
        assert np.array_equal(ia[key], ib[key]), f"{where}: info[{key!r}] {ia[key]!r} != {ib[key]!r}"


@pytest.mark.parametrize("kwargs", [{}, {"obs_mode": "sensors", "randomize_friction": (0.7, 1.3),
                                         "randomize_lift_rate": (0.0, 2.0)}], ids=["state", "sensors+randomized"])
def test_same_step_gives_the_next_step_episodes(kwargs):
    n_steps = 80
    nxt = events(make("next_step", **kwargs), n_steps, seed=3)
    same = events(make(AutoresetMode.SAME_STEP, **kwargs), n_steps, seed=3)
    ends = []
    for i, (a, b) in enumerate(zip(nxt, same, strict=True)):
        # The next_step stream spends one step per reset, so it covers fewer events in n_steps.
        assert len(b) > len(a)
        for k, (ea, eb) in enumerate(zip(a, b, strict=False)):  # b is longer (checked above)
            assert_event_equal(ea, eb, f"robot {i}, event {k}")
        robot_ends = [e for e in a if e[0] == "step" and (e[3] or e[4])]
        assert len(robot_ends) >= 3, f"robot {i}: {len(robot_ends)} episodes ended"
        ends += robot_ends
    assert any(e[3] for e in ends) and any(e[4] for e in ends), "need terminated and truncated episodes"


def test_same_step_final_keys_and_metadata():
    venv = make("same_step", n=4)
    assert venv.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    assert OmniPathVectorEnv.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP  # class dict untouched
    assert make("next_step").metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    seen_end = seen_quiet = False
    for _ in range(60):
        obs, rew, term, trunc, infos = venv.step(rng.uniform(-1, 1, size=(4, 3)))
        ended = term | trunc
        if not ended.any():
            assert "final_obs" not in infos and "final_info" not in infos
            seen_quiet = True
            continue
        seen_end = True
        fo, fi = infos["final_obs"], infos["final_info"]
        assert fo.dtype == np.float32 and fo.shape == obs.shape
        assert np.array_equal(infos["_final_obs"], ended) and np.array_equal(infos["_final_info"], ended)
        assert not fo[~ended].any()  # rows of robots still running are zero
        for key, value in fi.items():
            assert len(value) == 4
            if key.startswith("_"):
                assert np.array_equal(value, ended)
            else:
                assert not np.asarray(value)[~ended].any(), key
        # The returned rows of ended robots are their new episodes' first observations: at rest on the reference.
        assert np.array_equal(infos["velocity"][ended], np.zeros((ended.sum(), 3)))
    assert seen_end and seen_quiet


@pytest.mark.parametrize("mode", ["SameStep", "disabled", AutoresetMode.DISABLED, 1])
def test_bad_autoreset_mode_is_one_line(mode):
    with pytest.raises(ValueError, match=r"autoreset_mode=.*'next_step', 'same_step'"):
        make(mode)
