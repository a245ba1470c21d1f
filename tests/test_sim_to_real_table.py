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
