"""benchmarks/sim_to_real.py: the plants it draws and the figures its table derives (on made-up episodes, so every
figure can be computed by hand here)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.benchmark_loader import load_benchmark

s2r = load_benchmark("sim_to_real")


def test_the_plants_cover_both_robots_every_effect_that_moves_and_two_outside_causes():
    plants = s2r.plants()
    assert len(plants) >= 20
    kinds = {(p["robot"], p["kind"]) for p in plants}
    for robot in s2r.ROBOTS:
        for kind in ("none", "com_offset", "wheel_radius", "wheel_geometry", "motor_lag", "kinetic_friction",
                     "wheel_liftoff", "drag", "slope"):
            assert (robot, kind) in kinds
    assert ("williams2002", "roller_gap") in kinds and ("optiodom_omni4", "mecanum_lateral") in kinds
    assert len({p["seed"] for p in plants}) == len(plants)  # each plant its own seed
    assert s2r.plants() == plants  # drawn from the seeds alone


def _record(robot, kind, a, c, b=None, seed=1):
    models = {"nominal": {"plant": {"rmse": a, "success": [True] * len(a)}, "own": {"rmse": [0.002] * len(a),
                                                                                      "success": [True] * len(a)}},
              "gap": {"plant": {"rmse": c, "success": [True] * len(c)}, "own": {"rmse": [0.003] * len(c),
                                                                               "success": [True] * len(c)}}}
    if b is not None:
        models["kinematic"] = {"plant": {"rmse": b, "success": [True] * len(b)},
                               "own": {"rmse": [0.002] * len(b), "success": [True] * len(b)}}
    return {"robot": robot, "kind": kind, "seed": seed, "hidden": None, "gap_effect": kind, "notes": [],
            "models": models, "wall_s": 60.0, "gap_wall_s": 30.0}


def test_cost_win_back_ratios_and_gaps_follow_from_the_episodes():
    none = _record("williams2002", "none", [0.002, 0.002], [0.002, 0.002], b=[0.002, 0.002])
    radius = _record("williams2002", "wheel_radius", [0.010, 0.006], [0.004, 0.004])  # calibrate refused: no b
    rows = {r["kind"]: r for r in s2r.figures([none, radius])}
    r = rows["wheel_radius"]
    assert r["plant"]["nominal"] == pytest.approx(0.008) and r["plant"]["gap"] == pytest.approx(0.004)
    assert r["cost"] == pytest.approx(0.008 / 0.002 - 1)  # +300 %
    assert r["won_back"] == pytest.approx((0.008 - 0.004) / (0.008 - 0.002))
    assert r["c_over_a"]["ratio"] == pytest.approx(0.5)
    lo, hi = r["c_over_a"]["ci95"]
    assert lo <= 0.5 <= hi
    # calibrate refused: the engineer keeps the nominal model, so (b) is (a) and c ÷ b = c ÷ a
    assert r["b_refused"] and r["c_over_b"]["ratio"] == pytest.approx(0.5)
    assert r["sim_to_real_gap"]["nominal"] == pytest.approx(abs(0.002 - 0.008) / 0.008)
    assert r["sim_to_real_gap"]["gap"] == pytest.approx(abs(0.003 - 0.004) / 0.004)
    assert "cost" not in rows["none"] and not rows["none"]["b_refused"]
    pool = s2r.pooled([none, radius], list(rows.values()))
    assert pool["plants"] == ["williams2002/wheel_radius"] and pool["pairs"] == 2
    assert pool["won_back"] == pytest.approx(2 / 3)
    assert pool["won_back_ci95"][0] <= 2 / 3 <= pool["won_back_ci95"][1]
    text = s2r.table([none, radius], list(rows.values()), pool, "python benchmarks/sim_to_real.py", 2)
    assert "wins back 67%" in text and "†" in text and "+300%" in text
    assert "refused on 1 of 2 plants" in text


def test_a_cheap_effect_is_not_pooled():
    none = _record("optiodom_omni4", "none", [0.002, 0.002], [0.002, 0.002])
    slight = _record("optiodom_omni4", "drag", [0.0022, 0.0022], [0.0022, 0.0022])  # +10 %: below COST_MIN
    rows = s2r.figures([none, slight])
    assert rows[1]["cost"] == pytest.approx(0.1) and s2r.COST_MIN > 0.1
    assert s2r.pooled([none, slight], rows) is None
    text = s2r.table([none, slight], rows, None, "cmd", 2)
    assert "nothing to win back" in text and not math.isnan(np.mean(rows[1]["c_over_a"]["ci95"]))


def test_agents_run_on_six_plants_of_both_robots_among_the_drawn_ones():
    drawn = {(p["robot"], p["kind"]) for p in s2r.plants()}
    assert len(s2r.AGENT_PLANTS) >= 6 and set(s2r.AGENT_PLANTS) <= drawn
    assert {robot for robot, _ in s2r.AGENT_PLANTS} == set(s2r.ROBOTS)
    assert all((robot, "none") in s2r.AGENT_PLANTS for robot in s2r.ROBOTS)  # each robot's cost needs its baseline


def _agents(record, a, c, train_s=90.0):
    return {"robot": record["robot"], "kind": record["kind"], "seed": record["seed"], "episodes": len(a),
            "steps": s2r.AGENT_STEPS, "wall_s": 300.0,
            "models": {"nominal": {"plant": {"rmse": a, "success": [True] * len(a)},
                                   "own": {"rmse": [0.001] * len(a), "success": [True] * len(a)}, "train_s": train_s},
                       "gap": {"plant": {"rmse": c, "success": [True] * len(c)},
                               "own": {"rmse": [0.001] * len(c), "success": [True] * len(c)}, "train_s": train_s}}}


def test_the_agents_log_is_read_back_beside_its_plants_and_compared_with_ekf_pid(tmp_path):
    import argparse
    import json

    none = _record("williams2002", "none", [0.002, 0.002], [0.002, 0.002], seed=7)
    radius = _record("williams2002", "wheel_radius", [0.010, 0.006], [0.004, 0.004], seed=27)
    lines = [_agents(none, [0.001, 0.001], [0.001, 0.001]), _agents(radius, [0.006, 0.002], [0.002, 0.002]),
             {**_agents(radius, [1.0, 1.0], [1.0, 1.0]), "steps": 5}]  # another budget: not this study's
    (tmp_path / "sim_to_real_agents.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    args = argparse.Namespace(out=tmp_path, resume=False, report_only=True, agents_only=False, episodes=2,
                              agent_steps=s2r.AGENT_STEPS)
    done = s2r.agents_phase(args, [none, radius], backend=None)  # report only: nothing runs
    assert [r["kind"] for r in done] == ["none", "wheel_radius"]
    assert done[1]["gap_effect"] == "wheel_radius" and done[1]["models"]["nominal"]["plant"]["rmse"] == [0.006, 0.002]
    rows = s2r.figures(done)
    assert rows[1]["cost"] == pytest.approx(0.004 / 0.001 - 1)
    assert rows[1]["won_back"] == pytest.approx((0.004 - 0.002) / (0.004 - 0.001))
    text = "\n".join(s2r.agent_section(done, rows, s2r.pooled(done, rows), [none, radius], s2r.AGENT_STEPS))
    # agent ÷ ekf-pid on the same model and plant: nominal 0.004 ÷ 0.008 = 0.50, gap 0.002 ÷ 0.004 = 0.50
    assert "| williams2002 | wheel_radius | 0.50 [" in text and "1.5 min |" in text
    assert "1,000,000 steps" in text
