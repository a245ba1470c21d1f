"""Your robot works by default: ``OmniPathFollow-Custom-v0`` uses the model's kinematics unless told otherwise,
``train`` finds hyperparameters for it (and for Williams-v1) without ``--hyperparams``, and ``evaluate`` says
when an id built from a model file keeps the nominal kinematics."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.cli import main
from omni_gym.physics.kinematics import effective_kinematics
from omni_gym.physics.model import load_model

CUSTOM = "OmniPathFollow-Custom-v0"


def calibrated():
    """williams2002 with every wheel rolling on a radius 8 % above nominal (a calibration's finding)."""
    return load_model("williams2002", surface="grip", friction="initial").with_effect("wheel_radius",
                                                                                        {"scale": [1.08] * 3})


def test_custom_id_defaults_to_the_model_kinematics():
    model = calibrated()
    W_eff, W_nom = effective_kinematics(model).matrix, model.robot.wheel_matrix()
    assert not np.allclose(W_eff, W_nom)
    env = gym.make(CUSTOM, model=model)
    np.testing.assert_array_equal(env.unwrapped.wheel_matrix, W_eff)
    assert env.unwrapped.cfg.kinematics == "model"
    np.testing.assert_array_equal(gym.make(CUSTOM, model=model, kinematics="nominal").unwrapped.wheel_matrix, W_nom)
    venv = gym.make_vec(CUSTOM, num_envs=2, vectorization_mode="vector_entry_point", model=model)
    np.testing.assert_array_equal(venv.unwrapped.wheel_matrix, W_eff)
    # The other ids keep "nominal" under model= (bit-identical behaviour there).
    other = gym.make("OmniPathFollow-Phunopas-v0", model=model)
    assert other.unwrapped.cfg.kinematics == "nominal"


def test_default_hyperparameter_file_per_id():
    from agents.train import default_hyperparams, load_hyperparams

    assert default_hyperparams("ppo", "OmniPathFollow-Phunopas-v0") is None  # ppo.yml has it: unchanged
    assert default_hyperparams("ppo", "OmniPathFollow-Williams-v1") == "ppo_residual"
    assert default_hyperparams("ppo", CUSTOM) == "ppo_residual"
    assert default_hyperparams("sac", CUSTOM) == "sac_residual"
    assert default_hyperparams("ppo", CUSTOM, "ppo_privileged") == "ppo_privileged"  # given: kept
    assert default_hyperparams("td3", "OmniGoToPose-v0") is None  # nothing fits: the error names the files
    for algo in ("ppo", "sac"):
        hp = load_hyperparams(algo, CUSTOM, f"{algo}_residual")
        # The model's lift-off (or none) is the robot's: not randomised away.
        assert "randomize_lift_rate" not in hp["env_kwargs"]
        assert hp["env_wrapper"][0]["agents.wrappers.EKFFeatures"]["residual_scale"] == 0.3


def test_missing_entry_hint_names_a_command(capsys, tmp_path):
    rc = main(["train", "--algo", "td3", "--env", "OmniPathFollow-Williams-v1", "--out", str(tmp_path / "m"),
               "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert "no entry for 'OmniPathFollow-Williams-v1'" in err and "e.g. --hyperparams" in err


@pytest.mark.parametrize("env_id, noted", [("OmniPathFollow-Phunopas-v0", True), (CUSTOM, False)])
def test_evaluate_notes_nominal_kinematics_under_a_model(tmp_path, capsys, env_id, noted):
    path = tmp_path / "model.json"
    import json

    path.write_text(json.dumps(calibrated().to_json()))
    kwargs = json.dumps({"model": str(path), "episode_seconds": 0.5})
    assert main(["evaluate", "--policy", "ekf-pid", "--env", env_id, "--episodes", "1", "--seed", "10000",
                 "--env-kwargs", kwargs]) == 0
    err = capsys.readouterr().err
    assert ("keeps the robot preset's nominal kinematics" in err) == noted
