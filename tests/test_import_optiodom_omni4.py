"""``omni-gym import optiodom`` on the bundled four-wheeled OptiOdom runs (``data/optiodom-omni4``).

The dataset's own omni4 dead reckoning is written here from the data README alone: the run file read
with numpy, wheel travel per cycle π·D_i·odo_i/(ngear·encRes), the README's forward kinematics
dx = (Δ1 − Δ2 + Δ3 − Δ4)/4, dy = (−Δ1 − Δ2 + Δ3 + Δ4)/4, dθ = −(Δ1 + Δ2 + Δ3 + Δ4)/(2(l1 + l2)), and the
displacement applied along the mid-cycle heading (an arc when dθ ≠ 0). The replay tests check the mecanum
physics against it.
"""

from __future__ import annotations

import gzip
import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.importers.optiodom import (
    import_optiodom,
    nominal_model_json,
    omni4_wheel_layout,
    read_metadata,
    read_sessions,
)
from omni_gym.discrepancy.fit.kinematic_calibration import dead_reckon, layout_geometry, optiodom_geometry
from omni_gym.io import InputError

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "optiodom-omni4"
SQUARE = DATA / "square" / "080920201715"  # 8 runs of 58 s (held out by the benchmark)
OMNI3 = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"
D, L12 = 0.06, 0.4  # the README: Di 0.06 m, l1 = l2 = 0.2 m; ngear = encRes = 1 (a count is one revolution)



def read_raw(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (K,), pose (K, 3), odo (K, 4)) of an omni4 run file (.csv or .csv.gz), numpy alone."""
    a = np.loadtxt(path, delimiter=",", ndmin=2)
    return a[:, 0], a[:, 1:4], a[:, 4:8]


def readme_dead_reckoning(path: Path, D: float = D, l12: float = L12) -> np.ndarray:
    """Poses (K, 3) of a raw run from its first pose: row k's counts are the motion over (t_{k−1}, t_k]."""
    _, pose, odo = read_raw(path)
    d = math.pi * D * odo[1:]  # wheel travel [m] per cycle
    dx = (d[:, 0] - d[:, 1] + d[:, 2] - d[:, 3]) / 4
    dy = (-d[:, 0] - d[:, 1] + d[:, 2] + d[:, 3]) / 4
    dth = -(d.sum(axis=1)) / (2 * l12)
    out = np.empty((len(pose), 3))
    out[0] = pose[0]
    for k in range(len(dth)):  # a plain loop: the README's recursion as written
        x, y, th = out[k]
        mid = th + dth[k] / 2
        f = math.sin(dth[k] / 2) / (dth[k] / 2) if dth[k] != 0 else 1.0  # chord / arc length
        out[k + 1] = (x + f * (dx[k] * math.cos(mid) - dy[k] * math.sin(mid)),
                      y + f * (dx[k] * math.sin(mid) + dy[k] * math.cos(mid)), th + dth[k])
    return out


def copy_session(src: Path, dst: Path, runs: tuple[int, ...] = (1,), rows: int | None = None,
                 plain: bool = False, meta: str | None = None) -> Path:
    """A session folder with some runs of ``src`` (its .csv.gz or plain .csv files; first ``rows`` rows;
    written plain .csv if ``plain``) and its metadata (or the text ``meta``)."""
    dst.mkdir(parents=True)
    sid = src.name
    text = meta if meta is not None else (src / f"{sid}_metadata.csv").read_text()
    (dst / f"{sid}_metadata.csv").write_text(text)
    for k in runs:
        source = src / f"{sid}_run-{k:02d}.csv"
        lines = (source.read_text() if source.exists() else
                 gzip.decompress(source.with_suffix(".csv.gz").read_bytes()).decode()).splitlines()
        body = "\n".join(lines[:rows]) + "\n"
        if plain:
            (dst / f"{sid}_run-{k:02d}.csv").write_text(body)
        else:
            (dst / f"{sid}_run-{k:02d}.csv.gz").write_bytes(gzip.compress(body.encode()))
    return dst


