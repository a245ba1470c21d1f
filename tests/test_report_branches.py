"""Every branch of the gap report rendered from result objects built here (no ``gap`` run): several kept
effects are all named in the heading with the share of the gap each removed, every kept effect's parameters are
listed, and no line is left unfinished (a line ending in ':' with nothing after it, a bare warning sign)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from omni_gym.discrepancy.report.report import markdown

RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
BASE = json.loads((RESULTS / "real_optiodom_omni3_gap.json").read_text())  # every key a result has
OMNI4 = json.loads((RESULTS / "real_optiodom_omni4_gap.json").read_text())

COM = {"com": [0.012, -0.021]}
FRAME = {"offset": [-0.03, -0.025], "yaw": 0.0097}
ALL_STATUSES = {"identified": [], "merged": ["com1"], "loose": {"com2": 0.1}, "fixed": {"ox": 0.0},
                "bound_fixed": {"oy": 0.1}, "kept": {"yaw": 0.0}, "at_bound": ["com2"], "bound_cost": {"yaw": 1.0},
                "combinations": [], "line": "partly determined"}


def _step(k: int, effect: str, before: float, after: float, params: dict, status: str = "named") -> dict:
    return {"step": k, "effect": effect, "status": status, "why": f"{effect} removes part of the gap",
            "params": params, "gap_before": before, "gap_after": after, "ranking": []}


def two_kept(implausible: bool) -> dict:
    """com_offset kept first (10 → 8 mm: 20 % of the gap), then tracker_offset (8 → 1 mm: 70 %)."""
    r = copy.deepcopy(BASE)
    r.update(effect="com_offset", why="com_offset and tracker_offset remove 90 % of the gap", params=COM,
             effects=["com_offset", "tracker_offset"],
             steps=[_step(1, "com_offset", 0.010, 0.008, COM), _step(2, "tracker_offset", 0.008, 0.001, FRAME),
                    _step(3, "none", 0.001, 0.001, {}, status="end")])
    for row in r["ranking"]:
        row["implausible"] = ["offset = 0.3 m, plausible [-0.1, 0.1]"] if implausible else []
    return r


def variants() -> dict[str, dict]:
    out = {"omni3 (unexplained after one kept effect)": BASE, "omni4": OMNI4,
           "two kept, one implausible row": two_kept(True), "two kept, nothing implausible": two_kept(False)}
    r = two_kept(True)
    r["plausibility"] = {**r["plausibility"], "flags": [{"param": "com", "value": 0.3, "lo": -0.1, "hi": 0.1,
                                                          "why": "beyond the support polygon"}]}
    r["identifiability"] = {**r["identifiability"], "per_effect_status": {"com_offset": ALL_STATUSES,
                                                                          "tracker_offset": ALL_STATUSES}}
    r["non_finite"] = [f"ranking.{k}.score" for k in range(12)]
    out["flags, every parameter status, non-finite values"] = r
    r = copy.deepcopy(BASE)
    r.update(effect="none", why="no candidate beats the nominal model", params={}, effects=[],
             steps=[_step(1, "none", 0.01, 0.01, {}, status="end")], uncertainty=None)
    out["none"] = r
    r = copy.deepcopy(BASE)
    r.update(effect="unexplained", params={}, effects=[], steps=[_step(1, "unexplained", 0.01, 0.01, {}, "end")])
    out["unexplained, nothing kept"] = r
    r = two_kept(False)
    r["steps"][1]["params"] = {}
    r["steps"][0]["gap_before"] = None
    out["a kept effect without parameters, a missing gap"] = r
    return out


def unfinished(report: str) -> list[str]:
    """Lines that promise content and have none: ending in ':' without the list, table or sub-list it
    introduces on the next non-empty line, or a warning sign with nothing after it."""
    lines = report.splitlines()
    bad = []
    for i, line in enumerate(lines):
        text = line.rstrip()
        if text.endswith(":"):
            rest = [x for x in lines[i + 1:] if x.strip()]
            if not rest or not rest[0].startswith(("* ", "| ", "`")):
                bad.append(text)
        if text.strip().rstrip(":").strip() in ("⚠", "* ⚠", "⚠ **") or text.endswith("⚠:"):
            bad.append(text)
    return bad


@pytest.mark.parametrize("name", list(variants()))
@pytest.mark.parametrize("figures", [[], ["staircase.png", "residuals.png"]])
def test_no_line_is_left_unfinished(name, figures):
    report = markdown(variants()[name], figures)
    assert unfinished(report) == [], name
    assert "⚠: a fitted value outside its plausible range:" not in report


def test_every_kept_effect_is_in_the_heading_with_its_share_and_its_parameters():
    report = markdown(two_kept(False), [])
    lines = report.splitlines()
    assert lines[0] == "# Model-discrepancy report: `com_offset` + `tracker_offset`"
    outcome = next(line for line in lines if line.startswith("**Outcome:"))
    # (10 - 8) / 10 = 20 %, (8 - 1) / 10 = 70 % of the gap before the first step
    assert ("`com_offset` + `tracker_offset` (`com_offset` removed 20 % of the gap beyond noise; `tracker_offset` "
            "removed 70 % of the gap beyond noise)") in outcome
    params = report.split("Fitted parameters:")[1].split("##")[0]
    assert "`com_offset`:" in params and "* `com` = [0.012, -0.021]" in params
    assert "`tracker_offset`:" in params and "* `offset` = [-0.03, -0.025]" in params and "* `yaw` = 0.0097" in params


def test_the_warning_legend_comes_only_with_its_rows():
    flagged = markdown(two_kept(True), [])
    assert "⚠ marks a fitted value outside its plausible range:" in flagged
    assert "* tracker_offset: offset = 0.3 m, plausible [-0.1, 0.1]" in flagged
    assert "plausible range" not in markdown(two_kept(False), []).split("## Ranking")[1].split("##")[0]


def test_every_ratio_in_the_report_follows_from_its_columns():
    """The localisation table's ratio is its two columns divided (a tiny 'elsewhere' once printed as 0.000 beside
    a ratio of 1867); the held-out table's ratio is its reported and kinematic columns divided."""
    import re

    r = copy.deepcopy(BASE)
    r["where"]["conditions"] = {"accelerating": {"rows": 120, "mean_sq_growth": 1.867e-6, "elsewhere": 1.0e-9,
                                                 "ratio": 1867.0},
                                "turning": {"rows": 80, "mean_sq_growth": 2.5e-7, "elsewhere": 1.0e-7, "ratio": 2.5}}
    report = markdown(r, [])
    rows = [line for line in report.splitlines() if line.startswith(("| accelerating |", "| turning |"))]
    assert len(rows) == 2
    for line in rows:
        cells = [c.strip() for c in line.strip("|").split("|")]
        growth, elsewhere, ratio = (float(c) for c in cells[2:5])
        # 4 significant digits on each column, 3 on the ratio: they agree to the ratio's last digit
        assert abs(growth / elsewhere - ratio) <= 0.005 * ratio, line
    heldout = [line for line in report.splitlines() if re.match(r"\| (`|\(none|all)", line) and "÷" not in line]
    for line in heldout:
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) >= 6 and cells[-1] not in ("", "–"):
            values = [float(c) for c in cells[2:-1]]
            kinematic, reported = values[1], values[-1]
            assert abs(reported / kinematic - float(cells[-1])) <= 0.01 + 0.005 * float(cells[-1]), line
