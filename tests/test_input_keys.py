"""Unknown keys in the JSON files the package reads are refused at every level, with a "did you mean".

A misspelt optional key would otherwise fall back to its default without a word: a calibrated model
read as the nominal one.
"""

import json
from pathlib import Path

import gymnasium as gym
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import load_dataset, write_dataset
from omni_gym.io import InputError
from omni_gym.physics.model import SimModel, load_model

ROOT = Path(__file__).resolve().parents[1]


def _model_dict() -> dict:
    data = load_model("williams2002").to_json()
    data["effects"] = {"motor_lag": {"tau": 0.05}}
    return data


# (mutation, the key path the message must name, the suggestion it must make)
TYPOS = {
    "top": (lambda d: d.__setitem__("efects", d.pop("effects")), "'efects'", "did you mean 'effects'"),
    "body_radius": (lambda d: d.__setitem__("body_raduis", d.pop("body_radius")), "'body_raduis'",
                    "did you mean 'body_radius'"),
    "gravity": (lambda d: d.__setitem__("gravty", d.pop("gravity")), "'gravty'", "did you mean 'gravity'"),
    "com": (lambda d: d.__setitem__("comm", d.pop("com")), "'comm'", "did you mean 'com'"),
    "wheel": (lambda d: d["wheels"][2].__setitem__("positon", [0.0, 0.0]), "'wheels[2].positon'",
              "did you mean 'position'"),
    "surface": (lambda d: d["surface"].__setitem__("kk", 5.0), "'surface.kk'", "did you mean 'k'"),
    "effect_name": (lambda d: d.__setitem__("effects", {"motor_lags": {"tau": 0.05}}), "'effects.motor_lags'",
                    "did you mean 'motor_lag'"),
    "effect_param": (lambda d: d["effects"]["motor_lag"].__setitem__("tua", 0.05), "'effects.motor_lag.tua'",
                     "did you mean 'tau'"),
}