# --- pure data: no physics needed -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def square_runs():
    """Two runs on the file's time base: the README's formula reads the time column as written."""
    metas, runs = read_sessions([SQUARE], time_base="file")
    return metas[0], runs[:2]


def test_wheel_speeds_times_radius_are_the_readme_wheel_travel(square_runs):
    """Command of row k−1 × r × (t_k − t_{k−1}) = π·D·odo_k: the importer's units (revolutions, ngear,
    encRes) and timing (row k's counts are the cycle ending at row k), on two whole runs."""
    meta, runs = square_runs
    assert (meta.kind, meta.Li, meta.D, meta.ngear, meta.enc_res) == ("omni4", (0.2, 0.2), (D,) * 4, 1.0, 1.0)
    for run in runs:
        t, pose, odo = read_raw(SQUARE / f"{run.name}.csv.gz")
        assert np.array_equal(run.t, t) and np.array_equal(run.pose, pose)
        travel = run.cmd[:-1] * (D / 2) * np.diff(t)[:, None]
        assert np.allclose(travel, math.pi * D * odo[1:], rtol=1e-12, atol=1e-15)
        assert np.all(run.cmd[-1] == 0)
        assert np.allclose(run.enc[-1] * D / 2, math.pi * D * odo[1:].sum(axis=0), rtol=1e-12)


def test_dead_reckoning_from_the_import_is_the_readme_formula_and_tracks_motion_capture(square_runs):
    """The imported encoder angles dead-reckoned with the importer's omni4 geometry equal the README's
    recursion written above (within 1 µm over a 58 s run: only rounding differs); against motion capture
    both drift 80–200 mm RMS (README), measured 98 and 97 mm on these two runs. Band [60, 250] mm: a
    wrong sign on a wheel or column gives metres, a perfect match would mean no comparison."""
    meta, runs = square_runs
    geometry = optiodom_geometry(meta)
    for run in runs:
        ours = dead_reckon(run, geometry, start=run.pose[0])  # the README's recursion starts at the first row
        readme = readme_dead_reckoning(SQUARE / f"{run.name}.csv.gz")
        assert np.max(np.abs(ours - readme)) < 1e-6
        rms = math.sqrt(np.mean(np.sum((readme[:, :2] - run.pose[:, :2]) ** 2, axis=1)))
        assert 0.06 < rms < 0.25


def test_plain_and_gzipped_run_files_read_the_same(tmp_path):
    gz = copy_session(SQUARE, tmp_path / "gz", runs=(1, 2), rows=300)
    plain = copy_session(SQUARE, tmp_path / "plain", runs=(1, 2), rows=300, plain=True)
    (_, a), (_, b) = read_sessions([gz]), read_sessions([plain])
    assert [r.name for r in a] == [r.name for r in b] == ["080920201715_run-01", "080920201715_run-02"]
    for ra, rb in zip(a, b, strict=True):
        for key in ("t", "cmd", "enc", "pose"):
            assert np.array_equal(getattr(ra, key), getattr(rb, key))


def test_li_is_read_per_session(tmp_path):
    """A session listing Li 0.205, 0.215: the geometry and the nominal model use them (never 0.2, 0.2)."""
    meta_text = (SQUARE / "080920201715_metadata.csv").read_text().replace("Li,0.2,0.2", "Li,0.205,0.215")
    folder = copy_session(SQUARE, tmp_path / "s", rows=50, meta=meta_text)
    meta = read_metadata(folder / "080920201715_metadata.csv")
    assert meta.Li == (0.205, 0.215)
    assert optiodom_geometry(meta).size == pytest.approx(0.42)
    wheels = nominal_model_json(meta)["wheels"]
    assert [w["position"] for w in wheels] == [[0.1025, 0.1075], [0.1025, -0.1075], [-0.1025, 0.1075],
                                               [-0.1025, -0.1075]]
    assert [w["roller_angle"] for w in wheels] == pytest.approx([-math.pi / 4, math.pi / 4, math.pi / 4,
                                                                 -math.pi / 4])


