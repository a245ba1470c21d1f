"""Which loader of ``evaluate --policy`` takes which spec (agents/loaders.py), decided without loading anything."""

from __future__ import annotations

import json

import pytest

from agents.loaders import LOADERS, find_loader
from agents.policies import POLICY_NAMES
from agents.rllib.policy import CHECKPOINT_MARKER


def _dir(tmp_path, name: str, files: dict[str, str]) -> str:
    d = tmp_path / name
    d.mkdir()
    for f, text in files.items():
        (d / f).write_text(text)
    return str(d)


@pytest.mark.parametrize("name", POLICY_NAMES)
def test_scripted_names_go_to_the_scripted_loader(name):
    assert find_loader(name).name == "scripted"


def test_each_model_layout_goes_to_its_loader(tmp_path):
    sb3 = _dir(tmp_path, "sb3", {"meta.json": json.dumps({"algo": "ppo", "model": "m.zip", "wrapper": "none"})})
    rllib = _dir(tmp_path, "rllib", {"meta.json": json.dumps({"backend": "rllib", "model": "ckpt"})})
    bare = _dir(tmp_path, "bare", {CHECKPOINT_MARKER: "{}"})
    zoo = _dir(tmp_path, "zoo", {})
    gate = {"kind": "gated", "student": "sb3", "threshold_m": 0.003}
    gated = _dir(tmp_path, "gated", {"meta.json": json.dumps(gate)})
    assert find_loader(sb3).name == "sb3-model"
    assert find_loader(gated).name == "gated"  # has a meta.json too: the gated loader is asked before SB3's
    assert find_loader("recommended").name == "recommended"
    assert find_loader(rllib).name == "rllib"  # has a meta.json too: the RLlib loader is asked first
    assert find_loader(bare).name == "rllib"
    assert find_loader(zoo).name == "rl-zoo"
    # A .zip that is not there still goes to SB3, whose loader names the missing file.
    assert find_loader(str(tmp_path / "absent.zip")).name == "sb3-zip"
    assert [loader.name for loader in LOADERS] == ["scripted", "recommended", "rllib", "gated", "sb3-model", "rl-zoo",
                                                  "sb3-zip"]


def test_a_spec_no_loader_takes_gets_one_line_saying_what_it_is_not(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("x")
    with pytest.raises(ValueError, match=r"not a model \(a model directory, an RL Zoo folder or an SB3 \.zip\)"):
        find_loader(str(text))
    with pytest.raises(ValueError, match="no such folder or file"):
        find_loader(str(tmp_path / "missing"))
    with pytest.raises(ValueError) as exc:
        find_loader("ekf_pid")
    assert str(exc.value) == ("unknown policy 'ekf_pid'; choose one of open-loop, odometry-pid, ekf-pid, "
                              "ekf-pid-traction, 'recommended' or a saved model path (no such folder or file either)")


def test_model_options_apply_to_sb3_models_only():
    from agents.sb3_policy import ModelOptions

    options = ModelOptions(algo="ppo")
    with pytest.raises(ValueError, match="--algo applies to a trained model, not to the scripted policy 'ekf-pid'"):
        find_loader("ekf-pid").check_options("ekf-pid", options)
    find_loader("ekf-pid").check_options("ekf-pid", ModelOptions())  # none given: nothing to refuse


def test_trained_policies_share_the_estimate_and_reset_of_their_base():
    from agents.rllib.policy import RLlibPolicy
    from agents.rollout import TrainedPolicy
    from agents.sb3_policy import SB3Policy, VectorSB3Policy

    for cls in (SB3Policy, VectorSB3Policy, RLlibPolicy):
        assert issubclass(cls, TrainedPolicy) and "estimate" not in vars(cls)

    class Wrapped:  # an EKF wrapper's pose estimate (x [m], y [m], θ [rad])
        estimate = (1.0, 2.0, 0.5)

    assert SB3Policy(model=None, vecnormalize=None, env=Wrapped()).estimate == (1.0, 2.0, 0.5)
    assert SB3Policy(model=None, vecnormalize=None, env=object()).estimate is None  # no wrapper: open loop
    assert TrainedPolicy(Wrapped()).reset(None) is None
