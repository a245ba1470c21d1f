"""Hostile inputs found by a probe: each is refused with one line, before anything is written, and
nothing is written outside ``--out`` (run names), replaced where it is not ours (``--force``), or imported."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from omni_gym.cli import main
from omni_gym.outputs import OutputError, check_file_name

MODEL = "williams2002"
COLUMNS = "t=t,x=x,y=y,theta=theta,enc1=enc1,enc2=enc2,enc3=enc3"


def _one_line(err: str) -> str:
    """The one error line the command line prints (and nothing else on stderr)."""
    assert err.count("\n") == 1 and err.startswith("omni-gym: error: ") and "Traceback" not in err, err
    return err


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@pytest.fixture(scope="module")
def robot_csv(tmp_path_factory) -> Path:
    """A run of the Williams robot as a CSV log (a dataset run file has every column import csv needs)."""
    folder = tmp_path_factory.mktemp("log")
    assert main(["synth", "--model", MODEL, "--hidden", "none", "--runs", "1", "--duration", "2", "--out",
                 str(folder / "ds")]) == 0
    log = folder / "robot.csv"
    log.write_bytes((folder / "ds" / "runs" / "run000.csv").read_bytes())
    return log


# -- 1. run names are plain file names ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["/abs/dir/NAME", "../up", "a/../../b", "..", ".", ".hidden", "sub\\x", "a\nb",
                                  "esc\x1b[31m", "nul\x00", "x" * 300])
def test_window_names_that_are_paths_are_refused(robot_csv, tmp_path, capsys, name):
    work = tmp_path / "work"
    work.mkdir()
    if name.startswith("/"):
        name = str(work / "abs" / "NAME")
    before = _tree(tmp_path)
    rc = main(["import", "csv", str(robot_csv), "--model", MODEL, "--columns", COLUMNS, "--window", f"{name}=0:1",
               "--out", str(work / "ds")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "run name" in err and "--window" in err
    assert "\x1b" not in err and "\x00" not in err  # the name is echoed escaped
    assert _tree(tmp_path) == before  # nothing written anywhere (the default name would have been the log's)


def test_mapping_window_names_are_refused(robot_csv, tmp_path, capsys):
    mapping = tmp_path / "robot.json"
    mapping.write_text(json.dumps({"model": MODEL, "columns": COLUMNS, "window": ["ok=0:1", "../../evil=1:2"]}))
    before = _tree(tmp_path)
    rc = main(["import", "csv", str(robot_csv), "--mapping", str(mapping), "--out", str(tmp_path / "ds")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "'../../evil'" in err
    assert _tree(tmp_path) == before


def test_plain_window_names_still_work(robot_csv, tmp_path):
    out = tmp_path / "ds"
    assert main(["import", "csv", str(robot_csv), "--model", MODEL, "--columns", COLUMNS, "--window", "a..b=0:1",
                 "--window", "zwei=1:2", "--out", str(out)]) == 0
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["a..b.csv", "zwei.csv"]


def test_write_dataset_refuses_a_path_as_run_name(tmp_path):
    """The last guard, for every writer of datasets (importers, synth): the names are checked before any file."""
    import numpy as np

    from omni_gym.discrepancy.data.dataset import Run, write_dataset

    t = np.array([0.0, 0.1])
    runs = [Run(name="good", t=t, cmd=np.zeros((2, 3)), pose=np.zeros((2, 3))),
            Run(name="../../escaped", t=t, cmd=np.zeros((2, 3)), pose=np.zeros((2, 3)))]
    with pytest.raises(OutputError, match="path separator"):
        write_dataset(tmp_path / "ds", {}, "", runs)
    assert _tree(tmp_path) == set()


def test_check_file_name():
    assert check_file_name("run-01 (left) ü") == "run-01 (left) ü"
    for bad in ("", None, "a/b", "a\\b", "..", ".x", "a\tb", "a\x7f", "a\x85b", "é" * 101):
        with pytest.raises(OutputError):
            check_file_name(bad)


# -- 2. --force replaces only regular files and folders ------------------------------------------------------


def _special(tmp_path: Path, kind: str) -> Path:
    """A FIFO (as /dev/full would be: not a file omni-gym writes), or a symbolic link to one."""
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    if kind == "fifo":
        return fifo
    link = tmp_path / "link"
    link.symlink_to(fifo)
    return link


@pytest.mark.parametrize("kind", ["fifo", "link to fifo"])
def test_force_does_not_replace_a_fifo(tmp_path, capsys, kind):
    target = _special(tmp_path, kind)
    cmds = tmp_path / "cmd.csv"
    cmds.write_text("t,w1,w2,w3\n0,1,1,1\n0.1,1,1,1\n")
    rc = main(["simulate", "--model", MODEL, "--commands", str(cmds), "--out", str(target), "--force"])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "named pipe" in err and "even with --force" in err
    assert (tmp_path / "fifo").is_fifo() and os.path.islink(target) == (kind != "fifo")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({"cmd.csv", "fifo", target.name})  # no leftovers


def test_calibrate_force_does_not_replace_a_fifo(robot_csv, tmp_path, capsys):
    target = _special(tmp_path, "fifo")
    rc = main(["calibrate", str(robot_csv.parent / "ds"), "--out", str(target), "--force"])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "named pipe" in err and target.is_fifo()


def test_force_still_replaces_a_file(tmp_path):
    cmds = tmp_path / "cmd.csv"
    cmds.write_text("t,w1,w2,w3\n0,1,1,1\n0.1,1,1,1\n")
    out = tmp_path / "traj.csv"
    out.write_text("old\n")
    assert main(["simulate", "--model", MODEL, "--commands", str(cmds), "--out", str(out), "--force"]) == 0
    assert out.read_text().startswith("t,x,y,theta")


# -- 3. a model folder's env_id never imports a module ---------------------------------------------------------

ENV = "OmniPathFollow-Phunopas-v0"
COMMITTED = Path(__file__).resolve().parents[1] / "agents" / "models" / "ppo-residual"


@pytest.fixture
def evil_module(tmp_path, monkeypatch):
    """A module on sys.path whose import writes a marker file: (module name, marker)."""
    marker = tmp_path / "imported"
    name = f"evil_env_module_{os.getpid()}"
    (tmp_path / f"{name}.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return name, marker


def _model_with(tmp_path: Path, **meta_changes) -> Path:
    import shutil

    d = tmp_path / "model"
    shutil.copytree(COMMITTED, d)
    meta = json.loads((d / "meta.json").read_text())
    meta.update(meta_changes)
    (d / "meta.json").write_text(json.dumps(meta))
    return d


@pytest.mark.parametrize("command", ["export", "evaluate", "evaluate-trusted"])
def test_env_id_import_path_is_refused(tmp_path, capsys, evil_module, command):
    name, marker = evil_module
    model = _model_with(tmp_path, env_id=f"{name}:{ENV}")
    if command == "export":
        argv = ["export", str(model), "--out", str(tmp_path / "x")]
    else:
        argv = ["evaluate", "--policy", str(model), "--env", ENV, "--episodes", "1", "--env-kwargs",
                '{"episode_seconds": 0.5}'] + (["--trust-pickle"] if command.endswith("trusted") else [])
    rc = main(argv)
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "meta.json: key 'env_id'" in err and "names a module to import" in err
    assert not marker.exists() and name not in sys.modules
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("value", [["OmniGoToPose-v0"], "CartPole-v1", ""])
def test_env_id_must_be_a_registered_string(tmp_path, capsys, value):
    model = _model_with(tmp_path, env_id=value)
    rc = main(["export", str(model), "--out", str(tmp_path / "x")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "key 'env_id'" in err


def test_check_env_id():
    from agents.rollout import check_env_id

    assert check_env_id(ENV) == ENV and check_env_id(f"omni_gym:{ENV}") == f"omni_gym:{ENV}"
    with pytest.raises(ValueError, match="names a module"):
        check_env_id(f"os:{ENV}", "here")
    with pytest.raises(ValueError, match="unknown environment id"):
        check_env_id("Nope-v0")
    assert check_env_id("CartPole-v1", registered=False) == "CartPole-v1"  # make_env's own message follows


# -- 4. deep JSON, garbage gzip, a zstd bag: one line ------------------------------------------------------------


def test_export_deep_meta_json(tmp_path, capsys):
    model = _model_with(tmp_path)
    (model / "meta.json").write_text("[" * 100_000 + "]" * 100_000)
    rc = main(["export", str(model), "--out", str(tmp_path / "x")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "meta.json" in err and "nested" in err


OPTIODOM = Path(__file__).resolve().parents[1] / "data" / "optiodom-omni3" / "circular" / "221220201730"


@pytest.mark.parametrize("content", [b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03garbage",  # zlib.error
                                     b"not gzip at all",  # gzip.BadGzipFile
                                     None])  # truncated: EOFError
def test_optiodom_garbage_gz_is_one_line(tmp_path, capsys, content):
    import gzip
    import shutil

    session = tmp_path / OPTIODOM.name
    shutil.copytree(OPTIODOM, session)
    run = next(session.glob("*_run-01.csv"))
    if content is None:
        content = gzip.compress(run.read_bytes())[:200]
    run.unlink()
    run.with_name(run.name + ".gz").write_bytes(content)
    rc = main(["import", "optiodom", str(session), "--out", str(tmp_path / "ds")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "run-01.csv.gz" in err
    assert not (tmp_path / "ds").exists()


def _bag(tmp_path: Path, **kwargs) -> Path:
    pytest.importorskip("rosbags")
    from omni_gym.discrepancy.synthetic.bags import write_bag
    from omni_gym.discrepancy.synthetic.synth import synthesize
    from omni_gym.physics.model import load_model

    runs, _ = synthesize(load_model(MODEL), "none", runs=1, noise=0.0, seed=5, duration=1.0)
    bag = tmp_path / "bag"
    write_bag(bag, [(runs[0].t, runs[0].enc, runs[0].pose)], ["wl", "wr", "wb"], [1.0, -1.0, 1.0], **kwargs)
    return bag


BAG_ARGS = ["--model", MODEL, "--joints", "wl,-wr,wb", "--pose-topic", "/tracker/pose"]


@pytest.mark.parametrize("mode", ["MESSAGE", "FILE"])
def test_bag_claiming_zstd_is_one_line(tmp_path, capsys, mode):
    bag = _bag(tmp_path)
    meta = bag / "metadata.yaml"
    meta.write_text(meta.read_text().replace("compression_format: ''", "compression_format: zstd")
                    .replace("compression_mode: ''", f"compression_mode: {mode}"))
    rc = main(["import", "rosbag2", str(bag), *BAG_ARGS, "--out", str(tmp_path / "ds")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "cannot read the bag" in err


# -- 5. messages: untrusted strings escaped, no warning before the error, library pages folded --------------------

EVIL_FRAME = "w\x1b[31mRED\nforged line"


def test_bag_frame_id_is_escaped(tmp_path, capsys):
    bag = _bag(tmp_path, frame=EVIL_FRAME)
    rc = main(["import", "rosbag2", str(bag), *BAG_ARGS, "--frames", "world:base_link", "--out", str(tmp_path / "x")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "\x1b" not in err and "w\\x1b[31mRED\\nforged line" in err
    # accepted (no --frames): the description names the frame, printed and recorded, escaped
    assert main(["import", "rosbag2", str(bag), *BAG_ARGS, "--out", str(tmp_path / "ds")]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "w\\x1b[31mRED\\nforged line" in out and out.count("\n") == 2


def test_control_characters_in_any_message_are_escaped(tmp_path, capsys):
    rc = main(["simulate", "--model", MODEL, "--commands", str(tmp_path / "a\x1b]0;title\x07.csv"), "--out",
               str(tmp_path / "t.csv")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "\x1b" not in err and "\x07" not in err and "a\\x1b]0;title\\x07.csv" in err


def test_no_runtime_warning_before_the_error(robot_csv, tmp_path, capsys):
    import warnings

    lines = robot_csv.read_text().splitlines()
    cells = lines[4].split(",")
    cells[4] = "1e308"  # enc1: the mean speed to its neighbours overflows
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([*lines[:4], ",".join(cells), *lines[5:]]) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # printed by the command line: an exception here
        rc = main(["import", "csv", str(bad), "--model", MODEL, "--columns", COLUMNS, "--out", str(tmp_path / "ds")])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "bad.csv" in err


def test_torch_refusal_is_folded_to_its_reason(tmp_path, capsys):
    import torch

    model = _model_with(tmp_path)
    torch.save({"x": _Payload(str(tmp_path / "ran"))}, model / "policy.pt")
    rc = main(["evaluate", "--policy", str(model), "--env", ENV, "--episodes", "1"])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and "Unsupported global" in err and "\x1b" not in err and "weights_only" not in err
    assert len(err) < 300 and not (tmp_path / "ran").exists()


class _Payload:
    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


# -- 6. resource bounds in train ----------------------------------------------------------------------------------


@pytest.mark.parametrize("algo, entry, message", [
    ("ppo", '{policy_kwargs: "dict(net_arch=[100000000, 100000000])"}', "2e+16 parameters"),
    ("sac", "{policy_kwargs: {net_arch: {pi: [64], qf: [20000, 20000]}}}", "--max-parameters"),
    ("sac", "{buffer_size: 100000000}", "--max-buffer-mb"),
    ("ppo", "{n_steps: 1000000, n_envs: 64}", "n_steps 1000000 × n_envs 64"),
])
def test_train_refuses_huge_networks_and_buffers(tmp_path, capsys, algo, entry, message):
    hp = tmp_path / "hp.yml"
    hp.write_text(f"{ENV}: {entry}\n")
    rc = main(["train", "--algo", algo, "--env", ENV, "--hyperparams", str(hp), "--timesteps", "10", "--out",
               str(tmp_path / "m"), "--no-progress"])
    err = _one_line(capsys.readouterr().err)
    assert rc == 2 and message in err and "hp.yml" in err
    assert not (tmp_path / "m").exists()


def test_the_limits_can_be_raised_and_leave_the_committed_files_alone():
    from agents.options import MAX_PARAMETERS, check_training_size, network_parameters
    from agents.policy_spec import declarative
    from agents.train import HYPERPARAM_DIR
    from omni_gym.io import read_yaml

    decl = {"net_arch": [4000, 4000]}
    n = network_parameters(decl, "ppo", 30, 3, "x")
    assert n > MAX_PARAMETERS
    assert check_training_size({}, decl, "ppo", 1, 30, 3, "x", max_parameters=n) == n
    # Every shipped entry fits the defaults with room: 128 observations and 3 actions exceed every env's.
    for f in sorted(HYPERPARAM_DIR.rglob("*.yml")):
        for env_id, hp in (read_yaml(f) or {}).items():
            if not isinstance(hp, dict):
                continue
            where = f"{f.name}: {env_id}"
            kw = declarative(hp.get("policy_kwargs"), where)
            for algo in ("ppo", "sac", "td3"):  # whichever reads the file
                check_training_size(hp, kw, algo, int(hp.get("n_envs", 1)), 128, 3, where)


def test_network_parameters_match_sb3():
    """The estimate is exact for SB3's PPO, SAC and TD3 networks (target copies included)."""
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    import numpy as np
    from stable_baselines3 import PPO, SAC, TD3

    from agents.options import network_parameters

    class Box(gym.Env):
        observation_space = gym.spaces.Box(-1, 1, (7,), np.float32)
        action_space = gym.spaces.Box(-1, 1, (3,), np.float32)

    for cls, algo, kw in ((PPO, "ppo", {"net_arch": {"pi": [32, 16], "vf": [8]}}), (SAC, "sac", {"net_arch": [32, 16]}),
                          (TD3, "td3", {"net_arch": [32, 16]})):
        model = cls("MlpPolicy", Box(), policy_kwargs=kw, buffer_size=10, device="cpu") if algo != "ppo" else \
            cls("MlpPolicy", Box(), policy_kwargs=kw, n_steps=8, batch_size=8, device="cpu")
        counted = sum(p.numel() for p in model.policy.parameters())  # target networks are submodules: counted
        assert network_parameters(kw, algo, 7, 3, "test") == counted, algo