def _one_line(exc: pytest.ExceptionInfo) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_a_mix_of_robot_types_is_refused_in_one_line(tmp_path):
    four = copy_session(SQUARE, tmp_path / "four", rows=50)
    with pytest.raises(InputError) as info:
        import_optiodom([OMNI3, four], tmp_path / "ds")
    msg = _one_line(info)
    assert "type differs (omni3 vs omni4)" in msg and str(four / "080920201715_metadata.csv") in msg
    assert not (tmp_path / "ds").exists()


@pytest.mark.parametrize(("change", "expected"), [
    (("Li,0.2,0.2", "Li,0.2"), "line 4: Li has 1 value(s); type omni4 has two values (l1, l2)"),
    (("Li,0.2,0.2", "Li,0.2,1e308"), "line 4: Li 1e+308 m puts a wheel outside the model bound"),
    (("Di,0.06,0.06,0.06,0.06", "Di,0.06,0.06,0.06"), "line 5: Di has 3 value(s); type omni4 has 4 wheels"),
])
def test_bad_omni4_metadata_is_one_line_naming_file_and_line(tmp_path, change, expected):
    meta_text = (SQUARE / "080920201715_metadata.csv").read_text().replace(*change)
    folder = copy_session(SQUARE, tmp_path / "s", rows=50, meta=meta_text)
    with pytest.raises(InputError) as info:
        read_sessions([folder])
    msg = _one_line(info)
    assert expected in msg and str(folder / "080920201715_metadata.csv") in msg


def test_a_run_in_both_forms_and_a_short_row_are_refused(tmp_path):
    folder = copy_session(SQUARE, tmp_path / "s", rows=50)
    shutil.copy(copy_session(SQUARE, tmp_path / "p", rows=50, plain=True) / "080920201715_run-01.csv", folder)
    with pytest.raises(InputError, match="run 1 is there twice"):
        read_sessions([folder])
    bad = copy_session(SQUARE, tmp_path / "b", rows=50, plain=True)
    path = bad / "080920201715_run-01.csv"
    lines = path.read_text().splitlines()
    lines[9] = ",".join(lines[9].split(",")[:7])  # a row with three wheels on a four-wheeled robot
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as info:
        read_sessions([bad])
    assert f"{path}: line 10: expected 8 values" in _one_line(info)


# --- with the physics: replay and score --------------------------------------------------------------------


@pytest.fixture(scope="module")
def omni4_dataset(tmp_path_factory):
    """Runs 1 and 2 of square/080920201715 (58 s each) imported on the file's time base (the README's
    recursion reads the time column as written; the tracker's time base has its own tests)."""
    root = tmp_path_factory.mktemp("omni4")
    folder = copy_session(SQUARE, root / "session", runs=(1, 2))
    import_optiodom([folder], root / "ds", time_base="file")
    from omni_gym.discrepancy.data.dataset import load_dataset

    return folder, root / "ds", load_dataset(root / "ds")


def test_nominal_model_is_the_readme_kinematics(omni4_dataset):
    """The imported model's r·W is the README's inverse kinematics, and so is that of the layout the
    calibration geometry uses, at a session's own l1, l2."""
    _, _, ds = omni4_dataset
    r = ds.model.robot
    c = L12 / 2
    readme = np.array([[1, -1, -c], [-1, -1, -c], [1, 1, -c], [-1, 1, -c]])
    assert np.allclose(r.wheel_radius * r.wheel_matrix(), readme, atol=1e-12)
    assert r.mass == 4.0 and ds.model.surface.name == "grip"
    table = omni4_wheel_layout(0.205, 0.215)
    geometry = layout_geometry([w["position"] for w in table], [w["drive"] for w in table],
                               [w["roller_angle"] for w in table], np.full(4, 2.0))
    c = (0.205 + 0.215) / 2
    readme = np.array([[1, -1, -c], [-1, -1, -c], [1, 1, -c], [-1, 1, -c]])
    assert np.allclose(geometry.wheel_matrix(), readme, atol=1e-12)  # diameters 2 m: r = 1


