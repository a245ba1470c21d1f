"""The ``randomize_floor`` keyword: one floor per robot and reset, drawn from the environment's generator."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.physics.friction import SURFACES
from omni_gym.physics.layout import WP_MUW, WP_R
from omni_gym.physics.model import load_model

PHUNOPAS = "OmniPathFollow-Phunopas-v0"
CUSTOM = "OmniPathFollow-Custom-v0"
FLOORS = ("grip", "carpet")
OMNI4 = "benchmarks/inputs/omni4_calibrated_model.json"


def floor_sequence(env, seed: int, resets: int) -> list[str]:
    first = [env.reset(seed=seed)[1]["floor"]]
    return first + [env.reset()[1]["floor"] for _ in range(resets - 1)]


def test_same_seed_same_floor_sequence_single_and_vector_and_both_floors_occur():
    a = floor_sequence(gym.make(PHUNOPAS, randomize_floor=FLOORS), 7, 20)
    b = floor_sequence(gym.make(PHUNOPAS, randomize_floor=FLOORS), 7, 20)
    assert a == b
    # With the friction keyword's model (Phunopas: roller_gap) named; each floor drawn with p = 1/2, so a
    # floor missing from 20 draws would be a 2·2⁻²⁰ event: the draw is not uniform over the tuple.
    assert set(a) == {"grip:roller_gap", "carpet:roller_gap"}
    n = 3
    venv = gym.make_vec(PHUNOPAS, num_envs=n, vectorization_mode="vector_entry_point", randomize_floor=FLOORS)
    rows = [venv.reset(seed=7)[1]["floor"]] + [venv.reset()[1]["floor"] for _ in range(19)]
    for i in range(n):  # robot i draws from its own generator, seeded 7 + i: the single env's sequence
        assert [row[i] for row in rows] == floor_sequence(gym.make(PHUNOPAS, randomize_floor=FLOORS), 7 + i, 20)


def rollout(seed: int, steps: int = 60, **kwargs) -> tuple[list[np.ndarray], dict]:
    env = gym.make(PHUNOPAS, obs_mode="sensors", **kwargs)
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(0)
    out = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, step_info = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        out += [obs, np.array([reward, terminated, truncated]), step_info["pose"], step_info["slip"]]
        if terminated or truncated:
            break
    return out, info


def test_a_drawn_floor_gives_the_episode_of_that_surface_bit_for_bit():
    """The floor is the reset's last draw, so every other draw of the seed (reference, contacts, sensors) is
    the one of the fixed-surface environment: a draw of grip (carpet) replays surface="grip" ("carpet")."""
    seen = set()
    for seed in range(6):
        episode, info = rollout(seed, randomize_floor=FLOORS)
        surface = info["floor"].split(":")[0]
        seen.add(surface)
        fixed, fixed_info = rollout(seed, surface=surface)
        assert "floor" not in fixed_info  # the key only comes with the keyword
        assert len(episode) == len(fixed)
        for a, b in zip(episode, fixed, strict=True):
            np.testing.assert_array_equal(a, b)
    assert seen == set(FLOORS)


def test_friction_randomisation_scales_the_drawn_floor_and_the_model_keeps_its_effects():
    env = gym.make(PHUNOPAS, randomize_floor=("grip:initial",), randomize_friction=(0.5, 0.5))
    _, info = env.reset(seed=0)
    assert info["floor"] == "grip:initial" and env.unwrapped.core.models[0].friction == "initial"
    np.testing.assert_array_equal(env.unwrapped.core.world.wp[0, :, WP_MUW], SURFACES["grip"].mu_drive * 0.5)
    # model=: the floor replaces the calibrated model's surface (grip → carpet); its wheel_radius effect stays.
    model = load_model(OMNI4)
    env = gym.make(CUSTOM, model=OMNI4, randomize_floor=("carpet",))
    _, info = env.reset(seed=0)
    assert info["floor"] == "carpet:initial"  # the model's friction model: its mecanum wheels need 'initial'
    wp = env.unwrapped.core.world.wp[0]
    np.testing.assert_array_equal(wp[:, WP_MUW], SURFACES["carpet"].mu_drive)
    np.testing.assert_allclose(wp[:, WP_R], model.robot.wheel_radius * np.array(
        model.effects["wheel_radius"]["scale"]), rtol=1e-15)


def test_vector_env_with_floors_matches_single_envs():
    n, kwargs = 3, {"randomize_floor": FLOORS, "episode_seconds": 0.1, "action_mode": "wheels"}
    venv = gym.make_vec(PHUNOPAS, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(PHUNOPAS, **kwargs) for _ in range(n)]
    vobs, vinfo = venv.reset(seed=11)
    resets = [env.reset(seed=11 + i) for i, env in enumerate(singles)]
    assert np.array_equal(vobs, np.stack([r[0] for r in resets]))
    assert list(vinfo["floor"]) == [r[1]["floor"] for r in resets]
    rng = np.random.default_rng(3)
    pending = [False] * n
    for k in range(25):  # 10-step episodes: every robot autoresets (and draws a new floor) twice
        actions = rng.uniform(-1, 1, size=(n, 4)).astype(np.float32)
        vobs, _, _, _, vinfo = venv.step(actions)
        for i, env in enumerate(singles):
            if pending[i]:
                obs, info = env.reset()
                pending[i] = False
            else:
                obs, _, terminated, truncated, info = env.step(actions[i])
                pending[i] = terminated or truncated
            assert np.array_equal(vobs[i], obs) and vinfo["floor"][i] == info["floor"], f"step {k}, robot {i}"


@pytest.mark.parametrize("value, expected", [
    ((), "must be None or a non-empty sequence"),
    ("grip", "must be None or a non-empty sequence"),
    (("grip", "mud"), "randomize_floor[1]='mud': unknown surface 'mud'; choose one of 'paper', 'carpet', 'grip'"),
    (("grip:sticky",), "randomize_floor[0]='grip:sticky': unknown friction model 'sticky'; choose one of "
                       "'initial', 'roller_gap'"),
    (("grip", 3), "randomize_floor[1]=3; each floor is a string"),
])
def test_bad_floors_refused_in_one_line_naming_the_entry(value, expected):
    with pytest.raises(ValueError) as exc:
        gym.make(PHUNOPAS, randomize_floor=value)
    assert expected in str(exc.value) and "\n" not in str(exc.value)


def test_floors_that_cannot_carry_the_robot_or_model_are_refused():
    with pytest.raises(ValueError, match=r"randomize_floor\[1\]='carpet:roller_gap': friction model 'roller_gap' "
                                         "applies to omni wheels only"):
        gym.make("OmniPathFollow-Mecanum-v0", randomize_floor=("grip", "carpet:roller_gap"))
    fitted = load_model("phunopas2018").with_effect("roller_gap", {"mu_gap": 0.5, "roller_fraction": 0.9,
                                                                   "phase": [0.0, 0.1, 0.2, 0.3]})
    with pytest.raises(ValueError, match="invalid randomize_floor with model=: its effect 'roller_gap' holds "
                                         "friction coefficients"):
        gym.make(CUSTOM, model=fitted, randomize_floor=FLOORS)
