"""The plant protocol (omni_gym/physics/plant.py): the environment driving a plant instead of its own world.

A plant equal to the environment's model must give the environment's own figures bit for bit (the harness adds
nothing: same references, sensors, scoring); the second generator in closed loop, written apart from the world,
must agree with it to within what two integrators of the same equations differ by, and a hidden effect in it
must change the figures, deterministically.
"""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from agents.loaders import find_loader
from agents.rollout import run_episode
from omni_gym.analysis.closed_loop import SecondGeneratorPlant
from omni_gym.analysis.event_integrator import build_plant
from omni_gym.cli import main
from omni_gym.physics.friction import SURFACES
from omni_gym.physics.model import SimModel
from omni_gym.physics.plant import Plant, PlantState, SensorReading, SimulatorPlant
from omni_gym.physics.robot import robot_preset

SECONDS = 3.0  # s: long enough for lift-offs (0.5 /s) and roller-gap switches, short enough for the test budget


def _model(robot: str = "williams2002", friction: str = "roller_gap", **effects) -> dict:
    return SimModel(robot=robot_preset(robot), surface=SURFACES["carpet"], friction=friction,
                    effects=effects).to_json()


def _episode(env_id: str, env_kwargs: dict, plant=None, seed: int = 10000, policy: str = "ekf-pid"):
    env, pol = find_loader(policy).load(policy, env_id, dict(env_kwargs, episode_seconds=SECONDS), None)
    if plant is not None:
        core = env.unwrapped.core
        core.attach_plant(plant(core))
    episode = run_episode(env, pol, seed, record=True)
    env.close()
    return episode


@pytest.mark.parametrize("env_id, env_kwargs", [
    ("OmniPathFollow-Phunopas-v0", {}),  # lift-off at 0.5 /s, roller-gap switching, four wheels
    ("OmniPathFollow-Custom-v0", {"model": _model(com_offset={"com": [0.01, -0.005]},
                                                  wheel_liftoff={"lift_rate": 0.5, "recover_rate": 5.0})}),
    ("OmniPathFollow-Mecanum-v0", {}),
])
def test_simulator_plant_reproduces_the_environment_bit_for_bit(env_id, env_kwargs):
    own = _episode(env_id, env_kwargs)
    through_plant = _episode(env_id, env_kwargs, plant=lambda core: core.simulator_plant())
    assert through_plant.metrics() == own.metrics()
    assert np.array_equal(through_plant.pose, own.pose)  # every step's true pose, exactly
    assert np.array_equal(through_plant.contact, own.contact)


def test_second_generator_plant_agrees_with_the_world_and_a_hidden_effect_changes_it():
    model = _model()
    kwargs = {"model": model}
    world = _episode("OmniPathFollow-Custom-v0", kwargs)
    same = _episode("OmniPathFollow-Custom-v0", kwargs, plant=lambda core: SecondGeneratorPlant(core.base_model))
    # Two integrators of one model in closed loop: the world's semi-implicit 0.5 ms substeps against LSODA with
    # events. Their open-loop difference is below 1 mm over such runs (tests/test_second_generator.py); feedback
    # keeps it from growing, so the tracked poses stay within 2 mm, well below the 10 mm a hidden 2 cm centre of
    # mass offset causes below.
    assert np.max(np.hypot(*(same.pose[:, :2] - world.pose[:, :2]).T)) < 2e-3
    hidden = {"com_offset": {"com": [0.02, 0.0]}}
    offset = _episode("OmniPathFollow-Custom-v0", kwargs, plant=lambda core: SecondGeneratorPlant(core.base_model,
                                                                                                    hidden))
    again = _episode("OmniPathFollow-Custom-v0", kwargs, plant=lambda core: SecondGeneratorPlant(core.base_model,
                                                                                                   hidden))
    assert offset.metrics() == again.metrics() and np.array_equal(offset.pose, again.pose)  # deterministic
    assert np.max(np.hypot(*(offset.pose[:, :2] - world.pose[:, :2]).T)) > 1e-3
    assert offset.tracking_rmse != world.tracking_rmse


def test_second_generator_plant_lift_off_follows_its_seed():
    model = SimModel.from_json(_model("phunopas2018", wheel_liftoff={"lift_rate": 2.0, "recover_rate": 5.0}))
    plant = SecondGeneratorPlant(model)
    assert isinstance(plant, Plant)

    def contacts(seed):
        plant.reset(np.zeros(3), seed)
        return np.array([plant.step(np.full(4, 3.0), 0.01).contact for _ in range(300)])

    a, b, c = contacts(1), contacts(1), contacts(2)
    assert np.array_equal(a, b)
    assert not a.all()  # at 2 /s some wheel lifts within 3 s (probability 1 − e^−6)
    assert not np.array_equal(a, c)


def test_slope_pulls_downhill_and_unloads_the_wheels():
    model = SimModel.from_json(_model())
    alpha, beta = 0.1, 0.7
    p = build_plant(model, {"slope": {"angle": alpha, "direction": beta}})
    g = model.gravity
    assert p.slope == pytest.approx((g * math.sin(alpha) * math.cos(beta), g * math.sin(alpha) * math.sin(beta)))
    assert p.loads(np.zeros(3, dtype=bool)).sum() == pytest.approx(model.robot.mass * g * math.cos(alpha))
    plant = SecondGeneratorPlant(model, {"slope": {"angle": alpha, "direction": beta}})
    plant.reset(np.zeros(3), 0)
    for _ in range(100):
        st = plant.step(np.zeros(3), 0.01)
    # Wheels held still: the rollers' friction holds part of the pull; what slides goes downhill.
    assert st.pose[0] * math.cos(beta) + st.pose[1] * math.sin(beta) > 0


