"""The command line under Ctrl-C and kill: one line and status 130, no output, no worker left behind.

``gap --jobs 2`` runs its candidate fits in two worker processes. Whatever ends the parent (SIGINT,
repeated; SIGKILL, which it cannot handle), the workers and multiprocessing's resource tracker must end
with it, and an interrupt must leave no report. Processes are read from ``/proc`` (Linux; psutil is not
a dependency).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from omni_gym.cli import main

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc (Linux)")

def _default_sigint() -> None:
    """In a child before it runs: SIGINT at its default, as a command started from a terminal has it. A test
    run started in the background (``make test &``, some CI runners) has SIGINT ignored, every child inherits
    that, and the command then rightly ignores Ctrl-C (an inherited SIG_IGN is respected): every interrupt
    test would look like a hang. (Measured: every trial of benchmarks/interrupt_trials.py "hung" when it was
    started with ``nohup ... &``.)"""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture(autouse=True)
def _sigint_as_in_a_terminal():
    """This process's SIGINT handler as Python installs it in a terminal, whatever the test run inherited."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


# How long the workers may outlive their parent: the parent watch polls every 0.5 s and PR_SET_PDEATHSIG
# acts at once; 5 s leaves room for a loaded 2-core machine.
GONE_WITHIN_S = 5.0


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """A small synthetic dataset (4 runs of 3 s): gap on it runs long enough (about a minute with 2
    workers) to be interrupted while the workers fit."""
    out = tmp_path_factory.mktemp("interrupts") / "ds"
    assert main(["synth", "--model", "williams2002", "--hidden", "viscous_drag", "--runs", "4", "--duration", "3",
                 "--out", str(out)]) == 0
    return out


def _children(pid: int) -> dict[int, str]:
    """pid -> command line of the processes whose parent is ``pid``."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:  # ended meanwhile
            continue
        ppid = int(stat.rpartition(")")[2].split()[1])
        if ppid == pid:
            out[int(entry.name)] = cmd
    return out


def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, ended but not yet reaped by init, counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def _start_gap(dataset: Path, out: Path) -> tuple[subprocess.Popen, dict[int, str], Path]:
    """``gap --jobs 2`` in a new session (a signal reaches only the pids we name), waited for until its
    two workers run; returns the process, its helper processes (workers and resource tracker) and the file
    its stderr goes to. A file, not a pipe: a pipe nobody reads while the command runs fills up (64 KiB: the
    progress lines and, on a cold numba cache, the compiler's warnings of the workers, which share it), and the
    command then blocks for good writing its last line, which looked like a hang after the interrupt."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    err_path = out.parent / f"{out.name}.stderr.txt"
    with open(err_path, "w") as err_file:
        proc = subprocess.Popen([sys.executable, "-m", "omni_gym.cli", "gap", str(dataset), "--out", str(out),
                                 "--jobs", "2", "--no-plots"], stdout=subprocess.DEVNULL, stderr=err_file,
                                text=True, env=env, start_new_session=True, preexec_fn=_default_sigint)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        kids = _children(proc.pid)
        if sum("spawn_main" in c for c in kids.values()) == 2:
            return proc, kids, err_path
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    proc.kill()
    proc.wait()
    pytest.fail(f"gap --jobs 2 never had 2 workers running; stderr: {err_path.read_text()[-2000:]}")


def _wait_gone(pids, seconds: float) -> list[int]:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        left = [p for p in pids if _alive(p)]
        if not left:
            return []
        time.sleep(0.1)
    return [p for p in pids if _alive(p)]


def _cleanup(pids) -> None:
    for p in pids:
        if _alive(p):
            os.kill(p, signal.SIGKILL)


def test_workers_die_with_a_killed_parent(dataset, tmp_path):
    proc, helpers, _ = _start_gap(dataset, tmp_path / "report")
    time.sleep(1.0)  # the workers are inside their first fit
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    try:
        left = _wait_gone(helpers, GONE_WITHIN_S)
        assert not left, f"still running {GONE_WITHIN_S} s after the parent was killed: " + "; ".join(
            helpers[p][:120] for p in left)
    finally:
        _cleanup(helpers)
    assert not (tmp_path / "report").exists()


@pytest.mark.parametrize(("delay", "target"), [(0.5, "main"), (1.0, "group")])
def test_interrupting_gap_with_workers_stops_them_and_writes_nothing(dataset, tmp_path, delay, target):
    """SIGINT three times (the second and third while it stops the workers), to the main process only
    (``timeout -s INT``) or to the whole process group (Ctrl-C in a terminal): it exits 130 within
    seconds, says one line (no worker prints a KeyboardInterrupt), and leaves no report and no worker."""
    out = tmp_path / "report"
    proc, helpers, err_path = _start_gap(dataset, out)
    time.sleep(delay)
    try:
        for _ in range(3):
            if target == "main":
                os.kill(proc.pid, signal.SIGINT)
            else:
                os.killpg(proc.pid, signal.SIGINT)  # its own session: the group is gap and its workers
            time.sleep(0.15)
        proc.wait(timeout=30)  # it used to hang in multiprocessing's exit join
        err = err_path.read_text()
        assert proc.returncode == 130, err[-2000:]
        assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-2000:]
        assert err.strip().splitlines()[-1] == "omni-gym: interrupted"
        assert not _wait_gone(helpers, GONE_WITHIN_S)
    finally:
        if proc.poll() is None:
            proc.kill()
        _cleanup(helpers)
    assert not out.exists()
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".report")]  # no temporary, no lock


