"""Gymnasium environments; importing :mod:`omni_gym` registers them.

* ``OmniPathFollow-Williams-v0``: williams2002 (3 wheels) on carpet, roller-gap friction, no lift-off,
  random-waypoint paths, 20 s.
* ``OmniPathFollow-Williams-v1``: as v0, but every waypoint's heading change is a turn in place before
  the translation (``ref_turn="before"``): references the robot's friction can follow (docs/agents.md).
* ``OmniPathFollow-Phunopas-v0``: phunopas2018 (4 wheels) on carpet, roller-gap friction, random lift-off,
  random-waypoint paths, 20 s.
* ``OmniGoToPose-v0``: phunopas2018, reach a random pose along a quintic while wheels slip and lift off
  (Phunopas & Inoue 2018), 8 s.

Every id takes ``model=`` (a model JSON file path or dict, as ``omni-gym model show --json`` prints it):
the model then replaces the id's robot, surface and friction (``docs/environments.md``).
"""

from __future__ import annotations

import gymnasium as gym

ENTRY = "omni_gym.envs.omni_env:OmniPathEnv"
VECTOR_ENTRY = "omni_gym.envs.vector:OmniPathVectorEnv"
LIFT_OFF = {"lift_rate": 0.5, "recover_rate": 5.0}

ENV_IDS = {
    "OmniPathFollow-Williams-v0": ({"robot": "williams2002", "surface": "carpet", "friction": "roller_gap",
                                    "episode_seconds": 20.0}, 2000),
    "OmniPathFollow-Williams-v1": ({"robot": "williams2002", "surface": "carpet", "friction": "roller_gap",
                                    "episode_seconds": 20.0, "ref_turn": "before"}, 2000),
    "OmniPathFollow-Phunopas-v0": ({"robot": "phunopas2018", "surface": "carpet", "friction": "roller_gap",
                                    "episode_seconds": 20.0, **LIFT_OFF}, 2000),
    "OmniGoToPose-v0": ({"robot": "phunopas2018", "surface": "carpet", "friction": "roller_gap", "task": "goto",
                         "trajectory": "goto", "episode_seconds": 8.0, **LIFT_OFF}, 800),
}


def register_envs() -> None:
    for env_id, (kwargs, steps) in ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=ENTRY, vector_entry_point=VECTOR_ENTRY, max_episode_steps=steps,
                         kwargs=dict(kwargs))
