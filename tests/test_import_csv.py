"""``omni-gym import csv``: a spreadsheet-style log (other column names, mm and degrees, a flipped wheel,
interleaved wheel and pose rows) reads back as the simulated runs that wrote it; bad input gets one line."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import load_dataset
from omni_gym.discrepancy.data.importers.csv_log import import_csv, parse_columns
from omni_gym.discrepancy.data.importers.logs import parse_units, parse_windows
from omni_gym.discrepancy.synthetic.synth import synthesize
from omni_gym.io import InputError
from omni_gym.physics.model import load_model

MODEL = "williams2002"
COLUMNS = "t=stamp_ms,x=px,y=py,theta=yaw,enc1=wheel_a,enc2=-wheel_b,enc3=wheel_c"


@pytest.fixture(scope="module")
def sim():
    """Two simulated 3 s runs of the nominal Williams robot (a hidden wheel-radius effect; no tracker noise)."""
    model = load_model(MODEL)
    runs, _ = synthesize(model, "wheel_radius", runs=2, noise=0.0, seed=3, duration=3.0)
    return model, runs


def _cells(*values) -> str:
    return ",".join(repr(float(v)) for v in values)


def write_log(path: Path, run, interleave: bool = True, bom: bool = True) -> None:
    """The run as a logger writes it: ms, mm, degrees, wheel 2 with the opposite sign, CRLF, a BOM, and
    (``interleave``) pose rows at times between the wheel rows (half a row later)."""
    lines = ["stamp_ms,wheel_a,wheel_b,wheel_c,px,py,yaw,battery"]
    t = run.t
    for k in range(len(t)):
        e = run.enc[k]
        p = run.pose[k]
        ms = t[k] * 1000.0
        wheels = _cells(e[0], -e[1], e[2])
        pose = _cells(p[0] * 1000.0, p[1] * 1000.0, math.degrees(p[2]))
        if interleave and k + 1 < len(t):
            lines.append(f"{_cells(ms)},{wheels},{pose},12.1")
            # a pose-only row between two wheel rows: the midpoint (interpolation gives it back exactly)
            q = 0.5 * (run.pose[k] + run.pose[k + 1])
            tm = 0.5 * (t[k] + t[k + 1]) * 1000.0
            lines.append(f"{_cells(tm)},,,,{_cells(q[0] * 1000.0, q[1] * 1000.0, math.degrees(q[2]))},12.1")
        else:
            lines.append(f"{_cells(ms)},{wheels},{pose},12.1")
    text = "\r\n".join(lines) + "\r\n"
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode())


def test_import_reads_back_the_runs(sim, tmp_path):
    model, runs = sim
    files = []
    for run in runs:
        f = tmp_path / f"{run.name}.csv"
        write_log(f, run)
        files.append(f)
    out = tmp_path / "ds"
    rc = main(["import", "csv", *map(str, files), "--model", MODEL, "--columns", COLUMNS, "--units", "ms,mm,deg,"
               "wheel=rad", "--out", str(out)])
    assert rc == 0
    ds = load_dataset(out)
    assert [r.name for r in ds.runs] == [r.name for r in runs]
    assert "stamp_ms" in ds.description and "mm" in ds.description  # the assumptions are recorded
    for got, want in zip(ds.runs, runs, strict=True):
        # Times pass through ms (×1e-3, ×1e3): a few ulps; angles and poses through mm/deg and back.
        np.testing.assert_allclose(got.t, want.t, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.enc, want.enc, rtol=0, atol=1e-9)
        np.testing.assert_allclose(got.pose, want.pose, rtol=0, atol=1e-9)
        # The held command is the wheel's mean speed over each row (the log has no command column).
        np.testing.assert_allclose(got.cmd[:-1], np.diff(want.enc, axis=0) / np.diff(want.t)[:, None], atol=1e-6)
        assert np.all(got.cmd[-1] == 0)


def test_wheel_speeds_and_windows(sim, tmp_path):
    model, runs = sim
    run = runs[0]
    f = tmp_path / "speeds.csv"
    lines = ["time,w_a,w_b,w_c,x,y,th"]
    for k in range(len(run.t)):
        lines.append(",".join(repr(float(v)) for v in (run.t[k], *run.cmd[k], *run.pose[k])))
    f.write_text("\n".join(lines) + "\n")
    out = tmp_path / "ds"
    names, desc = import_csv([f], out, model, "t=time,x=x,y=y,theta=th,w1=w_a,w2=w_b,w3=w_c", parse_units(None),
                             parse_windows(["a=0:1.5", "b=1.5:"]))
    assert names == ["a", "b"] and "trapezoid" in desc
    ds = load_dataset(out)
    a, b = ds.runs
    assert a.t[-1] <= 1.5 + 1e-12 and b.t[0] == 0.0
    k = len(a.t)
    # Window b starts at the first row at or after 1.5 s; its pose is the log's there.
    start = int(np.searchsorted(run.t, 1.5))
    np.testing.assert_allclose(b.pose[0], run.pose[start], atol=1e-12)
    assert k == int(np.searchsorted(run.t, 1.5, side="right"))


def _corrupt_heading(text: str) -> str:
    """The log's 10th data row with a heading cell of 99999 (the file is in radians for this case)."""
    lines = text.split("\r\n")
    cells = lines[10].split(",")
    cells[6] = "99999"
    lines[10] = ",".join(cells)
    return "\r\n".join(lines)