class _ScriptedRobot:
    """A 'hardware' plant: the simulator underneath, reporting its own sensor readings (noise-free here) and the
    true pose for scoring, as a robot driver with motion capture would."""

    def __init__(self, sim: SimulatorPlant, fix_offset: float = 0.0) -> None:
        self.sim, self.n_wheels, self.fix_offset = sim, sim.n_wheels, fix_offset

    def _reading(self, st: PlantState) -> PlantState:
        fix = st.pose + np.array([self.fix_offset, 0.0, 0.0])
        reading = SensorReading(wheel_angles=st.wheel_angles, gyro=float(st.velocity[2]), compass=float(st.pose[2]),
                                accel=np.zeros(2), fix=fix)
        return PlantState(st.pose, st.velocity, st.wheel_angles, st.contact, reading)

    def reset(self, pose, seed):
        return self._reading(self.sim.reset(pose, seed))

    def step(self, wheel_speeds, duration):
        return self._reading(self.sim.step(wheel_speeds, duration))


def test_a_robot_with_its_own_sensors_is_driven_by_its_readings():
    kwargs = {"model": _model(friction="initial")}
    exact = _episode("OmniPathFollow-Custom-v0", kwargs, plant=lambda c: _ScriptedRobot(c.simulator_plant()))
    assert exact.tracking_rmse < 0.01  # noise-free sensors on a floor without roller gaps: a few mm at most
    # A tracker 5 cm off along x: the controller follows the tracker, so the true pose ends up about 5 cm away.
    biased = _episode("OmniPathFollow-Custom-v0", kwargs,
                      plant=lambda c: _ScriptedRobot(c.simulator_plant(), fix_offset=0.05))
    assert biased.final_position_error > 0.03


def test_attach_plant_refuses_what_cannot_drive_the_robot():
    env = gym.make("OmniPathFollow-Phunopas-v0")
    core = env.unwrapped.core
    three = SimulatorPlant(SimModel.from_json(_model()))
    with pytest.raises(ValueError, match="3 wheels, the environment's robot 4"):
        core.attach_plant(three)
    with pytest.raises(ValueError, match="must have n_wheels, reset"):
        core.attach_plant(object())

    class Broken:
        n_wheels = 4

        def reset(self, pose, seed):
            return PlantState(np.zeros(2), np.zeros(3), np.zeros(4))

        def step(self, wheel_speeds, duration):
            raise AssertionError("not reached")

    core.attach_plant(Broken())
    with pytest.raises(ValueError, match=r"plant.reset: pose must have shape \(3,\)"):
        env.reset(seed=0)
    vec = gym.make_vec("OmniPathFollow-Phunopas-v0", num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="a plant drives one robot"):
        vec.unwrapped.core.attach_plant(SimulatorPlant(SimModel.from_json(_model("phunopas2018"))))


def test_evaluate_on_a_plant_from_the_command_line(tmp_path, capsys):
    truth = tmp_path / "truth.json"
    truth.write_text(json.dumps(_model(com_offset={"com": [0.02, 0.0]})))
    nominal = tmp_path / "nominal.json"
    nominal.write_text(json.dumps(_model()))
    args = ["evaluate", "--policy", "ekf-pid", "--env", "OmniPathFollow-Custom-v0", "--episodes", "1", "--json",
            "--env-kwargs", json.dumps({"model": str(nominal), "episode_seconds": 1.0})]
    assert main(args) == 0
    own = json.loads(capsys.readouterr().out)
    assert main(args + ["--plant", "simulator"]) == 0
    sim = json.loads(capsys.readouterr().out)
    assert sim["plant"] == {"kind": "simulator", "model": None, "extra": None}
    assert sim["per_episode"] == own["per_episode"]
    assert main(args + ["--plant", "second-generator", "--plant-model", str(truth),
                        "--plant-extra", '{"drag": 1.0}']) == 0
    plant = json.loads(capsys.readouterr().out)
    assert plant["plant"] == {"kind": "second-generator", "model": "truth.json", "extra": {"drag": 1.0}}
    assert plant["per_episode"]["tracking_rmse"] != own["per_episode"]["tracking_rmse"]


@pytest.mark.parametrize("extra_args, message", [
    (["--plant-model", "x.json"], "--plant-model needs --plant"),
    (["--plant", "simulator", "--plant-extra", '{"drag": 1}'], "only the second-generator plant"),
    (["--plant", "second-generator", "--plant-extra", "[1, 2]"], "expected a JSON object"),
    (["--plant", "second-generator", "--plant-extra", '{"wind": 1}'], "unknown effect 'wind'"),
    (["--plant", "second-generator", "--plant-extra", '{"slope": {"angle": 0.5, "direction": 0}}'],
     r"outside \[0.0, 0.2\]"),
])
def test_plant_options_refused_in_one_line(extra_args, message, capsys, tmp_path):
    nominal = tmp_path / "nominal.json"
    nominal.write_text(json.dumps(_model()))
    code = main(["evaluate", "--policy", "ekf-pid", "--env", "OmniPathFollow-Custom-v0", "--episodes", "1",
                 "--env-kwargs", json.dumps({"model": str(nominal)}), *extra_args])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert __import__("re").search(message, err), err
