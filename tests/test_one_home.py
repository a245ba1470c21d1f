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
