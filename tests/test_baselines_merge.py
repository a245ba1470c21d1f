"""benchmarks/baselines.py ``--merge``: the ids run replace only their own sections of an earlier table."""

from __future__ import annotations

from pathlib import Path

from benchmark_loader import load_benchmark

ROOT = Path(__file__).resolve().parents[1]


def _load():
    return load_benchmark("baselines")


OLD = """# Baselines on OmniPathFollow-Phunopas-v0 and OmniPathFollow-WilliamsPaper-v0

Intro paragraph.

## OmniPathFollow-Phunopas-v0

Phunopas table, kept byte for byte.
| a | b |

## OmniPathFollow-WilliamsPaper-v0

Williams table.
"""


def test_merge_adds_then_replaces_one_section_and_keeps_the_others():
    b = _load()
    mec = b.MECANUM_ENV
    first = b.merge_sections(OLD, {mec: [f"## {mec}", "", "rows v1"]}, "cmd one", 50, 10000, 60.0)
    lines = first.split("\n")
    assert lines[0] == f"# Baselines on OmniPathFollow-Phunopas-v0, OmniPathFollow-WilliamsPaper-v0 and {mec}"
    # Everything of the old file but its title is kept, in order; a blank line now closes the last old section.
    assert "\n".join(lines[1:]).startswith("\n".join(OLD.split("\n")[1:]).rstrip("\n"))
    assert lines.index(f"## {mec}") > lines.index("## OmniPathFollow-WilliamsPaper-v0")  # ENV_IDS order
    assert "cmd one" in first and "rows v1" in first
    second = b.merge_sections(first, {mec: [f"## {mec}", "", "rows v2"]}, "cmd two", 50, 10000, 60.0)
    assert "rows v1" not in second and "cmd one" not in second and "rows v2" in second and "cmd two" in second
    assert second.count(f"## {mec}") == 1
    assert second.split(f"## {mec}")[0] == first.split(f"## {mec}")[0]  # the other sections untouched
    # The mecanum id's conditions keep the floors but use the only friction model of mecanum wheels.
    assert [c["surface"] for c in b.conditions(mec).values()] == [c["surface"] for c in b.CONDITIONS.values()]
    assert {c["friction"] for c in b.conditions(mec).values()} == {"initial"}
