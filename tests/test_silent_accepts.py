"""Inputs once accepted without a word are refused in one line, by a bound with its
reason in ``omni_gym/bounds.py``: a heading of 99999 rad, wheel commands of 3000 rad/s, 5 m of synthetic
tracker noise, a NaN row in an OptiOdom log."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from omni_gym.bounds import CLI, FILES
from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import Run, load_dataset, write_dataset
from omni_gym.physics.model import load_model

ROOT = Path(__file__).resolve().parents[1]
SESSION = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"


def _one_line(capsys, rc: int) -> str:
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and err.startswith("omni-gym: error: "), err
    return err


def test_a_heading_of_99999_rad_in_a_dataset_is_refused(tmp_path, capsys):
    model = load_model("williams2002")
    t = np.arange(0.0, 2.0, 0.02)
    pose = np.column_stack([0.1 * t, 0 * t, 0.2 * t])
    pose[40, 2] = 99999.0  # one corrupt cell
    write_dataset(tmp_path / "ds", model.to_json(), "a corrupt heading", [Run("r", t, np.zeros((len(t), 3)), pose)])
    assert not FILES["theta"].contains(99999.0)
    with pytest.raises(ValueError, match="theta"):
        load_dataset(tmp_path / "ds")
    err = _one_line(capsys, main(["score", str(tmp_path / "ds"), "--model", "williams2002"]))
    assert "theta" in err and "99999" in err


def test_wheel_commands_of_3000_rad_per_s_are_refused_by_simulate(tmp_path, capsys):
    commands = tmp_path / "cmd.csv"
    commands.write_text("t,w1,w2,w3\n0,3000,3000,3000\n0.5,3000,3000,3000\n1,0,0,0\n")
    out = tmp_path / "traj.csv"
    err = _one_line(capsys, main(["simulate", "--model", "williams2002", "--commands", str(commands), "--out",
                                  str(out)]))
    # 3000 rad/s on the Williams robot's 3 cm wheels: 90 m/s at the rim (bound: PLAUSIBLE_SPEED, 20 m/s)
    assert "cmd.csv" in err and "90 m/s at the rim" in err and not out.exists()


def test_five_metres_of_synthetic_tracker_noise_is_refused(tmp_path, capsys):
    assert not CLI["--noise"].contains(5.0)
    err = _one_line(capsys, main(["synth", "--model", "williams2002", "--hidden", "wheel_radius", "--runs", "1",
                                  "--duration", "1", "--noise", "5", "--out", str(tmp_path / "s")]))
    assert "--noise" in err and "[0, 1] m" in err and not (tmp_path / "s").exists()


@pytest.mark.parametrize("row", ["NaN,NaN,NaN,NaN,NaN,NaN,NaN", "0.16,NaN,NaN,NaN,NaN,NaN,NaN",
                                 "0.16,0.002,-0.0002,-0.011,NaN,NaN,NaN"])
def test_a_nan_row_in_an_optiodom_log_is_refused(tmp_path, capsys, row):
    """Only the pose cells of a row may be NaN (tracking lost: an unobserved row); a NaN time or wheel count
    leaves the wheels' motion unknown."""
    folder = tmp_path / "s"
    folder.mkdir()
    shutil.copy(SESSION / "221220201730_metadata.csv", folder)
    run = folder / "221220201730_run-01.csv"
    lines = (SESSION / run.name).read_text().splitlines()
    lines[4] = row
    run.write_text("\n".join(lines) + "\n")
    err = _one_line(capsys, main(["import", "optiodom", str(folder), "--out", str(tmp_path / "ds")]))
    assert "line 5" in err and "NaN" in err and not (tmp_path / "ds").exists()
