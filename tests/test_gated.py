"""agents/gated.py: ekf-pid until its own estimate leaves the path, then the student.

The gate's arithmetic by hand; with the gate shut the controller is ekf-pid to the bit; once it opens the student's
actions are the ones applied; the vector and single controllers agree; malformed gated directories get one line.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from agents.evaluate import evaluate
from agents.gated import GATE_ALPHA, GatedPolicy, GateState, VectorGatedPolicy, build, build_vector, read_gate
from agents.loaders import find_loader
from agents.rollout import run_episode
from agents.vector_rollout import run_episodes_vector

ROOT = Path(__file__).resolve().parents[1]
STUDENT = ROOT / "agents" / "models" / "dagger-student-williams"
ENV = "OmniPathFollow-Williams-v1"
SHORT = {"episode_seconds": 2.0}
SLIP = {"surface": "carpet", "friction": "roller_gap", "lift_rate": 0.5, "episode_seconds": 3.0}


def _gated(tmp_path: Path, threshold: float, student: str = "student") -> Path:
    if not (tmp_path / "student").exists():
        shutil.copytree(STUDENT, tmp_path / "student")
    d = tmp_path / f"gated-{threshold}"
    d.mkdir()
    (d / "meta.json").write_text(json.dumps({"kind": "gated", "student": student, "threshold_m": threshold,
                                             "env_id": ENV}))
    return d


def test_the_gate_averages_and_latches_as_written():
    gate = GateState(3, threshold_m=0.003)
    e = np.array([[0.004, 0.0], [0.0, 0.002], [0.003, 0.004]])  # |e| = 4, 2, 5 mm every period
    k_open = [None, None, None]
    for k in range(1, 400):
        latched = gate.update(e).copy()
        for i in range(3):
            if latched[i] and k_open[i] is None:
                k_open[i] = k
    # m_k = |e|·(1 − (1 − α)^k): above 3 mm first when (1 − α)^k < 1 − 3/|e|.
    for i, norm in ((0, 0.004), (2, 0.005)):
        assert k_open[i] == int(np.floor(np.log(1 - 0.003 / norm) / np.log(1 - GATE_ALPHA))) + 1
    assert k_open[1] is None  # 2 mm never reaches 3 mm
    gate.update(np.zeros((3, 2)))
    assert gate.latched[0] and gate.latched[2]  # latched: a smaller error later does not shut it
    gate.reset(np.array([True, False, False]))
    assert not gate.latched[0] and gate.latched[2] and gate.mean_error[0] == 0.0 and gate.mean_error[2] > 0


def test_shut_it_is_ekf_pid_to_the_bit(tmp_path):
    shut = _gated(tmp_path, 0.999)  # a metre: never reached
    assert find_loader(str(shut)).name == "gated"
    got = evaluate(str(shut), ENV, episodes=2, seed=5000, env_kwargs=SHORT, progress=False)
    want = evaluate("ekf-pid", ENV, episodes=2, seed=5000, env_kwargs=SHORT, progress=False)
    assert got["per_episode"]["tracking_rmse"] == want["per_episode"]["tracking_rmse"]


def test_once_open_the_student_drives(tmp_path):
    env, pol = build(_gated(tmp_path, 1e-5), ENV, SLIP)  # 0.01 mm: open after the first periods of any error
    assert isinstance(pol, GatedPolicy)
    try:
        obs, _ = env.reset(seed=5001)
        pol.reset(obs)
        for _ in range(30):
            a = pol.act(obs)
            if pol.student_driving:
                assert np.array_equal(a, pol.student.act(obs))  # the student's action, not ekf-pid's
            else:
                assert np.array_equal(a, pol.features.base_action.astype(np.float32))
            obs, *_ = env.step(a)
        assert pol.student_driving
    finally:
        env.close()


def test_vector_and_single_controllers_agree(tmp_path):
    d = _gated(tmp_path, 0.003)
    seeds = [5002, 5003]
    venv, vpol = build_vector(d, len(seeds), ENV, SLIP)
    assert isinstance(vpol, VectorGatedPolicy)
    try:
        vec = run_episodes_vector(venv, vpol, seeds)
    finally:
        venv.close()
    env, pol = build(d, ENV, SLIP)
    try:
        single = [run_episode(env, pol, s) for s in seeds]
    finally:
        env.close()
    # The batched EKF and the batched network equal the single ones within float rounding (the vector rollout's
    # own tolerance); a gate decision flipped by rounding would move the RMSE by far more than 1e-6.
    for v, s in zip(vec, single, strict=True):
        assert v.tracking_rmse == pytest.approx(s.tracking_rmse, rel=1e-6)


@pytest.mark.parametrize("meta,match", [
    ({"kind": "gated", "student": "../student", "threshold_m": 0.003}, "sibling model directory"),
    ({"kind": "gated", "student": "student", "threshold_m": float("nan")}, "threshold_m"),
    ({"kind": "gated", "student": "student", "threshold_m": 2}, "threshold_m"),
    ({"kind": "gated", "student": "elsewhere", "threshold_m": 0.003}, "not a model directory beside it"),
])
def test_a_malformed_gated_directory_gets_one_line(tmp_path, meta, match):
    shutil.copytree(STUDENT, tmp_path / "student")
    d = tmp_path / "gated"
    d.mkdir()
    (d / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=match) as err:
        read_gate(d)
    assert "\n" not in str(err.value) and "meta.json" in str(err.value)


def test_the_committed_gated_controllers_name_their_students():
    gated = sorted((ROOT / "agents" / "models").glob("gated-student-*"))
    assert len(gated) == 3
    for d in gated:
        spec = read_gate(d)
        assert spec.student.name.startswith("dagger-student-") and spec.env_id is not None
        assert json.loads((spec.student / "meta.json").read_text())["env_id"] == spec.env_id


def test_export_refuses_a_gated_controller_in_one_line(tmp_path):
    pytest.importorskip("onnxruntime")
    from agents.export import export

    with pytest.raises(ValueError, match="export its student") as err:
        export(str(_gated(tmp_path, 0.003)), tmp_path / "out")
    assert "\n" not in str(err.value) and not (tmp_path / "out").exists()


def test_recommended_resolves_per_id_and_is_that_controller():
    from agents.recommended import GATED, resolve

    assert resolve("OmniGoToPose-v0") == "ekf-pid" == resolve("OmniPathFollow-WilliamsPaper-v0")
    for env_id, name in GATED.items():
        assert Path(resolve(env_id)).name == name and read_gate(resolve(env_id)).env_id == env_id
    got = evaluate("recommended", ENV, episodes=1, seed=5000, env_kwargs=SHORT, progress=False)
    want = evaluate(resolve(ENV), ENV, episodes=1, seed=5000, env_kwargs=SHORT, progress=False)
    assert got["per_episode"]["tracking_rmse"] == want["per_episode"]["tracking_rmse"]
    with pytest.raises(ValueError, match="applies to a trained model, not to 'recommended'"):
        from agents.sb3_policy import ModelOptions

        find_loader("recommended").check_options("recommended", ModelOptions(algo="ppo"))


def test_the_benchmark_selects_the_smallest_threshold_that_keeps_every_grip_floor():
    from tests.benchmark_loader import load_benchmark

    bench = load_benchmark("gated")
    g2, g3, g5 = bench.THRESHOLDS

    def cell(gated_by_threshold):  # RMSE lists per policy: ekf-pid 1 mm; the student 2 mm
        return {"ekf-pid": {"rmse": [0.001, 0.001]}, "student": {"rmse": [0.002, 0.002]},
                **{f"gated:{g}": {"rmse": [v, v]} for g, v in gated_by_threshold.items()}}

    val = {("A", "no slip"): cell({g2: 0.00101, g3: 0.00101, g5: 0.001}),
           ("B", "no slip"): cell({g2: 0.00103, g3: 0.00101, g5: 0.001}),  # 2 mm: 1.03× on B's grip floor
           ("B", "slip"): cell({g2: 0.5, g3: 0.5, g5: 0.5})}  # slip does not decide
    chosen, lines = bench.select(val)
    assert chosen == g3 and any("| B | no slip | 1.03 | 1.01 | 1.00 | 2.00 |" in line for line in lines)
    val[("B", "no slip")] = cell({g2: 0.002, g3: 0.002, g5: 0.002})
    assert bench.select(val)[0] is None
