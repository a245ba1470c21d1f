"""Property-based fuzzing of the input files: commands CSVs and dataset folders.

Each example starts from a valid file and applies random mutations: a byte-order mark, CRLF line
ends, NaN/inf/huge/underscored/hex/non-ASCII-digit cells, missing or extra cells, binary bytes,
truncation, unordered times, UTF-16, broken or out-of-bound ``dataset.json``. The property: the file
is either read correctly (equal to the unmutated file where only the encoding changed, every value
finite and inside ``omni_gym.bounds``) or refused with a one-line ``ValueError`` naming the file;
through the command line the exit status is 0 or 2, never a traceback, and an output written with
status 0 holds finite numbers only.

Hypothesis runs derandomized (a fixed example sequence) with small budgets: about 20 s in all.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from omni_gym.bounds import FILES
from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import load_dataset, run_header
from omni_gym.io import column_bound, read_commands
from omni_gym.physics.model import load_model

N_WHEELS = 3
MODEL_JSON = load_model("williams2002").to_json()
FUZZ = settings(derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

# Cells that no reader may accept in any column: each is non-finite, out of every column's bound
# (1e9 > 1e8, the widest bound), or not a plain decimal number.
BAD_CELLS = ["nan", "NaN", "inf", "-inf", "1e308", "-1e308", "1e400", "1e9", "-1e9", "1_000", "0x1f",
             "\u0663", "abc", "1.2.3", "--1", "1,5", "\u00a0"]

# Mutations that leave the content unchanged (the file must read exactly as before) ...
SAME = ("bom", "crlf")
# ... that make any file invalid (the file must be refused) ...
INVALID = ("bad_cell", "drop_cell", "extra_cell", "binary", "unorder", "utf16")
# ... and that may or may not (either outcome is allowed, but only as the property says).
EITHER = ("truncate",)
MUTATIONS = SAME + INVALID + EITHER


def _rows_to_bytes(rows: list[list[str]]) -> bytes:
    return "".join(",".join(r) + "\n" for r in rows).encode()


def _mutate(rows: list[list[str]], header_len: int, ops: list[str], data: st.DataObject,
            bad_cells=BAD_CELLS) -> tuple[bytes, bool]:
    """Apply ``ops`` to a copy of ``rows`` (row 0 = header); (file bytes, must be refused)."""
    rows = [list(r) for r in rows]
    invalid = False
    for op in ops:  # structural mutations first
        r = data.draw(st.integers(1, len(rows) - 1))
        if op == "bad_cell":
            c = data.draw(st.integers(0, header_len - 1))
            rows[r][c] = data.draw(st.sampled_from(bad_cells))
            invalid = True
        elif op == "drop_cell":
            rows[r].pop(data.draw(st.integers(0, len(rows[r]) - 1)))
            invalid = True
        elif op == "extra_cell":
            at = data.draw(st.integers(0, len(rows[r])))
            rows[r][at:at] = ["0", "0"]  # two cells: a drop_cell on the same row cannot cancel them
            invalid = True
        elif op == "unorder" and len(rows) > 2:
            r = min(r, len(rows) - 2)
            rows[r][0], rows[r + 1][0] = rows[r + 1][0], rows[r][0]
            invalid = True
    raw = _rows_to_bytes(rows)
    for op in ops:  # then byte-level ones
        if op == "crlf":
            raw = raw.replace(b"\n", b"\r\n")
        elif op == "bom":
            raw = b"\xef\xbb\xbf" + raw
        elif op == "binary":
            at = data.draw(st.integers(0, len(raw)))
            junk = bytes(data.draw(st.lists(st.integers(0, 255), max_size=6))) + b"\xff"  # 0xff: never UTF-8
            raw = raw[:at] + junk + raw[at:]
            invalid = True
        elif op == "utf16":
            raw = b"\xff\xfe" + raw.decode("latin-1").encode("utf-16-le")  # as "Unicode text" exports
            invalid = True
    if "truncate" in ops:
        raw = raw[:data.draw(st.integers(0, len(raw)))]
    return raw, invalid


def _assert_one_line_naming(exc: BaseException, path: Path) -> None:
    message = str(exc)
    assert "\n" not in message and str(path) in message, message


# --- commands CSV --------------------------------------------------------------------------------


def _commands(rng: np.random.Generator, k: int) -> list[list[str]]:
    """A valid commands file of ``k`` rows lasting under 0.3 s (cheap to simulate)."""
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.005, 0.3 / k, k - 1))])
    w = rng.uniform(-30.0, 30.0, (k, N_WHEELS))
    return [["t", *[f"w{i + 1}" for i in range(N_WHEELS)]]] + [[repr(float(v)) for v in (t[j], *w[j])]
                                                                 for j in range(k)]


def _check_read(path: Path, raw: bytes, invalid: bool, base: tuple[np.ndarray, np.ndarray] | None, ops) -> bool:
    """Read the commands file; assert the property; True if it was accepted."""
    path.write_bytes(raw)
    try:
        times, cmds = read_commands(path, N_WHEELS)
    except ValueError as exc:
        _assert_one_line_naming(exc, path)
        assert invalid or "truncate" in ops, f"valid file refused ({ops}): {exc}"
        event("refused")
        return False
    assert not invalid or "truncate" in ops, f"invalid file accepted ({ops})"  # a cut may remove the defect
    event("accepted")
    assert times[0] == 0.0 and np.all(np.diff(times) > 0)
    assert np.all(np.abs(times) <= FILES["t"].hi) and np.all(np.abs(cmds) <= FILES["w1 … wn"].hi)
    if "truncate" not in ops:  # the encoding changed, not the content
        np.testing.assert_array_equal(times, base[0])
        np.testing.assert_array_equal(cmds, base[1])
    return True


@settings(FUZZ, max_examples=300)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(2, 6),
       ops=st.lists(st.sampled_from(MUTATIONS), max_size=3, unique=True), data=st.data())
def test_commands_csv_is_read_exactly_or_refused_naming_the_file(tmp_path, seed, k, ops, data):
    rows = _commands(np.random.default_rng(seed), k)
    folder = Path(tempfile.mkdtemp(dir=tmp_path))
    clean = folder / "clean.csv"
    clean.write_bytes(_rows_to_bytes(rows))
    base = read_commands(clean, N_WHEELS)
    raw, invalid = _mutate(rows, N_WHEELS + 1, ops, data)
    _check_read(folder / "c.csv", raw, invalid, base, ops)


@settings(FUZZ, max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(2, 4),
       ops=st.lists(st.sampled_from(MUTATIONS), max_size=2, unique=True), data=st.data())
def test_simulate_on_fuzzed_commands_exits_0_with_finite_output_or_2(tmp_path, capsys, seed, k, ops, data):
    rows = _commands(np.random.default_rng(seed), k)
    raw, invalid = _mutate(rows, N_WHEELS + 1, ops, data)
    folder = Path(tempfile.mkdtemp(dir=tmp_path))
    cmds, out = folder / "c.csv", folder / "traj.csv"
    cmds.write_bytes(raw)
    code = main(["simulate", "--model", "williams2002", "--commands", str(cmds), "--out", str(out)])
    event(f"exit {code}")
    err = capsys.readouterr().err.strip().splitlines()
    if code == 0:
        assert (not invalid or "truncate" in ops) and err == []
        traj = np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)
        assert traj.shape[0] == len(read_commands(cmds, N_WHEELS)[0]) and np.all(np.isfinite(traj))
    else:
        assert code == 2 and (invalid or "truncate" in ops)
        assert len(err) == 1 and err[0].startswith("omni-gym: error: ") and str(cmds) in err[0]
        assert not out.exists()


# --- dataset folders -----------------------------------------------------------------------------


def _run_rows(rng: np.random.Generator, k: int, encoders: bool, gyro: bool) -> list[list[str]]:
    """A valid run CSV: random commands, poses (some rows not observed), optional encoders and gyro."""
    header = run_header(N_WHEELS, encoders, gyro)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.01, 0.1, k - 1))])
    # Poses walk at up to 1 m/s and 1 rad/s per axis from a random start: a run a robot can drive
    # (faster poses are refused as other units, omni_gym.discrepancy.data.units).
    steps = rng.uniform(-1.0, 1.0, (k, 3)) * np.diff(t, prepend=0.0)[:, None]
    poses = rng.normal(0, 0.5, 3) + np.cumsum(steps, axis=0)
    rows = [header]
    for j in range(k):
        cells = [repr(float(t[j]))] + [repr(float(v)) for v in rng.uniform(-20, 20, N_WHEELS)]
        if encoders:
            cells += [repr(float(v)) for v in rng.uniform(-50, 50, N_WHEELS)]
        observed = j == k - 1 or rng.random() < 0.6  # the last row is always observed
        cells += [repr(float(v)) for v in poses[j]] if observed else ["", "", ""]
        if gyro:
            cells.append(repr(float(rng.normal(0, 1))) if rng.random() < 0.8 else "")
        rows.append(cells)
    return rows


def _meta_bytes(op: str | None, data: st.DataObject) -> tuple[bytes, bool]:
    """dataset.json, valid or broken by ``op``; (bytes, must be refused)."""
    model = json.loads(json.dumps(MODEL_JSON))
    meta = {"model": model, "description": "fuzz"}
    if op == "mass_huge":
        model["mass"] = 1e308
    elif op == "big_int":
        model["inertia"] = 10**400
    elif op == "rollers_fraction":
        model["rollers"] = 2.7
    elif op == "deep":
        meta["description"] = "DEEP"
    text = json.dumps(meta, indent=1)
    if op == "nan_token":
        text = text.replace('"mass": 2.0', '"mass": NaN')
    elif op == "deep":
        text = text.replace('"DEEP"', "[" * 100_000 + "]" * 100_000)
    raw = text.encode()
    if op == "bom":
        raw = b"\xef\xbb\xbf" + raw.replace(b"\n", b"\r\n")
    elif op == "binary":
        raw = bytes(data.draw(st.lists(st.integers(0, 255), max_size=20))) + b"\xfe" + raw
    elif op == "truncate":
        raw = raw[:data.draw(st.integers(0, len(raw) - 2))]  # never a complete object
    return raw, op not in (None, "bom")


META_OPS = [None, "bom", "mass_huge", "big_int", "rollers_fraction", "nan_token", "deep", "binary", "truncate"]


def _write_dataset(folder: Path, meta: bytes, runs: list[bytes]) -> None:
    (folder / "runs").mkdir(parents=True)
    (folder / "dataset.json").write_bytes(meta)
    for i, raw in enumerate(runs):
        (folder / "runs" / f"run{i}.csv").write_bytes(raw)


def _check_run_values(run) -> None:
    """Every accepted value is finite where required and inside its column's bound."""
    assert run.t[0] == 0.0 and np.all(np.diff(run.t) > 0) and np.all(np.isfinite(run.cmd))
    for column, values in (("t", run.t), ("w1", run.cmd), ("x", run.pose[:, :2]), ("theta", run.pose[:, 2]),
                           ("enc1", run.enc), ("gyro", run.gyro)):
        if values is not None:
            finite = values[np.isfinite(values)]
            assert np.all(np.abs(finite) <= column_bound(column).hi)
    observed = run.observed
    assert np.all(np.isfinite(run.pose[observed])) and np.all(np.isnan(run.pose[~observed]))