@pytest.mark.parametrize("case", sorted(TYPOS))
def test_unknown_model_key_is_refused_with_path_and_suggestion(tmp_path, capsys, case):
    mutate, path, hint = TYPOS[case]
    data = _model_dict()
    mutate(data)
    f = tmp_path / "robot.json"
    f.write_text(json.dumps(data))
    assert main(["model", "show", str(f)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert captured.out == "" and len(lines) == 1
    assert str(f) in lines[0] and f"unknown key {path}" in lines[0] and hint in lines[0]
    # The same model as a dict to gym.make: the same refusal, naming the key.
    with pytest.raises(ValueError, match="unknown key " + path.replace("[", r"\[").replace("]", r"\]")):
        gym.make("OmniPathFollow-Williams-v1", model=data)


@pytest.mark.parametrize("effects", [[], ["motor_lag"], None, "motor_lag"])
def test_effects_must_be_an_object_whatever_else_it_is(effects):
    data = _model_dict()
    data["effects"] = effects
    with pytest.raises(ValueError, match=r"'effects' must be an object \{EFFECT: \{parameters\}\}"):
        SimModel.from_json(data)


def test_empty_effects_object_and_absent_effects_mean_no_effect():
    data = _model_dict()
    data["effects"] = {}
    assert SimModel.from_json(data).effects == {}
    del data["effects"]
    assert SimModel.from_json(data).effects == {}


def test_roller_angle_is_a_known_wheel_key():
    """``roller_angle`` [rad] (mecanum wheels) is part of the wheel schema, so it is not an unknown key."""
    data = _model_dict()
    data["wheels"][0]["roller_angle"] = 0.0
    try:
        SimModel.from_json(data)
    except ValueError as exc:  # a bound or layout check may apply; the key itself must be known
        assert "unknown key" not in str(exc)


def test_unknown_key_in_dataset_json_is_refused(tmp_path):
    folder = tmp_path / "ds"
    write_dataset(folder, load_model("williams2002").to_json(), "x", [])
    meta = json.loads((folder / "dataset.json").read_text())
    meta["descripton"] = meta.pop("description")
    (folder / "dataset.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match=r"dataset\.json: unknown key 'descripton'; did you mean 'description'"):
        load_dataset(folder)
    meta["description"] = meta.pop("descripton")
    meta["model"]["surface"]["mu_gapp"] = 0.4
    (folder / "dataset.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=r"dataset\.json: model: unknown key 'surface\.mu_gapp'"):
        load_dataset(folder)


def test_gym_make_keyword_typo_suggests_the_keyword():
    with pytest.raises(ValueError, match="unknown keyword argument 'lift_rte'; did you mean 'lift_rate'"):
        gym.make("OmniPathFollow-Williams-v1", lift_rte=0.5)


def _models_in(obj):
    """Every model object (a dict with 'wheels' and 'surface') nested in a JSON value."""
    if isinstance(obj, dict):
        if "wheels" in obj and "surface" in obj:
            yield obj
        for v in obj.values():
            yield from _models_in(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _models_in(v)


def test_every_committed_model_json_still_loads():
    files = [p for d in ("agents", "benchmarks", "data", "docs") for p in (ROOT / d).rglob("*.json")]
    models = [(f, m) for f in files for m in _models_in(json.loads(f.read_text(encoding="utf-8-sig")))]
    assert models, "the repository commits model JSON (benchmarks/inputs/omni4_calibrated_model.json)"
    for f, m in models:
        SimModel.from_json(m, where=str(f))


# --- the wheel count: one bound (omni_gym.bounds), checked before anything is built ----------------


def test_one_wheel_count_bound_for_presets_model_files_and_environments():
    from omni_gym.bounds import wheel_count
    from omni_gym.envs.config import WHEEL_COUNT
    from omni_gym.physics.robot import RobotSpec, regular, robot_preset, tangential_wheels

    lo, hi = wheel_count()
    assert (lo, hi) == WHEEL_COUNT == (3, 16)
    assert robot_preset(f"regular{hi}").n_wheels == hi
    for n in (lo - 1, hi + 1):
        with pytest.raises(ValueError, match=f"N from {lo} to {hi} wheels, got {n}"):
            robot_preset(f"regular{n}")
        with pytest.raises(ValueError, match=f"from {lo} to {hi}"):
            regular(n)
        with pytest.raises(ValueError, match=f"needs {lo} to {hi} wheels, got {n}"):
            RobotSpec("r", tangential_wheels(0.1, [6.28 * k / n for k in range(n)]), 0.03, 2.0, 0.01)
    data = load_model(f"regular{hi}").to_json()
    data["wheels"].append(data["wheels"][0])
    with pytest.raises(ValueError, match=r"wheels \(count\) must be an integer in \[3, 16\], got 17"):
        SimModel.from_json(data)
    with pytest.raises(ValueError, match="regularN"):
        gym.make("OmniPathFollow-Williams-v1", robot=f"regular{hi + 1}")


def test_huge_regular_n_is_refused_before_it_is_converted():
    from omni_gym.physics.robot import robot_preset

    # 10⁵ digits: int() of it alone is refused by Python's digit limit, and building it would exhaust memory.
    with pytest.raises(ValueError, match=r"regularN takes N from 3 to 16 wheels, got 111111…\(100000 digits\)"):
        robot_preset("regular" + "1" * 100_000)


@pytest.mark.parametrize("name", ["regular1000000000", "regular" + "1" * 40, "regular" + "1" * 5000])
def test_cli_refuses_huge_regular_n_in_one_line_fast(name):
    import subprocess
    import sys
    import time

    start = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "omni_gym.cli", "model", "show", name], capture_output=True,
                         text=True, timeout=60)
    # The import of the package takes about 1 s here; building 10⁹ wheels would take minutes and GBs.
    assert time.perf_counter() - start < 30
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and res.stdout == "" and len(lines) == 1
    assert "regularN takes N from 3 to 16 wheels" in lines[0] and len(lines[0]) < 200  # the name is cut
