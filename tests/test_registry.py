"""The named-choice registry of the agents (agents/registry.py) and the tables declared with it."""

from __future__ import annotations

import pytest

from agents.algorithms import ALGORITHMS
from agents.batched.policies import VECTOR_POLICIES
from agents.options import TRAINING_BACKENDS
from agents.policies import POLICIES
from agents.registry import Registry
from agents.rewards import REWARDS
from agents.traction import MODES
from agents.train import VEC_ENV_KINDS
from agents.wrappers import WRAPPERS


def _colours() -> Registry[int]:
    return Registry("colour", [("red", 1), ("green", 2), ("blue", 3)])


def test_names_keep_registration_order_not_sorted():
    reg = _colours()
    reg.register("amber", 4)
    assert reg.names() == ("red", "green", "blue", "amber")
    assert list(reg) == list(reg.names()) and len(reg) == 4
    assert reg.items()[-1] == ("amber", 4)


def test_get_returns_the_registered_value():
    reg = _colours()
    assert reg.get("green") == 2
    assert reg.check("blue") == "blue"
    assert "red" in reg and "Red" not in reg and 1 not in reg


def test_unknown_name_is_one_line_naming_it_and_the_choices():
    with pytest.raises(ValueError) as exc:
        _colours().get("purple")
    assert str(exc.value) == "unknown colour 'purple'; choose one of red, green, blue"
    with pytest.raises(ValueError) as exc:
        _colours().check("x", what="--colour", where="cfg.yml: key 'colour'")
    assert str(exc.value) == "cfg.yml: key 'colour': unknown --colour 'x'; choose one of red, green, blue"


def test_unhashable_or_non_string_name_is_the_same_message_not_a_type_error():
    with pytest.raises(ValueError, match=r"unknown colour \['red'\]; choose one of"):
        _colours().get(["red"])


def test_duplicate_and_empty_names_are_refused():
    reg = _colours()
    with pytest.raises(ValueError, match="colour 'red' is registered already"):
        reg.register("red", 9)
    assert reg.get("red") == 1  # the first registration stands
    with pytest.raises(ValueError, match="non-empty string"):
        reg.register("", 0)
    with pytest.raises(ValueError, match="registered already"):
        Registry("colour", [("a", 1), ("a", 2)])


def test_agent_tables_keep_their_names_and_messages():
    # The names the command line, meta.json and the hyperparameter files use, in the order --help lists them.
    assert POLICIES.names() == ("open-loop", "odometry-pid", "ekf-pid", "ekf-pid-traction")
    assert VECTOR_POLICIES.names() == POLICIES.names()  # every scripted policy has its batched twin
    assert all(cls.name == name for name, cls in (*POLICIES.items(), *VECTOR_POLICIES.items()))
    assert WRAPPERS.names() == ("none", "residual-ekf-pid", "ekf-features", "feedforward")
    assert REWARDS.names() == ("env", "tracking", "squared", "gaussian", "pose", "pose_fine")
    assert ALGORITHMS.names() == ("ppo", "sac", "td3")
    assert VEC_ENV_KINDS.names() == ("native", "dummy", "subproc")
    assert MODES.names() == ("static", "moving")
    assert TRAINING_BACKENDS.names() == ("sb3", "rllib")
    cases = [(POLICIES, "unknown policy 'pid'; choose one of open-loop, odometry-pid, ekf-pid, ekf-pid-traction"),
             (VECTOR_POLICIES, "unknown vector policy 'pid'; choose one of open-loop, odometry-pid"),
             (WRAPPERS, "unknown wrapper 'pid'; choose one of none, residual-ekf-pid"),
             (ALGORITHMS, "unknown algo 'pid'; choose one of ppo, sac, td3"),
             (VEC_ENV_KINDS, "unknown vec_env 'pid'; choose one of native, dummy, subproc")]
    for reg, message in cases:
        with pytest.raises(ValueError) as exc:
            reg.get("pid")
        assert str(exc.value).startswith(message) and "\n" not in str(exc.value)
