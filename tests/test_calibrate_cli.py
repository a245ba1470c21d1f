"""``omni-gym calibrate DATASET --out model.json`` as a user runs it (a subprocess).

The dataset: runs 1 and 2 of the bundled omni3 session circular/221220201730 (17 s each) imported.
The written model is checked by what it is for: dead reckoning with its wheel radii and positions
(read back through the force kernel's parameters) gives the "calibrated" RMS the command printed,
below the nominal one.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from omni_gym.discrepancy.data.dataset import load_dataset, write_dataset
from omni_gym.discrepancy.data.importers.optiodom import import_optiodom
from omni_gym.discrepancy.fit.kinematic_calibration import dead_reckon, layout_geometry
from omni_gym.physics.layout import WP_DX, WP_DY, WP_PX, WP_PY, WP_R
from omni_gym.physics.model import load_model

ROOT = Path(__file__).resolve().parents[1]
SESSION = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"


def cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "omni_gym.cli", *args], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=timeout)


@pytest.fixture(scope="module")
def dataset(omni3_two_runs) -> Path:
    return omni3_two_runs


def _rms(runs, geometry) -> float:
    """Position RMS [m] over every tracked row after the start, all runs pooled (as the calibration)."""
    err = []
    for run in runs:
        obs = run.observed
        obs[0] = False
        err.append(np.sum((dead_reckon(run, geometry)[obs, :2] - run.pose[obs, :2]) ** 2, axis=1))
    return float(np.sqrt(np.mean(np.concatenate(err))))


def test_calibrate_writes_the_model_it_reports(dataset, tmp_path):
    out = tmp_path / "model.json"
    res = cli("calibrate", str(dataset), "--out", str(out))
    assert res.returncode == 0, res.stderr
    text = res.stdout
    assert "calibrated on 2 runs" in text and "L = " in text and f"wrote {out}" in text
    before, after = (float(v) for v in re.search(r"([\d.]+) mm nominal -> ([\d.]+) mm calibrated", text).groups())
    assert after < 0.7 * before  # the omni3 calibration more than halves this session's error (library test)
    model = load_model(str(out), None, None)
    _, wp = model.kernel_params()
    geometry = layout_geometry(wp[:, [WP_PX, WP_PY]], wp[:, [WP_DX, WP_DY]], np.zeros(3), 2 * wp[:, WP_R])
    runs = load_dataset(dataset).runs
    assert 1e3 * _rms(runs, geometry) == pytest.approx(after, abs=0.06)  # printed to 0.1 mm
    # The fitted diameters are printed as they are in the file.
    printed = [float(v) for v in re.search(r"D = \[([^\]]+)\] mm", text).group(1).split(",")]
    assert np.allclose(printed, 2e3 * wp[:, WP_R], atol=0.006)
    # An existing file: refused in one line (exit 2), untouched; --force replaces it.
    written = out.read_text()
    again = cli("calibrate", str(dataset), "--out", str(out))
    assert again.returncode == 2 and again.stderr.count("\n") == 1 and "use --force" in again.stderr
    assert out.read_text() == written
    assert cli("calibrate", str(dataset), "--out", str(out), "--force").returncode == 0
    assert json.loads(out.read_text()) == json.loads(written)  # deterministic


def test_a_dataset_without_wheel_odometry_is_refused_in_one_line(dataset, tmp_path):
    ds = load_dataset(dataset)
    bare = tmp_path / "no_enc"
    runs = [type(r)(name=r.name, t=r.t, cmd=r.cmd, pose=r.pose) for r in ds.runs]  # no enc columns
    write_dataset(bare, ds.model_json, "no encoders", runs)
    out = tmp_path / "model.json"
    res = cli("calibrate", str(bare), "--out", str(out))
    assert res.returncode == 2 and res.stdout == ""
    err = res.stderr.strip()
    assert "\n" not in err and err.startswith("omni-gym: error: ") and str(bare) in err
    assert "221220201730_run-01 has no wheel odometry" in err
    assert not out.exists()


def test_calibrate_holds_out_each_recorded_session(tmp_path):
    """Two omni3 sessions (circular/221220201730 and 221220201726, 4 runs each) imported together: the command
    prints, per session, the calibration fitted on the other session scored on it. The figure is recomputed
    here from a calibration of the other session's runs alone (a session leaking into its own fit changes it
    beyond the 0.1 mm printed), and the calibration beats the nominal geometry on each session held out
    (measured 0.64× and 0.51×; bound 0.8×: the nominal diameters are 4–6 % off the effective ones)."""
    from omni_gym.discrepancy.fit.kinematic_calibration import calibrate, nominal_geometry, position_rms

    other = SESSION.parent / "221220201726"
    import_optiodom([SESSION, other], tmp_path / "ds")
    res = cli("calibrate", str(tmp_path / "ds"), "--out", str(tmp_path / "m.json"))
    assert res.returncode == 0, res.stderr
    held = re.findall(r"held out: session (\d+) \((\d+) runs\), calibrated on the other sessions: ([\d.]+) mm nominal "
                      r"-> ([\d.]+) mm calibrated", res.stdout)
    assert [h[:2] for h in held] == [("221220201726", "4"), ("221220201730", "4")]
    ds = load_dataset(tmp_path / "ds")
    for session, _, nominal_mm, calibrated_mm in held:
        mine = [r for r in ds.runs if r.session == session]
        fit = calibrate([r for r in ds.runs if r.session != session], ds.model)
        expect = np.mean([position_rms(r.pose, dead_reckon(r, fit.geometry)) for r in mine])
        nominal = np.mean([position_rms(r.pose, dead_reckon(r, nominal_geometry(ds.model))) for r in mine])
        assert float(calibrated_mm) == pytest.approx(1e3 * expect, abs=0.06)
        assert float(nominal_mm) == pytest.approx(1e3 * nominal, abs=0.06)
        assert float(calibrated_mm) < 0.8 * float(nominal_mm)
    # One session: said, not silently skipped.
    import_optiodom([SESSION], tmp_path / "one")
    one = cli("calibrate", str(tmp_path / "one"), "--out", str(tmp_path / "o.json"))
    assert one.returncode == 0 and "held out: the runs are one recording session" in one.stdout


def test_calibrate_writes_the_model_gap_starts_from(tmp_path):
    """On the omni3 training sessions of the committed two-robot benchmark, ``omni-gym calibrate`` writes the
    kinematic model (wheel radii and L, on the tracker's clock) that ``gap`` with its defaults started from
    (its ``result.json``: ``start.model``, kept as ``benchmarks/results/real_optiodom_omni3_gap.json``).
    Tolerance 1e-9 relative: the same least squares on the same rows, run on another day's numpy build."""
    data = ROOT / "data" / "optiodom-omni3"
    import_optiodom([data / "circular" / "221220201701", data / "square" / "221220201953"], tmp_path / "train")
    done = cli("calibrate", str(tmp_path / "train"), "--out", str(tmp_path / "kinematic.json"))
    assert done.returncode == 0, done.stderr
    written = json.loads((tmp_path / "kinematic.json").read_text())["effects"]
    gap = json.loads((ROOT / "benchmarks" / "results" / "real_optiodom_omni3_gap.json").read_text())
    assert gap["start"]["kind"] == "kinematic"
    started = gap["start"]["model"]["effects"]
    assert written.keys() == started.keys() == {"wheel_radius", "wheel_geometry"}
    for effect, params in started.items():
        for name, values in params.items():
            np.testing.assert_allclose(written[effect][name], values, rtol=1e-9, atol=1e-12, err_msg=effect)


def test_gap_tracker_start_is_the_model_calibrate_tracker_writes(dataset, tmp_path):
    """``gap --start tracker`` starts from what ``omni-gym calibrate --tracker`` writes: the same wheel radii,
    length and tracked frame (1e-12 relative: one least-squares fit of the same rows in the same process
    order). Each held-out fold starts from the calibration of the other runs alone, and the plain kinematic
    calibration (no frame) stays the side-by-side baseline."""
    from omni_gym.discrepancy.fit.kinematic_calibration import calibrate
    from omni_gym.discrepancy.workflow import start_model

    res = cli("calibrate", str(dataset), "--tracker", "--out", str(tmp_path / "frame.json"))
    assert res.returncode == 0, res.stderr
    written = json.loads((tmp_path / "frame.json").read_text())
    ds = load_dataset(dataset)
    first = start_model(ds, np.array([0, 1]), "tracker")
    started = first.model.to_json()
    assert first.kind == "tracker" and set(first.excluded) == {"wheel_radius", "wheel_geometry", "tracker_offset"}
    assert started["effects"].keys() == written["effects"].keys() == {"wheel_radius", "wheel_geometry"}
    for part in ("effects", "tracker"):
        for effect, params in written[part].items():
            for name, values in params.items():
                np.testing.assert_allclose(started[part][effect][name], values, rtol=1e-12, atol=1e-15)
    for k, fold in enumerate(first.fold_models):  # fold k is scored on run k: fitted on the other run
        alone = calibrate([ds.runs[1 - k]], ds.model, tracker=True).model.to_json()
        assert fold.to_json()["tracker"] == alone["tracker"] and fold.to_json()["effects"] == alone["effects"]
    assert "tracker" not in first.kinematic_all.to_json() or not first.kinematic_all.to_json()["tracker"]


@pytest.mark.slow  # about 100 s of CPU: a whole gap search (six candidates on two 17 s runs)
def test_gap_cli_tracker_start_keeps_the_frame_in_model_json(dataset, tmp_path):
    """``omni-gym gap --start tracker`` as a user runs it: the search starts from the joint calibration, keeps
    its effects as fitted, says so in result.json and report.md, and model.json carries the tracked frame under
    its ``tracker`` key (what ``omni-gym score`` applies) exactly as ``calibrate --tracker`` wrote it."""
    assert cli("calibrate", str(dataset), "--tracker", "--out", str(tmp_path / "frame.json")).returncode == 0
    done = cli("gap", str(dataset), "--start", "tracker", "--max-effects", "1", "--out", str(tmp_path / "rep"),
               timeout=900)  # a search: 2-3 minutes on a busy 2-core machine
    assert done.returncode == 0, done.stderr
    assert "start: kinematic calibration with the tracked frame" in done.stderr
    result = json.loads((tmp_path / "rep" / "result.json").read_text())
    assert result["start"]["kind"] == "tracker"
    assert set(result["start"]["kept_effects"]) == {"wheel_radius", "wheel_geometry", "tracker_offset"}
    frame = json.loads((tmp_path / "frame.json").read_text())["tracker"]
    model = json.loads((tmp_path / "rep" / "model.json").read_text())
    assert model["tracker"]["tracker_offset"] == frame["tracker_offset"]
    report = (tmp_path / "rep" / "report.md").read_text()
    assert "kinematic calibration of the runs with the tracked frame" in report
    assert "Tracker (measurement) effects (tracker_offset" in report
