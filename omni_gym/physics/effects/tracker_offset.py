"""``tracker_offset`` (tracker): the tracked point is not the robot's geometric centre.

A motion-capture body is rarely centred on the wheels, nor aligned with the robot's x axis. The
tracker reports the pose of its own body point: with the geometric centre at (p, θ) in the world,

    p_measured = p + R(θ)·offset,      θ_measured = θ + yaw,

``offset`` [m] in the robot's body frame, ``yaw`` [rad] counter-clockwise. A measurement effect
(``kind = "tracker"``): it changes what is measured, not how the robot moves.
"""

from __future__ import annotations

import math

import numpy as np

from omni_gym.physics.effects.base import Dim, Effect, Param, Range


class TrackerOffset(Effect):
    name = "tracker_offset"
    kind = "tracker"
    summary = "tracked point and heading offset from the geometric centre (a measurement effect)"
    params = (
        Param("offset", "xy", "m (x, y of the tracked point from the geometric centre, body frame)", -1.0, 1.0, "m",
              "each coordinate; a tracked point a metre off the centre is on another body",
              plausible=Range(-0.1, 0.1, "a marker body sits on the robot's top plate: within 10 cm of the centre")),
        Param("yaw", "scalar", "rad (tracked heading minus the robot's, counter-clockwise)", -math.pi, math.pi, "rad",
              "an angle", plausible=Range(-0.2, 0.2, "a rigid body defined by eye is aligned within about 10°")),
    )
    recovery_sizes = {"small": {"offset": [0.01, -0.006], "yaw": 0.01},
                      "large": {"offset": [0.025, 0.015], "yaw": -0.03}}
    tolerances = {"offset": 0.002, "yaw": 0.005}  # m, rad

    def measure(self, params, t, pose, velocity=None) -> np.ndarray:
        o = np.asarray(params["offset"], dtype=float)
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        out = np.array(pose, dtype=float, copy=True)
        out[:, 0] += c * o[0] - s * o[1]
        out[:, 1] += s * o[0] + c * o[1]
        out[:, 2] += float(params["yaw"])
        return out

    def unmeasure(self, params, pose, velocity):
        o = np.asarray(params["offset"], dtype=float)
        theta = float(pose[2]) - float(params["yaw"])
        c, s = math.cos(theta), math.sin(theta)
        q = np.array([c * o[0] - s * o[1], s * o[0] + c * o[1]])  # R(θ)·offset, world frame
        p = np.array([pose[0] - q[0], pose[1] - q[1], theta])
        v = np.array(velocity, dtype=float, copy=True)
        v[0] += velocity[2] * q[1]  # the tracked point moves at v + ω z × q
        v[1] -= velocity[2] * q[0]
        return p, v

    def fit_dims(self, model) -> tuple[Dim, ...]:
        c = model.robot.lever()  # a tracked point within one lever of the centre
        return (Dim("ox", -c, c), Dim("oy", -c, c), Dim("yaw", -0.2, 0.2))

    def from_fit(self, values, model) -> dict:
        return {"offset": [values[0], values[1]], "yaw": values[2]}

    def null_fit(self, model) -> dict[str, float]:
        cur = model.effects.get(self.name, {"offset": [0.0, 0.0], "yaw": 0.0})
        return {"ox": float(cur["offset"][0]), "oy": float(cur["offset"][1]), "yaw": float(cur["yaw"])}

    def synth_default(self, model, rng) -> dict:
        return {"offset": [0.02, -0.01], "yaw": 0.02}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"offset": float(np.hypot(*(np.asarray(fitted["offset"]) - truth["offset"]))),
                "yaw": abs(float(fitted["yaw"]) - float(truth["yaw"]))}
