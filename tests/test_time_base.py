"""The log's own time base (``omni-gym import optiodom --time-base``; docs/formats.md, "The time base").

OptiOdom's synchronisation resampled each run's motion capture over [gt_ti, gt_tf] (tracker clock) onto the
odometry rows of [odo_ti, odo_tf] (the log's clock) and kept both windows in the metadata. The expected values
here come from the metadata and the run files read with the csv module and numpy, not from the importer.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.importers.optiodom import (
    clock_scale_of,
    convert_run,
    find_session,
    read_metadata,
    read_run_file,
    read_sessions,
    read_sessions_timed,
)
from omni_gym.discrepancy.fit.kinematic_calibration import calibrate, dead_reckon, position_rms
from omni_gym.io import InputError
from tests.test_import_optiodom_omni4 import copy_session

ROOT = Path(__file__).resolve().parents[1]
OMNI4 = ROOT / "data" / "optiodom-omni4"
SQUARE = OMNI4 / "square" / "080920201715"
OMNI3 = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"
OMNI3_META = (OMNI3 / "221220201730_metadata.csv").read_text()


def windows(folder: Path) -> list[tuple[float, float, float, float]]:
    """Per run (gt_ti, gt_tf, odo_ti, odo_tf) [s] of a session's metadata, read with the csv module."""
    meta = next(folder.glob("*_metadata.csv"))
    keys = ("gt_ti", "gt_tf", "odo_ti", "odo_tf")
    rows = {r[0]: [float(c) for c in r[1:] if c.strip()] for r in csv.reader(meta.read_text().splitlines())
            if r and r[0] in keys}
    return list(zip(rows["gt_ti"], rows["gt_tf"], rows["odo_ti"], rows["odo_tf"], strict=True))


def scale_of(window: tuple[float, float, float, float]) -> float:
    gt_ti, gt_tf, odo_ti, odo_tf = window
    return (gt_tf - gt_ti) / (odo_tf - odo_ti)


def test_omni4_rows_take_the_tracker_window_and_keep_the_logged_wheel_speeds():
    """omni4 logs fractional revolutions (speed × the nominal 10 ms cycle): on the tracker's time base row k
    is at t_k · s with s = (gt_tf − gt_ti)/(odo_tf − odo_ti), the wheel speeds are the file's, and the wheel
    angles are the counts · s (the travel the tracker saw). The last row lands on gt_tf − gt_ti."""
    file_runs = read_sessions([SQUARE], time_base="file")[1][:2]
    read = read_sessions_timed([SQUARE], time_base="tracker")
    for i, (f, t) in enumerate(zip(file_runs, read.runs[:2], strict=False)):
        s = scale_of(windows(SQUARE)[i])
        assert 1.09 < s < 1.12  # the squares of day 1: the tracker window is 10–11 % longer
        assert read.clock_scales[t.name] == pytest.approx(s, rel=1e-12)
        assert np.allclose(t.t, f.t * s, rtol=1e-12, atol=0)
        gt_ti, gt_tf, _, _ = windows(SQUARE)[i]
        assert t.t[-1] == pytest.approx(gt_tf - gt_ti, rel=1e-9)
        assert np.array_equal(t.cmd, f.cmd)
        assert np.allclose(t.enc, f.enc * s, rtol=1e-12, atol=0)
        assert np.array_equal(t.pose, f.pose, equal_nan=True)


def test_omni3_whole_ticks_keep_their_rotation_and_stretch_the_speed():
    """omni3 logs whole encoder ticks (a rotation, whatever the cycle lasted): the angles are the file's and
    the speeds are divided by the clock scale (1.014–1.020 in this session)."""
    file_runs = read_sessions([OMNI3], time_base="file")[1]
    tracker_runs = read_sessions([OMNI3], time_base="tracker")[1]
    for i, (f, t) in enumerate(zip(file_runs, tracker_runs, strict=True)):
        s = scale_of(windows(OMNI3)[i])
        assert 1.01 < s < 1.025
        assert np.allclose(t.t, f.t * s, rtol=1e-12, atol=0)
        assert np.array_equal(t.enc, f.enc)
        assert np.allclose(t.cmd, f.cmd / s, rtol=1e-12, atol=0)


def _read(session: str, base: str, numbers: tuple[int, ...]):
    """Runs ``numbers`` of a bundled omni4 session on time base ``base``, reading only those files (the
    importer's per-run steps, as read_sessions_timed composes them)."""
    meta_path, paths = find_session(OMNI4 / session)
    meta = read_metadata(meta_path)
    out = []
    for k in numbers:
        raw = read_run_file(paths[k - 1], "omni4")
        out.append(convert_run(raw, meta, clock_scale=clock_scale_of(meta, raw) if base == "tracker" else 1.0))
    return out


