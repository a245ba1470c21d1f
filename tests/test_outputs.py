"""Outputs are complete or absent: every case on a process the test starts.

A killed writer (SIGKILL, no chance to clean up) must leave the old output byte for byte, a second
writer of the same target must be refused, an output that is an input must be refused before
anything is written, and files get the user's umask. Each subprocess is the real command line.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from omni_gym.discrepancy.data.dataset import load_dataset
from omni_gym.discrepancy.synthetic.synth import read_truth, truth_path
from omni_gym.outputs import Output, OutputError, is_temporary

ENV = "OmniPathFollow-Phunopas-v0"
CHILD_ENV = {**os.environ, "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}
POLL_S = 0.005
WAIT_S = 120.0  # generous: a loaded 2-core machine; a wait that runs out fails the test, it never passes it


def cli(*args: str, umask: int | None = None) -> subprocess.CompletedProcess:
    pre = None if umask is None else (lambda: os.umask(umask))
    return subprocess.run([sys.executable, "-m", "omni_gym.cli", *args], capture_output=True, text=True,
                          env=CHILD_ENV, preexec_fn=pre, timeout=600)


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "omni_gym.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=CHILD_ENV)


def snapshot(*paths: Path) -> dict[str, bytes]:
    """Every file under ``paths`` (relative name -> bytes): equal snapshots mean byte-identical outputs."""
    files = {}
    for p in paths:
        items = [p] if p.is_file() else sorted(q for q in p.rglob("*") if q.is_file())
        for q in items:
            files[str(q.relative_to(p.parent))] = q.read_bytes()
    return files


def temp_siblings(target: Path) -> list[Path]:
    return sorted(p for p in target.parent.iterdir() if p.name.startswith(f".{target.name}.") and is_temporary(p))


def wait_for_temp(proc: subprocess.Popen, target: Path, inside: str | None = None) -> Path:
    """Poll until ``proc``'s temporary sibling of ``target`` exists (and holds a file matching
    ``inside``); fail if the process ends first: then the kill would not test anything."""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        for tmp in temp_siblings(target):
            if f"tmp-{proc.pid}-" in tmp.name and (inside is None or any(tmp.glob(inside))):
                return tmp
        if proc.poll() is not None:
            pytest.fail(f"the process ended (exit {proc.returncode}) before its temporary output appeared: "
                        f"{proc.stderr.read()}")
        time.sleep(POLL_S)
    proc.kill()
    pytest.fail(f"no temporary sibling of {target} within {WAIT_S} s")


def kill9(proc: subprocess.Popen) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL


def one_line_error(res: subprocess.CompletedProcess, *words: str) -> None:
    assert res.returncode == 2, res.stderr
    assert res.stderr.startswith("omni-gym: error: ") and res.stderr.count("\n") == 1, res.stderr
    assert "Traceback" not in res.stderr
    for w in words:
        assert w in res.stderr, (w, res.stderr)


def synth(out: Path, *extra: str, runs: int = 2, seed: int = 0) -> subprocess.CompletedProcess:
    return cli("synth", "--model", "williams2002", "--hidden", "com_offset", "--runs", str(runs),
               "--duration", "0.5", "--seed", str(seed), "--out", str(out), *extra)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """A tiny dataset (2 runs of 0.5 s), made once."""
    ds = tmp_path_factory.mktemp("outputs") / "ds"
    assert synth(ds).returncode == 0
    return ds


def _old_report(path: Path) -> dict[str, bytes]:
    """A stand-in for an earlier gap report (its marker result.json, report.md, a plot); a real one
    would cost a gap run and test nothing more: the transaction never reads the old content."""
    path.mkdir()
    (path / "result.json").write_text('{"effect": "earlier"}\n')
    (path / "report.md").write_text("# earlier report\n")
    (path / "paths.png").write_bytes(b"earlier plot")
    return snapshot(path)


# --- synth -----------------------------------------------------------------------------------------


def test_synth_into_existing_dataset_refused_then_replaced_completely_with_force(tmp_path):
    ds = tmp_path / "ds"
    assert synth(ds, runs=3).returncode == 0
    old = snapshot(ds, truth_path(ds))
    res = synth(ds, runs=2, seed=1)
    one_line_error(res, str(ds), "--force", "would be lost")
    assert snapshot(ds, truth_path(ds)) == old  # untouched, byte for byte
    res = synth(ds, "--force", runs=2, seed=1)
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in (ds / "runs").iterdir()) == ["run000.csv", "run001.csv"]  # no old run002 left
    assert len(load_dataset(ds).runs) == 2
    assert read_truth(ds)["seed"] == 1  # the truth file belongs to the new folder (its digest matches)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", "ds.truth.json"]  # no temporary or lock left


def test_kill9_during_synth_leaves_old_dataset_and_a_rerun_succeeds(tmp_path):
    ds = tmp_path / "ds"
    assert synth(ds).returncode == 0
    old = snapshot(ds, truth_path(ds))
    # A large dataset: the simulation lasts seconds, the kill lands while the new folder is being built.
    proc = start("synth", "--model", "williams2002", "--hidden", "none", "--runs", "40", "--duration", "5",
                 "--out", str(ds), "--force")
    tmp = wait_for_temp(proc, ds)
    kill9(proc)
    assert snapshot(ds, truth_path(ds)) == old  # the old dataset, complete: no new run beside the old ones
    assert len(load_dataset(ds).runs) == 2
    assert tmp.exists()  # the killed run's temporary folder, which the loader refuses
    with pytest.raises(ValueError, match="temporary"):
        load_dataset(tmp)
    res = synth(ds, "--force", seed=3)
    assert res.returncode == 0, res.stderr
    assert read_truth(ds)["seed"] == 3
    assert temp_siblings(ds) == [] and not (tmp_path / ".ds.lock").exists()  # stale temporary removed


def test_stale_old_output_of_a_run_killed_between_its_two_renames_is_put_back(tmp_path):
    """Killed after moving the old output aside, before renaming the new one in: the next run restores it."""
    target = tmp_path / "rep"
    aside = tmp_path / ".rep.old-999999-0"
    aside.mkdir()
    (aside / "result.json").write_text("{}\n")
    with pytest.raises(OutputError, match="--force"), Output(target, "dir", marker="result.json", what="gap report"):
        pass
    assert (target / "result.json").read_text() == "{}\n" and not aside.exists()


def test_load_dataset_ignores_stray_temporary_and_hidden_files(tmp_path, dataset):
    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    (ds / "runs" / ".run000.csv.tmp-123-0").write_text("t,w1\n0,")  # an unfinished write's file
    (ds / "runs" / ".run009.csv").write_text("not,a,run\n")  # an editor's hidden file
    assert [r.name for r in load_dataset(ds).runs] == [r.name for r in load_dataset(dataset).runs]


# --- gap -------------------------------------------------------------------------------------------


@pytest.mark.slow  # about 20 CPU-s: two gap runs; make test keeps the concurrent-gap and kill -9 synth/train cases
def test_kill9_during_gap_into_existing_report_leaves_it_intact_and_a_rerun_succeeds(tmp_path, dataset):
    rep = tmp_path / "rep"
    old = _old_report(rep)
    proc = start("gap", str(dataset), "--out", str(rep), "--force", "--no-plots")
    tmp = wait_for_temp(proc, rep)  # the run is under way, building its report in the temporary folder
    kill9(proc)
    assert snapshot(rep) == old  # no new model.json/report.md beside the old result.json
    res = cli("gap", str(dataset), "--out", str(rep), "--force", "--no-plots")
    assert res.returncode == 0, res.stderr
    assert not tmp.exists() and temp_siblings(rep) == []
    assert {"result.json", "report.md", "model.json"} <= {p.name for p in rep.iterdir()}
    assert not (rep / "paths.png").exists()  # the complete new report, nothing of the old one left


def test_two_gap_processes_into_one_out_exactly_one_succeeds(tmp_path, dataset):
    ds = dataset
    rep = tmp_path / "rep"
    first = start("gap", str(ds), "--out", str(rep), "--no-plots")
    wait_for_temp(first, rep)
    os.kill(first.pid, signal.SIGSTOP)  # hold the first writer mid-transaction: the overlap is certain
    try:
        second = cli("gap", str(ds), "--out", str(rep), "--no-plots")
    finally:
        os.kill(first.pid, signal.SIGCONT)
    _, err = first.communicate(timeout=600)
    assert first.returncode == 0, err
    one_line_error(second, str(rep), "another process is writing", ".rep.lock")
    assert {"result.json", "report.md", "model.json"} <= {p.name for p in rep.iterdir()}
    assert temp_siblings(rep) == [] and not (tmp_path / ".rep.lock").exists()


def test_gap_out_existing_file_is_refused_before_the_dataset_is_read(tmp_path, dataset):
    ds = dataset
    f = tmp_path / "notes.txt"
    f.write_text("keep me\n")
    one_line_error(cli("gap", str(ds), "--out", str(f)), str(f), "not a folder")
    # The output is checked first: with a dataset that does not exist, the error is still about --out.
    one_line_error(cli("gap", str(tmp_path / "missing"), "--out", str(f), "--force"), str(f), "not a folder")
    assert f.read_text() == "keep me\n"


def test_gap_refuses_a_report_that_is_or_is_inside_the_dataset(dataset):
    ds = dataset
    before = snapshot(ds)
    one_line_error(cli("gap", str(ds), "--out", str(ds), "--force"), "input")
    one_line_error(cli("gap", str(ds), "--out", str(ds / "report")), "inside the input")
    assert snapshot(ds) == before


# --- simulate --------------------------------------------------------------------------------------


@pytest.fixture
def commands(tmp_path) -> Path:
    c = tmp_path / "c.csv"
    c.write_text("t,w1,w2,w3\n0,1,-1,0.5\n0.1,1,-1,0.5\n")
    return c


def test_simulate_refuses_to_overwrite_its_commands(commands):
    before = commands.read_bytes()
    res = cli("simulate", "--model", "williams2002", "--commands", str(commands), "--out", str(commands), "--force")
    one_line_error(res, "overwrite the input")
    assert commands.read_bytes() == before


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_simulate_output_mode_follows_the_umask_and_existing_output_needs_force(tmp_path, commands, umask):
    out = tmp_path / "traj.csv"
    assert cli("simulate", "--model", "williams2002", "--commands", str(commands), "--out", str(out),
               umask=umask).returncode == 0
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask
    one_line_error(cli("simulate", "--model", "williams2002", "--commands", str(commands), "--out", str(out)),
                   str(out), "--force")


# --- train -----------------------------------------------------------------------------------------


def _old_model_dir(path: Path) -> dict[str, bytes]:
    """A stand-in for an earlier training's directory (the marker meta.json and a model file)."""
    path.mkdir()
    (path / "meta.json").write_text('{"algo": "ppo"}\n')
    (path / "model.zip").write_bytes(b"earlier model")
    return snapshot(path)


def test_train_into_existing_model_dir_refused_and_kill9_leaves_it_intact(tmp_path):
    out = tmp_path / "model"
    old = _old_model_dir(out)
    res = cli("train", "--algo", "ppo", "--env", ENV, "--timesteps", "100", "--out", str(out), "--no-progress")
    one_line_error(res, str(out), "--force")
    assert snapshot(out) == old
    hp = tmp_path / "hp.yml"
    data = yaml.safe_load((Path(__file__).resolve().parents[1] / "agents/hyperparams/ppo.yml").read_text())[ENV]
    data.update(n_envs=1, n_steps=64, batch_size=64, n_epochs=1)
    hp.write_text(yaml.safe_dump({ENV: data}))
    proc = start("train", "--algo", "ppo", "--env", ENV, "--timesteps", "1000000", "--out", str(out), "--force",
                 "--hyperparams", str(hp), "--env-kwargs", '{"episode_seconds": 1.0}', "--eval-freq", "0",
                 "--checkpoint-freq", "64", "--no-progress")
    wait_for_temp(proc, out, inside="checkpoints/*.zip")  # training under way, writing into its temporary folder
    kill9(proc)
    assert snapshot(out) == old
