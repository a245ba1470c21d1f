"""``wheel_liftoff``: wheels leave the floor at random (Phunopas & Inoue 2018).

No kernel numbers: the effect installs a seeded :class:`~omni_gym.physics.liftoff.ContactProcess`
in the world (rates ``lift_rate``/``recover_rate`` [1/s]). Stochastic: a dataset holds one
realisation of it, so the discrepancy workflow fits it by lift-event inference, not by a parameter
search (``omni_gym.discrepancy.fit.events``).
"""

from __future__ import annotations

import math

from omni_gym.bounds import RATE_MAX, RATE_REASON
from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.liftoff import ContactProcess


class WheelLiftoff(Effect):
    name = "wheel_liftoff"
    summary = "random wheel lift-off: a contact process with lift and recover rates"
    stochastic = True
    params = (
        Param("lift_rate", "scalar", "1/s (rate of lifting a wheel from all-down)", 0.0, RATE_MAX, "1/s",
              "0 disables lift-off; " + RATE_REASON,
              plausible=Range(0.0, 2.0, "more than two lifts per second on a floor is chatter (a suspension or a "
                                        "rocking chassis), not the occasional lift-off of Phunopas & Inoue (2018); "
                                        "the library's environments use 0.5/s")),
        Param("recover_rate", "scalar", "1/s (rate of setting it down again)", 0.0, RATE_MAX, "1/s",
              "0 keeps a lifted wheel up until the end of the run; " + RATE_REASON,
              plausible=Range(1.0, 20.0, "mean lifted durations of 50 ms-1 s: shorter lifts do not move the pose "
                                         "beyond tracker noise, a wheel up for longer than 1 s is a persistent "
                                         "unloading (a centre-of-mass offset), not a lift")),
    )
    recovery_sizes = {"small": {"lift_rate": 0.4, "recover_rate": 5.0},
                      "large": {"lift_rate": 1.0, "recover_rate": 5.0}}
    tolerances = {"lift_rate": 1.0, "recover_rate": 1.0}  # |ln(fit/true)|: a factor e

    def contact_process(self, params, n_wheels, rng) -> ContactProcess | None:
        if params["lift_rate"] <= 0:
            return None  # never lifts: the world needs no process
        return ContactProcess(n_wheels, params["lift_rate"], params["recover_rate"], rng)

    def fit_dims(self, model) -> tuple[Dim, ...]:
        return (Dim("lift_rate", 0.05, 5.0, log=True), Dim("recover_rate", 0.5, 50.0, log=True))

    def from_fit(self, values, model) -> dict:
        return {"lift_rate": values[0], "recover_rate": values[1]}

    def null_fit(self, model) -> dict[str, float]:
        lift, recover = self.fit_dims(model)
        return {"lift_rate": lift.lo, "recover_rate": recover.hi}  # rarest, shortest lifts

    def synth_default(self, model, rng) -> dict:
        return {"lift_rate": 0.5, "recover_rate": 5.0}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {k: abs(math.log(fitted[k] / truth[k])) for k in ("lift_rate", "recover_rate")}