def test_on_the_tracker_clock_the_omni4_wheels_are_their_nominal_size_and_predict_other_sessions_better():
    """The evidence for the time base, on real runs (runs 1, 4, 7, 10 of each training session: both
    driving directions; runs 1 and 2 of each held-out session).

    On the file's time base the calibration wants wheels of 64.1–65.0 mm for nominal 60 mm ones (measured),
    because the logged travel falls short of the tracked travel by the clock scale, which differs by path
    family (1.06 circles, 1.11 squares). On the tracker's clock it finds 60.4–61.3 mm (measured; all 24
    training runs: 60.4–61.3 mm). Bound: within 2.5 % of the nominal 60 mm, where the file's time base is
    7–9 % off. Held out, the calibrated dead reckoning on the tracker's clock is 0.77, 0.99 and 0.83× the
    file's (measured; all runs through `score`: 0.72–0.96×, benchmarks/time_base.py). Bounds: no session
    worse than 1.02× (a session may gain nothing: the day-2 circles share the training circles' clock), the
    mean at most 0.92×.
    """
    from omni_gym.discrepancy.data.importers.optiodom import nominal_model

    nominal = nominal_model(read_metadata(next((OMNI4 / "square" / "080920201810").glob("*_metadata.csv"))))
    train = ("circular/080920201015", "square/080920201810")
    heldout = ("square/080920201715", "circular/231220200440", "circular/231220200502")
    rms = {}
    for base in ("file", "tracker"):
        cal = calibrate([r for s in train for r in _read(s, base, (1, 4, 7, 10))], nominal)
        if base == "tracker":
            assert np.all(np.abs(cal.diameters / 0.06 - 1) < 0.025), cal.diameters
        else:
            assert np.all(cal.diameters > 0.063), cal.diameters
        rms[base] = [np.mean([position_rms(r.pose, dead_reckon(r, cal.geometry)) for r in _read(s, base, (1, 2))])
                     for s in heldout]
    ratios = np.array(rms["tracker"]) / np.array(rms["file"])
    assert np.all(ratios < 1.02) and ratios.mean() <= 0.92, ratios


# --- what the importer says and refuses ------------------------------------------------------------------


def test_a_run_whose_clock_is_unlike_its_sessions_is_reported(tmp_path):
    """Run 2's tracker window made 3 % longer than the others' (every bundled run is within 0.53 % of its
    session's median): named in a note; the other runs are not."""
    def stretch(text: str) -> str:
        lines = text.splitlines()
        for i, line in enumerate(lines):
            if line.startswith("gt_tf,"):
                cells = line.split(",")
                cells[2] = f"{float(cells[2]) + 0.03 * 17.0:.2f}"
                lines[i] = ",".join(cells)
        return "\n".join(lines) + "\n"

    folder = copy_session(OMNI3, tmp_path / "s", runs=(1, 2, 3, 4), plain=True, meta=stretch(OMNI3_META))
    notes = read_sessions_timed([folder]).notes
    assert len(notes) == 1 and "221220201730_run-02: clock scale" in notes[0] and "from its session's" in notes[0]


def test_windows_that_do_not_describe_the_file_are_refused_or_left_out(tmp_path):
    """A run cut to 30 rows no longer lasts odo_tf − odo_ti: ``tracker`` refuses it naming the metadata
    line; ``auto`` keeps the file's time column for that session and says so."""
    folder = copy_session(OMNI3, tmp_path / "s", runs=(1,), rows=30, plain=True)
    with pytest.raises(InputError, match=r"_metadata\.csv: line \d+: run 1: the odometry window .* is not this "
                                         r"file's"):
        read_sessions_timed([folder], time_base="tracker")
    read = read_sessions_timed([folder])
    assert read.time_bases == {"221220201730": "file"} and read.clock_scales["221220201730_run-01"] == 1.0
    assert len(read.notes) == 1 and "keeps the file's time column" in read.notes[0]


def test_metadata_without_windows_keeps_the_time_column_and_partial_windows_are_refused(tmp_path):
    def drop(keys):
        return lambda text: "\n".join(line for line in text.splitlines() if line.split(",")[0] not in keys) + "\n"

    none = copy_session(OMNI3, tmp_path / "none", runs=(1,), plain=True,
                        meta=drop({"gt_ti", "gt_tf", "odo_ti", "odo_tf"})(OMNI3_META))
    read = read_sessions_timed([none])
    assert read.time_bases == {"221220201730": "file"} and "no synchronisation windows" in read.notes[0]
    with pytest.raises(InputError, match="no synchronisation windows"):
        read_sessions_timed([none], time_base="tracker")
    partial = copy_session(OMNI3, tmp_path / "partial", runs=(1,), plain=True, meta=drop({"odo_tf"})(OMNI3_META))
    with pytest.raises(InputError, match=r"has gt_ti, gt_tf, odo_ti but no odo_tf row"):
        read_sessions_timed([partial])
    # The message's way out works: the file's time column needs no windows.
    assert read_sessions_timed([partial], time_base="file").time_bases == {"221220201730": "file"}

    def backwards(text: str) -> str:
        return text.replace("gt_tf,23.72", "gt_tf,1.5")

    bad = copy_session(OMNI3, tmp_path / "bad", runs=(1,), plain=True, meta=backwards(OMNI3_META))
    with pytest.raises(InputError, match=r"line \d+: run 1: gt_tf 1.5 is not after gt_ti 6.52"):
        read_sessions_timed([bad])


def test_cli_time_base_file_and_its_refusal_for_other_formats(tmp_path, capsys):
    out = tmp_path / "ds"
    assert main(["import", "optiodom", str(OMNI3), "--out", str(out), "--time-base", "file"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert "69.7 s of robot time" in lines[0] and lines[1] == "time base: 221220201730 the file's time column"
    assert main(["import", "csv", "x.csv", "--out", str(tmp_path / "c"), "--time-base", "file"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--time-base applies to 'import optiodom'" in err
