"""Packaging: the wheel ships the data files the code reads, ``omni-gym --version``, and the message for
a missing optional dependency. The full non-editable install and a short training from outside the
source tree run in CI (``.ci/install_check.sh``, ``make install-check``).
"""

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import omni_gym
from agents import require_agents_extra
from omni_gym.cli import main

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built from a copy of the sources (building in the tree would write build/ into it)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "models", "*.egg-info")
    for pkg in ("omni_gym", "agents"):
        shutil.copytree(ROOT / pkg, src / pkg, ignore=ignore)
    # --no-build-isolation: the venv's setuptools builds it, without fetching anything.
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", str(src),
                           "-w", str(tmp / "dist")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    (whl,) = (tmp / "dist").glob("omni_gym-*.whl")
    return whl


def test_wheel_ships_the_hyperparameter_files(wheel):
    """A non-editable install left out agents/hyperparams/*.yml, so `omni-gym train` failed."""
    names = set(zipfile.ZipFile(wheel).namelist())
    for folder in ("hyperparams", "rllib"):  # agents/rllib/ppo.yml: omni-gym train --backend rllib
        committed = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "agents" / folder).glob("*.yml"))
        assert committed and set(committed) <= names
    for module in ("agents/train.py", "agents/callbacks.py", "omni_gym/cli.py", "omni_gym/envs/__init__.py"):
        assert module in names
    assert not any(n.startswith("agents/models/") for n in names)  # the committed models stay in the checkout


def test_wheel_metadata_version_and_entry_point(wheel):
    z = zipfile.ZipFile(wheel)
    (meta,) = [n for n in z.namelist() if n.endswith(".dist-info/METADATA")]
    version = next(line.split(":", 1)[1].strip() for line in z.read(meta).decode().splitlines()
                   if line.startswith("Version:"))
    assert version == omni_gym.__version__  # one source of truth: pyproject.toml
    (entry,) = [n for n in z.namelist() if n.endswith(".dist-info/entry_points.txt")]
    assert "omni-gym = omni_gym.cli:main" in z.read(entry).decode()
    extras = z.read(meta).decode()
    for extra in ("agents", "render", "dev", "rllib"):
        assert f"Provides-Extra: {extra}" in extras


def test_version_option(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"omni-gym {omni_gym.__version__}"
    assert omni_gym.__version__[0].isdigit()


@pytest.mark.parametrize("module, dist", [("torch", "torch"), ("stable_baselines3", "stable-baselines3"),
                                          ("yaml", "pyyaml")])
def test_missing_agents_extra_is_named_in_one_line(module, dist, monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, module, None)  # find_spec then reports the package as absent
    with pytest.raises(ModuleNotFoundError, match=r"needs the agents extra \(missing: " + dist):
        require_agents_extra("x")
    for args in (["train", "--algo", "ppo", "--env", "OmniPathFollow-Phunopas-v0", "--out", str(tmp_path / "m")],
                 ["evaluate", "--policy", str(tmp_path / "m.zip"), "--algo", "ppo", "--env",
                  "OmniPathFollow-Phunopas-v0", "--episodes", "1", "--seed", "0"]):
        (tmp_path / "m.zip").write_bytes(b"")
        assert main(args) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("omni-gym: error: ") and "needs the agents extra" in err[0], err
        # The constraints keep pip from fetching a multi-gigabyte CUDA torch (README, "Install with pip").
        assert "pip install -c constraints.txt -e '.[agents]'" in err[0] and "CUDA" in err[0]
        assert not (tmp_path / "m").exists()


def test_a_foreign_agents_package_is_named(tmp_path):
    """The OpenAI Agents SDK installs a top-level ``agents`` too: when Python finds that one, train and evaluate
    say so in one line (no ModuleNotFoundError traceback), and the other commands still work."""
    fake = tmp_path / "agents"
    fake.mkdir()
    (fake / "__init__.py").write_text("class Agent:\n    pass\n")  # the SDK's package, as far as we care
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    for args in (["train", "--algo", "ppo", "--env", "OmniPathFollow-Phunopas-v0", "--out", str(tmp_path / "m")],
                 ["evaluate", "--policy", "ekf-pid", "--env", "OmniPathFollow-Phunopas-v0", "--episodes", "1"]):
        proc = subprocess.run([sys.executable, "-m", "omni_gym.cli", *args], capture_output=True, text=True, env=env,
                              cwd=tmp_path, timeout=120)
        err = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(err) == 1, proc.stderr
        assert err[0].startswith("omni-gym: error: the package 'agents' that Python imports (") and str(fake) in err[0]
        assert not (tmp_path / "m").exists()
    proc = subprocess.run([sys.executable, "-m", "omni_gym.cli", "model", "show", "williams2002"], capture_output=True,
                          text=True, env=env, cwd=tmp_path, timeout=120)
    assert proc.returncode == 0 and "williams2002" in proc.stdout, proc.stderr
