"""``time_offset`` (tracker): the tracker's time stamps are shifted against the odometry's.

Commands and encoders are logged on the robot's clock, poses on the tracker's; latency and clock
sync leave a constant shift. The pose stamped t was taken at t − ``delay``:

    pose_measured(t) = pose(t − delay),

``delay`` [s] > 0 when the tracker's stamps are late. Before the run's first row the robot is where
it started. A measurement effect (``kind = "tracker"``).
"""

from __future__ import annotations

import numpy as np

from omni_gym.physics.effects.base import Dim, Effect, Param, Range


class TimeOffset(Effect):
    name = "time_offset"
    kind = "tracker"
    summary = "time offset between tracker and odometry stamps (a measurement effect)"
    params = (
        Param("delay", "scalar", "s (tracker stamp minus the time the pose was taken)", -1.0, 1.0, "s",
              "a second of latency is a broken log, not a sync offset",
              plausible=Range(-0.1, 0.1, "motion-capture latency plus clock sync over a network: tens of ms")),
    )
    recovery_sizes = {"small": {"delay": 0.02}, "large": {"delay": -0.05}}
    tolerances = {"delay": 0.005}  # s

    def measure(self, params, t, pose, velocity=None) -> np.ndarray:
        tau = float(params["delay"])
        if tau == 0.0 or len(t) < 2:
            return pose
        q = np.clip(t - tau, t[0], t[-1])  # held at the first/last row outside the replay
        out = np.empty_like(pose)
        for j in range(3):
            out[:, j] = np.interp(q, t, np.unwrap(pose[:, j]) if j == 2 else pose[:, j])
        return out

    def unmeasure(self, params, pose, velocity):
        # The tracked start state is the centre's state delay earlier: move it on by delay (first order).
        return pose + float(params["delay"]) * np.asarray(velocity, dtype=float), velocity

    def fit_dims(self, model) -> tuple[Dim, ...]:
        return (Dim("delay", -0.15, 0.15),)

    def from_fit(self, values, model) -> dict:
        return {"delay": values[0]}

    def null_fit(self, model) -> dict[str, float]:
        return {"delay": float(model.effects.get(self.name, {"delay": 0.0})["delay"])}

    def synth_default(self, model, rng) -> dict:
        return {"delay": 0.03}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"delay": abs(float(fitted["delay"]) - float(truth["delay"]))}
