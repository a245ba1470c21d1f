"""The pymunk version gate of omni_gym.physics.pymunk_batch."""

from __future__ import annotations

import re
from pathlib import Path

import pymunk
import pytest

from omni_gym.physics import pymunk_batch

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("version", ["6.9.0", "8.0.0", "10.1", "not-a-version"])
def test_a_pymunk_outside_the_range_is_refused_naming_both_versions(version):
    with pytest.raises(ImportError) as err:
        pymunk_batch.check_version(version)
    assert str(err.value) == (f"omni_gym needs pymunk>=7.0,<8 (it calls pymunk's batch internals), "
                              f"but pymunk {version} is installed")


@pytest.mark.parametrize("version", ["7.0", "7.0.0", "7.99.1"])
def test_versions_inside_the_range_pass(version):
    pymunk_batch.check_version(version)


def test_the_installed_pymunk_is_supported():
    pymunk_batch.check_version(pymunk.version)


def test_pyproject_pins_the_same_range():
    # tomllib is Python >= 3.11 and the package supports 3.10: read the one quoted pymunk requirement.
    pins = re.findall(r'"(pymunk[^"]*)"', (ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert [p.replace(" ", "") for p in pins] == [pymunk_batch.SUPPORTED_TEXT]
