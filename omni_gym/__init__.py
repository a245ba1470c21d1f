"""omni-gym: omnidirectional wheeled robots whose wheels slip and lift off the floor."""

import os

# Threads of the parallel force kernel (OpenMP) sleep instead of spinning while they wait: on a
# shared 2-core machine spinning threads made a loaded run 40x slower (passive: 2x faster than serial).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from omni_gym.envs import ENV_IDS, register_envs  # noqa: E402


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
