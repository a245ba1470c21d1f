"""Committed records name no machine's paths: ``meta.json`` commands and results headers say
``--out agents/models/x`` or ``--cache ns_cache.json``, never ``/work/main/...`` or ``/tmp/...``, and the writers
record paths that way (``omni_gym.record_paths``)."""

from __future__ import annotations

import re
from pathlib import Path

from omni_gym.record_paths import ROOT, record_args, record_command, record_path

# An absolute path of a Unix home, a scratch folder or a container's work tree, or a Windows drive.
ABSOLUTE = re.compile(r"(?<![\w.:/])(/work|/tmp|/root|/home|/Users|/mnt|/var/folders)/|\b[A-Z]:\\\\")
RECORDS = ("agents/models", "benchmarks/results", "docs")


def _records() -> list[Path]:
    files = [ROOT / "README.md"]
    for folder in RECORDS:
        files += [f for f in (ROOT / folder).rglob("*") if f.suffix in (".json", ".md", ".csv", ".txt", ".yml")]
    return files


def test_committed_records_hold_no_absolute_paths():
    bad = []
    for f in _records():
        for k, line in enumerate(f.read_text(errors="replace").splitlines(), start=1):
            if ABSOLUTE.search(line):
                bad.append(f"{f.relative_to(ROOT)}:{k}")
    assert not bad, f"{len(bad)} lines with absolute paths, e.g. {bad[:5]}"


def test_record_path_is_repository_relative_or_the_name():
    assert record_path(ROOT / "agents" / "models" / "x") == "agents/models/x"
    assert record_path("/tmp/runs/ppo-s0") == "ppo-s0"
    assert record_path("/work/ns_cache.json") == "ns_cache.json"
    assert record_path("benchmarks/results") == "benchmarks/results"  # relative: kept


def test_record_args_rewrites_every_absolute_path():
    args = ["--out", str(ROOT / "benchmarks" / "results"), "--cache=/work/ns_cache.json", "--episodes", "50"]
    assert record_args(args) == ["--out", "benchmarks/results", "--cache=ns_cache.json", "--episodes", "50"]
    assert record_command("python benchmarks/oracle.py", ["--out", "/tmp/my dir/o"]) == \
        "python benchmarks/oracle.py --out o"
    assert record_command("python b.py", ["--out", "/tmp/my dir"]) == "python b.py --out 'my dir'"
