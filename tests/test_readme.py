"""The README's claims a machine can check: its commands parse, its ids exist, the files it cites are there.

A newcomer copies the README's commands first; a renamed option, id or file must fail here, not on them.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.cli import build_parser
from omni_gym.envs import RENAMED

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
TOP_DIRS = ("omni_gym/", "agents/", "benchmarks/", "docs/", "data/", "tests/", ".ci/")
PROCESS_WORDS = ("issue ", "issue\n", "session-start", "this session", "helper")


def code_lines() -> list[str]:
    """Every command line of the README's fenced code blocks (backslash continuations joined)."""
    lines: list[str] = []
    for block in re.findall(r"```[a-z]*\n(.*?)```", README, re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        lines += [line.strip() for line in joined.splitlines() if line.strip()]
    return lines


def shell_words(line: str) -> list[str]:
    """The words of a command line before its comment."""
    return shlex.split(line, comments=True)


def omni_gym_commands() -> list[list[str]]:
    return [words for line in code_lines() if line.startswith("omni-gym ") for words in [shell_words(line)]]


def script_commands() -> list[list[str]]:
    """Benchmark commands, in code blocks and in inline code (the headline results cite them inline)."""
    inline = [re.sub(r"\s+", " ", c) for c in re.findall(r"`(python benchmarks/[^`]+)`", README)]
    lines = [line for line in code_lines() if line.startswith("python benchmarks/")] + inline
    return [shell_words(line.replace("|", "_")) for line in lines]


def test_the_readme_has_commands_to_check():
    # The quick start, CLI and headline sections each show commands; an extraction that finds none checks nothing.
    assert len(omni_gym_commands()) >= 8 and len(script_commands()) >= 3


@pytest.mark.parametrize("words", omni_gym_commands(), ids=lambda w: " ".join(w[:3]))
def test_every_omni_gym_command_parses(words):
    parser = build_parser()
    try:
        args = parser.parse_args(words[1:])
    except SystemExit as exc:  # argparse exits 0 for --help/--version only
        assert exc.code == 0, f"README command does not parse: {shlex.join(words)}"
        return
    assert callable(args.handler)


def test_every_benchmark_command_names_a_script_and_its_options():
    helps: dict[str, str] = {}
    for words in script_commands():
        script = ROOT / words[1]
        assert script.is_file(), f"README names a missing script: {words[1]}"
        if words[1] not in helps:  # the script's own --help: options added by shared helpers count too
            done = subprocess.run([sys.executable, words[1], "--help"], cwd=ROOT, capture_output=True, text=True,
                                  timeout=120, env=dict(os.environ, MPLBACKEND="Agg", SDL_VIDEODRIVER="dummy"))
            assert done.returncode == 0, f"{words[1]} --help failed: {done.stderr[-500:]}"
            helps[words[1]] = done.stdout
        options = [w.split("=", 1)[0] for w in words[2:] if w.startswith("--")]
        unknown = [o for o in options if not re.search(rf"{re.escape(o)}\b", helps[words[1]])]
        assert unknown == [], f"{words[1]} has no option {unknown} (README: {shlex.join(words)})"


def test_every_id_the_readme_names_is_registered_and_current():
    ids = set(re.findall(r"\bOmni[A-Za-z]+(?:-[A-Za-z]+)?-v\d+\b", README))
    assert ids, "the README names no environment id"
    for env_id in ids:
        assert env_id in gym.registry, f"README names an unregistered id {env_id}"
        assert env_id not in RENAMED, f"README names the old id {env_id} (now {RENAMED[env_id]})"


def test_the_readme_id_table_is_the_registry():
    """The registry (omni_gym.envs.all_ids) is the one list of ids: the README's table has each once, with its
    registered step limit, and nothing else."""
    from omni_gym.envs import all_ids

    table = README.split("## Environments", 1)[1].split("\n\n", 2)[1]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in table.splitlines()[2:]]
    listed = {row[0].strip("`"): int(row[-1]) for row in rows}
    assert len(listed) == len(rows), "an id is listed twice"
    assert listed == {i: gym.spec(i).max_episode_steps for i in all_ids()}


def test_every_repository_file_the_readme_cites_exists():
    cited = set(re.findall(r"`([^`\s]+)`", README)) | set(re.findall(r"\]\(([^)\s]+)\)", README))
    paths = [c for c in cited if c.startswith(TOP_DIRS) and not re.search(r"[<>*{}|]|\.\.\.|…", c)]
    assert paths, "the README cites no repository file"
    missing = [p for p in paths if not (ROOT / p.split("#")[0].rstrip(":,.")).exists()]
    assert missing == [], f"README cites missing files: {missing}"


def test_the_readme_speaks_to_users_not_to_our_process():
    lowered = README.lower()
    assert [w for w in PROCESS_WORDS if w in lowered] == []


def test_the_layout_names_every_module():
    layout = README.split("## Layout", 1)[1].split("```")[1]
    words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", layout))
    modules = [p for base in ("omni_gym", "agents") for p in (ROOT / base).rglob("*.py") if p.stem != "__init__"]
    missing = sorted(str(p.relative_to(ROOT)) for p in modules if p.stem not in words)
    assert missing == [], f"README's Layout does not name {missing}"


def test_the_readme_stays_short_with_its_sections():
    """At most 300 lines (detail lives in docs/, e.g. docs/results.md), with what a new user looks for: what it is,
    install, the two commands, the environments table, the command line and the headline results."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 300
    headings = [line for line in text.splitlines() if line.startswith("## ")]
    for section in ("## Quick start", "## Install", "## Environments", "## Command line", "## Headline results"):
        assert section in headings, section
    assert "omni-gym gap" in text and "gym.make" in text
