"""omni-gym: omnidirectional wheeled robots whose wheels slip and lift off the floor."""

import importlib
import os
from typing import TYPE_CHECKING

# The OpenMP threads of the parallel force kernel must sleep, not spin, while they wait: on a shared
# 2-core machine spinning threads made a loaded run 40x slower (passive: 2x faster than serial).
# libgomp reads OMP_WAIT_POLICY once, when it is loaded, and the first parallel call may come from
# any module (the discrepancy workflow's batched replay, the vector env), so the kernel's own warm-up
# (physics.kernel._passive_openmp) is not enough: setting it only there made `make test` run 35
# CPU-minutes instead of 19. Hence this one process-wide default at import (kept
# and documented); a value the user set is never changed.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

# The command line's Ctrl-C handling starts here, before the slow imports below: the console script and
# `python -m omni_gym.cli` import this package first. Nothing changes for `import omni_gym` elsewhere.
from omni_gym.interrupts import guard_startup  # noqa: E402

guard_startup()

from omni_gym.envs import ENV_IDS, register_envs  # noqa: E402

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