@pytest.mark.parametrize("marker", ["numpy", "gymnasium.spaces"])
def test_ctrl_c_while_the_command_starts_is_one_line(marker):
    """An interrupt during the imports (Gymnasium, numpy: the first ~0.2 s) is one line and status 130.

    The interrupt is sent when the process reports (``PYTHONPROFILEIMPORTTIME``, one stderr line per
    finished import) that it imported ``marker``, which the package import loads after its Ctrl-C guard:
    earlier, the interpreter itself is still starting (its own site import), which no program controls."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1]), "PYTHONPROFILEIMPORTTIME": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "omni_gym.cli", "model", "show", "williams2002"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=_default_sigint)
    for line in proc.stderr:  # "import time: self | cumulative | [indent]module"
        if line.startswith("import time:") and line.rpartition("|")[2].strip() == marker:
            break
    proc.send_signal(signal.SIGINT)
    _, rest = proc.communicate(timeout=30)
    err = [ln for ln in rest.splitlines() if not ln.startswith("import time:")]
    if proc.returncode == 0:
        pytest.skip(f"the command finished before the interrupt after {marker}")
    assert proc.returncode == 130, "\n".join(err)
    assert err == ["omni-gym: interrupted"], "\n".join(err)


# A driver that maps tasks with large results, so that the workers spend most of their time writing them
# into the result pipe: an interrupt then often kills a worker in the middle of a message.
_LARGE_RESULTS = '''
import sys

from omni_gym.interrupts import MESSAGE, exit_interrupted, main_handler
from omni_gym.parallel import Backend, executor


def large(i):
    return bytes(20_000_000 + i)


if __name__ == "__main__":
    restore = main_handler()
    try:
        with executor(Backend(jobs=2)) as ex:
            ex.start()
            print("started", flush=True)
            while True:
                ex.map(large, range(4))
    except KeyboardInterrupt:
        print(MESSAGE, file=sys.stderr)
        exit_interrupted()  # as the command line leaves: no exit join on the pools' manager threads
    finally:
        restore()
'''


@pytest.mark.slow  # about 20 CPU-s; make test keeps the interrupt cases with workers (make test-slow, which CI runs)
def test_interrupt_ends_the_driver_whatever_the_workers_were_doing(tmp_path):
    """SIGINT at many points of a run whose workers write large results: every trial ends (status 130, one
    line, no worker left). A worker killed mid-write used to leave the pool's manager thread reading the
    rest of its message forever, and the interpreter's exit waiting for that thread."""
    script = tmp_path / "driver.py"
    script.write_text(_LARGE_RESULTS)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    for k in range(10):
        proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, env=env, preexec_fn=_default_sigint)
        assert proc.stdout.readline().strip() == "started"
        workers = list(_children(proc.pid))
        time.sleep(0.05 + 0.11 * k)  # spread over the write and read phases of the 4-task maps
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=60)  # a hang, not a slow machine, would exceed this
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            _cleanup(workers)
            pytest.fail(f"trial {k}: the driver did not end after SIGINT")
        left = _wait_gone(workers, GONE_WITHIN_S)
        _cleanup(left)
        assert proc.returncode == 130 and err.strip().splitlines()[-1] == "omni-gym: interrupted", (k, err)
        assert not left, k


def _interrupt_turned_into(exc_type):
    """A command that receives Ctrl-C inside a library which re-raises it as ``exc_type`` (numba does so with
    a KeyboardInterrupt raised while it loads its extension modules: ``ImportError: numba._devicearray failed
    to import``, seen when a Ctrl-C reached `synth` as it imported numba)."""
    def command(args):
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            raise exc_type("numba._devicearray failed to import") from None
        return 0
    return command


@pytest.mark.parametrize("exc_type", [ImportError, ValueError])
def test_an_interrupt_a_library_re_raised_as_another_error_is_still_an_interrupt(monkeypatch, capsys, exc_type):
    import omni_gym.cli as cli

    monkeypatch.setattr(cli, "_cmd_calibrate", _interrupt_turned_into(exc_type))
    assert cli.main(["calibrate", "somewhere", "--out", "elsewhere"]) == 130
    assert capsys.readouterr().err.strip().splitlines() == ["omni-gym: interrupted"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # pytest's handler is back


def test_an_import_error_without_an_interrupt_is_not_reported_as_one(monkeypatch):
    import omni_gym.cli as cli

    def broken(args):
        raise ImportError("a genuinely missing module")
    monkeypatch.setattr(cli, "_cmd_calibrate", broken)
    with pytest.raises(ImportError, match="genuinely missing"):
        cli.main(["calibrate", "somewhere", "--out", "elsewhere"])


def test_an_interrupt_while_workers_start_is_held_back_not_lost():
    """SIGINT inside the block that starts or kills workers neither interrupts the block (the pool would be
    left half started) nor is lost (it used to be ignored there: three Ctrl-C in 0.3 s could all vanish and
    the run went on): it raises KeyboardInterrupt when the block ends. A process started inside inherits
    the signal blocked (bit 2 of SigBlk in /proc), so a worker cannot raise KeyboardInterrupt as it starts."""
    from omni_gym.parallel import _sigint_deferred

    finished = []
    with pytest.raises(KeyboardInterrupt):
        with _sigint_deferred():
            signal.raise_signal(signal.SIGINT)
            child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
            finished.append(True)
    try:
        blocked = int(next(line for line in Path(f"/proc/{child.pid}/status").read_text().splitlines()
                           if line.startswith("SigBlk:")).split()[1], 16)
    finally:
        child.communicate(b"")
    assert finished == [True]
    assert blocked & (1 << (signal.SIGINT - 1))


def test_a_held_back_interrupt_respects_an_ignored_sigint():
    """Under an inherited SIG_IGN (a background job) or once the way out has begun, nothing is raised."""
    from omni_gym.parallel import _sigint_deferred

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with _sigint_deferred():
            signal.raise_signal(signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
