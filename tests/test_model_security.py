"""Opening a model or hyperparameter file from someone else runs no code from it (docs/security.md).

Each crafted file below would create a marker file when unpickled (or evaluated); every loader must refuse
it in one line and leave no marker, unless the user passes --trust-pickle (then, for the pickle formats,
the marker appears: the crafted files are real attacks, so the refusals are not vacuous).
"""

import base64
import io
import json
import pickle
import shutil
import zipfile
from pathlib import Path

import pytest
import yaml

from agents.evaluate import evaluate
from agents.sb3_policy import ModelOptions, load
from omni_gym.cli import main

MODELS = Path(__file__).resolve().parents[1] / "agents" / "models"
ENV = "OmniPathFollow-Phunopas-v0"
SHORT = {"episode_seconds": 1.0}


class _Marker:
    """Unpickling this creates ``path`` (open(path, "w")): what an attacker's payload could do instead."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def _pickle(marker: Path) -> bytes:
    return pickle.dumps(_Marker(marker))


def _evil_sb3_zip(path: Path, marker: Path) -> Path:
    """An SB3 zip whose ``data`` holds a serialized entry (SB3 unpickles such entries when loading)."""
    entry = {":type:": "<class 'x'>", ":serialized:": base64.b64encode(_pickle(marker)).decode()}
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("data", json.dumps({"policy_class": entry, "observation_space": entry}))
        z.writestr("_stable_baselines3_version", "2.3.0")
    return path


def _one_line_error(capsys, args: list[str]) -> str:
    assert main(["evaluate", "--env", ENV, "--episodes", "1", "--seed", "0", "--env-kwargs", json.dumps(SHORT),
                 *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("omni-gym: error: "), err
    return err[0]


def test_crafted_sb3_zip_runs_no_code(tmp_path, capsys):
    marker = tmp_path / "owned"
    z = _evil_sb3_zip(tmp_path / "evil.zip", marker)
    err = _one_line_error(capsys, ["--policy", str(z), "--algo", "ppo"])
    assert "pickle" in err and "--trust-pickle" in err and str(z) in err
    assert not marker.exists()
    # With the flag the zip is unpickled, as SB3 does: the payload runs (then the load fails, in one line).
    _one_line_error(capsys, ["--policy", str(z), "--algo", "ppo", "--trust-pickle"])
    assert marker.exists()


def test_crafted_rl_zoo_folder_runs_no_code(tmp_path, capsys):
    marker = tmp_path / "owned"
    run = tmp_path / "zoo"
    (run / ENV).mkdir(parents=True)
    _evil_sb3_zip(run / f"{ENV}.zip", marker)
    (run / ENV / "args.yml").write_text(yaml.safe_dump({"algo": "ppo", "env": ENV}))
    (run / ENV / "config.yml").write_text(yaml.safe_dump({"normalize": True}))
    (run / ENV / "vecnormalize.pkl").write_bytes(_pickle(marker))
    err = _one_line_error(capsys, ["--policy", str(run)])
    assert "--trust-pickle" in err and not marker.exists()


@pytest.fixture
def model_copy(tmp_path) -> Path:
    d = tmp_path / "model"
    shutil.copytree(MODELS / "ppo-residual", d)
    return d


def test_committed_model_opens_without_trust(model_copy):
    meta, policy, norm = load(model_copy)
    assert meta["format"] == "weights-1" and norm is not None
    assert not list(MODELS.glob("*/*.pkl")) and not list(MODELS.glob("*/*.zip"))  # nothing left to unpickle


def test_pickled_normalisation_statistics_run_no_code(model_copy, capsys):
    """A weights-format folder whose statistics file is a pickle: numpy reads it with pickles refused."""
    marker = model_copy / "owned"
    (model_copy / "normalisation.npz").write_bytes(_pickle(marker))
    err = _one_line_error(capsys, ["--policy", str(model_copy)])
    assert "normalisation.npz" in err and not marker.exists()


def test_pickled_weights_run_no_code(model_copy, capsys):
    """policy.pt replaced by a pickle with a payload: torch.load(weights_only=True) refuses it."""
    import torch

    marker = model_copy / "owned"
    buf = io.BytesIO()
    torch.save({"x": _Marker(marker)}, buf)
    (model_copy / "policy.pt").write_bytes(buf.getvalue())
    err = _one_line_error(capsys, ["--policy", str(model_copy)])
    assert "policy.pt: not a weights file" in err and not marker.exists()


def test_legacy_vecnormalize_pickle_needs_trust(model_copy, tmp_path, capsys):
    """A folder of the older layout (SB3 zip + VecNormalize pickle) is refused before either is opened."""
    marker = tmp_path / "owned"
    meta = json.loads((model_copy / "meta.json").read_text())
    meta.pop("format")
    meta.update(model="model.zip", vecnormalize="vecnormalize.pkl")
    (model_copy / "meta.json").write_text(json.dumps(meta))
    _evil_sb3_zip(model_copy / "model.zip", marker)
    (model_copy / "vecnormalize.pkl").write_bytes(_pickle(marker))
    err = _one_line_error(capsys, ["--policy", str(model_copy)])
    assert "model.zip" in err and "--trust-pickle" in err and not marker.exists()
    with pytest.raises(ValueError, match="--trust-pickle"):
        evaluate(str(model_copy), ENV, 1, 0, SHORT, progress=False)


@pytest.mark.parametrize("key, name", [("model", "../../../../etc/passwd"), ("model", "/etc/passwd"),
                                       ("vecnormalize", "../other/normalisation.npz")])
def test_meta_paths_stay_inside_the_model_folder(model_copy, capsys, key, name):
    meta = json.loads((model_copy / "meta.json").read_text())
    meta[key] = name
    (model_copy / "meta.json").write_text(json.dumps(meta))
    err = _one_line_error(capsys, ["--policy", str(model_copy)])
    assert f"key '{key}'" in err and "outside the model folder" in err


def test_symlink_out_of_the_model_folder_is_refused(model_copy, tmp_path, capsys):
    (model_copy / "policy.pt").rename(tmp_path / "elsewhere.pt")
    (model_copy / "policy.pt").symlink_to(tmp_path / "elsewhere.pt")
    assert "outside the model folder" in _one_line_error(capsys, ["--policy", str(model_copy)])


def test_crafted_rllib_checkpoint_runs_no_code(tmp_path, capsys):
    marker = tmp_path / "owned"
    ckpt = tmp_path / "ckpt"
    module = ckpt.joinpath("learner_group", "learner", "rl_module", "default_policy")
    module.mkdir(parents=True)
    (ckpt / "rllib_checkpoint.json").write_text("{}")
    (module / "class_and_ctor_args.pkl").write_bytes(_pickle(marker))
    err = _one_line_error(capsys, ["--policy", str(ckpt)])
    assert "RLlib checkpoint is a Python pickle" in err and not marker.exists()
    meta_dir = tmp_path / "ours"
    meta_dir.mkdir()
    (meta_dir / "meta.json").write_text(json.dumps({"backend": "rllib", "model": "../ckpt"}))
    assert "outside the model folder" in _one_line_error(capsys, ["--policy", str(meta_dir)])


def test_yaml_python_tags_run_no_code(tmp_path):
    """A hyperparameter file with a python/object tag: the safe loader refuses it, nothing runs."""
    from agents.train import load_hyperparams

    marker = tmp_path / "owned"
    f = tmp_path / "hp.yml"
    f.write_text(f"{ENV}: !!python/object/apply:builtins.open ['{marker}', 'w']\n")
    with pytest.raises(ValueError, match="hp.yml: not valid YAML"):
        load_hyperparams("ppo", ENV, f)
    assert not marker.exists()


@pytest.mark.parametrize("text", [
    "dict(x=__import__('os'))",
    "dict(activation_fn=nn.modules.module.__builtins__['exec'])",
    "dict(activation_fn=nn.Tanh.__subclasses__)",
    "dict(net_arch=[64] * 10**9)",
    "(lambda: 1)()",
    "dict(activation_fn=os.system)",
])
def test_policy_kwargs_are_data_not_code(text):
    """The RL Zoo string form is parsed into names and numbers; no attribute, subscript or call but dict(...)."""
    from agents.policy_spec import declarative

    with pytest.raises(ValueError, match="hp.yml"):
        declarative(text, "hp.yml")


def test_policy_kwargs_forms_agree():
    from agents.policy_spec import declarative, to_sb3

    text = "dict(log_std_init=-1.5, net_arch=dict(pi=[64, 64], vf=[64, 64]), activation_fn=nn.Tanh, ortho_init=True)"
    mapping = {"log_std_init": -1.5, "net_arch": {"pi": [64, 64], "vf": [64, 64]}, "activation_fn": "Tanh",
               "ortho_init": True}
    assert declarative(text, "f") == declarative(mapping, "f") == mapping
    import torch.nn as nn

    assert to_sb3(mapping)["activation_fn"] is nn.Tanh
    skip = declarative("dict(features_extractor_class=AffineSkip, features_extractor_kwargs=dict(hidden=64))", "f")
    assert skip["features_extractor_class"] == "AffineSkip"


def test_trust_pickle_is_not_a_model_option_for_scripted_policies(capsys):
    """--trust-pickle only permits; it is accepted (and ignored) with a scripted policy."""
    assert main(["evaluate", "--policy", "ekf-pid", "--env", ENV, "--episodes", "1", "--seed", "0",
                 "--env-kwargs", json.dumps(SHORT), "--trust-pickle", "--json"]) == 0
    json.loads(capsys.readouterr().out)


def test_options_record_trust():
    assert ModelOptions(trust_pickle=True).given() == []
