"""``model=``: a calibrated model (JSON file or dict, effects included) enters every environment.

The central check: a model with fitted effects drives the environment exactly as ``omni-gym simulate``
(:func:`omni_gym.physics.replay.simulate_commands`) replays it. Both build the same world from the same model
and run the same physics substeps on the same wheel commands, so the poses agree bit for bit; any
tolerance would hide a model that did not reach the environment whole.
"""

from __future__ import annotations

import json
import math
import pickle
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.cli import main
from omni_gym.physics.layout import SP_CX, SP_CY, WP_MUW, WP_R
from omni_gym.physics.model import load_model
from omni_gym.physics.replay import simulate_commands

WILLIAMS = "OmniPathFollow-WilliamsPaper-v0"
PHUNOPAS = "OmniPathFollow-Phunopas-v0"
GOTO = "OmniGoToPose-v0"
# Wheel commands as actions in [-1, 1] (wheels mode), held for a third of the run each: a turn, a
# translation, a spin, so that radius and centre-of-mass errors all show in the pose.
ACTION_PHASES = np.array([[0.30, -0.10, 0.25, 0.05], [0.40, 0.40, -0.40, -0.40], [-0.2, -0.2, -0.2, -0.2]],
                         dtype=np.float32)


def fitted_model():
    """phunopas2018 on carpet with effects a gap run could fit: per-wheel radius scale and a CoM offset."""
    return (load_model("phunopas2018")
            .with_effect("wheel_radius", {"scale": [1.04, 0.97, 1.0, 1.02]})
            .with_effect("com_offset", {"com": [0.012, -0.008]}))


def write_model(path: Path, model) -> Path:
    path.write_text(json.dumps(model.to_json(), indent=2))
    return path


