"""Calibration an engineer can trust: gap starts from the kinematic calibration, scores whole-run drift on
held-out runs, and splits its folds by recording session."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from omni_gym.discrepancy.data.dataset import Dataset, Run, load_dataset, sessions_of, write_dataset
from omni_gym.discrepancy.data.folds import source_folds
from omni_gym.discrepancy.data.importers.optiodom import nominal_model, read_sessions
from omni_gym.discrepancy.data.segments import fit_data
from omni_gym.discrepancy.decide.score import heldout_whole_runs
from omni_gym.discrepancy.fit.fitting import Evaluator
from omni_gym.discrepancy.fit.kinematic_calibration import nominal_geometry
from omni_gym.discrepancy.replay.residuals import run_sse
from omni_gym.discrepancy.replay.simulate import Job, simulate_poses
from omni_gym.discrepancy.synthetic import synth
from omni_gym.discrepancy.synthetic.synth import pose_lever
from omni_gym.discrepancy.workflow import gap
from omni_gym.io import InputError

DATA = Path(__file__).resolve().parents[1] / "data" / "optiodom-omni3"


@pytest.fixture(scope="module")
def omni3():
    """The bundled omni3 robot's nominal model (dead reckoning from its encoders works: it rolls)."""
    metas, _ = read_sessions([DATA / "circular" / "221220201730"])
    return nominal_model(metas[0])


def _runs(n: int = 2) -> list[Run]:
    t = np.arange(0.0, 1.0, 0.1)
    return [Run(f"r{i}", t, np.zeros((len(t), 3)), np.zeros((len(t), 3))) for i in range(n)]


def test_sessions_round_trip_and_old_datasets_load(tmp_path, omni3):
    runs, _ = synth.synthesize(omni3, "none", 3, 0.001, seed=4, duration=2.0)
    write_dataset(tmp_path / "old", omni3.to_json(), "no sessions", runs)
    assert "sessions" not in json.loads((tmp_path / "old" / "dataset.json").read_text())
    old = load_dataset(tmp_path / "old")
    assert [r.session for r in old.runs] == [None] * 3 and sessions_of(old.runs) is None
    tagged = [replace(r, session=s) for r, s in zip(runs, ["a", "a", "b"], strict=True)]
    write_dataset(tmp_path / "new", omni3.to_json(), "two sessions", tagged)
    new = load_dataset(tmp_path / "new")
    assert sessions_of(new.runs) == ["a", "a", "b"]


