"""No words about how the project was made in its code, docs or tests.

A reader of the package has no issue tracker and no planning notes: "issue 16", "the issue's budget" or a
"moonshot" points at nothing they can open. Every tracked text file is scanned; a hit names file:line.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SUFFIXES = (".py", ".md", ".yml", ".yaml", ".sh", ".toml", ".cfg")
NAMES = ("Makefile", "run")  # .ci/run has no suffix
# Words that only make sense with the tracker at hand. A plain "issue" in another sense (a known
# limitation) is not flagged; a numbered one, "the issue's ...", or the tracker's goal words are.
PATTERNS = [re.compile(p, re.I) for p in (
    r"\bissues?[ -]?#?\d",          # issue 16, issue-6, issues 12.7, issue #3
    r"\bissue[ -]items?\b",         # issue item 2
    r"\b(the|this|that|our|its) issue\b",
    r"\bissue's\b",
    r"\bissue asks\b",
    r"\bmoonshot",
)]
THIS_FILE = Path(__file__).resolve().relative_to(ROOT).as_posix()


def tracked_text_files() -> list[str]:
    """Tracked files with a text suffix, relative to the repository root (git ls-files)."""
    try:
        done = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    except FileNotFoundError:
        return []
    if done.returncode != 0:
        return []
    return [p for p in done.stdout.splitlines()
            if (p.endswith(SUFFIXES) or Path(p).name in NAMES) and p != THIS_FILE and (ROOT / p).is_file()]


def process_words(text: str) -> list[tuple[int, str]]:
    """(line number from 1, matched words) for every line of ``text`` that has a process word."""
    hits = []
    for number, line in enumerate(text.splitlines(), 1):
        for pattern in PATTERNS:
            found = pattern.search(line)
            if found:
                hits.append((number, found.group(0)))
                break
    return hits


@pytest.mark.parametrize("line, flagged", [
    ("the budget of issue 5", True), ("(issue-16 agents)", True), ("issues 12.7, 13.9", True),
    ("Issue 6 asks whether", True), ("the issue's 2-minute budget", True), ("the moonshot 0.7x", True),
    ("(issue item 2)", True), ("a known issue with pymunk's damping", False), ("tissue 5 mm", False),
])
def test_the_patterns_flag_process_words_and_nothing_else(line, flagged):
    assert bool(process_words(line)) is flagged


def test_no_tracked_file_has_process_words():
    files = tracked_text_files()
    if not files:
        pytest.skip("not a git checkout: nothing to list")
    assert any(f.endswith(".md") for f in files) and any(f.endswith(".py") for f in files)
    hits = [f"{path}:{number}: {word!r}" for path in files
            for number, word in process_words((ROOT / path).read_text(encoding="utf-8", errors="replace"))]
    assert hits == [], "process words (rephrase for a reader without the tracker):\n" + "\n".join(hits)
