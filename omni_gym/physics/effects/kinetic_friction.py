"""``kinetic_friction``: a Stribeck drop from static to kinetic friction.

Every friction coefficient falls from μ to ``ratio``·μ as the slip speed grows past the Stribeck
velocity ``v_s`` [m/s] (force kernel, ``docs/model.md``).
"""

from __future__ import annotations

from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.layout import SP_KIN_RATIO, SP_VS


class KineticFriction(Effect):
    name = "kinetic_friction"
    summary = "Stribeck drop of friction from static μ to ratio·μ above the slip speed v_s"
    params = (
        Param("ratio", "scalar", "(dimensionless, mu_kinetic / mu_static)", 0.0, 1.0, "",
              "μ_k/μ_s: kinetic friction is at most static friction (the effect is a drop from static to kinetic)",
              plausible=Range(0.5, 1.0, "mu_kinetic / mu_static of dry contacts (rubber, plastic, metal on floors) "
                                         "is 0.5-1 in friction tables; above 1 is not a Stribeck drop at all")),
        Param("v_s", "scalar", "m/s (Stribeck velocity)", 1e-4, 10.0, "m/s",
              "Stribeck speeds are about 1 mm/s to 0.1 m/s; must be > 0 (the law divides by it)",
              plausible=Range(0.001, 0.1, "Stribeck velocities of dry and boundary-lubricated contacts are 1e-3 "
                                          "to 1e-1 m/s (Armstrong-Helouvry et al., Automatica 1994)")),
    )
    recovery_sizes = {"small": {"ratio": 0.75, "v_s": 0.02}, "large": {"ratio": 0.6, "v_s": 0.02}}
    tolerances = {"ratio": 0.05, "v_s": 0.3}  # v_s: relative

    def write_kernel(self, params, sp, wp, model) -> None:
        sp[SP_KIN_RATIO] = params["ratio"]
        sp[SP_VS] = params["v_s"]

    def fit_dims(self, model) -> tuple[Dim, ...]:
        return (Dim("ratio", 0.2, 1.0), Dim("v_s", 0.002, 0.3, log=True))

    def from_fit(self, values, model) -> dict:
        return {"ratio": values[0], "v_s": values[1]}

    def null_fit(self, model) -> dict[str, float]:
        return {"ratio": 1.0}  # v_s does nothing at ratio 1

    def synth_default(self, model, rng) -> dict:
        return {"ratio": 0.6, "v_s": 0.02}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"ratio": abs(fitted["ratio"] - truth["ratio"]), "v_s": abs(fitted["v_s"] / truth["v_s"] - 1)}
