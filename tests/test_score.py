"""``omni-gym score``: open-loop replay of a dataset's runs with several models, scored against the tracker."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import write_dataset
from omni_gym.discrepancy.decide.run_spread import refit_run
from omni_gym.discrepancy.fit.kinematic_calibration import position_rms
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
    assert "run000" in out and "over 2 runs, nominal: position RMS mean" in out
    assert "after a per-run heading refit" in out  # what no model of the robot predicts


def _curved_run(seconds: float = 4.0, rate: float = 100.0) -> np.ndarray:
    """A tracked path (K, 3): forward at 0.3 m/s while turning at 0.8 rad/s, then at -0.5 rad/s."""
    t = np.arange(0.0, seconds, 1.0 / rate)
    omega = np.where(t < seconds / 2, 0.8, -0.5)
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) / rate)])
    v = 0.3
    x = np.concatenate([[0.0], np.cumsum(v * np.cos(0.5 * (theta[1:] + theta[:-1])) / rate)])
    y = np.concatenate([[0.0], np.cumsum(v * np.sin(0.5 * (theta[1:] + theta[:-1])) / rate)])
    return np.stack([x, y, theta], axis=1)


def test_the_refit_finds_a_start_heading_error_and_leaves_nothing():
    """A replay that started 3 degrees off (the whole path rotated about its start) is refitted to that
    offset, a unit yaw scale and a residual far below a millimetre (the rotation is exact in the bend)."""
    truth = _curved_run()
    off = math.radians(3.0)
    c, s = math.cos(-off), math.sin(-off)
    replay = truth.copy()
    replay[:, 0], replay[:, 1] = c * truth[:, 0] - s * truth[:, 1], s * truth[:, 0] + c * truth[:, 1]
    replay[:, 2] = truth[:, 2] - off
    before = position_rms(truth, replay)
    refit = refit_run(truth, replay)
    assert before > 0.01  # about 2 cm over a 1.2 m path
    assert refit.heading_offset == pytest.approx(off, abs=1e-6) and refit.yaw_scale == pytest.approx(1.0, abs=1e-6)
    assert refit.position_rms < 1e-6


def test_the_refit_finds_a_yaw_rate_scale_of_a_path_integrated_with_another_turn_rate():
    """A replay integrated with 5 % less turn (same speed, same body-frame velocity) is refitted to k of
    about 1/0.95; the bend keeps the replay's body-frame velocities, so the fit is close, not exact: the
    residual is a small fraction of the error before (first order in k - 1)."""
    truth = _curved_run()
    t = np.arange(len(truth)) / 100.0
    omega = np.where(t < 2.0, 0.8, -0.5) * 0.95
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) / 100.0)])
    mid = 0.5 * (theta[1:] + theta[:-1])
    replay = np.stack([np.concatenate([[0.0], np.cumsum(0.3 * np.cos(mid) / 100.0)]),
                       np.concatenate([[0.0], np.cumsum(0.3 * np.sin(mid) / 100.0)]), theta], axis=1)
    before = position_rms(truth, replay)
    refit = refit_run(truth, replay)
    assert refit.yaw_scale == pytest.approx(1 / 0.95, rel=0.01)
    assert abs(refit.heading_offset) < 0.01
    assert refit.position_rms < 0.05 * before


def test_score_json_has_the_spread_and_the_refit(hidden_radius, capsys):
    assert main(["score", str(hidden_radius / "data"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    m = out["models"]["nominal"]
    rms = [r["position_rms"] for r in out["runs"]]
    assert m["min_position_rms"] == min(rms) and m["max_position_rms"] == max(rms)
    assert m["min_position_rms"] <= m["median_position_rms"] <= m["max_position_rms"]
    # A refit of two more parameters can only lower each run's error (least squares from the unbent start).
    assert all(r["refit_position_rms"] <= r["position_rms"] + 1e-12 for r in out["runs"])


def test_bad_models_and_datasets_are_one_line(hidden_radius, tmp_path, capsys):
    for model, what in (("regular4", "4 wheels"), ("no_such_robot", "unknown robot")):
        code = main(["score", str(hidden_radius / "data"), "--model", model])
        err = capsys.readouterr().err.strip()
        assert code == 2 and what in err and len(err.splitlines()) == 1 and err.startswith("omni-gym: error:"), err
    code = main(["score", str(tmp_path / "missing")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "not a dataset folder" in err and len(err.splitlines()) == 1, err


def _kinematic_runs(matrix: np.ndarray, seeds: range, noise: float = 0.0005) -> list:
    """Runs whose tracked poses are the wheel travel integrated through ``matrix`` (3, n), with tracker noise."""
    from omni_gym.discrepancy.data.dataset import Run
    from omni_gym.discrepancy.fit.kinematic_calibration import integrate_twist

    runs = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        k, n = 400, matrix.shape[1]
        speeds = np.repeat(rng.uniform(-8, 8, size=(8, n)), k // 8, axis=0)  # rad/s, 8 steps of 0.5 s
        enc = np.concatenate([np.zeros((1, n)), np.cumsum(speeds[1:] * 0.01, axis=0)])
        pose = integrate_twist(np.diff(enc, axis=0) @ matrix.T, np.zeros(3))
        pose[1:, :2] += rng.normal(0.0, noise, size=(k - 1, 2))
        cmd = speeds.copy()
        cmd[0] = 0.0  # at rest at the first row: the start pose is that row
        runs.append(Run(f"run{seed}", np.arange(k) * 0.01, cmd, pose, enc=enc))
    return runs


def test_a_linear_map_recovers_a_skewed_rotated_kinematics_the_layout_cannot_express():
    """Poses made through a map the wheel layout cannot give (the tracked frame turned 2 degrees and y moving
    with x) are fitted from the nominal kinematics to within tracker noise, and predict unseen runs as well."""
    from omni_gym.discrepancy.fit.kinematic_calibration import nominal_geometry
    from omni_gym.discrepancy.fit.linear_map import fit_linear_map

    model = recovery.nominal_model()
    a_nominal = np.linalg.pinv(nominal_geometry(model).wheel_matrix())
    turn = math.radians(2.0)
    rot = np.array([[math.cos(turn), -math.sin(turn), 0], [math.sin(turn), math.cos(turn), 0], [0, 0, 1]])
    skew = np.array([[1.0, 0, 0], [-0.016, 1.0, 0], [0, 0, 1.03]])  # y gains -0.016 v_x, 3 % more yaw
    truth = skew @ rot @ a_nominal
    lm = fit_linear_map(_kinematic_runs(truth, range(4)), model)
    # The distortion (2 deg, 1.6 % skew, 3 % yaw) moves these short paths by about 4 mm against 0.7 mm of noise.
    assert lm.start_position_rms > 4 * lm.train_position_rms
    assert lm.train_position_rms < 0.001  # tracker noise 0.5 mm per axis: 0.7 mm in the plane
    held_out = [position_rms(r.pose, lm.predict(r)) for r in _kinematic_runs(truth, range(10, 13))]
    assert max(held_out) < 0.0015  # a map that generalises: within about twice the noise on unseen runs
    assert np.allclose(lm.matrix, truth, atol=0.02 * np.max(np.abs(truth)))


def test_score_can_add_a_linear_map_baseline(hidden_radius, capsys):
    data = str(hidden_radius / "data")
    assert main(["score", data, "--linear-map-from", data, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    names = list(out["models"])
    assert names[0] == "nominal" and names[1].startswith("linear map (2 runs of")
    rows = [r for r in out["runs"] if r["model"] == names[1]]
    assert len(rows) == 2 and all(0 < r["position_rms"] < 0.1 for r in rows)
    # Not asserted: that the map beats the nominal simulation. These runs slip (the Williams robot on carpet),
    # and dead reckoning from the encoders does not see slip: measured, 19 mm against the simulation's 10 mm.
    code = main(["score", data, "--linear-map-from", str(hidden_radius / "missing")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "missing" in err