def env_poses(model, steps: int) -> tuple[np.ndarray, np.ndarray, object]:
    """Drive OmniGoToPose-v0 with ``model`` by the fixed wheel actions; (poses (steps, 3), commands [rad/s], env)."""
    # lift_rate=0: the id's random lift-off would draw contacts simulate does not have (the model has
    # no wheel_liftoff effect). lost_distance at its bound: open-loop commands leave the reference.
    env = gym.make(GOTO, model=model, action_mode="wheels", lift_rate=0.0, lost_distance=1e4,
                   episode_seconds=steps / 100.0)
    _, info = env.reset(seed=3)
    # The go-to-pose reference starts at (0, 0, 0), where simulate starts.
    assert np.array_equal(info["pose"], [0.0, 0.0, 0.0])
    scale = env.unwrapped.core.wheel_scale
    poses, commands = [], []
    for k in range(steps):
        action = ACTION_PHASES[3 * k // steps]
        commands.append(action.astype(np.float64) * scale)  # the env's own action → rad/s product
        _, _, terminated, truncated, info = env.step(action)
        assert not terminated
        poses.append(info["pose"])
    assert truncated
    return np.array(poses), np.array(commands), env


def test_fitted_model_in_env_replays_as_simulate(tmp_path):
    path = write_model(tmp_path / "model.json", fitted_model())
    steps = 150
    poses, commands, env = env_poses(str(path), steps)
    cfg = env.unwrapped.cfg
    # What `omni-gym simulate --model model.json` runs: the file loaded by load_model, one command row per
    # control period (the last row only ends the run), the env's physics step.
    times = np.arange(steps + 1) / cfg.control_hz
    rows = np.vstack([commands, commands[-1:]])
    replay = simulate_commands(load_model(str(path)), times, rows, dt=cfg.physics_dt)
    assert np.array_equal(poses, replay[1:, 0:3])
    # The robot really moved (a turn and a translation), so equality is not two robots standing still.
    assert math.hypot(*poses[-1, 0:2]) > 0.05 and abs(poses[-1, 2]) > 0.05

    # The effects matter: the nominal model strays from the fitted one by up to 19 mm and 0.72 rad (measured),
    # while the env and simulate agree exactly.
    nominal, _, _ = env_poses(str(write_model(tmp_path / "nominal.json", load_model("phunopas2018"))), steps)
    assert np.max(np.hypot(*(nominal[:, 0:2] - poses[:, 0:2]).T)) > 0.01
    assert np.max(np.abs(nominal[:, 2] - poses[:, 2])) > 0.3
    # The effects reached the physics, not only the bookkeeping.
    # (rtol 1e-15: one rounding of the product r·scale.)
    core = env.unwrapped.core
    np.testing.assert_allclose(core.world.wp[0, :, WP_R] / core.robot.wheel_radius, [1.04, 0.97, 1.0, 1.02],
                               rtol=1e-15)
    assert np.array_equal(core.world.sp[0, [SP_CX, SP_CY]], [0.012, -0.008])


def rollout(env, seed: int, steps: int) -> list[tuple]:
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(0)
    out = [(obs, info["pose"])]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        out.append((obs, reward, terminated, truncated, info["pose"]))
        if terminated or truncated:
            break
    return out


def assert_same(ra: list[tuple], rb: list[tuple]) -> None:
    assert len(ra) == len(rb)
    for k, (a, b) in enumerate(zip(ra, rb, strict=True)):
        for x, y in zip(a, b, strict=True):
            assert np.array_equal(x, y), f"record {k}"


def test_file_path_dict_and_pathlike_give_the_same_episode(tmp_path):
    model = fitted_model()
    path = write_model(tmp_path / "model.json", model)
    runs = [rollout(gym.make(PHUNOPAS, model=m, obs_mode="sensors"), seed=5, steps=60)
            for m in (str(path), path, json.loads(path.read_text()), model)]
    for other in runs[1:]:
        assert_same(runs[0], other)
    # ... and not the nominal episode.
    nominal = rollout(gym.make(PHUNOPAS, obs_mode="sensors"), seed=5, steps=60)
    assert not np.array_equal(nominal[-1][-1], runs[0][-1][-1])


def three_wheel_model():
    """williams2002 (3 wheels) with a radius effect, on paper: used on the 4-wheel Phunopas id."""
    return load_model("williams2002", surface="paper").with_effect("wheel_radius", {"scale": [1.05, 1.0, 0.96]})


def test_model_defines_robot_surface_friction_and_sizes(tmp_path):
    model = three_wheel_model()
    env = gym.make(PHUNOPAS, model=str(write_model(tmp_path / "m.json", model)), action_mode="wheels",
                   obs_mode="sensors")
    core = env.unwrapped.core
    # The id passes robot='phunopas2018', surface='carpet': the model overrides both.
    assert core.n_wheels == 3 and core.robot.name == "williams2002"
    assert env.action_space.shape == (3,)
    assert env.observation_space.shape == (3 + 5 + 5 + 7 + 12 + 3,)
    assert np.all(core.world.wp[0, :, WP_MUW] == model.surface.mu_drive)
    assert model.surface.mu_drive != load_model("phunopas2018").surface.mu_drive


def test_vector_env_with_model_matches_single_envs(tmp_path):
    # Every per-episode draw is exercised too: the model's lift-off process and randomisation on top of it.
    model = three_wheel_model().with_effect("wheel_liftoff", {"lift_rate": 5.0, "recover_rate": 10.0})
    path = str(write_model(tmp_path / "m.json", model))
    n, kwargs = 3, {"model": path, "action_mode": "wheels", "episode_seconds": 0.2,
                    "randomize_friction": (0.7, 1.3), "randomize_mass": (0.8, 1.2)}
    venv = gym.make_vec(PHUNOPAS, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(PHUNOPAS, **kwargs) for _ in range(n)]
    assert venv.single_action_space.shape == (3,)
    vobs, _ = venv.reset(seed=20)
    assert np.array_equal(vobs, np.stack([env.reset(seed=20 + i)[0] for i, env in enumerate(singles)]))
    rng = np.random.default_rng(2)
    pending = [False] * n
    for k in range(30):  # 20-step episodes: every sub-environment autoresets once
        actions = rng.uniform(-1, 1, size=(n, 3)).astype(np.float32)
        vobs, vrew, vterm, vtrunc, _ = venv.step(actions)
        for i, env in enumerate(singles):
            if pending[i]:  # NEXT_STEP autoreset
                expected = (env.reset()[0], 0.0, False, False)
            else:
                expected = env.step(actions[i])[:4]
            pending[i] = expected[2] or expected[3]
            assert np.array_equal(vobs[i], expected[0]), f"step {k}, env {i}"
            assert (vrew[i], vterm[i], vtrunc[i]) == expected[1:], f"step {k}, env {i}"


def test_wheel_liftoff_effect_sets_contact_rates():
    model = load_model("phunopas2018").with_effect("wheel_liftoff", {"lift_rate": 2.5, "recover_rate": 7.0})
    env = gym.make(PHUNOPAS, model=model.to_json())  # the id passes lift_rate=0.5, recover_rate=5
    env.reset(seed=0)
    proc = env.unwrapped.core.world.contact_processes[0]
    assert (proc.lift_rate, proc.recover_rate) == (2.5, 7.0)
    # Randomisation still applies on top: the drawn lift rate replaces the model's, its recovery stays.
    env = gym.make(PHUNOPAS, model=model.to_json(), randomize_lift_rate=(10.0, 20.0))
    env.reset(seed=0)
    proc = env.unwrapped.core.world.contact_processes[0]
    assert 10.0 <= proc.lift_rate <= 20.0 and proc.recover_rate == 7.0
    # Without the effect, the keywords set the process (the Phunopas id's 0.5/s).
    env = gym.make(PHUNOPAS, model=load_model("phunopas2018").to_json())
    env.reset(seed=0)
    assert env.unwrapped.core.world.contact_processes[0].lift_rate == 0.5


def test_randomised_friction_scales_the_fitted_gap_coefficient():
    model = load_model("phunopas2018").with_effect("roller_gap", {"mu_gap": 0.2, "roller_fraction": 0.85,
                                                                  "phase": [0.0, 0.1, 0.2, 0.3]})
    env = gym.make(PHUNOPAS, model=model.to_json(), randomize_friction=(0.5, 0.6))
    env.reset(seed=1)
    drawn = env.unwrapped.core.models[0]
    s = drawn.surface.mu_drive / model.surface.mu_drive
    assert 0.5 <= s <= 0.6
    # One scale on every coefficient, the fitted gap coefficient included (1e-12: products round differently).
    assert drawn.effects["roller_gap"]["mu_gap"] / 0.2 == pytest.approx(s, rel=1e-12)


def test_pickled_env_with_model_continues_identically(tmp_path):
    env = gym.make(PHUNOPAS, model=str(write_model(tmp_path / "m.json", fitted_model())))
    env.reset(seed=4)
    for _ in range(5):
        env.step(np.array([0.2, 0.1, 0.0], dtype=np.float32))
    copy = pickle.loads(pickle.dumps(env))
    (tmp_path / "m.json").unlink()  # the config holds the model, not the file
    for _ in range(5):
        a, b = env.step(np.array([0.1, 0.3, -0.2])), copy.step(np.array([0.1, 0.3, -0.2]))
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]


