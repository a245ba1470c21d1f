"""The command line: JSON contract, simulate round trip, and one-line errors on bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.model import SimModel, load_model


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "omni_gym.cli", *args], capture_output=True, text=True)


def test_model_show_json_contract(capsys):
    assert main(["model", "show", "williams2002", "--surface", "paper", "--friction", "initial", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    for key in ("name", "mass", "inertia", "gravity", "wheel_radius", "wheels", "com", "rollers",
                "roller_fraction", "friction", "surface"):
        assert key in data
    assert data["surface"] == {"name": "paper", "mu_drive": 0.26, "mu_transverse": 0.09, "mu_gap": 0.47, "k": 1000.0}
    assert data["friction"] == "initial" and data["com"] == [0.0, 0.0]
    assert len(data["wheels"]) == 3 and data["rollers"] == 8 and data["roller_fraction"] == 0.9
    # Round trip: the printed model rebuilds the same model.
    assert SimModel.from_json(data).to_json() == data


def test_simulate_matches_library_and_starts_at_rest(tmp_path):
    model = load_model("phunopas2018", "carpet", "roller_gap")
    w = model.robot.wheel_matrix() @ np.array([0.2, 0.1, 0.3])
    cmds = tmp_path / "c.csv"
    cmds.write_text("t,w1,w2,w3,w4\n0," + ",".join(map(str, w)) + "\n0.5,0,0,0,0\n0.8,0,0,0,0\n")
    out = tmp_path / "traj.csv"
    assert main(["simulate", "--model", "phunopas2018", "--surface", "carpet", "--commands", str(cmds),
                 "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "t,x,y,theta,vx,vy,omega"
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape == (3, 7)
    np.testing.assert_array_equal(data[0], np.zeros(7))
    # Moving forward-left while turning: x and θ grow over the first 0.5 s; stopped wheels brake it.
    assert data[1, 1] > 0.05 and data[1, 3] > 0.05
    assert abs(data[2, 4]) < 1e-3 and abs(data[2, 6]) < 1e-2


def test_model_file_round_trip_through_simulate(tmp_path):
    model_file = tmp_path / "m.json"
    model_file.write_text(json.dumps(load_model("williams2002").to_json()))
    cmds = tmp_path / "c.csv"
    cmds.write_text("t,w1,w2,w3\n0,5,5,5\n0.2,0,0,0\n")
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["simulate", "--model", str(model_file), "--commands", str(cmds), "--out", str(a)]) == 0
    assert main(["simulate", "--model", "williams2002", "--commands", str(cmds), "--out", str(b)]) == 0
    assert a.read_text() == b.read_text()


BAD_COMMANDS = {
    "unordered": ("t,w1,w2,w3\n0,1,1,1\n0.5,1,1,1\n0.4,0,0,0\n", "row 4: times must be strictly increasing"),
    "wrong_wheels": ("t,w1,w2,w3,w4\n0,1,1,1,1\n1,0,0,0,0\n", "header has 4 wheel columns, the model has 3"),
    "nan": ("t,w1,w2,w3\n0,1,nan,1\n1,0,0,0\n", "row 2: column w2: value must be finite"),
    "text": ("t,w1,w2,w3\n0,1,x,1\n1,0,0,0\n", "row 2: column w2: not a number"),
    "short_row": ("t,w1,w2,w3\n0,1,1\n", "row 2: expected 4 values, got 3"),
    "not_from_zero": ("t,w1,w2,w3\n0.1,1,1,1\n1,0,0,0\n", "row 2: the first time must be 0"),
    "empty": ("", "empty file"),
}


@pytest.mark.parametrize("case", sorted(BAD_COMMANDS))
def test_bad_commands_give_one_line_error(tmp_path, case):
    text, expected = BAD_COMMANDS[case]
    cmds = tmp_path / "c.csv"
    cmds.write_text(text)
    out = tmp_path / "traj.csv"
    res = run_cli("simulate", "--model", "williams2002", "--commands", str(cmds), "--out", str(out))
    assert res.returncode == 2
    assert "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and str(cmds) in lines[0]
    assert not out.exists()  # no partial output


@pytest.mark.parametrize("mutate, expected", [
    (lambda d: d.pop("mass"), "missing key 'mass'"),
    (lambda d: d["surface"].pop("mu_gap"), "missing key 'surface.mu_gap'"),
    (lambda d: d.__setitem__("inertia", float("nan")), "inertia must be finite"),
    (lambda d: d.__setitem__("wheels", d["wheels"][:2]), "at least 3 wheels"),
    (lambda d: d.__setitem__("friction", "magic"), "unknown friction model 'magic'"),
])
def test_bad_model_file_gives_one_line_error(tmp_path, mutate, expected):
    data = load_model("williams2002").to_json()
    mutate(data)
    model_file = tmp_path / "m.json"
    model_file.write_text(json.dumps(data))
    cmds = tmp_path / "c.csv"
    cmds.write_text("t,w1,w2,w3\n0,1,1,1\n1,0,0,0\n")
    res = run_cli("simulate", "--model", str(model_file), "--commands", str(cmds), "--out", str(tmp_path / "o.csv"))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and str(model_file) in lines[0]


def test_malformed_json_and_unknown_preset(tmp_path):
    bad = tmp_path / "m.json"
    bad.write_text("{not json")
    res = run_cli("model", "show", str(bad), "--json")
    assert res.returncode == 2 and "not valid JSON" in res.stderr and "Traceback" not in res.stderr
    res = run_cli("model", "show", "hexapod")
    assert res.returncode == 2 and "unknown robot 'hexapod'" in res.stderr
