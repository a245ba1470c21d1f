"""Hand-written datasets in the wrong units or with the wrong separator: refused naming the likely cause."""

import numpy as np
import pytest

from omni_gym.discrepancy.data.dataset import Run, load_dataset, write_dataset
from omni_gym.discrepancy.data.units import tracked_rates
from omni_gym.io import InputError
from omni_gym.physics.model import load_model

MODEL = load_model("williams2002")  # wheel radius 0.03 m


def _run(scale_xy=1.0, theta_unit=1.0, w_unit=1.0) -> Run:
    """3 s at 0.5 m/s along x while turning at 1 rad/s; wheel commands of the same twist."""
    t = np.arange(0.0, 3.0001, 0.05)
    pose = np.column_stack([0.5 * t * scale_xy, np.zeros_like(t), 1.0 * t * theta_unit])
    w = MODEL.robot.wheel_matrix() @ np.array([0.5, 0.0, 1.0])  # body twist → rad/s (a rough match is enough)
    cmd = np.tile(w * w_unit, (t.size, 1))
    return Run(name="run000", t=t, cmd=cmd, pose=pose)


def _dataset(tmp_path, run):
    folder = tmp_path / "ds"
    write_dataset(folder, MODEL.to_json(), "hand-written", [run])
    return folder


def test_a_run_in_metres_radians_and_rad_per_second_loads(tmp_path):
    ds = load_dataset(_dataset(tmp_path, _run()))
    speed, yaw = tracked_rates(ds.runs[0].t, ds.runs[0].pose)
    assert speed == pytest.approx(0.5) and yaw == pytest.approx(1.0)  # exact straight-line data


@pytest.mark.parametrize(("units", "cause"), [
    ({"scale_xy": 1000.0}, "positions look like millimetres; the format wants metres"),
    ({"theta_unit": 180.0 / np.pi}, "theta looks like degrees; the format wants radians"),
    ({"w_unit": 180.0 / np.pi}, "look like rpm or degrees per second; the format wants rad/s"),
])
def test_a_run_in_other_units_is_refused_naming_the_cause(tmp_path, units, cause):
    folder = _dataset(tmp_path, _run(**units))
    with pytest.raises(InputError, match="run000.csv: .*" + cause):
        load_dataset(folder)


def test_tracker_noise_and_a_jump_do_not_look_like_other_units():
    run = _run()
    rng = np.random.default_rng(0)
    pose = run.pose + rng.normal(0.0, 0.05, run.pose.shape)  # 5 cm noise: a poor camera tracker
    pose[30:33, :2] += 5.0  # a 0.15 s tracker glitch of 5 m
    speed, yaw = tracked_rates(run.t, pose)
    # Noise over a 1 s baseline adds about σ·√2 ≈ 0.07 m/s; the glitch touches under a third of the windows.
    assert speed < 1.0 and yaw < 2.0


@pytest.mark.parametrize(("sep", "name"), [(";", "';'"), ("\t", "tabs")])
def test_a_csv_with_another_separator_says_so(tmp_path, sep, name):
    folder = _dataset(tmp_path, _run())
    csv = folder / "runs" / "run000.csv"
    text = csv.read_text().replace(",", sep)
    csv.write_text(text.replace(".", ",") if sep == ";" else text)  # the European spreadsheet form
    with pytest.raises(InputError, match=f"run000.csv: row 1: the file uses {name} as separator; omni-gym reads "
                                         "comma-separated values"):
        load_dataset(folder)


def test_commands_csv_with_semicolons_says_so(tmp_path):
    from omni_gym.io import read_commands

    f = tmp_path / "c.csv"
    f.write_text("t;w1;w2;w3\n0;1,5;0;0\n1;0;0;0\n")
    with pytest.raises(InputError, match=r"c\.csv: row 1: the file uses ';' as separator"):
        read_commands(f, 3)
