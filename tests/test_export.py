"""``omni-gym export``: every committed agent kind (PPO and SAC; privileged, EKF features, residual; MLP and
AffineSkip actors) exported to ONNX gives, run by onnxruntime, the trained policy's deterministic actions on
1,000 observations within 1e-5; the TorchScript file too; the sidecar states what a robot program needs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("onnxruntime")
pytest.importorskip("stable_baselines3")

import onnxruntime as ort  # noqa: E402

from agents.export import PARITY_OBSERVATIONS, _normaliser, parity_observations  # noqa: E402
from agents.gated import is_gated  # noqa: E402
from agents.loaders import find_loader  # noqa: E402
from agents.sb3_policy import ModelOptions  # noqa: E402
from omni_gym.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "agents" / "models"
TOL = 1e-5  # float32 networks: onnxruntime and torch sum in other orders (differences of about 1e-7)


def committed_kinds() -> dict[str, Path]:
    """One committed model per kind: (algo, wrapper, obs_mode, actor network)."""
    kinds: dict[str, Path] = {}
    for meta_file in sorted(MODELS.glob("*/meta.json")):
        meta = json.loads(meta_file.read_text())
        if is_gated(meta_file.parent):  # ekf-pid and a student: not one network (export refuses it, test_gated)
            continue
        actor = "skip" if "AffineSkip" in str(meta.get("hyperparams", {}).get("policy_kwargs")) else "mlp"
        kinds.setdefault(f"{meta['algo']}-{meta['wrapper']}-{meta.get('obs_mode')}-{actor}", meta_file.parent)
    return kinds


KINDS = committed_kinds()


def test_the_kinds_cover_both_algorithms_and_every_wrapper():
    assert {k.split("-")[0] for k in KINDS} == {"ppo", "sac"}
    assert {"none", "ekf", "residual"} <= {k.split("-")[1] for k in KINDS}
    assert any(k.endswith("skip") for k in KINDS)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_onnx_and_torchscript_parity(kind, tmp_path, capsys):
    model_dir = KINDS[kind]
    out = tmp_path / "export"
    assert main(["export", str(model_dir), "--out", str(out), "--torchscript"]) == 0
    assert "onnxruntime matches the policy" in capsys.readouterr().out
    side = json.loads((out / "policy.json").read_text())
    meta = json.loads((model_dir / "meta.json").read_text())
    # The policy as evaluate loads it, independently of the export.
    env, policy = find_loader(str(model_dir)).load(str(model_dir), meta["env_id"], None, None)
    try:
        obs = parity_observations(env, policy, seed=123)  # other observations than the export checked
        assert obs.shape == (PARITY_OBSERVATIONS, side["input"]["shape"][1])
        want = np.asarray(policy.act(obs), dtype=np.float32).reshape(len(obs), -1)
        normalises = _normaliser(policy.vecnormalize) is not None  # weights format or an SB3 VecNormalize
    finally:
        env.close()
    got = ort.InferenceSession(str(out / "policy.onnx")).run(["action"], {"obs": obs})[0]
    assert np.max(np.abs(got - want)) <= TOL
    import torch

    ts = torch.jit.load(str(out / "policy.pt"))
    with torch.no_grad():
        assert np.max(np.abs(ts(torch.from_numpy(obs)).numpy() - want)) <= TOL
    # The sidecar
    assert side["wrapper"] == meta["wrapper"] and side["env_id"] == meta["env_id"]
    assert side["control_period_s"] > 0 and side["action"]["mode"] == "twist"
    fields = side["observation"]["fields"]
    assert fields[0]["start"] == 0 and fields[-1]["stop"] == side["input"]["shape"][1]
    assert all(a["stop"] == b["start"] for a, b in zip(fields, fields[1:], strict=False))
    if meta["wrapper"] == "none":
        assert side["ekf_features"] is None and side["observation"]["mode"] == meta["obs_mode"]
    else:
        assert side["ekf_features"]["class"] == "agents.wrappers.EKFFeatureFilter"
        assert ("residual" in side["action"]) == (meta["wrapper"] == "residual-ekf-pid")
    assert side["normalisation"].startswith("built in") == normalises


def test_bad_input_one_line(tmp_path, capsys):
    assert main(["export", "ekf-pid", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "scripted controller, not a trained network" in err
    assert main(["export", str(tmp_path / "nothing"), "--out", str(tmp_path / "x")]) == 2
    assert "no such folder or file" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


TINY_RLLIB = """OmniPathFollow-Phunopas-v0:
  env_kwargs: {obs_mode: state}
  env_wrapper:
    - agents.rewards.TrackingReward: {reward: squared}
  n_envs: 4
  training: {train_batch_size_per_learner: 128, minibatch_size: 64, num_epochs: 1}
  model: {fcnet_hiddens: [16, 16]}
"""


@pytest.mark.slow  # a live Ray cluster: 10-25 s of start-up per worker on 2 cores (the rllib extra; CI runs test-slow)
def test_rllib_model_parity(ray_cluster, tmp_path, capsys):
    """An RLlib model (one tiny PPO iteration): the exported mean action equals RLlibPolicy's."""
    pytest.importorskip("ray")
    hp = tmp_path / "tiny.yml"
    hp.write_text(TINY_RLLIB)
    model = tmp_path / "model"
    short = json.dumps({"episode_seconds": 2.0})
    assert main(["train", "--backend", "rllib", "--env", "OmniPathFollow-Phunopas-v0", "--hyperparams", str(hp),
                 "--timesteps", "128", "--seed", "3", "--out", str(model), "--eval-freq", "0", "--env-kwargs", short,
                 "--address", ray_cluster, "--num-env-runners", "1", "--no-progress"]) == 0
    out = tmp_path / "export"
    # An RLlib checkpoint is a pickle: refused in one line without --trust-pickle, exported with it.
    assert main(["export", str(model), "--out", str(out), "--env-kwargs", short]) == 2
    assert main(["export", str(model), "--out", str(out), "--env-kwargs", short, "--trust-pickle"]) == 0
    side = json.loads((out / "policy.json").read_text())
    assert side["backend"] == "rllib" and side["observation"]["mode"] == "state"
    env, policy = find_loader(str(model)).load(str(model), "OmniPathFollow-Phunopas-v0", {"episode_seconds": 2.0},
                                               ModelOptions(trust_pickle=True))
    try:
        obs = parity_observations(env, policy, seed=123)
        want = np.asarray(policy.act(obs), dtype=np.float32)
    finally:
        env.close()
    got = ort.InferenceSession(str(out / "policy.onnx")).run(["action"], {"obs": obs})[0]
    assert np.max(np.abs(got - want)) <= TOL
