"""The committed trained models: they load on a fresh clone, evaluate end to end, and deterministically.

Seeds below 10 000 (the benchmark reports from 10 000).
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from agents.evaluate import evaluate
from agents.gated import is_gated
from agents.sb3_policy import ModelOptions, build, read_meta
from agents.train import load_hyperparams, train
from omni_gym.cli import main

torch.set_num_threads(1)

MODELS = sorted(p for p in (Path(__file__).resolve().parents[1] / "agents" / "models").glob("*")
                if (p / "meta.json").is_file() and not is_gated(p))  # gated controllers: tests/test_gated.py
ENV = "OmniPathFollow-Phunopas-v0"
SHORT = {"episode_seconds": 2.0}

pytestmark = pytest.mark.skipif(not MODELS, reason="no committed model under agents/models")


@pytest.mark.parametrize("model", MODELS, ids=lambda p: p.name)
def test_committed_model_records_how_it_was_made(model):
    meta = read_meta(model)
    for key in ("command", "seed", "git_commit", "timesteps", "wall_time_s", "env_id", "hyperparams"):
        assert meta.get(key) is not None, key
    assert meta["timesteps"] >= 1 and meta["wall_time_s"] > 0
    assert (model / meta["model"]).is_file() and (model / "curve.csv").is_file() and (model / "curve.png").is_file()
    if meta.get("vecnormalize"):
        assert (model / meta["vecnormalize"]).is_file()
    committed = [model / meta["model"], model / "meta.json", model / "curve.csv", model / "curve.png"]
    if meta.get("vecnormalize"):
        committed.append(model / meta["vecnormalize"])
    assert sum(f.stat().st_size for f in committed) < 2_000_000  # small files in git (brief: < 5 MB in total)


@pytest.mark.parametrize("model", MODELS, ids=lambda p: p.name)
def test_committed_model_evaluates_and_is_deterministic(model):
    """Same seeds twice, on the id the model was trained on: identical metrics (deterministic actions, seeded
    environments)."""
    env_id = read_meta(model)["env_id"]
    a = evaluate(str(model), env_id, 2, 321, SHORT, progress=False)
    b = evaluate(str(model), env_id, 2, 321, SHORT, progress=False)
    assert a["per_episode"] == b["per_episode"]
    assert all(math.isfinite(v) for v in a["per_episode"]["tracking_rmse"])
    # Different seeds give different episodes (the comparison above is not vacuous).
    c = evaluate(str(model), env_id, 1, 322, SHORT, progress=False)
    assert c["per_episode"]["tracking_rmse"][0] != a["per_episode"]["tracking_rmse"][0]
    json.dumps(a)  # the summary is JSON-serialisable (the CLI prints it with --json)


@pytest.mark.parametrize("model", MODELS, ids=lambda p: p.name)
def test_committed_model_acts_within_the_action_space(model):
    env, policy = build(model, read_meta(model)["env_id"], SHORT)
    obs, _ = env.reset(seed=5)
    policy.reset(obs)
    for _ in range(20):
        action = policy.act(obs)
        assert env.action_space.contains(action)
        obs, *_ = env.step(action)
    assert np.all(np.isfinite(obs))


def test_model_with_other_obs_mode_is_refused():
    model = MODELS[0]
    meta = read_meta(model)
    other = "state" if meta.get("obs_mode", "sensors") == "sensors" else "sensors"
    with pytest.raises(ValueError, match="obs_mode"):
        build(model, ENV, {"obs_mode": other})


# --- models from elsewhere: a plain SB3 zip ------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    """A PPO residual agent trained for one small update (64 steps) with the committed ppo.yml."""
    tmp = tmp_path_factory.mktemp("tiny")
    hp = load_hyperparams("ppo", ENV)
    hp.update(n_envs=1, n_steps=64, batch_size=32, n_epochs=1)
    f = tmp / "hp.yml"
    f.write_text(yaml.safe_dump({ENV: hp}))
    train("ppo", ENV, 64, 0, tmp / "model", SHORT, f, eval_freq=0, progress=False)
    return tmp / "model"


def test_plain_sb3_zip_evaluates_as_its_model_directory(tiny_model):
    """The zip alone, with what meta.json would say given as options, gives the same episodes."""
    ref = evaluate(str(tiny_model), ENV, 2, 40, SHORT, progress=False)
    opts = ModelOptions("ppo", "residual-ekf-pid", 0.3, str(tiny_model / "vecnormalize.pkl"), trust_pickle=True)
    plain = evaluate(str(tiny_model / "model.zip"), ENV, 2, 40, SHORT, progress=False, model_options=opts)
    assert plain["per_episode"] == ref["per_episode"]
    # Without its normalisation statistics the same weights act differently: the equality is not vacuous.
    bare = evaluate(str(tiny_model / "model.zip"), ENV, 2, 40, SHORT, progress=False,
                    model_options=ModelOptions("ppo", "residual-ekf-pid", trust_pickle=True))
    assert bare["per_episode"]["tracking_rmse"] != ref["per_episode"]["tracking_rmse"]


def _cli_error(capsys, *args: str) -> str:
    assert main(["evaluate", "--env", ENV, "--episodes", "1", "--seed", "0", "--env-kwargs", json.dumps(SHORT),
                 *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("omni-gym: error: "), err
    return err[0]


def test_plain_zip_errors_name_what_is_missing(tiny_model, capsys):
    z = str(tiny_model / "model.zip")
    assert "give --algo" in _cli_error(capsys, "--policy", z)
    assert "refused (pass --trust-pickle" in _cli_error(capsys, "--policy", z, "--algo", "ppo")
    z = [z, "--trust-pickle"]
    assert "--wrapper" in _cli_error(capsys, "--policy", *z, "--algo", "ppo")  # wrong observation shape
    assert "cannot load it as a td3 model" in _cli_error(capsys, "--policy", *z, "--algo", "td3",
                                                         "--wrapper", "residual-ekf-pid")
    assert "--wrapper 'residual'" in _cli_error(capsys, "--policy", *z, "--algo", "ppo", "--wrapper", "residual")
    assert "nope.pkl: file not found" in _cli_error(capsys, "--policy", *z, "--algo", "ppo", "--wrapper",
                                                    "residual-ekf-pid", "--vecnormalize", str(tiny_model / "nope.pkl"))
    assert "--residual-scale must be a number in [0, 1]" in _cli_error(capsys, "--policy", z, "--algo", "ppo",
                                                                        "--residual-scale", "2")
    assert "--algo 'sac' contradicts" in _cli_error(capsys, "--policy", str(tiny_model), "--algo", "sac")
    assert "--algo applies to a trained model" in _cli_error(capsys, "--policy", "ekf-pid", "--algo", "ppo")
    assert "--episodes must be an integer in [1, 100000], got 0" in _cli_error(
        capsys, "--policy", "ekf-pid", "--episodes", "0")


def test_committed_model_evaluates_through_the_cli(capsys):
    """`omni-gym evaluate --policy agents/models/ppo-residual` still needs no options."""
    assert main(["evaluate", "--policy", str(MODELS[0]), "--env", ENV, "--episodes", "1", "--seed", "321",
                 "--env-kwargs", json.dumps(SHORT), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    api = evaluate(str(MODELS[0]), ENV, 1, 321, SHORT, progress=False)
    assert out["per_episode"] == api["per_episode"]


def test_export_converts_to_weights_and_keeps_the_actions(tiny_model, tmp_path):
    """agents.export_model (how the committed models were converted) on a model of the older layout: the
    directory then holds no pickle, loads without trust and acts bit for bit as the SB3 zip did."""
    import shutil

    from agents.export_model import main as export_main
    from agents.sb3_policy import load

    model = tmp_path / "m"
    shutil.copytree(tiny_model, model)
    meta = json.loads((model / "meta.json").read_text())
    legacy = {k: v for k, v in meta.items() if k not in ("format", "policy")}
    legacy.update(model="model.zip", vecnormalize="vecnormalize.pkl")
    (model / "meta.json").write_text(json.dumps(legacy))
    (model / "policy.pt").unlink()
    (model / "normalisation.npz").unlink()
    with pytest.raises(ValueError, match="--trust-pickle"):
        load(model)
    _, sb3, vn = load(model, ModelOptions(trust_pickle=True))
    assert export_main([str(model), "--remove-pickles"]) == 0
    assert not list(model.glob("*.zip")) and not list(model.glob("*.pkl"))
    _, policy, norm = load(model)  # no trust needed
    obs = np.random.default_rng(1).normal(scale=3.0, size=(32, *sb3.observation_space.shape)).astype(np.float32)
    a1, _ = sb3.predict(vn.normalize_obs(obs).astype(np.float32), deterministic=True)
    a2, _ = policy.predict(norm.normalize_obs(obs).astype(np.float32), deterministic=True)
    np.testing.assert_array_equal(a1, a2)
    assert export_main([str(tmp_path / "missing")]) == 2  # no meta.json: one line on stderr, exit 2