def bad_models(tmp_path: Path) -> list[tuple[object, str]]:
    good = load_model("phunopas2018").to_json()
    (tmp_path / "bad.json").write_text("{ not json")
    (tmp_path / "binary.json").write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff\xfe")
    (tmp_path / "nomass.json").write_text(json.dumps({k: v for k, v in good.items() if k != "mass"}))
    (tmp_path / "effect.json").write_text(json.dumps({**good, "effects": {"wheel_radius": {"scale": [1.0]}}}))
    (tmp_path / "list.json").write_text("[1, 2]")
    (tmp_path / "twowheels.json").write_text(json.dumps({**good, "wheels": good["wheels"][:2]}))
    fast_lift = {**good, "effects": {"wheel_liftoff": {"lift_rate": 1e6, "recover_rate": 5.0}}}
    return [
        (str(tmp_path / "missing.json"), "missing.json"),
        (str(tmp_path / "bad.json"), "not valid JSON"),
        (str(tmp_path / "binary.json"), "binary.json"),
        (str(tmp_path / "nomass.json"), "'mass'"),
        (str(tmp_path / "effect.json"), "scale"),
        (str(tmp_path / "list.json"), "JSON object"),
        (str(tmp_path / "twowheels.json"), "wheels"),
        (str(tmp_path), "directory"),
        ({k: v for k, v in good.items() if k != "surface"}, "'surface'"),
        (fast_lift, "lift_rate"),
        ({**good, "effects": {"wheel_liftoff": {"lift_rate": 5000.0, "recover_rate": 5.0}}}, "lift_rate"),
        ({**good, "effects": {"wheel_liftoff": {"lift_rate": 1.0, "recover_rate": 5000.0}}}, "recover_rate"),
        (5, "model=5"),
        ("williams2002", "file not found"),
    ]


def test_bad_models_refused_with_one_line_naming_model(tmp_path):
    for value, detail in bad_models(tmp_path):
        with pytest.raises(ValueError) as excinfo:
            gym.make(WILLIAMS, model=value)
        message = str(excinfo.value)
        assert message.startswith("invalid model"), message
        assert detail in message and "\n" not in message, message
    with pytest.raises(ValueError, match=re.escape("invalid model")):
        gym.make_vec(WILLIAMS, num_envs=2, vectorization_mode="vector_entry_point", model=str(tmp_path / "no.json"))


