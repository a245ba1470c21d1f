"""``omni-gym calibrate`` refuses what is not an answer: fitted values at the optimiser's bounds,
a frozen encoder, a dead-reckoning residual far above noise and modelling. Each refusal is one line naming
what is wrong, points to ``omni-gym gap``, exits 2 and writes nothing."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import load_dataset, write_dataset
from omni_gym.discrepancy.synthetic.synth import synthesize
from omni_gym.physics.model import load_model

ROOT = Path(__file__).resolve().parents[1]
SESSION = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"


@pytest.fixture(scope="module")
def real(omni3_two_runs) -> Path:
    return omni3_two_runs


def _refused(capsys, dataset: Path, out: Path, *extra: str) -> str:
    rc = main(["calibrate", str(dataset), "--out", str(out), *extra])
    captured = capsys.readouterr()
    err = captured.err
    assert rc == 2 and err.count("\n") == 1 and err.startswith("omni-gym: error: "), err
    assert f"omni-gym gap {dataset}" in err and not out.exists() and "wrote" not in captured.out
    return err


def test_a_slipping_robot_gets_no_calibration(tmp_path, capsys):
    """The Williams robot on its own (slipping) floor: the fit runs into the ±50 % box on the diameters and L
    (and, with --tracker, the frame's yaw), values the optimiser was stopped at, not measurements."""
    model = load_model("williams2002")
    runs, _ = synthesize(model, "none", runs=2, noise=0.001, seed=1, duration=6.0)
    write_dataset(tmp_path / "ds", model.to_json(), "slipping Williams robot", runs)
    err = _refused(capsys, tmp_path / "ds", tmp_path / "m.json")
    assert "D1 = 40.00 mm at its lower bound (nominal 60.00 / 1.5)" in err and "L = 60.00 mm at its lower bound" in err
    assert "dead reckoning is still" in err  # the residual too: 43 mm per 1 s window against at most 19 mm
    err = _refused(capsys, tmp_path / "ds", tmp_path / "m.json", "--tracker")
    assert "tracker yaw = 200.0 mrad at its bound ±200" in err


def test_a_frozen_encoder_is_named(real, tmp_path, capsys):
    ds = load_dataset(real)
    runs = []
    for run in ds.runs:
        enc = run.enc.copy()
        enc[:, 1] = enc[0, 1]  # wheel 2's encoder stuck at its first reading
        runs.append(replace(run, enc=enc))
    write_dataset(tmp_path / "frozen", ds.model_json, "enc2 frozen", runs)
    err = _refused(capsys, tmp_path / "frozen", tmp_path / "m.json")
    assert "enc2 never changes while the other wheels turn" in err and "frozen encoder" in err


def test_a_residual_far_above_noise_is_refused(real, tmp_path, capsys):
    """The tracked robot also slides sideways (world y) at 0.1 m/s, which no wheel diameter or length explains:
    100 mm per 1 s window against the 25 % of its ~150 mm travel (plus 3 × 2σ of noise) a model may leave."""
    ds = load_dataset(real)
    runs = []
    for run in ds.runs:
        pose = run.pose.copy()
        pose[:, 1] += 0.1 * run.t
        runs.append(replace(run, pose=pose))
    write_dataset(tmp_path / "drift", ds.model_json, "sliding", runs)
    err = _refused(capsys, tmp_path / "drift", tmp_path / "m.json")
    assert "dead reckoning is still" in err and "over 1 s windows" in err


def test_the_real_session_is_still_calibrated(real, tmp_path, capsys):
    assert main(["calibrate", str(real), "--out", str(tmp_path / "m.json")]) == 0
    assert main(["calibrate", str(real), "--out", str(tmp_path / "t.json"), "--tracker"]) == 0
    assert (tmp_path / "m.json").exists() and (tmp_path / "t.json").exists()