def test_replay_reproduces_the_readme_dead_reckoning_within_1mm_on_a_stiff_floor(omni4_dataset):
    """The simulator replaying the imported commands (nominal model, μ_drive 10 and free rollers, 0.1 ms
    substep as the omni3 check) against the README recursion over two whole 58 s runs.

    Measured 0.04 and 0.06 mm, 0.08 and 0.09 mrad (on the nominal grip floor at the default 0.5 ms step:
    0.14–0.26 mm, 0.40–0.48 mrad). Bounds: the goal's 1 mm, and 0.25 mm / 1 mrad, because the 10 ms
    cycles are short: commands shifted by one cycle are off by only 0.77 mm but 5.1 mrad (measured); a
    unit or sign error is metres."""
    from omni_gym.discrepancy.replay.simulate import Job, simulate_jobs
    from omni_gym.physics.friction import Surface

    folder, _, ds = omni4_dataset
    stiff = replace(ds.model, surface=Surface("kinematic", mu_drive=10.0, mu_transverse=0.0, mu_gap=10.0))
    n = stiff.n_wheels
    # From the first row, as the README's recursion starts (a run's start_pose is the mean of its rest rows).
    sims = simulate_jobs([Job(stiff, run, state0=(run.pose[0], np.zeros(3), np.zeros(n), np.zeros(n)))
                          for run in ds.runs], dt=1e-4)
    for run, (pose, _) in zip(ds.runs, sims, strict=True):
        readme = readme_dead_reckoning(folder / f"{run.name}.csv.gz")
        assert np.max(np.hypot(*(pose[:, :2] - readme[:, :2]).T)) < 0.25e-3  # within the goal's 1 mm
        assert np.max(np.abs(pose[:, 2] - readme[:, 2])) < 1e-3


def test_score_and_calibrate_work_on_an_omni4_dataset(omni4_dataset, tmp_path, capsys):
    """``score`` replays the omni4 runs (nominal 80–200 mm RMS as the README's dead reckoning, wider band
    [60, 250] mm for the simulated friction); ``calibrate`` fits D1–D4 and l1 + l2 and the calibrated model
    scores better on these runs."""
    _, ds_path, _ = omni4_dataset
    model = tmp_path / "model.json"
    assert main(["calibrate", str(ds_path), "--out", str(model)]) == 0
    out = capsys.readouterr().out
    assert "l1+l2 = " in out and "(nominal 400.00)" in out
    assert len(json.loads(model.read_text())["wheels"]) == 4
    assert main(["score", str(ds_path), "--model", str(model), "--json"]) == 0
    means = json.loads(capsys.readouterr().out)["models"]
    nominal, calibrated = means["nominal"]["mean_position_rms"], means[str(model)]["mean_position_rms"]
    assert 0.06 < nominal < 0.25 and calibrated < nominal


@pytest.mark.parametrize("damage", ["plain text", "truncated"])
def test_a_broken_gzip_run_file_is_one_line_naming_it(tmp_path, damage):
    folder = copy_session(SQUARE, tmp_path / "s", rows=50)
    path = folder / "080920201715_run-01.csv.gz"
    data = path.read_bytes()
    path.write_bytes(b"0,0,0,0,0,0,0,0\n" if damage == "plain text" else data[: len(data) // 2])
    with pytest.raises(InputError) as info:
        read_sessions([folder])
    assert f"{path}: not a readable gzip file" in _one_line(info)
