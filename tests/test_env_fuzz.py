"""Property-based fuzzing of environment keywords and actions.

Property: for any keyword values (valid or not: numpy scalars, huge, tiny, NaN, negative, wrong types),
``gym.make`` either raises a one-line ValueError naming a keyword it was given, or the environment
resets and steps with finite observations and rewards. Any action is either refused with a one-line
ValueError (NaN, complex, wrong shape, not numbers), leaving the episode intact, or stepped with
finite results. Hypothesis runs derandomised (a fixed example sequence: the test is deterministic) with
a small example budget so that the file runs in well under 30 s.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.physics.model import load_model

IDS = ("OmniPathFollow-WilliamsPaper-v0", "OmniPathFollow-Phunopas-v0", "OmniPathFollow-Mecanum-v0", "OmniGoToPose-v0")
STEPS = 3

# Values no numeric keyword may take, or that only some may (0, tiny, huge): wrong types included.
ODD_NUMBERS = [math.nan, math.inf, -math.inf, -1.0, 0.0, 1e308, -1e308, 1e-300, 5e-324, "1", "1_000", None, 1 + 2j,
               True, np.bool_(False), [1.0], np.float64(math.nan), np.float32(1e38), 10**400, -(10**400)]
NUMERIC = {
    "control_hz": [1, 20, 100, 200, 1000, 10000, 3],
    "physics_dt": [1e-5, 1e-4, 0.0005, 0.001, 0.002],
    "episode_seconds": [0.01, 0.05, 1.0, 20.0, 3600.0],
    "lift_rate": [0, 1e-300, 1e-6, 0.5, 1000.0],
    "recover_rate": [0, 1e-300, 1e-6, 5.0, 1000.0],
    "sensor_noise": [0, 1.0, 100.0],
    "arena_half_size": [0.1, 2.0, 1000.0],
    "ref_speed": [0.001, 0.25, 10.0],
    "max_speed": [0.001, 0.6, 10.0],
    "max_yaw_rate": [0.001, 3.0, 100.0],
    "lost_distance": [0.001, 0.5, 1e4],
    "success_distance": [1e-9, 0.05, 1e4],
    "success_heading": [1e-9, 0.1, math.pi],
}
NUMPY_TYPES = (np.float32, np.float64, np.int64)
LIFT = load_model("phunopas2018").with_effect("wheel_liftoff", {"lift_rate": 3.0, "recover_rate": 4.0})
# (values that should work, values that should be refused) of the other keywords.
CHOICES = {
    # optiodom_omni4 (mecanum) runs with friction 'initial' and is refused, naming robot, with 'roller_gap'.
    "robot": (["williams2002", "phunopas2018", "optiodom_omni4", "regular3", "regular16"],
              ["regular17", "regular", 5, None, ["x"]]),
    "surface": (["paper", "carpet", "grip"], ["ice", 3]),
    "friction": (["initial", "roller_gap"], ["magic"]),
    "task": (["path", "goto"], ["fly"]),
    "trajectory": (["waypoints", "circle", "figure_eight", "line", "goto"], ["spiral"]),
    "ref_heading": (["forward", "tangent", "random"], ["up"]),
    "obs_mode": (["state", "sensors", np.str_("sensors")], ["pixels"]),
    "action_mode": (["wheels", "twist"], ["torque"]),
    "actuation": (["ideal", "servo"], ["magic"]),
    "walls": ([True, False, np.bool_(True)], [1, "yes", None]),
    "obstacles": ([(), [(1.0, 1.0, 0.1)], np.array([[0.05, -0.05, 0.04]])],
                  [(1, 2, 3), [1, 2, 3], [("a", 1, 1)], [(0.0, 0.0, 0.5)], [(1.0, 1.0, 1e308)],
                   [(math.nan, 0.0, 0.1)], "obstacles", [(1.0, 1.0)], None]),
    "randomize_friction": ([None, (0.5, 1.5), [0.0, 0.0]], [(2.0, 1.0), (math.nan, 1.0), "12", (0.0, 1e308)]),
    "randomize_mass": ([None, (0.8, 1.2), np.array([0.05, 20.0])], [(0.0, 1.0), (1.0,)]),
    "randomize_lift_rate": ([None, (0.0, 2.0), (0.0, 1e-30)], [(0.0, 1e6), (-1.0, 1.0)]),
    "randomize_sensor_noise": ([None, (0.5, 2.0), (0.0, 0.0), np.array([0.0, 10.0])], [(0.0, 11.0), (2.0, 1.0), 1.5]),
    "model": ([None, load_model("williams2002").to_json(), LIFT.to_json(),
               load_model("phunopas2018").with_effect("com_offset", {"com": [0.01, 0.0]}).to_json()],
              [{"name": "x"}, "missing.json", 5]),
}


def valid_value(name: str) -> st.SearchStrategy:
    if name in NUMERIC:
        good = st.sampled_from(NUMERIC[name])
        as_numpy = st.tuples(good, st.sampled_from(NUMPY_TYPES)).map(lambda p: p[1](p[0]))
        return st.one_of(good, as_numpy)
    return st.sampled_from(CHOICES[name][0])


def odd_value(name: str) -> st.SearchStrategy:
    if name in NUMERIC:
        return st.one_of(st.sampled_from(ODD_NUMBERS), st.floats(allow_nan=True, allow_infinity=True))
    return st.sampled_from(CHOICES[name][1])


NAMES = sorted([*NUMERIC, *CHOICES])


@st.composite
def env_kwargs(draw) -> dict:
    """A few keywords at plausible values (numpy types included), and often one or two odd ones."""
    kwargs = {}
    for name in draw(st.lists(st.sampled_from(NAMES), max_size=6, unique=True)):
        kwargs[name] = draw(valid_value(name))
    for name in draw(st.lists(st.sampled_from(NAMES), max_size=2, unique=True)):
        kwargs[name] = draw(odd_value(name))
    return kwargs


KWARGS = env_kwargs()

# Actions: fine (also far outside [-1, 1], clipped) or refused.
ODD_ACTIONS = [math.nan, math.inf, 1j, "a", None, True]


def assert_one_line_naming(exc: ValueError, kwargs: dict) -> None:
    message = str(exc)
    assert "\n" not in message, message
    assert any(name in message for name in kwargs), f"{message!r} names none of {sorted(kwargs)}"


def finite_step(env, action) -> tuple[bool, float]:
    obs, reward, terminated, truncated, info = env.step(action)
    assert np.all(np.isfinite(obs)) and math.isfinite(reward), (obs, reward)
    assert np.all(np.isfinite(info["pose"]))
    return terminated or truncated, reward


@settings(max_examples=150, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(env_id=st.sampled_from(IDS), kwargs=KWARGS, data=st.data())
def test_random_configuration_is_refused_or_runs_finite(env_id, kwargs, data):
    try:
        env = gym.make(env_id, **kwargs)
    except ValueError as exc:
        assert_one_line_naming(exc, kwargs)
        event("refused")
        return
    event("ran")
    obs, info = env.reset(seed=0)
    assert np.all(np.isfinite(obs)) and obs in env.observation_space
    shape = env.action_space.shape
    for _ in range(STEPS):
        kind = data.draw(st.sampled_from(["fine", "huge", "odd value", "wrong shape", "batch"]))
        action = data.draw(st.lists(st.floats(-1, 1), min_size=shape[0], max_size=shape[0]).map(np.array))
        if kind == "huge":
            action = action * 1e300  # finite: clipped to [-1, 1]
        elif kind == "odd value":
            action = action.astype(object)
            action[0] = data.draw(st.sampled_from(ODD_ACTIONS))
        elif kind == "wrong shape":
            action = action[:-1]
        elif kind == "batch":
            action = action[None, :]
        if kind in ("fine", "huge"):
            done, _ = finite_step(env, action)
            if done:
                break
        else:
            before = env.unwrapped.core.step_count.copy()
            try:
                env.step(action)
            except ValueError as exc:
                assert "\n" not in str(exc) and "action" in str(exc)
            else:
                raise AssertionError(f"action {action!r} ({kind}) was accepted")
            assert np.array_equal(env.unwrapped.core.step_count, before)  # a refused action takes no step
    env.close()


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(kwargs=KWARGS)
def test_random_configuration_same_in_vector_and_single(kwargs):
    kwargs.pop("render_mode", None)
    env_id = "OmniPathFollow-Phunopas-v0"
    try:
        single = [gym.make(env_id, **kwargs) for _ in range(2)]
    except ValueError as exc:
        assert_one_line_naming(exc, kwargs)
        # The vector refuses the same configuration.
        try:
            gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
        except ValueError as vexc:
            assert_one_line_naming(vexc, kwargs)
        else:
            raise AssertionError("the vector env accepted what the single env refused") from None
        return
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    vobs, _ = venv.reset(seed=1)
    assert np.array_equal(vobs, np.stack([env.reset(seed=1 + i)[0] for i, env in enumerate(single)]))
    actions = np.zeros(venv.action_space.shape)
    vobs, vrew, *_ = venv.step(actions)
    assert np.all(np.isfinite(vobs)) and np.all(np.isfinite(vrew))
