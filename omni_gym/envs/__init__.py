"""Gymnasium environments; importing :mod:`omni_gym` registers them.

* ``OmniPathFollow-WilliamsPaper-v0``: williams2002 (3 wheels) on carpet, roller-gap friction, no lift-off,
  random-waypoint paths, 20 s.
* ``OmniPathFollow-Williams-v1``: as WilliamsPaper-v0, but every waypoint's heading change is a turn in place before
  the translation (``ref_turn="before"``): references the robot's friction can follow (docs/agents.md).
* ``OmniPathFollow-Phunopas-v0``: phunopas2018 (4 wheels) on carpet, roller-gap friction, random lift-off,
  random-waypoint paths, 20 s.
* ``OmniPathFollow-Mecanum-v0``: optiodom_omni4 (4 mecanum wheels, rollers at ±45°) on carpet, ``initial``
  friction (the only model for mecanum wheels), random lift-off as the Phunopas id, random-waypoint paths, 20 s.
  Carpet as every other id, so the robots are compared on one floor; there the rollers' rolling friction
  (μ'_T = 0.6·μ'_W) makes sideways and diagonal moves sluggish (docs/environments.md).
* ``OmniGoToPose-v0``: phunopas2018, reach a random pose along a quintic while wheels slip and lift off
  (Phunopas & Inoue 2018), 8 s.
* ``OmniPathFollow-Custom-v0``: "my robot": robot, surface, friction, effects and lift-off entirely from
  ``model=`` (required); random-waypoint paths, 20 s.

Every id takes ``model=`` (a model JSON file path or dict, as ``omni-gym model show --json`` prints it):
the model then replaces the id's robot, surface and friction (``docs/environments.md``); the preset ids
keep their own lift-off rates, the custom id has none unless the model has a ``wheel_liftoff`` effect.

``OmniPathFollow-Williams-v0`` was the paper's task's first name; it stays registered only to say so
(:data:`RENAMED`): with ``-v1`` registered beside it, Gymnasium told its users to "upgrade" to v1, a
different task.
"""

from __future__ import annotations

import gymnasium as gym

ENTRY = "omni_gym.envs.omni_env:OmniPathEnv"
VECTOR_ENTRY = "omni_gym.envs.vector:OmniPathVectorEnv"
LIFT_OFF = {"lift_rate": 0.5, "recover_rate": 5.0}
# References within the wheels' reach (omni_gym.envs.references.draw_task_reference): the share of the friction set
# a reference may ask for. The preset ids' references already ask at most 0.74-0.96 of it (benchmarks/results/
# feasibility.md), so 1 changes none of them; WilliamsPaper-v0 keeps the paper's task as it is (it asks 1.2-1.4).
WITHIN_REACH = {"ref_traction": 1.0}

ENV_IDS = {
    "OmniPathFollow-WilliamsPaper-v0": ({"robot": "williams2002", "surface": "carpet", "friction": "roller_gap",
                                    "episode_seconds": 20.0}, 2000),
    "OmniPathFollow-Williams-v1": ({"robot": "williams2002", "surface": "carpet", "friction": "roller_gap",
                                    "episode_seconds": 20.0, "ref_turn": "before", **WITHIN_REACH}, 2000),
    "OmniPathFollow-Phunopas-v0": ({"robot": "phunopas2018", "surface": "carpet", "friction": "roller_gap",
                                    "episode_seconds": 20.0, **LIFT_OFF, **WITHIN_REACH}, 2000),
    "OmniPathFollow-Mecanum-v0": ({"robot": "optiodom_omni4", "surface": "carpet", "friction": "initial",
                                   "episode_seconds": 20.0, **LIFT_OFF, **WITHIN_REACH}, 2000),
    "OmniGoToPose-v0": ({"robot": "phunopas2018", "surface": "carpet", "friction": "roller_gap", "task": "goto",
                         "trajectory": "goto", "episode_seconds": 8.0, **LIFT_OFF, **WITHIN_REACH}, 800),
}

# "My robot": everything physical from model= (required; omni_gym.envs.config.check_custom). Its references stay
# within CUSTOM_TRACTION of what the model's wheels can transmit on its floor, and turn in place before each
# translation: a robot of unknown traction gets a task it can do (docs/environments.md, "Tasks within reach").
CUSTOM_ID = "OmniPathFollow-Custom-v0"
CUSTOM_TRACTION = 0.15  # of the headroom above the rolling resistance (benchmarks/results/feasible_tasks.md)
CUSTOM = ({"episode_seconds": 20.0, "ref_traction": CUSTOM_TRACTION}, 2000)  # ref_turn: envs.config.CUSTOM_DEFAULTS
CUSTOM_ENTRY = "omni_gym.envs.omni_env:OmniCustomEnv"
CUSTOM_VECTOR_ENTRY = "omni_gym.envs.vector:OmniCustomVectorEnv"



def all_ids() -> tuple[str, ...]:
    """Every id a user can make: the preset ids (:data:`ENV_IDS`), then :data:`CUSTOM_ID` (renamed ids left out)."""
    return (*ENV_IDS, CUSTOM_ID)


# Old id → its new name: making one raises an error that names the new id.
RENAMED = {"OmniPathFollow-Williams-v0": "OmniPathFollow-WilliamsPaper-v0"}
RENAMED_ENTRY = "omni_gym.envs:williams_v0_renamed"  # a string, as every omni-gym entry point ("omni_gym.…")


class RenamedIdError(gym.error.DeprecatedEnv, ValueError):
    """A renamed id was made: a Gymnasium error and, as every bad input to the environments, a ValueError."""


def williams_v0_renamed(**_: object):
    """The entry point (single and vector) of ``OmniPathFollow-Williams-v0``: raise naming its new id."""
    old = "OmniPathFollow-Williams-v0"
    raise RenamedIdError(f"{old} was renamed {RENAMED[old]} (the same task: Williams et al.'s references, turning "
                         "while translating); OmniPathFollow-Williams-v1 is a different task (turns in place before "
                         "each translation)")


def register_envs() -> None:
    for env_id, (kwargs, steps) in ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=ENTRY, vector_entry_point=VECTOR_ENTRY, max_episode_steps=steps,
                         kwargs=dict(kwargs))
    if CUSTOM_ID not in gym.registry:
        gym.register(id=CUSTOM_ID, entry_point=CUSTOM_ENTRY, vector_entry_point=CUSTOM_VECTOR_ENTRY,
                     max_episode_steps=CUSTOM[1], kwargs=dict(CUSTOM[0]))
    for old in RENAMED:
        if old not in gym.registry:
            gym.register(id=old, entry_point=RENAMED_ENTRY, vector_entry_point=RENAMED_ENTRY)