@settings(FUZZ, max_examples=200)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(2, 6), n_runs=st.integers(1, 3),
       encoders=st.booleans(), gyro=st.booleans(),
       ops=st.lists(st.sampled_from(MUTATIONS), max_size=3, unique=True),
       meta_op=st.sampled_from(META_OPS), data=st.data())
def test_dataset_folder_is_read_or_refused_naming_the_file(tmp_path, capsys, seed, k, n_runs, encoders, gyro,
                                                           ops, meta_op, data):
    rng = np.random.default_rng(seed)
    runs = [_run_rows(rng, k, encoders, gyro) for _ in range(n_runs)]
    width = len(runs[0][0])
    # Only the last run is mutated; blank cells are valid in pose/encoder/gyro columns, so not "bad".
    raw_last, invalid = _mutate(runs[-1], width, ops, data, bad_cells=[c for c in BAD_CELLS if c.strip()])
    meta, meta_invalid = _meta_bytes(meta_op, data)
    folder = Path(tempfile.mkdtemp(dir=tmp_path)) / "ds"
    _write_dataset(folder, meta, [_rows_to_bytes(r) for r in runs[:-1]] + [raw_last])
    try:
        ds = load_dataset(folder)
    except ValueError as exc:
        _assert_one_line_naming(exc, folder)
        event("refused")
        assert invalid or meta_invalid or "truncate" in ops, f"valid dataset refused ({ops}, {meta_op}): {exc}"
        if meta_invalid and not invalid:
            assert "dataset.json" in str(exc)  # the model is read before the runs
        # Through the command line: exit 2 with one error line and no report.
        code = main(["gap", str(folder), "--out", str(folder.parent / "rep")])
        errors = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("omni-gym: error: ")]
        assert code == 2 and len(errors) == 1 and str(folder) in errors[0]
        assert not (folder.parent / "rep").exists()
        return
    assert not meta_invalid and (not invalid or "truncate" in ops), f"invalid dataset accepted ({ops}, {meta_op})"
    event("accepted")
    assert len(ds.runs) == n_runs and ds.model.to_json() == MODEL_JSON
    for run in ds.runs:
        _check_run_values(run)
    if "truncate" not in ops:  # the last run reads as its unmutated twin
        twin = folder.parent / "twin"
        _write_dataset(twin, _meta_bytes(None, data)[0], [_rows_to_bytes(runs[-1])])
        ref = load_dataset(twin).runs[0]
        for a, b in ((ds.runs[-1].t, ref.t), (ds.runs[-1].cmd, ref.cmd), (ds.runs[-1].pose, ref.pose)):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("column", ["t", "w2", "enc3", "x", "y", "theta", "gyro"])
def test_every_run_column_has_a_bound(column):
    assert column_bound(column) is not None
