"""Replay piecewise-constant wheel commands through the world (what ``omni-gym simulate`` runs)."""

from __future__ import annotations

import numpy as np

from omni_gym.physics.model import Actuation, SimModel
from omni_gym.physics.world import DEFAULT_DT, Arena, World


def simulate_commands(model: SimModel, times: np.ndarray, commands: np.ndarray, dt: float = DEFAULT_DT,
                      actuation: Actuation | None = None, seed: int = 0,
                      arena: Arena | None = None) -> np.ndarray:
    """States at every command time, starting at rest at (0, 0, 0).

    Row j of ``commands`` [rad/s] holds from ``times[j]`` to ``times[j+1]`` [s]; the last row ends
    the run. Switch times are rounded to the nearest substep ``dt``. Returns (K, 6):
    x, y [m], θ [rad] of the geometric centre and its world velocity ẋ, ẏ [m/s], ω [rad/s].
    An effect's wheel contact process (``wheel_liftoff``), if any, draws from ``seed``.
    """
    times = np.asarray(times, dtype=float)
    commands = np.asarray(commands, dtype=float)
    world = World(model, dt=dt, actuation=actuation, arena=arena)
    process = model.contact_process(np.random.default_rng(seed))
    if process is not None:
        world.set_contact_process(0, process)
    world.reset()
    out = np.zeros((len(times), 6))
    ticks = np.rint(times / dt).astype(np.int64)
    for j in range(len(times) - 1):
        world.set_commands(commands[j])
        world.substeps(int(ticks[j + 1] - ticks[j]))
        out[j + 1, 0:3] = world.pose[0]
        out[j + 1, 3:6] = world.velocity[0]
    return out
