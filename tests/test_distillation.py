"""Teacher → student distillation (``agents.distillation``): the clone, the labels, the fit and the model it writes.

Episodes are short (0.3-1 s) on seeds below 10 000 (the benchmarks' held-out seeds start at 10 000). The
student's quality is a benchmark (``benchmarks/students.py``), not a test; these check the mechanics that
quality rests on: the start is ekf-pid exactly, the teacher labels the states the student visits, the fit
moves only the correction, and the model directory loads as any agent's does.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from agents.batched.policies import make_vector_policy
from agents.distillation import (
    DAggerSpec,
    collect_round,
    distil,
    fit_student,
    make_features_env,
    make_student,
    student_actions,
)
from agents.oracle import MPPIOracle, OracleConfig
from agents.vector_rollout import make_vector_env
from agents.wrappers import pid_twist_columns

PHUNOPAS = "OmniPathFollow-Phunopas-v0"
CARPET = {"surface": "carpet", "friction": "roller_gap", "lift_rate": 0.5, "episode_seconds": 1.0}
SEEDS = [31, 32, 33, 34]

torch.set_num_threads(1)


def _env(kwargs=CARPET):
    env = make_features_env(PHUNOPAS, len(SEEDS), kwargs)
    obs, _ = env.reset(seed=SEEDS)
    return env, obs


def test_the_student_starts_as_ekf_pid_exactly():
    """The clone's action is ekf-pid's on every step of a closed-loop run (float32 rounding of the features)."""
    env, obs = _env()
    raw = make_vector_env(PHUNOPAS, len(SEEDS), CARPET)
    ekf_pid = make_vector_policy("ekf-pid", raw)
    raw_obs, _ = raw.reset(seed=SEEDS)
    ekf_pid.reset(raw_obs)
    student = make_student(env.single_observation_space, env.single_action_space, 16)
    try:
        for _ in range(50):
            a, b = student_actions(student, obs), np.asarray(ekf_pid.act(raw_obs), dtype=np.float32)
            np.testing.assert_allclose(a, b, atol=1e-5)  # the features are float32: 1e-7 relative of ≤ 10
            obs, *_ = env.step(a)
            raw_obs, *_ = raw.step(b)
    finally:
        env.close()
        raw.close()


def test_the_teacher_labels_the_states_the_student_visits():
    """beta 1: the teacher drives and the labels are exactly the actions an oracle of the same seed takes when
    it drives alone; beta 0: the student drives (other states), and the labels are still the teacher's."""
    env, obs = _env()
    alone, obs_alone = _env()
    student = make_student(env.single_observation_space, env.single_action_space, 16)
    try:
        teacher = MPPIOracle(env, OracleConfig(samples=4))
        teacher.reset(obs)
        x, y, _, _ = collect_round(env, obs, teacher, student, 1.0, 12, np.random.default_rng(0),
                                   np.zeros(len(SEEDS), bool))
        solo = MPPIOracle(alone, OracleConfig(samples=4))
        solo.reset(obs_alone)
        acts = []
        for _ in range(12):
            acts.append(solo.act(obs_alone))
            obs_alone, *_ = alone.step(acts[-1])
        np.testing.assert_array_equal(y, np.concatenate(acts))
        assert x.shape == (12 * len(SEEDS), env.single_observation_space.shape[0])
    finally:
        env.close()
        alone.close()

    env, obs = _env()
    try:
        teacher = MPPIOracle(env, OracleConfig(samples=4))
        teacher.reset(obs)
        x0, y0, _, _ = collect_round(env, obs, teacher, student, 0.0, 12, np.random.default_rng(0),
                                     np.zeros(len(SEEDS), bool))
    finally:
        env.close()
    assert not np.array_equal(x0, x)  # the student's own states
    cols = pid_twist_columns(x0.shape[1])
    assert np.abs(y0 - np.clip(x0[:, cols], -1, 1)).max() > 1e-3  # labelled by the teacher, not by ekf-pid


def test_the_fit_moves_the_correction_and_keeps_the_ekf_pid_part():
    """Labels = ekf-pid's twist + a correction that depends on the features: the fit lowers the error below the
    clone's and leaves the affine weights on the features exactly the clone's."""
    env, obs = _env()
    try:
        student = make_student(env.single_observation_space, env.single_action_space, 32)
        rng = np.random.default_rng(0)
        xs = []
        for _ in range(60):
            xs.append(np.array(obs))
            obs, *_ = env.step(student_actions(student, obs))
    finally:
        env.close()
    x = np.concatenate(xs)
    cols = pid_twist_columns(x.shape[1])
    y = np.clip(x[:, cols] + 0.1 * np.tanh(3 * x[:, 3:6]), -1, 1)  # a smooth correction of the estimated twist
    before = float(np.mean((student_actions(student, x) - y) ** 2))
    d = x.shape[1]
    affine = student.action_net.weight[:, :d].detach().clone()
    losses = fit_student(student, x, y, DAggerSpec(epochs=30, batch_size=64), rng)
    after = float(np.mean((student_actions(student, x) - y) ** 2))
    assert after < 0.3 * before and losses[-1] < losses[0]
    assert torch.equal(student.action_net.weight[:, :d], affine)


def test_distil_writes_a_model_that_loads_and_is_reproducible(tmp_path):
    """A tiny run (1 round of 8 steps, 4 validation episodes of 0.3 s) writes a model directory the
    evaluation loader opens; the same seed writes the same weights."""
    from agents.sb3_policy import build_vector

    spec = DAggerSpec(robots=2, rounds=1, round_steps=8, validation_episodes=4, epochs=1,
                      oracle=OracleConfig(samples=2), seed=3)
    metas = [distil(PHUNOPAS, spec, tmp_path / name, progress=False, episode_seconds=0.3) for name in "ab"]
    d = metas[0]["distillation"]
    assert [r["round"] for r in d["rounds"]] == [-1, 0] and d["rounds"][1]["samples"] == 16
    assert d["validation_episodes"] == 4 and d["validation_seeds"] == [5000, 5000]
    assert json.loads((tmp_path / "a" / "meta.json").read_text())["wrapper"] == "ekf-features"
    wa, wb = (torch.load(tmp_path / n / "policy.pt", weights_only=True) for n in "ab")
    assert all(torch.equal(wa[k], wb[k]) for k in wa)
    venv, policy = build_vector(str(tmp_path / "a"), 2, None, {"episode_seconds": 0.3})
    try:
        obs, _ = venv.reset(seed=[41, 42])
        assert policy.act(obs).shape == (2, 3)
    finally:
        venv.close()


@pytest.mark.parametrize("bad, match", [({"rounds": 0}, "rounds"), ({"beta": 1.5}, "beta"),
                                        ({"oracle": OracleConfig(state="ekf")}, "privileged")])
def test_bad_settings_are_refused_in_one_line(bad, match):
    with pytest.raises(ValueError, match=match):
        DAggerSpec(**bad)
