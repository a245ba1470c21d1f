"""The execution backends (omni_gym.parallel) and ``omni-gym gap --ray``.

On the module's local Ray cluster (``ray_cluster``, tests/conftest.py: 127.0.0.1, 2 CPUs): ``gap``
through Ray gives the local result byte for byte, also when a Ray worker is killed while it runs a fit
(Ray retries the task); the ordered map keeps order and values on every backend; an address nothing
listens on is a one-line error. The dataset is tiny and only two candidates are fitted, so a gap run
takes seconds.
"""

from __future__ import annotations

import json
import math
import operator
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from omni_gym import parallel
from omni_gym.cli import main
from omni_gym.discrepancy import workflow
from omni_gym.discrepancy.fit import candidates
from omni_gym.discrepancy.synthetic.recovery import nominal_model
from omni_gym.discrepancy.synthetic.synth import write_synthetic
from omni_gym.parallel import Backend, BackendError, parallel_map

FAST = ("motor_lag", "wheel_radius")  # two cheap candidates: enough for a decision, seconds per gap run


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("ray") / "data"
    write_synthetic(folder, nominal_model(), 'motor_lag:{"tau": 0.08}', 3, 0.001, 5, 1.5)
    return folder


def _fit_only_fast(mp: pytest.MonkeyPatch) -> None:
    """Fit only FAST (the driver builds the tasks, so the workers need no patch); the rules are unchanged."""
    mp.setattr(workflow, "candidates", lambda model: [c for c in candidates.candidates(model) if c.name in FAST])


@pytest.fixture
def fast_library(monkeypatch):
    _fit_only_fast(monkeypatch)


@pytest.fixture(scope="module")
def local_report(dataset, tmp_path_factory) -> Path:
    """The reference: gap in this process, the default backend (module-scoped: computed once)."""
    mp = pytest.MonkeyPatch()
    _fit_only_fast(mp)
    try:
        out = tmp_path_factory.mktemp("local") / "rep"
        workflow.gap(dataset, out, progress=False, plots=False, max_effects=2)
    finally:
        mp.undo()
    return out


def _same_report(a: Path, b: Path) -> None:
    """The same report byte for byte but for ``work`` (measured seconds) and the folder's own path."""
    ra, rb = (json.loads((d / "result.json").read_text().replace(str(d), "")) for d in (a, b))
    wa, wb = ra.pop("work"), rb.pop("work")
    assert json.dumps(ra) == json.dumps(rb)
    # The same searches, round for round, on both backends (the tasks they were cut into may differ).
    assert [[f["rounds"] for f in s["fits"]] for s in wa["steps"]] == [[f["rounds"] for f in s["fits"]]
                                                                        for s in wb["steps"]]
    assert (a / "report.md").read_bytes() == (b / "report.md").read_bytes()


@pytest.mark.slow  # a live Ray cluster: 10-25 s of start-up per worker on 2 cores (the rllib extra; CI runs test-slow)
def test_map_keeps_order_and_values_on_every_backend(ray_cluster) -> None:
    # Library functions: a worker must import the function, and this test module is not importable there.
    xs = [5, 0, 3, 9, 1, 7, 2]
    for backend in (Backend(), Backend(jobs=2), Backend(ray=True, address=ray_cluster)):
        seen: list[int] = []
        out = parallel_map(math.factorial, xs, backend, on_done=lambda i, _r, s=seen: s.append(i))
        assert out == [math.factorial(x) for x in xs]
        assert sorted(seen) == list(range(len(xs)))  # every task reported once, in whatever order it finished
        assert parallel_map(operator.add, xs, backend, shared=10) == [10 + x for x in xs]


@pytest.mark.slow  # a live Ray cluster: 10-25 s of start-up per worker on 2 cores (the rllib extra; CI runs test-slow)
def test_gap_through_ray_equals_the_local_run_byte_for_byte(dataset, local_report, ray_cluster, fast_library,
                                                            tmp_path) -> None:
    out = tmp_path / "rep"
    workflow.gap(dataset, out, progress=False, plots=False, max_effects=2,
                 backend=Backend(ray=True, address=ray_cluster))
    _same_report(local_report, out)
    local = json.loads((local_report / "result.json").read_text())
    assert local["effect"] == "motor_lag"  # the comparison is about a real answer, not an empty search


