"""The normalised tracking score (``agents.normalised_score``, ``omni-gym evaluate --score``): formula, anchors
on the policy's own seeds, interval, and the command. (``omni-gym score``, the dataset replay, is test_score.py.)"""

import json
import math

import numpy as np
import pytest

from agents.evaluate import evaluate
from agents.normalised_score import normalised_score, score_episodes, score_results
from omni_gym.cli import main

ENV = "OmniPathFollow-Phunopas-v0"
SHORT = {"episode_seconds": 1.0}


def test_formula_anchors_and_direction():
    assert normalised_score(0.10, 0.10, 0.02) == 0.0  # as bad as open-loop
    assert normalised_score(0.02, 0.10, 0.02) == 100.0  # as good as ekf-pid
    assert normalised_score(0.06, 0.10, 0.02) == pytest.approx(50.0)  # half-way, linear in the RMSE
    assert normalised_score(0.01, 0.10, 0.02) == pytest.approx(112.5)  # better than ekf-pid: above 100
    assert normalised_score(0.14, 0.10, 0.02) == pytest.approx(-50.0)  # worse than open-loop: negative
    assert math.isnan(normalised_score(0.05, 0.03, 0.03))  # equal anchors: no scale


def test_score_of_episodes_uses_means_and_a_paired_interval():
    """The per-seed spread is shared by the three policies (a hard seed is hard for all); the policy is
    exactly 30 % of the way from open-loop to ekf-pid on every seed, so the paired interval is a point."""
    rng = np.random.default_rng(0)
    hard = rng.uniform(0.5, 2.0, 40)
    o, e = 0.1 * hard, 0.02 * hard
    p = o - 0.3 * (o - e)
    s = score_episodes(p, o, e)
    assert s.score == pytest.approx(30.0) and s.ci95 == pytest.approx((30.0, 30.0))
    assert (s.rmse_open, s.rmse_ekfpid, s.episodes) == (pytest.approx(o.mean()), pytest.approx(e.mean()), 40)
    assert not s.degenerate
    noisy = score_episodes(p + rng.normal(0, 0.01, 40), o, e)
    assert noisy.ci95[0] < noisy.score < noisy.ci95[1] and noisy.ci95[1] - noisy.ci95[0] > 1.0
    assert score_episodes([0.05], [0.1], [0.02]).ci95 is None  # one episode: no interval
    assert score_episodes([0.05, 0.05], [0.1, 0.1], [0.099, 0.099]).degenerate  # anchors 1 % apart
    assert score_episodes([0.05, 0.05], [0.012, 0.012], [0.014, 0.014]).degenerate  # ekf-pid worse: inverted
    with pytest.raises(ValueError, match="equal, non-empty"):
        score_episodes([0.1, 0.2], [0.1], [0.1])


def test_anchors_score_0_and_100_on_real_episodes():
    """On the same seeds, open-loop scores exactly 0 and ekf-pid exactly 100 (the definition), and a policy
    run on other seeds than the anchors is refused."""
    o = evaluate("open-loop", ENV, 2, 11, SHORT, progress=False)
    e = evaluate("ekf-pid", ENV, 2, 11, SHORT, progress=False)
    assert score_results(o, o, e).score == 0.0 and score_results(e, o, e).score == pytest.approx(100.0)
    with pytest.raises(ValueError, match="open-loop ran on other seeds"):
        score_results(e, evaluate("open-loop", ENV, 2, 12, SHORT, progress=False), e)


def test_evaluate_score_command(capsys):
    """``--score`` runs the anchors on the policy's seeds and keywords: the JSON score equals the formula
    applied to the three printed RMSE means; with ``--against`` both policies get one."""
    argv = ["evaluate", "--policy", "odometry-pid", "--against", "ekf-pid", "--env", ENV, "--episodes", "2",
            "--seed", "11", "--env-kwargs", json.dumps(SHORT), "--score", "--json"]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    s = out["score"]
    o = evaluate("open-loop", ENV, 2, 11, SHORT, progress=False)["tracking_rmse"]["mean"]
    assert s["rmse_open"] == o and s["rmse_policy"] == out["tracking_rmse"]["mean"]
    assert s["rmse_ekfpid"] == out["against"]["tracking_rmse"]["mean"]  # the --against run is reused
    assert s["score"] == pytest.approx(normalised_score(s["rmse_policy"], o, s["rmse_ekfpid"]))
    assert out["against"]["score"]["score"] == pytest.approx(100.0)
    assert main(argv[:-1]) == 0  # the text form names the anchors
    text = capsys.readouterr().out
    assert "odometry-pid: normalised score" in text and "0 = open-loop" in text and "100 = ekf-pid" in text


def test_benchmark_table_runs_the_mecanum_id_in_its_own_conditions():
    """benchmarks/normalised_score.py: the mecanum id has no roller-gap friction model, so its three conditions
    keep the floors and lift-off rates of the others with ``initial`` friction; the omni ids keep theirs."""
    from benchmark_loader import load_benchmark

    ns = load_benchmark("normalised_score")
    assert ns.MECANUM in ns.ENV_IDS
    for cond in ("no slip", "slip", "slip + lift-off"):
        mec = ns.Cell(ns.MECANUM, "ekf-pid", cond, (1,)).env_kwargs()
        omni = ns.Cell(ENV, "ekf-pid", cond, (1,)).env_kwargs()
        assert mec["friction"] == "initial"
        assert (mec["surface"], mec["lift_rate"]) == (omni["surface"], omni["lift_rate"])
    assert ns.Cell(ENV, "ekf-pid", "slip", (1,)).env_kwargs()["friction"] == "roller_gap"
    assert ns.Cell(ns.MECANUM, "ekf-pid", "slip", (1,), 2.0).env_kwargs()["episode_seconds"] == 2.0


def test_an_interval_that_does_not_hold_its_estimate_is_not_shown():
    """Anchors with equal means (open-loop 10 mm, ekf-pid 9, 9 and 12 mm): no score, and the resamples' percentile
    interval [-200, 200] used to be printed beside "nan". No interval is given then, with the reason; an
    interval that holds its estimate is kept."""
    from agents.normalised_score import NO_INTERVAL, NO_SCORE, score_episodes

    s = score_episodes([0.008] * 3, [0.010] * 3, [0.009, 0.009, 0.012])
    assert s.ci95 is None and s.ci_note == NO_SCORE
    assert "interval not defined" in s.text() and "[" not in s.text().split(" over ")[0]
    ok = score_episodes([0.005, 0.006, 0.004], [0.010, 0.011, 0.009], [0.002, 0.003, 0.002])
    assert ok.ci95 is not None and ok.ci95[0] <= ok.score <= ok.ci95[1] and ok.ci_note is None
    assert NO_INTERVAL != NO_SCORE
