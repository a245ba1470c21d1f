"""``omni-gym score``: open-loop replay of a dataset's runs with several models, scored against the tracker."""

from __future__ import annotations

import json
import math

import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import write_dataset
from omni_gym.discrepancy.synthetic import recovery, synth

NOISE = 0.001  # m, tracker noise per axis


@pytest.fixture(scope="module")
def hidden_radius(tmp_path_factory):
    """A dataset whose nominal model lacks wheel-radius errors (+10 %, -5 %), and the true model's JSON file."""
    nominal = recovery.nominal_model()
    truth = nominal.with_effect("wheel_radius", {"scale": [1.1, 0.95, 1.0]})
    runs, _ = synth.synthesize(truth, "none", 2, NOISE, seed=4, duration=5.0)
    root = tmp_path_factory.mktemp("score")
    write_dataset(root / "data", nominal.to_json(), "hidden wheel radius", runs)
    (root / "truth.json").write_text(json.dumps(truth.to_json()))
    return root


def test_the_true_model_scores_at_tracker_noise_and_nominal_does_not(hidden_radius, capsys):
    code = main(["score", str(hidden_radius / "data"), "--model", str(hidden_radius / "truth.json"), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    means = out["models"]
    truth = means[str(hidden_radius / "truth.json")]["mean_position_rms"]
    nominal = means["nominal"]["mean_position_rms"]
    # The true model leaves only tracker noise: Euclidean error of two axes of σ = 1 mm has RMS √2·σ
    # (1.41 mm); 2 mm allows the world's own step error and the few hundred rows' scatter.
    assert truth < 2.0e-3, truth
    # Radius errors of +10 % and -5 % on two of three wheels over 5 s of driving: measured 10.5 mm, 7.5x the truth.
    assert nominal > 3 * truth, (nominal, truth)
    assert len(out["runs"]) == 4 and all(math.isfinite(r["final_error"]) for r in out["runs"])


def test_score_prints_a_table_with_means(hidden_radius, capsys):
    assert main(["score", str(hidden_radius / "data")]) == 0
    out = capsys.readouterr().out
    assert "run000" in out and "mean over 2 runs, nominal: position RMS" in out


def test_bad_models_and_datasets_are_one_line(hidden_radius, tmp_path, capsys):
    for model, what in (("regular4", "4 wheels"), ("no_such_robot", "unknown robot")):
        code = main(["score", str(hidden_radius / "data"), "--model", model])
        err = capsys.readouterr().err.strip()
        assert code == 2 and what in err and len(err.splitlines()) == 1 and err.startswith("omni-gym: error:"), err
    code = main(["score", str(tmp_path / "missing")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "not a dataset folder" in err and len(err.splitlines()) == 1, err
