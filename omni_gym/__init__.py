"""omni-gym: omnidirectional wheeled robots whose wheels slip and lift off the floor."""

from omni_gym.envs import ENV_IDS, register_envs

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "register_envs", "__version__"]

register_envs()
