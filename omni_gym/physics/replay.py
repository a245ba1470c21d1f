"""Replay piecewise-constant wheel commands through the world (what ``omni-gym simulate`` runs)."""

from __future__ import annotations

import numpy as np

from omni_gym.physics.liftoff import ContactProcess
from omni_gym.physics.model import Actuation, SimModel
from omni_gym.physics.world import DEFAULT_DT, Arena, World


def simulate_commands(model: SimModel, times: np.ndarray, commands: np.ndarray, dt: float = DEFAULT_DT,
                      actuation: Actuation | None = None, seed: int = 0,
                      arena: Arena | None = None) -> np.ndarray:
    """States at every command time, starting at rest at (0, 0, 0).

    Row j of ``commands`` [rad/s] holds from ``times[j]`` to ``times[j+1]`` [s]; the last row ends
    the run. Switch times are rounded to the nearest substep ``dt``. Returns (K, 6):
    x, y [m], θ [rad] of the geometric centre and its world velocity ẋ, ẏ [m/s], ω [rad/s].
    The ``wheel_liftoff`` effect, if present, draws its contact process from ``seed``.
    """
    times = np.asarray(times, dtype=float)
    commands = np.asarray(commands, dtype=float)
    world = World(model, dt=dt, actuation=actuation, arena=arena)
    if "wheel_liftoff" in model.effects:
        p = model.effects["wheel_liftoff"]
        world.set_contact_process(0, ContactProcess(model.n_wheels, p["lift_rate"], p["recover_rate"],
                                                    np.random.default_rng(seed)))
    world.reset()
    out = np.zeros((len(times), 6))
    ticks = np.rint(times / dt).astype(np.int64)
    for j in range(len(times) - 1):
        world.set_commands(commands[j])
        world.substeps(int(ticks[j + 1] - ticks[j]))
        out[j + 1, 0:3] = world.pose[0]
        out[j + 1, 3:6] = world.velocity[0]
    return out
