"""benchmarks/omni4_end_to_end.py: a controller with its design model's kinematics (omni_gym.physics.kinematics
.effective_kinematics, tested in test_kinematics.py), the paired statistics and
the command's input checks (the benchmark's figures are in benchmarks/results/omni4_end_to_end.md)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from benchmark_loader import load_benchmark

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "omni4_end_to_end.py"


def _load():
    return load_benchmark("omni4_end_to_end")


def test_open_loop_with_the_models_own_kinematics_follows_it():
    """On the calibrated model (a floor where the wheels grip, no lift-off), feed-forward through its own
    kinematics drives the reference; through the nominal kinematics every wheel turns ~7 % too far, a drift
    that grows with the distance travelled. 2 s episodes: the calibrated feed-forward stays within 3 mm
    (wheel-speed steps settle within milliseconds on grip), the nominal one is at least 3x worse."""
    e2e = _load()
    seeds = [0, 1]
    own = e2e.run_scripted((e2e.CALIBRATED, e2e.Scripted("open-loop", e2e.CALIBRATED), seeds, 2.0, e2e.MODEL))
    nom = e2e.run_scripted((e2e.CALIBRATED, e2e.Scripted("open-loop", e2e.NOMINAL), seeds, 2.0, e2e.MODEL))
    own_rmse = np.mean([e["tracking_rmse"] for e in own])
    nom_rmse = np.mean([e["tracking_rmse"] for e in nom])
    assert own_rmse < 0.003
    assert nom_rmse > 3.0 * own_rmse


def test_paired_ratio_share_and_ties():
    e2e = _load()
    rng = np.random.default_rng(1)
    b = rng.uniform(0.01, 0.05, 40)
    c = e2e.paired(0.5 * b, b)  # half the error on every seed: the paired interval is a point
    assert c["ratio"] == pytest.approx(0.5) and c["ratio_ci95"] == pytest.approx([0.5, 0.5])
    assert c["better"] == 1.0 and c["better_ci95"] == [1.0, 1.0] and c["ties"] == 0.0
    same = e2e.paired(b, b)  # the same controller: all ties, none better
    assert same["ratio"] == 1.0 and same["better"] == 0.0 and same["ties"] == 1.0
    mixed = e2e.paired(np.where(np.arange(40) < 10, 0.5 * b, 2.0 * b), b)  # better on 10 of 40 seeds
    assert mixed["better"] == 0.25 and mixed["better_ci95"][0] < 0.25 < mixed["better_ci95"][1]
    with pytest.raises(ValueError, match="two equal 1-D samples"):
        e2e.paired(b[:3], b)


def test_command_help_and_bad_input():
    run = [sys.executable, str(SCRIPT)]
    ok = subprocess.run([*run, "--help"], capture_output=True, text=True, cwd=ROOT)
    assert ok.returncode == 0 and "--quick" in ok.stdout and "calibrated" in ok.stdout
    bad = subprocess.run([*run, "--model", "no/such.json"], capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and "--model no/such.json: no such file" in bad.stderr
    assert "Traceback" not in bad.stderr
    bad = subprocess.run([*run, "--ppo-nominal", "nowhere"], capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and "--ppo-nominal nowhere: not a model directory" in bad.stderr