def test_a_session_of_an_unknown_run_is_refused(tmp_path, omni3):
    runs, _ = synth.synthesize(omni3, "none", 2, 0.001, seed=4, duration=2.0)
    write_dataset(tmp_path / "d", omni3.to_json(), "", runs)
    meta = json.loads((tmp_path / "d" / "dataset.json").read_text())
    meta["sessions"] = {"run999": "a"}
    (tmp_path / "d" / "dataset.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match=r"dataset.json: sessions: run 'run999' has no file"):
        load_dataset(tmp_path / "d")


def test_the_importer_records_each_runs_session():
    _, runs = read_sessions([DATA / "circular" / "221220201730"])
    assert {r.session for r in runs} == {"221220201730"}


@pytest.mark.parametrize("n_sessions,k", [(2, 3), (3, 3), (7, 3), (7, 5)])
def test_folds_never_split_a_session(n_sessions, k):
    rng = np.random.default_rng(0)
    sessions = [f"s{j}" for j in rng.integers(0, n_sessions, 40)]
    sessions[:n_sessions] = [f"s{j}" for j in range(n_sessions)]  # every session present
    folds = source_folds(len(sessions), np.random.default_rng(1), k, sessions)
    for s in set(sessions):
        assert len({int(f) for f, t in zip(folds, sessions, strict=True) if t == s}) == 1, s
    # At most k sessions: leave one session out (one fold per session); more: k folds of whole sessions.
    assert int(folds.max()) + 1 == (k if n_sessions > k else n_sessions)
    assert folds.min() == 0


def test_without_sessions_the_folds_are_by_run():
    a = source_folds(9, np.random.default_rng(3), 3, None)
    assert sorted(np.bincount(a).tolist()) == [3, 3, 3]


def _circles(model) -> Dataset:
    """Two noise-free 40 s circles (0.2 m/s forward, ±0.5 rad/s), replayed by ``model`` itself."""
    W = nominal_geometry(model).wheel_matrix()
    runs = []
    for i, twist in enumerate([(0.2, 0.0, 0.5), (0.2, 0.0, -0.5)]):
        t = np.arange(0.0, 40.0 + 1e-9, 0.01)
        cmd = np.tile(W @ np.array(twist), (len(t), 1))
        cmd[-1] = 0.0
        shell = Run(f"c{i}", t, cmd, np.zeros((len(t), 3)))
        runs.append(replace(shell, pose=simulate_poses([Job(model, shell)])[0]))
    return Dataset(None, model, model.to_json(), "", runs)


def test_drift_aware_score_ranks_a_yaw_rate_error_worse(omni3):
    """A 0.5 % yaw-rate error (wheel distances 1.005) against a 2 % size error that keeps the yaw rate
    (diameters and distances both 1.02: circles 2 % too large, in phase). Over 8 s segments the size error
    is the larger (its offset is there at once; the heading error has had no time to grow); over whole
    40 s runs the heading error has turned the path by 0.1 rad and the yaw-rate model is the worse."""
    ds = _circles(omni3)
    yaw = omni3.with_effect("wheel_geometry", {"distance": [1.005] * 3, "mount": [0.0] * 3})
    size = (omni3.with_effect("wheel_radius", {"scale": [1.02] * 3})
            .with_effect("wheel_geometry", {"distance": [1.02] * 3, "mount": [0.0] * 3}))
    fd = fit_data(ds, budget=16.0)
    assert fd.segmented and fd.segment == 8.0
    res = Evaluator(fd.dataset, pose_lever(omni3)).residuals([yaw, size])
    seg = [sum(run_sse(r) for r in per_run) for per_run in res]
    rows = heldout_whole_runs(ds, np.zeros(2, dtype=int), {"yaw": [yaw], "size": [size]}, {"yaw": yaw, "size": size})
    drift = {n: np.mean([r.position_rms[n] for r in rows]) for n in ("yaw", "size")}
    # Measured: segment SSE ratio yaw/size 0.21 (RMS 0.46), whole-run RMS 23.3 vs 11.0 mm: a flip with margin.
    assert seg[0] < 0.5 * seg[1]
    assert drift["yaw"] > 1.5 * drift["size"]


@pytest.mark.slow  # about 20 s of CPU: a whole gap search (one step)
def test_gap_starts_from_the_kinematic_calibration(tmp_path, omni3):
    """A 5 % smaller wheel 2 on the rolling omni3 robot, with the calibration insisted on (``start="kinematic"``):
    the kinematic calibration of each fold's training session removes most of it on the held-out session; gap
    searches on top of it and says so. (With the default ``auto`` the calibration competes, and here the library's
    own wheel_radius explains the data better and wins: tests/test_evidence_rule.py holds that path, and
    tests/test_discrepancy_real_omni4.py the real robot on which the calibration wins it.)"""
    runs, truth = synth.synthesize(omni3, "wheel_radius", 4, 0.001, seed=1, duration=5.0)
    runs = [replace(r, session="day1" if i < 2 else "day2") for i, r in enumerate(runs)]
    write_dataset(tmp_path / "d", omni3.to_json(), "synthetic, two sessions", runs)
    result = gap(tmp_path / "d", tmp_path / "out", progress=False, start="kinematic", max_effects=1, plots=False)
    assert result["start"]["kind"] == "kinematic"
    assert "wheel_radius" in result["start"]["refit_effects"]  # refitted from the calibrated values
    assert result["settings"]["folds_by"] == "session" and result["settings"]["folds"] == 2
    h = result["heldout"]
    assert [s["session"] for s in h["per_session"]] == ["day1", "day2"]
    for block in [*h["per_session"], h["mean"]]:
        m = block["mean_position_rms"]
        assert m["kinematic"] <= m["nominal"]  # measured: 1.9 vs 4.2 mm mean (the wheel error drifts)
    # Each fold's calibration saw only the other session: wheel 2's diameter within 1 % of the truth.
    true_d2 = 2 * omni3.robot.wheel_radius * truth["params"]["scale"][1]
    for cal in result["start"]["fold_calibrations"]:
        assert abs(cal["diameters"][1] / true_d2 - 1) < 0.01
    text = (tmp_path / "out" / "report.md").read_text()
    assert "## Held-out whole runs" in text and "day2" in text


def _step(model, name: str, params: dict, K: int):
    """A search step that named ``name`` with ``params`` on all runs and in every fold."""
    from omni_gym.discrepancy.decide.decision import Decision
    from omni_gym.discrepancy.fit.candidates import candidates
    from omni_gym.discrepancy.fit.fitting import FitResult
    from omni_gym.discrepancy.workflow import Step

    cand = next(c for c in candidates(model) if c.name == name)
    z = np.zeros(2)
    fit = FitResult(candidate=cand, u_all=z, params_all=params, sse_all=z, heldout=z, fold_params=[params] * K,
                    pool_u=z[None], pool_sse=z[None])
    return Step(fits=[fit], decision=Decision(effect=name, why="", ranking=[]))


def test_drift_check_drops_an_effect_that_makes_a_session_drift(omni3):
    """On segment fits, an effect that makes whole runs of a held-out session drift more is dropped, with
    every effect after it; one that changes nothing is kept. Without the gate (whole runs fitted) nothing
    is dropped: the fit's own score already saw the drift."""
    from omni_gym.discrepancy.workflow import _drift_check, start_model

    ds = _circles(omni3)
    ds.runs = [replace(r, session=f"s{i}") for i, r in enumerate(ds.runs)]
    fold_src = np.array([0, 1])
    first = start_model(ds, fold_src, "nominal")
    same = _step(omni3, "motor_lag", {"tau": 0.0}, 2)
    yaw = _step(omni3, "wheel_geometry", {"distance": [1.01] * 3, "mount": [0.0] * 3}, 2)
    rows, check = _drift_check(ds, fold_src, first, [same, yaw, same], 1e-3, gate=True)
    assert check["dropped"] == ["wheel_geometry", "motor_lag"]
    # The reported "extended" column is the kept chain: the data's own model with a zero motor lag (its null point),
    # which replays these noise-free runs to within 2 mm (the world's integration error over 40 s is ~1 mm).
    for r in rows:
        assert r.position_rms["extended"] < 2e-3
    _, check = _drift_check(ds, fold_src, first, [same, yaw], 1e-3, gate=False)
    assert check["dropped"] == []


def test_kinematic_start_without_odometry_is_refused_in_one_line(tmp_path, omni3):
    runs, _ = synth.synthesize(omni3, "none", 2, 0.001, seed=4, duration=2.0)
    write_dataset(tmp_path / "d", omni3.to_json(), "", [replace(r, enc=None) for r in runs])
    with pytest.raises(ValueError, match=r"run run000 has no complete wheel odometry") as err:
        gap(tmp_path / "d", None, progress=False, start="kinematic")
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="start must be one of"):
        gap(tmp_path / "d", None, progress=False, start="calibrated")
