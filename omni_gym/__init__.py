"""omni-gym: omnidirectional wheeled robots whose wheels slip and lift off the floor."""

# Importing the package changes no process-wide setting of other libraries: the OpenMP wait policy
# of the threaded force kernel is set where its threads start (omni_gym.physics.kernel.warm_up).
import importlib
from typing import TYPE_CHECKING

from omni_gym.envs import ENV_IDS, register_envs

# The everyday physics entry points, imported on first use (PEP 562): `import omni_gym` stays light,
# because the environments load numba and pymunk only when one is made.
_EXPORTS = {
    "Surface": "omni_gym.physics.friction",
    "surface_preset": "omni_gym.physics.friction",
    "Actuation": "omni_gym.physics.model",
    "SimModel": "omni_gym.physics.model",
    "load_model": "omni_gym.physics.model",
    "simulate_commands": "omni_gym.physics.replay",
    "RobotSpec": "omni_gym.physics.robot",
    "Wheel": "omni_gym.physics.robot",
    "robot_preset": "omni_gym.physics.robot",
    "Arena": "omni_gym.physics.world",
    "World": "omni_gym.physics.world",
}

if TYPE_CHECKING:
    from omni_gym.physics.friction import Surface, surface_preset
    from omni_gym.physics.model import Actuation, SimModel, load_model
    from omni_gym.physics.replay import simulate_commands
    from omni_gym.physics.robot import RobotSpec, Wheel, robot_preset
    from omni_gym.physics.world import Arena, World


def __getattr__(name: str):
    """``omni_gym.World`` and the other names of :data:`_EXPORTS`, loaded from their module on first use."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'omni_gym' has no attribute {name!r}")

def _version() -> str:
    """The installed distribution's version (one source of truth: ``version`` in pyproject.toml)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("omni-gym")
    except PackageNotFoundError:  # a source tree on sys.path that was never installed
        return "0+unknown"


__version__ = _version()
__all__ = [
    "ENV_IDS",
    "Actuation",
    "Arena",
    "RobotSpec",
    "SimModel",
    "Surface",
    "Wheel",
    "World",
    "__version__",
    "load_model",
    "register_envs",
    "robot_preset",
    "simulate_commands",
    "surface_preset",
]

register_envs()