@pytest.mark.slow  # a live Ray cluster: 10-25 s of start-up per worker on 2 cores (the rllib extra; CI runs test-slow)
def test_gap_survives_a_worker_killed_mid_task(dataset, local_report, ray_cluster, fast_library, tmp_path) -> None:
    """SIGKILL a Ray worker while it runs a fit: Ray re-runs the task, and the result is unchanged."""
    killed: list[int] = []
    stop = threading.Event()

    def killer() -> None:
        # Ray names a worker process "ray::<task>" while it runs one ("ray::IDLE" between tasks). Only this
        # test's own cluster is searched: its workers descend from the raylet this process started.
        while not stop.is_set() and not killed:
            for pid, title in _descendants():
                if title.startswith("ray::_call_ray"):
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                    break
            time.sleep(0.05)

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    try:
        out = tmp_path / "rep"
        workflow.gap(dataset, out, progress=False, plots=False, max_effects=2,
                     backend=Backend(ray=True, address=ray_cluster, max_retries=3))
    finally:
        stop.set()
        thread.join()
    assert killed, "no worker was caught running a task"
    _same_report(local_report, out)


@pytest.mark.slow  # a live Ray cluster: 10-25 s of start-up per worker on 2 cores (the rllib extra; CI runs test-slow)
def test_gap_cli_with_ray_address_equals_the_local_run(dataset, local_report, ray_cluster, tmp_path) -> None:
    """A second process joins the cluster by address (``--ray ADDRESS``; the token of the cluster's
    ``ray.init`` is sent, RAY_AUTH_MODE=token being inherited). The subprocess applies the same
    candidate patch as ``fast_library`` before calling the CLI's main."""
    out = tmp_path / "rep"
    code = ("import sys; from omni_gym.discrepancy import workflow; from omni_gym.discrepancy.fit import candidates; "
            f"workflow.candidates = lambda m: [c for c in candidates.candidates(m) if c.name in {FAST!r}]; "
            "from omni_gym.cli import main; sys.exit(main(sys.argv[1:]))")
    proc = subprocess.run([sys.executable, "-c", code, "gap", str(dataset), "--out", str(out), "--no-plots",
                           "--max-effects", "2", "--ray", ray_cluster],
                          capture_output=True, text=True, timeout=300)  # the defaults, as the local run's
    assert proc.returncode == 0, proc.stderr[-2000:]
    _same_report(local_report, out)


def test_unreachable_address_is_one_line_exit_2(dataset, tmp_path, capsys) -> None:
    code = main(["gap", str(dataset), "--out", str(tmp_path / "rep"), "--ray", "127.0.0.1:1"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("omni-gym: error: cannot reach the Ray cluster at 127.0.0.1:1") and "\n" not in err
    assert not (tmp_path / "rep").exists()


def test_bad_backend_settings_are_refused() -> None:
    with pytest.raises(BackendError, match="jobs"):
        Backend(jobs=0)
    with pytest.raises(BackendError, match="ray=True"):
        Backend(address="127.0.0.1:6379")
    with pytest.raises(BackendError, match="HOST:PORT"):
        Backend(ray=True, address="nohost").preflight()
    with pytest.raises(BackendError, match="cpus"):
        Backend(ray=True, cpus=0)
    # One job runs in this process unless a pool is asked for (scaling.py measures 1 and N workers alike).
    assert Backend().serial and not Backend(pool=True).serial
    assert Backend(ray=True, cpus=1).describe() == "a local Ray with 1 CPU"


def test_missing_ray_names_the_extra(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(BackendError, match=r"pip install -c constraints.txt -e '\.\[rllib\]'"):
        Backend(ray=True).preflight()
    assert "omni-gym[" not in parallel.RAY_EXTRA  # not on PyPI: the line that works from a checkout


def _descendants() -> list[tuple[int, str]]:
    """(pid, command line) of every descendant of this process (from /proc: no psutil needed)."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            ppid = int(stat.rsplit(")", 1)[1].split()[1])
            children.setdefault(ppid, []).append(int(entry))
    out, todo = [], [os.getpid()]
    while todo:
        for pid in children.get(todo.pop(), []):
            todo.append(pid)
            try:
                title = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
            except OSError:
                continue
            out.append((pid, title))
    return out