def test_rllib_unreachable_address_is_refused_at_once(tmp_path, capsys):
    import time

    t0 = time.monotonic()
    rc = main(["train", "--backend", "rllib", "--env", ENV, "--address", "256.1.1.1:1", "--out", str(tmp_path / "m"),
               "--no-progress"])
    err = _one_line(capsys.readouterr().err)
    # gap --ray refuses the same address within 3 s; ray.init would retry it for more than a minute. 30 s leaves
    # room for a loaded machine's imports.
    assert rc == 2 and "256.1.1.1:1" in err and time.monotonic() - t0 < 30
    assert not (tmp_path / "m").exists()


# -- 7. SIGTERM takes the interrupt's way out: no lock or temporary folder left ----------------------------------


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="Linux")
def test_sigterm_removes_the_lock_and_the_temporary(tmp_path):
    import signal
    import subprocess
    import time

    assert main(["synth", "--model", MODEL, "--hidden", "viscous_drag", "--runs", "3", "--duration", "3", "--out",
                 str(tmp_path / "ds")]) == 0
    out = tmp_path / "rep"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.Popen([sys.executable, "-m", "omni_gym.cli", "gap", str(tmp_path / "ds"), "--out", str(out),
                             "--no-plots"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True)
    lock = tmp_path / ".rep.lock"
    deadline = time.monotonic() + 120  # the imports and the lock: seconds; 120 s for a loaded machine
    while not (lock.exists() and any(p.name.startswith(".rep.tmp-") for p in tmp_path.iterdir())):
        assert proc.poll() is None and time.monotonic() < deadline, "gap ended or never took its lock"
        time.sleep(0.05)
    time.sleep(0.5)  # into the work
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == "omni-gym: interrupted" and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", "ds.truth.json"]  # no lock, no .rep.tmp-PID


def test_rllib_sizes_are_checked_before_ray_starts():
    """The RLlib module's networks (fcnet_hiddens) and train batch within the same limits (no Ray needed)."""
    import gymnasium as gym
    import numpy as np

    from agents.rllib.config import RLlibHyperparams
    from agents.rllib.train import _check_sizes
    from agents.zoo_config import wrapper_spec

    env = type("E", (), {"observation_space": gym.spaces.Box(-1, 1, (30,), np.float32),
                         "action_space": gym.spaces.Box(-1, 1, (3,), np.float32)})()
    spec = wrapper_spec({}, "x")

    def hp(model=None, training=None):
        return RLlibHyperparams({}, spec, 10, 1, training or {}, model or {})

    _check_sizes(hp(), "ppo.yml", env, None, None)  # RLlib's defaults fit
    with pytest.raises(ValueError, match="ppo.yml: model: policy_kwargs: .*--max-parameters"):
        _check_sizes(hp({"fcnet_hiddens": [100_000, 100_000]}), "ppo.yml", env, None, None)
    with pytest.raises(ValueError, match="--max-buffer-mb"):
        _check_sizes(hp(training={"train_batch_size_per_learner": 10**9}), "ppo.yml", env, None, None)
    with pytest.raises(ValueError, match="minibatch_size must be an integer"):
        _check_sizes(hp(training={"minibatch_size": "x"}), "ppo.yml", env, None, None)
