"""Each concept is declared once and read from there: ids, observation modes, the custom id."""

from __future__ import annotations

import pytest

import omni_gym.envs as envs
from omni_gym.envs import config, docgen


def test_ids_observation_modes_and_the_custom_id_have_one_home():
    assert config.CUSTOM_ID is envs.CUSTOM_ID
    assert docgen.OBS_MODES is config.OBS_MODES
    assert envs.all_ids() == (*envs.ENV_IDS, envs.CUSTOM_ID)
    assert not set(envs.RENAMED) & set(envs.all_ids())


def test_unknown_id_message_lists_every_id_including_the_custom_one():
    from agents.rollout import make_env

    with pytest.raises(ValueError, match="unknown environment id 'NoSuchEnv-v0'") as err:
        make_env("NoSuchEnv-v0")
    assert all(i in str(err.value) for i in envs.all_ids())


def test_the_optiodom_importer_takes_its_robots_from_the_presets():
    """Both OptiOdom robot types are physics presets; the importer's nominal wheels are theirs (the
    imported JSON was checked byte-identical to the importer's own omni3 construction when it moved)."""
    from omni_gym.discrepancy.data.importers import optiodom
    from omni_gym.physics.robot import PRESETS, optiodom_omni3

    robot = optiodom_omni3(0.2, 0.1)
    assert optiodom.wheel_layout(0.2) == [{"position": list(w.position), "drive": list(w.drive)} for w in robot.wheels]
    # The README's drive table, exact zeros included, and clockwise rotation for equal positive speeds.
    drives = [c for w in PRESETS["optiodom_omni3"]().wheels for c in w.drive]
    assert drives == pytest.approx([-0.8660254, -0.5, 0.8660254, -0.5, 0.0, 1.0], abs=1e-7)
    assert PRESETS["optiodom_omni3"]().wheels[2].position[1] == 0.0
    assert optiodom.default_mass("omni3") == robot.mass and optiodom.default_mass("omni4") == PRESETS[
        "optiodom_omni4"]().mass


def test_a_near_miss_robot_name_gets_a_suggestion():
    from omni_gym.physics.robot import robot_preset

    with pytest.raises(ValueError, match="did you mean optiodom_omni4[?]"):
        robot_preset("optiodom-omni4")
    with pytest.raises(ValueError) as err:
        robot_preset("hexapod")
    assert "did you mean" not in str(err.value)


def test_the_environments_use_only_worlds_public_members():
    import re
    from pathlib import Path

    root = Path(envs.__file__).parent
    private = [f"{p.name}:{n}" for p in root.glob("*.py") for n, line in enumerate(p.read_text().splitlines(), 1)
               if re.search(r"\bworld\._[a-z]", line)]
    assert private == []


def test_cfg_shows_the_models_robot_floor_and_friction_not_the_ids_ignored_ones():
    import gymnasium as gym

    import omni_gym  # noqa: F401
    from omni_gym.physics.model import load_model

    model = load_model("optiodom_omni4", "grip", "initial")
    cfg = gym.make("OmniPathFollow-Phunopas-v0", model=model.to_json()).unwrapped.cfg
    assert (cfg.robot, cfg.surface, cfg.friction) == ("optiodom_omni4", "grip", "initial")
    assert cfg.base_model().surface.name == "grip"


def test_the_package_docstring_describes_exactly_the_registered_ids():
    import re

    described = re.findall(r"^\* ``(Omni[^`]+)``", envs.__doc__, re.M)
    assert described == list(envs.all_ids())


def test_world_body_states_is_the_public_read_of_what_pose_and_velocity_convert():
    import numpy as np

    from omni_gym.physics.model import load_model
    from omni_gym.physics.world import World

    model = load_model("phunopas2018")
    world = World(model, n_robots=2)
    world.reset(np.array([[0.1, -0.2, 0.3], [0.0, 0.0, -1.0]]))
    world.set_commands(np.tile(model.robot.wheel_matrix() @ [0.2, 0.1, 0.5], (2, 1)))
    world.step(0.1)
    states = world.body_states()
    assert states.shape == (2, 6)
    # The centre of mass is the geometric centre here: pose is the state less each arena's origin.
    np.testing.assert_array_equal(world.pose[:, 0:2], states[:, 0:2] - world.origins)
    np.testing.assert_array_equal(world.velocity[:, 2], states[:, 5])
