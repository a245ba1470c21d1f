"""omni-gym: omnidirectional wheeled robots whose wheels slip and lift off the floor."""

# Importing the package changes no process-wide setting of other libraries: the OpenMP wait policy
# of the threaded force kernel is set where its threads start (omni_gym.physics.kernel.warm_up).
from omni_gym.envs import ENV_IDS, register_envs

# The everyday physics entry points (already loaded by the environments, so this costs nothing).
from omni_gym.physics.friction import Surface, surface_preset
from omni_gym.physics.model import Actuation, SimModel, load_model
from omni_gym.physics.replay import simulate_commands
from omni_gym.physics.robot import RobotSpec, Wheel, robot_preset
from omni_gym.physics.world import Arena, World


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
