"""``motor_lag``: wheel speeds follow their commands with a first-order lag ``tau`` [s]."""

from __future__ import annotations

from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.layout import SP_TAU


class MotorLag(Effect):
    name = "motor_lag"
    summary = "first-order lag tau of every wheel speed behind its command"
    params = (
        Param("tau", "scalar", "s (first-order time constant)", 0.0, 10.0, "s",
              "a drive that needs more than 10 s to follow its command is not a velocity source",
              plausible=Range(0.0, 0.2, "small geared DC drives under speed control reach a set speed within 200 ms "
                                        "(mechanical time constant of the motor with the reflected wheel inertia, "
                                        "a few to 100 ms); 0 is the ideal actuator of the nominal model")),
    )
    recovery_sizes = {"small": {"tau": 0.04}, "large": {"tau": 0.08}}
    tolerances = {"tau": 0.2}  # relative

    def write_kernel(self, params, sp, wp, model) -> None:
        sp[SP_TAU] = params["tau"]

    def fit_dims(self, model) -> tuple[Dim, ...]:
        return (Dim("tau", 0.001, 0.5, log=True),)

    def from_fit(self, values, model) -> dict:
        return {"tau": values[0]}

    def null_fit(self, model) -> dict[str, float]:
        return {"tau": self.fit_dims(model)[0].lo}  # the shortest lag the fit can express

    def synth_default(self, model, rng) -> dict:
        return {"tau": 0.08}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"tau": abs(fitted["tau"] / truth["tau"] - 1)}
