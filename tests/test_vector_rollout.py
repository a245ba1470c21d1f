"""Batched evaluation (agents/vector_rollout.py) against run_episode, one single environment per seed.

The vector env reproduces each single env bit for bit (tests/test_vector_autoreset.py), so any difference
comes from the policies. Tolerances:

* open-loop: none. Its batched twists are the single policy's up to numpy's vectorised cos/sin (an ulp
  of float64), which never changed a float32 action in any episode we ran: the metrics are identical.
* ekf-pid, ekf-pid-traction: the batched EKF differs from OmniEKF by ~1e-12 (tests/test_batched_estimation.py);
  a float32 action that rounds the other way moves the robot by < 1e-9 m in one period, and slip lets such
  differences grow along an episode. Measured over full 20 s episodes on both ids: metric differences
  <= 1e-11 m. We allow 1e-8 m (1e-7 m for 5 s here would do; 1e-8 keeps three orders of margin).
* SB3 models: torch multiplies a batch of N observations with another summation blocking than one
  observation (float32, relative ~1e-7 on the action), and under slip the episodes drift apart slowly.
  Measured on agents/models/ppo-residual, 3 s episodes without lift-off: <= 1.1e-8 m (and 5 s with
  lift-off: up to 3e-4 m, hence no lift-off here); we allow 1e-6, two orders above.
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.batched.policies import make_vector_policy
from agents.policies import make_policy
from agents.rollout import make_env, run_episode
from agents.vector_rollout import make_vector_env, run_episodes_vector

PHUNOPAS = "OmniPathFollow-Phunopas-v0"
WILLIAMS = "OmniPathFollow-Williams-v1"
SEEDS = [10_000, 10_001, 10_002]
SHORT = {"episode_seconds": 5.0}
EKF_TOL = 1e-8  # m: module docstring (measured <= 1e-11 over 20 s episodes)
SB3_TOL = 1e-6  # m, and relative on the RMSE: module docstring (measured <= 1.1e-8 over 3 s)


def _pair(env_id: str, name: str, kw: dict, seeds=SEEDS):
    venv = make_vector_env(env_id, len(seeds), kw)
    vector = run_episodes_vector(venv, make_vector_policy(name, venv), seeds)
    env = make_env(env_id, kw)
    policy = make_policy(name, env)
    return vector, [run_episode(env, policy, s) for s in seeds]


@pytest.mark.parametrize("env_id", [PHUNOPAS, WILLIAMS])
def test_open_loop_vector_equals_run_episode_bit_for_bit(env_id):
    vector, single = _pair(env_id, "open-loop", SHORT)
    assert [e.metrics() for e in vector] == [e.metrics() for e in single]


def _close(vector, single, tol: float) -> None:
    for a, b in zip(vector, single, strict=True):
        assert (a.seed, a.steps, a.terminated, a.success) == (b.seed, b.steps, b.terminated, b.success)
        assert a.tracking_rmse == pytest.approx(b.tracking_rmse, rel=tol, abs=tol)
        assert a.final_position_error == pytest.approx(b.final_position_error, abs=tol)
        assert a.final_heading_error == pytest.approx(b.final_heading_error, abs=tol)


@pytest.mark.parametrize("env_id", [PHUNOPAS, WILLIAMS])
@pytest.mark.parametrize("name", ["ekf-pid", "ekf-pid-traction"])
def test_ekf_policies_vector_match_run_episode(env_id, name):
    vector, single = _pair(env_id, name, SHORT)
    _close(vector, single, EKF_TOL)


def test_lost_episodes_end_at_their_own_step():
    """A small lost distance ends open-loop episodes early, at different steps: each robot's first episode counts."""
    kw = {**SHORT, "lost_distance": 0.02, "success_distance": 0.01}  # success below lost
    vector, single = _pair(PHUNOPAS, "open-loop", kw, seeds=[10_000, 10_001, 10_002, 10_003])
    assert [e.metrics() for e in vector] == [e.metrics() for e in single]
    assert any(e.terminated for e in vector) and len({e.steps for e in vector}) >= 2


def test_traction_limiter_acts_in_the_batched_pid():
    """On Williams the limiter clips some twist changes, and every twist sent is inside its set."""
    venv = make_vector_env(WILLIAMS, 2, SHORT)
    policy = make_vector_policy("ekf-pid-traction", venv)
    clipped = []

    def counting(twist, prev, estimate, dt):
        out = policy.traction(twist, prev, estimate, dt)
        clipped.append(int(np.sum(np.any(out != twist, axis=1))))
        return out

    policy.pid.limiter = counting
    obs, _ = venv.reset(seed=SEEDS[:2])
    policy.reset(obs)
    outside = 0
    for _ in range(300):
        before = policy.twist.copy()
        obs = venv.step(policy.act(obs))[0]
        acc = policy.traction.accelerations(policy.twist, before, policy.dt)
        outside += int(np.sum(policy.traction.scale(acc, before) < 1.0 - 1e-9))  # 1e-9: rounding of λ = 1
    assert sum(clipped) > 0
    assert outside == 0


def test_bad_input_is_one_line_value_error():
    venv = make_vector_env(PHUNOPAS, 2, SHORT)
    with pytest.raises(ValueError, match="3 seeds for 2 robots"):
        run_episodes_vector(venv, make_vector_policy("open-loop", venv), SEEDS)
    with pytest.raises(ValueError, match="positive integer"):
        make_vector_env(PHUNOPAS, 0)
    with pytest.raises(ValueError, match="unknown environment id"):
        make_vector_env("Nope-v0", 2)


def test_sb3_model_vector_matches_single():
    pytest.importorskip("stable_baselines3")
    from agents.sb3_policy import build, build_vector

    kw = {"episode_seconds": 3.0, "lift_rate": 0.0}
    model = "agents/models/ppo-residual"
    venv, vpolicy = build_vector(model, len(SEEDS), PHUNOPAS, kw)
    vector = run_episodes_vector(venv, vpolicy, SEEDS)
    env, policy = build(model, PHUNOPAS, kw)
    single = [run_episode(env, policy, s) for s in SEEDS]
    _close(vector, single, SB3_TOL)
