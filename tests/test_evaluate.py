"""``omni-gym evaluate``: episode return, progress when piped, the default seed, path messages and the paired
comparison of two policies (``--against``)."""

import json

import numpy as np
import pytest

from agents.evaluate import DEFAULT_SEED, compare, evaluate, paired_bootstrap_ratio, progress_lines
from agents.policies import make_policy
from agents.rollout import make_env, run_episode
from agents.wrappers import wrap_env
from omni_gym.cli import build_parser, main

ENV = "OmniPathFollow-Phunopas-v0"
SHORT = {"episode_seconds": 1.0}


def test_episode_return_is_the_sum_of_the_environments_reward():
    """Summed by hand from env.step's rewards; under the residual wrapper (squared reward) it stays the
    environment's: the zero residual drives exactly the ekf-pid episode, so both returns are equal."""
    env = make_env(ENV, SHORT)
    policy = make_policy("ekf-pid", env)
    obs, _ = env.reset(seed=3)
    policy.reset(obs)
    total = 0.0
    while True:
        obs, r, terminated, truncated, _ = env.step(policy.act(obs))
        total += r
        if terminated or truncated:
            break
    plain = run_episode(env, make_policy("ekf-pid", env), 3)
    assert plain.episode_return == total  # the same floats summed in the same order

    class Zero:
        def reset(self, obs):
            pass

        def act(self, obs):
            return np.zeros(3, dtype=np.float32)

    wrapped = wrap_env(make_env(ENV, SHORT), "residual-ekf-pid", reward="squared")
    assert run_episode(wrapped, Zero(), 3).episode_return == total  # not the wrapper's −(e/0.1 m)² sum
    result = evaluate("ekf-pid", ENV, 2, 3, SHORT, progress=False)
    assert result["per_episode"]["episode_return"][0] == total
    assert result["episode_return"]["mean"] == pytest.approx(np.mean(result["per_episode"]["episode_return"]))


def test_progress_lines_when_stderr_is_not_a_terminal(capsys, monkeypatch):
    ticks = iter([0.0, 4.0, 11.0, 12.0, 30.0, 31.0])  # start, then after each of 5 items
    items = list(progress_lines(range(5), 5, "p on E", every_s=10.0, clock=lambda: next(ticks)))
    assert items == [0, 1, 2, 3, 4]
    lines = capsys.readouterr().err.splitlines()
    # 11 s after item 2 (≥ 10 s since start), 30 s after item 4 (≥ 10 s since 11 s); none after the last item
    assert lines == ["p on E: 2/5 episodes, 11 s, about 16 s left", "p on E: 4/5 episodes, 30 s, about 8 s left"]

    import agents.evaluate as ev

    monkeypatch.setattr(ev, "PROGRESS_EVERY_S", 0.0)  # a line after every episode but the last
    assert main(["evaluate", "--policy", "open-loop", "--env", ENV, "--episodes", "3", "--env-kwargs",
                 json.dumps(SHORT), "--json"]) == 0  # under pytest, stderr is not a terminal
    captured = capsys.readouterr()
    assert [line.split(",")[0] for line in captured.err.splitlines()] == [
        f"open-loop on {ENV}: 1/3 episodes", f"open-loop on {ENV}: 2/3 episodes"]
    assert json.loads(captured.out)["episodes"] == 3  # stdout stays one JSON object


def test_evaluate_seed_has_a_documented_default(capsys):
    """Held out: training uses small seeds, validation 5000 and up (agents.train.VALIDATION_SEED)."""
    from agents.train import VALIDATION_SEED

    assert DEFAULT_SEED == 10_000 and DEFAULT_SEED > VALIDATION_SEED + 1000  # validation stays at ≤ 1000 episodes
    ev = build_parser()._subparsers._group_actions[0].choices["evaluate"]
    assert "default 10000" in " ".join(ev.format_help().split())
    assert main(["evaluate", "--policy", "open-loop", "--env", ENV, "--episodes", "2", "--env-kwargs",
                 json.dumps(SHORT), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["seeds"] == [DEFAULT_SEED, DEFAULT_SEED + 1]


@pytest.mark.parametrize("policy, expected", [
    ("runs/nonexistent", "policy 'runs/nonexistent': no such folder or file"),
    ("./model", "policy './model': no such folder or file"),
    ("ekf_pid", "unknown policy 'ekf_pid'; choose one of"),
])
def test_a_mistyped_policy_says_what_is_missing(policy, expected, capsys):
    assert main(["evaluate", "--policy", policy, "--env", ENV, "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0] == f"omni-gym: error: {err[0][len('omni-gym: error: '):]}" and expected in err[0]


def test_paired_comparison_of_two_policies(capsys):
    """--against runs the second policy on the same seeds; the ratio and shares follow from the per-episode
    values, the interval is a paired bootstrap from a seeded Generator (the same on every run)."""
    argv = ["evaluate", "--policy", "ekf-pid", "--against", "open-loop", "--env", ENV, "--episodes", "4",
            "--seed", "20", "--env-kwargs", json.dumps({"episode_seconds": 2.0}), "--json"]
    assert main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    a, b = data, data["against"]
    assert a["policy"] == "ekf-pid" and b["policy"] == "open-loop"
    assert a["per_episode"]["seed"] == b["per_episode"]["seed"] == [20, 21, 22, 23]
    x, y = np.array(a["per_episode"]["tracking_rmse"]), np.array(b["per_episode"]["tracking_rmse"])
    cmp = data["comparison"]
    assert cmp["ratio"] == pytest.approx(x.mean() / y.mean(), rel=1e-12)
    assert cmp["a_better"] == np.mean(x < y) and cmp["a_better"] + cmp["ties"] + cmp["b_better"] == 1.0
    lo, hi = cmp["ci95"]
    # A percentile interval of resampled ratios lies within the per-seed extremes of the ratio of means.
    assert lo <= hi and np.min(x / y) - 1e-12 <= lo and hi <= np.max(x / y) + 1e-12
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["comparison"] == cmp  # seeded: the same interval again
    assert main(argv[:-1]) == 0  # the table
    out = capsys.readouterr().out
    assert "ratio of mean tracking_rmse" in out and "episodes where ekf-pid is better" in out


def test_a_policy_against_itself_ties():
    r = evaluate("odometry-pid", ENV, 3, 7, SHORT, progress=False)
    cmp = compare(r, evaluate("odometry-pid", ENV, 3, 7, SHORT, progress=False))
    assert cmp["ratio"] == 1.0 and cmp["ci95"] == [1.0, 1.0] and cmp["ties"] == 1.0
    with pytest.raises(ValueError, match="same seeds"):
        compare(r, evaluate("odometry-pid", ENV, 3, 8, SHORT, progress=False))


def test_paired_bootstrap_is_paired():
    """Large, shared per-seed spread with a constant 10 % difference: the paired interval is tight around 0.9
    (an unpaired one would be wide)."""
    rng = np.random.default_rng(0)
    den = rng.uniform(0.01, 1.0, 50)
    ci, upper = paired_bootstrap_ratio(0.9 * den, den, np.random.default_rng(1))
    assert ci == pytest.approx([0.9, 0.9], rel=1e-12) and upper == pytest.approx(0.9, rel=1e-12)


def test_against_with_a_mistyped_path_fails_before_evaluating(capsys):
    assert main(["evaluate", "--policy", "ekf-pid", "--against", "runs/x", "--env", ENV, "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["omni-gym: error: --against: policy 'runs/x': no such folder or file (a model directory, an RL "
                   "Zoo folder, an SB3 .zip or an RLlib checkpoint)"]
