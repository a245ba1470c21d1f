"""omni-gym: omnidirectional wheeled robots whose wheels slip and lift off the floor."""

# Importing the package changes no process-wide setting of other libraries: the OpenMP wait policy
# of the threaded force kernel is set where its threads start (omni_gym.kernel.warm_up).
from omni_gym.envs import ENV_IDS, register_envs


def _version() -> str:
    """The installed distribution's version (one source of truth: ``version`` in pyproject.toml)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("omni-gym")
    except PackageNotFoundError:  # a source tree on sys.path that was never installed
        return "0+unknown"


__version__ = _version()
__all__ = ["ENV_IDS", "register_envs", "__version__"]

register_envs()
