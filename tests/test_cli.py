"""The command line: JSON contract, simulate round trip, and one-line errors on bad input."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from omni_gym.cli import build_parser, main
from omni_gym.physics.model import SimModel, load_model


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



def test_simulate_says_in_one_line_that_it_leaves_out_a_model_s_tracker_part(tmp_path, capsys):
    """A model with tracker effects replays the body's physics only: the same trajectory as without them,
    and one line on stderr that names them and the command that applies them; none for a physics-only model."""
    data = load_model("williams2002").to_json()
    data["tracker"] = {"tracker_offset": {"offset": [0.03, -0.02], "yaw": 0.01}}
    model_file = tmp_path / "m.json"
    model_file.write_text(json.dumps(data))
    cmds = tmp_path / "c.csv"
    cmds.write_text("t,w1,w2,w3\n0,5,5,5\n0.2,0,0,0\n")
    assert main(["simulate", "--model", "williams2002", "--commands", str(cmds), "--out", str(tmp_path / "b.csv")]) == 0
    assert capsys.readouterr().err == ""
    out = tmp_path / "a.csv"
    assert main(["simulate", "--model", str(model_file), "--commands", str(cmds), "--out", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tracker part (tracker_offset)" in err[0] and "omni-gym score" in err[0]
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()

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
    (lambda d: d.__setitem__("wheels", d["wheels"][:2]), "wheels (count) must be an integer in [3, 16], got 2"),
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


# --- input files: BOM, CRLF, bounds, messages that name where ---------------------------------------


def _simulate(tmp_path, commands_text, *extra, model="williams2002", name="c.csv"):
    """Run ``simulate`` in-process on a commands text; returns (exit code, stderr, output path)."""
    cmds = tmp_path / name
    cmds.write_bytes(commands_text.encode() if isinstance(commands_text, str) else commands_text)
    out = tmp_path / f"{name}.out.csv"
    code = main(["simulate", "--model", model, "--commands", str(cmds), "--out", str(out), *extra])
    return code, cmds, out


def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("omni-gym: error: ")
    return err[0]


def test_commands_with_bom_and_crlf_replay_exactly_like_plain_ones(tmp_path):
    plain = "t,w1,w2,w3\n0,5,4,-3\n0.2,1,1,1\n0.3,0,0,0\n"
    code, _, ref = _simulate(tmp_path, plain, name="plain.csv")
    assert code == 0
    # As a spreadsheet saves it: UTF-8 byte-order mark and CRLF line ends.
    spreadsheet = b"\xef\xbb\xbf" + plain.replace("\n", "\r\n").encode()
    code, _, out = _simulate(tmp_path, spreadsheet, name="excel.csv")
    assert code == 0 and out.read_bytes() == ref.read_bytes()


def test_model_json_with_bom_and_crlf_is_read(tmp_path):
    data = load_model("phunopas2018", "paper", "initial").to_json()
    f = tmp_path / "m.json"
    f.write_bytes(b"\xef\xbb\xbf" + json.dumps(data, indent=2).replace("\n", "\r\n").encode())
    assert load_model(str(f)).to_json() == data


BOUNDED_COMMANDS = {
    "underscore": ("t,w1,w2,w3\n0,1_000,1,1\n1,0,0,0\n", "row 2: column w1: not a number: '1_000'"),
    "time_1e308": ("t,w1,w2,w3\n0,1,1,1\n1e308,0,0,0\n", "row 3: column t: must be a number in [0, 3600] s"),
    "speed_1e5": ("t,w1,w2,w3\n0,1,-1e5,1\n1,0,0,0\n", "row 2: column w2: must be a number in [-10000, 10000]"),
    "hex": ("t,w1,w2,w3\n0,0x10,1,1\n1,0,0,0\n", "row 2: column w1: not a number: '0x10'"),
    "arabic_digits": ("t,w1,w2,w3\n0,\u0661,1,1\n1,0,0,0\n", "row 2: column w1: not a number"),
    "binary": (b"\x89PNG\r\n\x1a\n\xff\x00\x00", "not a UTF-8 text file (byte 0x89 at offset 0)"),
    "utf16": ("t,w1,w2,w3\n0,1,1,1\n".encode("utf-16"), "UTF-16 text; save it as UTF-8"),
}


@pytest.mark.parametrize("case", sorted(BOUNDED_COMMANDS))
def test_out_of_bound_or_unreadable_commands_are_refused_naming_file_row_column(tmp_path, capsys, case):
    text, expected = BOUNDED_COMMANDS[case]
    code, cmds, out = _simulate(tmp_path, text)
    line = _one_error_line(capsys)
    assert code == 2 and expected in line and str(cmds) in line
    assert not out.exists()


def _model_variant(tmp_path, mutate):
    data = load_model("williams2002").to_json()
    mutate(data)
    f = tmp_path / "m.json"
    f.write_text(json.dumps(data))
    return f


BOUNDED_MODELS = {
    "mass_1e308": (lambda d: d.__setitem__("mass", 1e308), "mass must be a number in [0.001, 10000] kg"),
    "mass_huge_int": (lambda d: d.__setitem__("mass", 10**400), "mass must be finite, got an integer of 401 digits"),
    "rollers_2.7": (lambda d: d.__setitem__("rollers", 2.7), "rollers must be an integer in [1, 100], got 2.7"),
    "rollers_true": (lambda d: d.__setitem__("rollers", True), "rollers must be a number, got True"),
    "gravity_0": (lambda d: d.__setitem__("gravity", 0), "gravity must be a number in [0.1, 100]"),
    "inertia_tiny": (lambda d: d.__setitem__("inertia", 1e-300), "inertia must be a number in [1e-7, 100000]"),
    "position_1e308": (lambda d: d["wheels"][1].__setitem__("position", [1e308, 0]),
                       "wheels[1].position[0] must be a number in [-10, 10] m"),
    "drive_tiny": (lambda d: d["wheels"][0].__setitem__("drive", [1e-300, 0]),
                   "wheels[0].drive length must be a number in [1e-6, 1e6]"),
    "com_far": (lambda d: d.__setitem__("com", [0, 50]), "com[1] must be a number in [-10, 10] m"),
    "mu_100": (lambda d: d["surface"].__setitem__("mu_drive", 100), "surface.mu_drive must be a number in [0, 10]"),
    "k_0.5": (lambda d: d["surface"].__setitem__("k", 0.5), "surface.k must be a number in [1, 10000] s/m"),
    "body_radius_0": (lambda d: d.__setitem__("body_radius", 0), "body_radius must be a number in [0.001, 20] m"),
    "v_s_0": (lambda d: d.__setitem__("effects", {"kinetic_friction": {"ratio": 0.5, "v_s": 0}}),
              "effect 'kinetic_friction': v_s must be a number in [0.0001, 10] m/s"),
    "lift_rate_2000": (lambda d: d.__setitem__("effects", {"wheel_liftoff": {"lift_rate": 2000, "recover_rate": 5}}),
                       "lift_rate must be a number in [0, 1000] 1/s"),
    "phase_text": (lambda d: d.__setitem__("effects", {"roller_gap": {"mu_gap": 0.5, "roller_fraction": 0.9,
                                                                      "phase": [0, "a", 0]}}),
                   "effect 'roller_gap': phase[1] must be a number, got 'a'"),
    "scale_dict": (lambda d: d.__setitem__("effects", {"wheel_radius": {"scale": {"a": 1}}}),
                   "effect 'wheel_radius': scale must be 3 numbers (one per wheel)"),
}


@pytest.mark.parametrize("case", sorted(BOUNDED_MODELS))
def test_out_of_bound_model_is_refused_naming_file_and_key(tmp_path, capsys, case):
    mutate, expected = BOUNDED_MODELS[case]
    model_file = _model_variant(tmp_path, mutate)
    code, _, out = _simulate(tmp_path, "t,w1,w2,w3\n0,1,1,1\n1,0,0,0\n", model=str(model_file))
    line = _one_error_line(capsys)
    assert code == 2 and expected in line and str(model_file) in line
    assert not out.exists()


def test_model_at_its_bounds_is_accepted(tmp_path):
    """Bounds are inclusive as documented: the extreme values themselves still simulate finitely. The smallest
    wheel (1 mm) takes the largest command (1e4 rad/s): 10 m/s at the rim, inside the plausible rim speed."""
    def extremes(d):
        d.update(mass=1e-3, inertia=1e-7, gravity=100.0, rollers=100, roller_fraction=1.0, wheel_radius=1e-3)
        d["surface"].update(mu_drive=10.0, k=1e4)
        d["effects"] = {"wheel_liftoff": {"lift_rate": 0, "recover_rate": 1e3}}

    code, _, out = _simulate(tmp_path, "t,w1,w2,w3\n0,1e4,-1e4,0\n0.01,0,0,0\n",
                             model=str(_model_variant(tmp_path, extremes)))
    assert code == 0 and np.all(np.isfinite(np.loadtxt(out, delimiter=",", skiprows=1)))


def test_binary_model_file_is_named(tmp_path, capsys):
    f = tmp_path / "model.json"
    f.write_bytes(bytes(range(128, 256)))
    assert main(["model", "show", str(f)]) == 2
    line = _one_error_line(capsys)
    assert str(f) in line and "not a UTF-8 text file" in line and "codec" not in line


@pytest.mark.parametrize(("dt", "ok"), [("0.01", False), ("0.0021", False), ("1e-9", False), ("nan", False),
                                         ("0.002", True), ("1e-5", True)])
def test_simulate_dt_matches_the_environments_bound_and_has_a_floor(tmp_path, capsys, dt, ok):
    code, _, out = _simulate(tmp_path, "t,w1,w2,w3\n0,1,1,1\n0.01,0,0,0\n", "--dt", dt)
    if ok:
        assert code == 0 and out.exists()
    else:
        line = _one_error_line(capsys)
        assert code == 2 and "--dt must be a number in [1e-5, 0.002] s" in line and not out.exists()


def test_simulate_refuses_a_run_with_too_many_substeps_before_running(tmp_path, capsys):
    # 3000 s at the finest step is 3e8 substeps (about half an hour): refused at once, naming both.
    code, cmds, out = _simulate(tmp_path, "t,w1,w2,w3\n0,1,1,1\n3000,0,0,0\n", "--dt", "1e-5")
    line = _one_error_line(capsys)
    assert code == 2 and "--dt 1e-05 s" in line and str(cmds) in line and "3e+08 substeps" in line
    assert not out.exists()


@pytest.mark.parametrize("command", [
    ["simulate", "--model", "williams2002", "--commands", "c.csv", "--out", "o.csv", "--seed", "-1"],
    ["synth", "--model", "williams2002", "--hidden", "none", "--out", "ds", "--seed", "-1"],
    ["gap", "ds", "--out", "rep", "--seed", "-1"],
])
def test_negative_seed_is_refused_naming_the_option(tmp_path, capsys, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.csv").write_text("t,w1,w2,w3\n0,1,1,1\n1,0,0,0\n")
    assert main(command) == 2
    line = _one_error_line(capsys)
    assert "--seed must be an integer in [0, 9007199254740992], got -1" in line
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "ds").exists()


@pytest.mark.parametrize(("option", "value", "expected"), [
    ("--duration", "1e308", "--duration must be a number in [0.2, 3600] s"),
    ("--duration", "inf", "--duration must be a number in [0.2, 3600] s"),
    ("--runs", "0", "--runs must be an integer in [1, 1000]"),
    ("--noise", "nan", "--noise must be a number in [0, 1] m"),
    ("--hidden", 'motor_lag:{"tau": 1e308}', "--hidden motor_lag: effect 'motor_lag': tau must be a number in [0, 10]"),
    ("--hidden", 'viscous_drag:{"c": 1e308}', "--hidden viscous_drag: c / mass must be a number in [0, 1000] 1/s"),
])
def test_synth_options_out_of_bounds_are_one_line_errors(tmp_path, capsys, option, value, expected):
    args = {"--hidden": "none", "--runs": "1", "--duration": "1"}
    args[option] = value
    argv = ["synth", "--model", "williams2002", "--out", str(tmp_path / "ds")]
    for k, v in args.items():
        argv += [k, v]
    if option not in args:
        argv += [option, value]
    assert main(argv) == 2
    assert expected in _one_error_line(capsys)
    assert not (tmp_path / "ds").exists()


def test_simulate_never_writes_a_non_finite_number(tmp_path, capsys, monkeypatch):
    """Whatever the cause, a non-finite state is refused before anything is written."""
    import omni_gym.physics.replay

    def diverging(model, times, commands, **kwargs):
        states = np.zeros((len(times), 6))
        states[1:, 0] = np.nan
        return states

    monkeypatch.setattr(omni_gym.physics.replay, "simulate_commands", diverging)
    code, cmds, out = _simulate(tmp_path, "t,w1,w2,w3\n0,1,1,1\n0.5,0,0,0\n")
    line = _one_error_line(capsys)
    assert code == 2 and "non-finite at t = 0.5 s" in line and not out.exists()


def test_refused_simulate_leaves_no_folder_it_created(tmp_path, capsys):
    """--out in folders that do not exist: they appear with the output, never for a refused run."""
    cmds = tmp_path / "c.csv"
    cmds.write_text("t,w1,w2,w3\n0,1,1,1\n1,0,0,0\n")
    out = tmp_path / "nodir" / "sub" / "traj.csv"
    for argv in (["--commands", str(tmp_path / "missing.csv")], ["--commands", str(cmds), "--seed", "-1"]):
        assert main(["simulate", "--model", "williams2002", "--out", str(out), *argv]) == 2
        _one_error_line(capsys)
        assert not (tmp_path / "nodir").exists()
    assert main(["simulate", "--model", "williams2002", "--out", str(out), "--commands", str(cmds)]) == 0
    assert out.is_file() and sorted(p.name for p in out.parent.iterdir()) == ["traj.csv"]  # no lock, no temporary


def _fake_gap(monkeypatch) -> list:
    """Replace the workflow by a recorder of its backend (the CLI's checks and messages are under test)."""
    import omni_gym.discrepancy.workflow as workflow

    seen = []
    monkeypatch.setattr(workflow, "gap", lambda *a, backend, **kw: seen.append(backend) or {})
    return seen


@pytest.mark.parametrize(("value", "expected"), [
    ("0", "--jobs must be an integer in [1, 1024], got 0"),
    ("1000000000000000000000000000000", "--jobs must be an integer in [1, 1024], got 1000000000000000000000000000000"),
    ("-3", "--jobs must be an integer in [1, 1024], got -3"),
])
def test_gap_jobs_out_of_bounds_is_one_line_naming_the_option(tmp_path, capsys, monkeypatch, value, expected):
    seen = _fake_gap(monkeypatch)
    assert main(["gap", str(tmp_path / "ds"), "--out", str(tmp_path / "rep"), "--jobs", value]) == 2
    assert expected in _one_error_line(capsys)
    assert not seen and not (tmp_path / "rep").exists()


def test_gap_jobs_beyond_the_cores_is_capped_with_a_warning(tmp_path, capsys, monkeypatch):
    import omni_gym.cli

    seen = _fake_gap(monkeypatch)
    monkeypatch.setattr(omni_gym.cli, "usable_cores", lambda: 2)
    assert main(["gap", str(tmp_path / "ds"), "--out", str(tmp_path / "rep"), "--jobs", "64", "--json"]) == 0
    err = capsys.readouterr().err
    assert "warning: --jobs 64 is more than the 2 cores" in err and "running 2 local processes" in err
    assert seen[0].jobs == 2
    assert main(["gap", str(tmp_path / "ds"), "--out", str(tmp_path / "rep"), "--jobs", "2", "--json"]) == 0
    assert "warning" not in capsys.readouterr().err and seen[1].jobs == 2


def test_gap_fit_budget_below_the_minimum_says_the_minimum(tmp_path, capsys, monkeypatch):
    from omni_gym.discrepancy.data.budget import MIN_FIT_BUDGET, MIN_SEGMENT

    seen = _fake_gap(monkeypatch)
    assert main(["gap", str(tmp_path / "ds"), "--out", str(tmp_path / "rep"), "--fit-budget", "0.5"]) == 2
    line = _one_error_line(capsys)
    assert f"--fit-budget must be at least {MIN_FIT_BUDGET:g} s" in line and "got 0.5" in line
    assert MIN_FIT_BUDGET == 2 * MIN_SEGMENT  # two runs' shortest segments: held-out folds need 2 source runs
    for ok in (str(MIN_FIT_BUDGET), "inf"):
        assert main(["gap", str(tmp_path / "ds"), "--out", str(tmp_path / "rep"), "--fit-budget", ok, "--json"]) == 0
    assert len(seen) == 2


def test_gap_help_states_the_segment_length_gap_uses(capsys):
    from omni_gym.discrepancy.data.budget import FIT_BUDGET, segment_seconds

    with pytest.raises(SystemExit):
        main(["gap", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"24 runs and the default: {segment_seconds(FIT_BUDGET, 24):g} s" in text
    assert "10 s segments" not in text


def test_an_overflow_anywhere_is_one_line(tmp_path, capsys, monkeypatch):
    import omni_gym.discrepancy.workflow as workflow

    def overflow(*args, **kwargs):
        return int(float(10**400))  # OverflowError: int too large to convert to float

    monkeypatch.setattr(workflow, "gap", overflow)
    assert main(["gap", str(tmp_path / "ds"), "--out", str(tmp_path / "rep")]) == 2
    assert "too large" in _one_error_line(capsys)


# --- the bounds table and the docs --------------------------------------------------------------

DOCS = Path(__file__).resolve().parent.parent / "docs"


def test_every_bound_in_code_is_the_table_in_docs_bounds_md():
    from omni_gym.bounds import SECTIONS, markdown_table
    from omni_gym.physics.model import MODEL_BOUNDS

    text = (DOCS / "bounds.md").read_text()
    for name, table in {"model": MODEL_BOUNDS, **SECTIONS}.items():
        assert markdown_table(table) in text, f"docs/bounds.md: the {name} table differs from omni_gym/bounds.py"


def test_every_physical_model_input_has_a_bound():
    from omni_gym.physics.effects import REGISTRY
    from omni_gym.physics.model import MODEL_BOUNDS

    data = load_model("williams2002").to_json()
    numeric = [k for k, v in data.items() if isinstance(v, (int, float))]
    numeric += [f"surface.{k}" for k, v in data["surface"].items() if isinstance(v, (int, float))]
    numeric += ["wheels (count)", "wheels[i].position", "wheels[i].drive (length)", "wheels[i].roller_angle", "com"]
    numeric += [f"effects.{name}.{k}" for name, effect in REGISTRY.items() for k in effect.keys]
    assert sorted(numeric) == sorted(MODEL_BOUNDS)


def test_every_surface_is_in_the_docs_table_with_its_coefficients():
    from omni_gym.physics.friction import SURFACES

    rows = [line for line in (DOCS / "model.md").read_text().splitlines() if line.startswith("| `")]
    help_text = build_parser()._subparsers._group_actions[0].choices["simulate"].format_help()
    for name, s in SURFACES.items():
        row = [r for r in rows if r.startswith(f"| `{name}` |")]
        assert row, f"docs/model.md: no row for surface {name!r}"
        cells = [c.strip() for c in row[0].split("|")[2:6]]
        assert [float(c) for c in cells] == [s.mu_drive, s.mu_transverse, s.mu_gap, s.k]
        assert name in help_text


def test_no_file_cites_a_path_outside_the_repository():
    root = DOCS.parent
    files = [*root.glob("omni_gym/**/*.py"), *root.glob("docs/*.md"), *root.glob("agents/**/*.py"), root / "README.md"]
    offenders = [str(f.relative_to(root)) for f in files if "shared/" in f.read_text()]
    assert offenders == []
    from omni_gym.physics.robot import PRESETS

    for make in PRESETS.values():
        assert all("shared/" not in why for why in make().assumptions.values())
