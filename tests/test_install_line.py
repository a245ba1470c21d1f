"""The install lines the package prints and documents work from a checkout.

omni-gym is not on PyPI, so ``pip install 'omni-gym[EXTRA]'`` fails for a new user; the messages that
name a missing extra give ``pip install -e '.[EXTRA]'``, run from the repository root.
"""

from __future__ import annotations

import re
from pathlib import Path

import agents
from agents import export
from omni_gym import parallel, rllib
from omni_gym.discrepancy.data.importers import rosbag2
from omni_gym.envs import render

ROOT = Path(__file__).resolve().parents[1]
# A pip line installing the distribution by name (with or without extras): what does not work.
BY_NAME = re.compile(r"pip install[^\n`]*?['\"]?omni-gym\[")


def test_missing_extra_messages_give_the_checkout_line():
    for message in (rosbag2.MISSING, rllib.RLLIB_EXTRA, parallel.RAY_EXTRA, agents.AGENTS_EXTRA_HINT, export.MISSING,
                    render.RENDER_EXTRA):
        assert not BY_NAME.search(message), message
        assert re.search(r"pip install (-c constraints\.txt )?-e ['\"]\.\[\w+\]['\"]", message), message


def test_docs_do_not_install_by_name():
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    bad = [f"{f.name}:{k + 1}" for f in files for k, line in enumerate(f.read_text().splitlines())
           if BY_NAME.search(line)]
    assert not bad, bad