def test_cli_evaluate_takes_a_model_through_env_kwargs(tmp_path, capsys):
    from agents.evaluate import evaluate

    path = str(write_model(tmp_path / "model.json", fitted_model()))
    env_kwargs = {"model": path, "episode_seconds": 2.0}
    argv = ["evaluate", "--policy", "ekf-pid", "--env", GOTO, "--episodes", "1", "--seed", "0", "--json",
            "--env-kwargs", json.dumps(env_kwargs)]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    # The CLI ran the model: it equals a direct evaluation with the model, and differs from the nominal robot.
    assert result["per_episode"] == evaluate("ekf-pid", GOTO, 1, 0, env_kwargs)["per_episode"]
    nominal = evaluate("ekf-pid", GOTO, 1, 0, {"episode_seconds": 2.0})["per_episode"]
    assert nominal != result["per_episode"]
    # A bad model is a one-line CLI error (exit 2), not a traceback.
    assert main([*argv[:-1], json.dumps({"model": str(tmp_path / "none.json")})]) == 2
    err = capsys.readouterr().err
    assert err.startswith("omni-gym: error:") and "none.json" in err and err.count("\n") == 1


def test_scripted_policy_reads_the_model_robot():
    from agents.evaluate import evaluate

    # A 3-wheel model on the 4-wheel id: the EKF + PID baseline takes the wheel layout from the env (a
    # 4-wheel controller would not even fit the 3-wheel action). It tracks: 1.7 mm RMS measured, 2 cm allowed.
    result = evaluate("ekf-pid", PHUNOPAS, 1, 0, {"model": three_wheel_model().to_json(), "episode_seconds": 1.0})
    episode = result["per_episode"]
    assert episode["terminated"] == [False]
    assert episode["tracking_rmse"][0] < 0.02


MECANUM = "OmniPathFollow-Mecanum-v0"


def mecanum_model():
    """optiodom_omni4 (mecanum wheels, initial friction) on paper with a radius and a centre-of-mass effect."""
    return (load_model("optiodom_omni4", surface="paper")
            .with_effect("wheel_radius", {"scale": [1.03, 0.98, 1.0, 1.01]})
            .with_effect("com_offset", {"com": [0.01, -0.005]}))


def test_mecanum_model_file_in_env_replays_as_simulate(tmp_path):
    """A mecanum model file drives the environment exactly as simulate replays it (as the omni model above)."""
    model = mecanum_model()
    assert model.friction == "initial" and model.robot.has_angled_rollers
    path = write_model(tmp_path / "mecanum.json", model)
    steps = 150
    poses, commands, env = env_poses(str(path), steps)
    cfg = env.unwrapped.cfg
    times = np.arange(steps + 1) / cfg.control_hz
    replay = simulate_commands(load_model(str(path)), times, np.vstack([commands, commands[-1:]]), dt=cfg.physics_dt)
    assert np.array_equal(poses, replay[1:, 0:3])
    assert math.hypot(*poses[-1, 0:2]) > 0.05  # it moved
    core = env.unwrapped.core
    np.testing.assert_allclose(core.world.wp[0, :, WP_R] / core.robot.wheel_radius, [1.03, 0.98, 1.0, 1.01],
                               rtol=1e-15)  # one rounding of r·scale


def test_mecanum_id_takes_model_files_of_either_wheel_kind(tmp_path):
    """model= replaces the ids' robot, surface and friction keywords: a mecanum model on the omni Phunopas id
    (which passes friction='roller_gap') and an omni model with roller-gap friction on the Mecanum id (which
    passes 'initial') both run; the Mecanum id's episode with its own model file differs from the nominal one."""
    mec = write_model(tmp_path / "mecanum.json", mecanum_model())
    env = gym.make(PHUNOPAS, model=str(mec))
    assert env.unwrapped.core.robot.has_angled_rollers and env.unwrapped.cfg.base_model().friction == "initial"
    omni = write_model(tmp_path / "omni.json", load_model("williams2002", surface="paper", friction="roller_gap"))
    env = gym.make(MECANUM, model=str(omni), action_mode="wheels")
    assert env.unwrapped.core.n_wheels == 3 and env.action_space.shape == (3,)
    assert env.unwrapped.cfg.base_model().friction == "roller_gap"
    env.reset(seed=0)
    env.step(env.action_space.sample())
    runs = [rollout(gym.make(MECANUM, **kw), seed=5, steps=60) for kw in ({"model": str(mec)}, {"model": mec}, {})]
    assert_same(runs[0], runs[1])  # str and Path name the same file
    assert not np.array_equal(runs[0][-1][-1], runs[2][-1][-1])  # the model file, not the nominal robot
