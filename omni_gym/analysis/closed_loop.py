"""The second generator in closed loop: the event integrator as a plant a controller drives.

:class:`SecondGeneratorPlant` implements the plant protocol (:mod:`omni_gym.physics.plant`) with the
separately written integrator of :mod:`omni_gym.analysis.event_integrator`: every library effect of a model
file, and effects outside the library (``drag``), integrated with event handling at every roller/rigid
switch and lift-off switch, one control period at a time. It is the robot's stand-in for measuring what a
controller designed on one model is worth on a robot that differs from it (``omni-gym evaluate --plant``).

What it leaves to the environment: the sensors. It returns the true motion, and the environment measures it
with the project's sensor models. The tracker effects of a model (``tracker_offset``, ``time_offset``) change
how a logged pose is measured, not how the robot moves, so they are not part of the plant (as in
:func:`~omni_gym.analysis.event_integrator.build_plant`).
"""

from __future__ import annotations

import math

import numpy as np

from omni_gym.analysis.event_integrator import build_plant, draw_lift_schedule, run_piece, start_state
from omni_gym.physics.model import SimModel
from omni_gym.physics.plant import PlantState

__all__ = ["SecondGeneratorPlant", "HORIZON_S"]

HORIZON_S = 3600.0  # s after a reset over which the lift-off schedule is drawn (a step past it is refused)


class SecondGeneratorPlant:
    """One robot of ``model`` (its own effects) with ``extra`` effects on top ({name: params}, e.g. ``drag``),
    integrated by the event integrator (LSODA, rtol 1e-6 and atol 1e-9 by default: in closed loop the tracked
    poses move by about 1e-9 m against rtol 1e-8, at 1.6× the speed; the open-loop datasets keep 1e-8).

    ``reset(pose, seed)`` draws the lift-off schedule of a ``wheel_liftoff`` effect from
    ``numpy.random.default_rng(seed)``; the same seed and commands give the same run, bit for bit.
    """

    def __init__(self, model: SimModel, extra: dict | None = None, method: str = "LSODA", rtol: float = 1e-6,
                 atol: float = 1e-9) -> None:
        self.model = model
        self.plant = build_plant(model, extra)
        self.n_wheels = self.plant.n
        self.method, self.rtol, self.atol = method, rtol, atol
        self._state: np.ndarray | None = None
        self.counts = {"pieces": 0, "gap_switches": 0}

    def reset(self, pose: np.ndarray, seed: int) -> PlantState:
        """At rest at ``pose`` (x, y [m], θ [rad], geometric centre), all wheels down, at t = 0."""
        p = self.plant
        start = np.asarray(pose, dtype=float).reshape(3)
        if not np.all(np.isfinite(start)):
            raise ValueError(f"reset: pose must be finite, got {start.tolist()}")
        self._state, self._regions = start_state(p, start)
        self._schedule = draw_lift_schedule(p, HORIZON_S, np.random.default_rng(int(seed)))
        self._next = 0  # index of the next lift-off switch
        self._lifted = np.zeros(p.n, dtype=bool)
        self._t = 0.0
        self.counts = {"pieces": 0, "gap_switches": 0}
        return self._report()

    def step(self, wheel_speeds: np.ndarray, duration: float) -> PlantState:
        """Hold ``wheel_speeds`` (n,) [rad/s] for ``duration`` [s], switching lift-off exactly on its schedule."""
        if self._state is None:
            raise RuntimeError("reset the plant before stepping it")
        cmd = np.asarray(wheel_speeds, dtype=float).reshape(self.n_wheels)
        if not np.all(np.isfinite(cmd)) or not (math.isfinite(duration) and duration > 0):
            raise ValueError("step: wheel speeds and duration must be finite (duration > 0)")
        end = self._t + float(duration)
        if end > HORIZON_S:
            raise ValueError(f"step: the plant runs at most {HORIZON_S:.0f} s after a reset")
        p = self.plant
        t = self._t
        while t < end:
            while self._next < len(self._schedule) and self._schedule[self._next][0] <= t:
                self._lifted = self._schedule[self._next][1]
                self._next += 1
            b = end
            if self._next < len(self._schedule):
                b = min(b, float(self._schedule[self._next][0]))
            self._state = run_piece(p, self._state, self._regions, cmd, p.loads(self._lifted), t, b, self.counts,
                                    self.method, self.rtol, self.atol)
            t = b
        self._t = end
        return self._report()

    def _report(self) -> PlantState:
        """The geometric centre's pose and velocity (world frame), wheel angles and contacts now."""
        p, y = self.plant, self._state
        th, om = y[2], y[5]
        c, s = math.cos(th), math.sin(th)
        rx, ry = c * p.com[0] - s * p.com[1], s * p.com[0] + c * p.com[1]  # R(θ)·com
        pose = np.array([y[0] - rx, y[1] - ry, th])
        velocity = np.array([y[3] + om * ry, y[4] - om * rx, om])  # v_centre = V − ω z × R·com
        return PlantState(pose=pose, velocity=velocity, wheel_angles=y[6:6 + p.n].copy(), contact=~self._lifted)
