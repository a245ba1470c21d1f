"""benchmarks/discrepancy_recovery.py --budget-only: new timing rows replace their effects' rows in the json
and in the table's budget section; the sweep rows, the notes and the other timing rows stay."""

from __future__ import annotations

import json

from benchmark_loader import load_benchmark


def test_budget_only_replaces_its_rows_and_keeps_everything_else(tmp_path):
    bench = load_benchmark("discrepancy_recovery")
    old = {"sweep": [{"hidden": "motor_lag", "named": "motor_lag"}],
           "budget": [{"hidden": "motor_lag", "named": "motor_lag", "reduction": 1.0, "wall_s": 120.0},
                      {"hidden": "com_offset", "named": "com_offset", "reduction": 0.99, "wall_s": 140.0}],
           "runs_note": ["full sweep: 30 min"]}
    md = ["# title", "", "a hand-written note", "", "| effect | named | gap reduction | wall [s] |",
          "|---|---|---|---|",
          "| motor_lag | motor_lag | 1.00 | 120.0 |", "| com_offset | com_offset | 0.99 | 140.0 |", "", "after"]
    (tmp_path / "discrepancy_recovery.md").write_text("\n".join(md))
    new = [{"hidden": "com_offset", "named": "com_offset", "reduction": 1.0, "wall_s": 61.5},
           {"hidden": "time_offset", "named": "time_offset", "reduction": 0.98, "wall_s": 30.0}]
    bench._replace_budget_rows(tmp_path, old, new)
    data = json.loads((tmp_path / "discrepancy_recovery.json").read_text())
    assert data["sweep"] == [{"hidden": "motor_lag", "named": "motor_lag"}]
    assert [(r["hidden"], r["wall_s"]) for r in data["budget"]] == [("motor_lag", 120.0), ("com_offset", 61.5),
                                                                   ("time_offset", 30.0)]
    assert data["runs_note"][0] == "full sweep: 30 min" and "com_offset, time_offset" in data["runs_note"][1]
    lines = (tmp_path / "discrepancy_recovery.md").read_text().split("\n")
    assert lines[:6] == md[:6] and lines[-2:] == ["", "after"]
    assert lines[6:9] == ["| motor_lag | motor_lag | 1.00 | 120.0 |", "| com_offset | com_offset | 1.00 | 61.5 |",
                          "| time_offset | time_offset | 0.98 | 30.0 |"]