@pytest.mark.parametrize("columns, units, edit, message", [
    (COLUMNS, "ms,mm,deg", lambda s: s.replace("wheel_c", "wheel_z", 1), "no column 'wheel_c'"),
    (COLUMNS.replace("enc3=wheel_c", ""), "ms,mm,deg", None, "no enc3"),
    (COLUMNS, "ms,mm,deg,furlong", None, "unknown unit 'furlong'"),
    (COLUMNS, "ms,deg", None, "positions look like millimetres"),  # mm read as metres
    (COLUMNS, "ms,mm,deg,s", None, "two time units"),
    (COLUMNS, "ms,mm,deg", lambda s: s.replace(",12.1\r\n", ",12.1\r\nabc,1,2,3,4,5,6,7\r\n", 1), "not a number"),
    # a corrupt heading cell: 99999 rad (in degrees here) is beyond any tracked heading; unwrapping it must not
    # fold it into a small jump that passes
    (COLUMNS, "ms,mm,rad", _corrupt_heading, "theta must be"),
])
def test_bad_input_one_line(sim, tmp_path, capsys, columns, units, edit, message):
    _, runs = sim
    f = tmp_path / "log.csv"
    write_log(f, runs[0], interleave=False, bom=False)
    if edit is not None:
        f.write_bytes(edit(f.read_bytes().decode()).encode())
    rc = main(["import", "csv", str(f), "--model", MODEL, "--columns", columns, "--units", units,
               "--out", str(tmp_path / "ds")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "ds").exists()


def test_still_wheel_and_non_monotonic_time(sim, tmp_path):
    model, runs = sim
    run = runs[0]
    f = tmp_path / "log.csv"
    rows = ["t,a,b,c,x,y,th"] + [",".join(repr(float(v)) for v in (run.t[k], run.enc[k, 0], 0.0, run.enc[k, 2],
                                                                   *run.pose[k])) for k in range(len(run.t))]
    f.write_text("\n".join(rows) + "\n")
    cmap = "t=t,x=x,y=y,theta=th,enc1=a,enc2=b,enc3=c"
    with pytest.raises(InputError, match=r"wheel 2 \(b\) never moves"):
        import_csv([f], tmp_path / "ds", model, cmap, parse_units(None))
    rows[5], rows[6] = rows[6], rows[5]
    f.write_text("\n".join(rows).replace(",0.0,", ",1.0,", 1) + "\n")
    with pytest.raises(InputError, match=r"log.csv: row 7: times must be strictly increasing"):
        import_csv([f], tmp_path / "ds", model, cmap, parse_units(None))


def test_column_map_errors():
    with pytest.raises(InputError, match="not both"):
        parse_columns("t=a,x=b,y=c,theta=d,enc1=e,w1=f", 1)
    with pytest.raises(InputError, match="only wheel columns take a sign"):
        parse_columns("t=-a,x=b,y=c,theta=d,enc1=e", 1)
    with pytest.raises(InputError, match="no theta"):
        parse_columns("t=a,x=b,y=c,enc1=e", 1)
    assert parse_columns("t=a,x=b,y=c,theta=d,enc1=-e", 1).wheels == (("e", -1.0),)
    # One column read as two quantities is a copy-paste slip, never a mapping (it used to import silently).
    for spec in ("t=a,x=b,y=c,theta=e,enc1=e", "t=a,x=b,y=b,theta=d,enc1=e", "t=a,x=b,y=c,theta=d,w1=b"):
        with pytest.raises(InputError, match=r"column '[be]' is mapped to \w+ and \w+"):
            parse_columns(spec, 1)


def test_reads_are_bounded(sim, tmp_path, monkeypatch):
    from omni_gym.discrepancy.data.importers import csv_log

    model, runs = sim
    f = tmp_path / "log.csv"
    write_log(f, runs[0])
    monkeypatch.setattr(csv_log, "MAX_BYTES", 100)
    with pytest.raises(InputError, match=r"log.csv: .* MiB; at most"):
        import_csv([f], tmp_path / "ds", model, COLUMNS, parse_units("ms,mm,deg"))
    monkeypatch.setattr(csv_log, "MAX_BYTES", 2**30)
    monkeypatch.setattr(csv_log, "MAX_ROWS", 10)
    with pytest.raises(InputError, match=r"rows; at most 10 per file"):
        import_csv([f], tmp_path / "ds", model, COLUMNS, parse_units("ms,mm,deg"))
