"""``roller_gap``: the rigid material between an omni wheel's rollers touches the floor.

Williams et al. (2002): between two rollers the wheel rides on hub or frame material with friction
coefficient μ'' (``mu_gap``) in both directions, for the share ``1 − roller_fraction`` of each roller
pitch 2π/rollers; ``phase`` [rad] is each wheel's rotation at which its first gap starts. Turns the
gap model on even for a nominal ``initial`` friction model.

Omni wheels only: a robot with mecanum wheels (roller angle ≠ 0) refuses it (:meth:`RollerGap.check_robot`),
since a mecanum wheel's rollers overlap seen from the side and it always touches the floor with a roller.
"""

from __future__ import annotations

import math

import numpy as np

from omni_gym.bounds import MU_REASON
from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.layout import SP_GAP, SP_PITCH, WP_GAPT, WP_GAPW, WP_PHASE


class RollerGap(Effect):
    name = "roller_gap"
    has_friction_coefficients = True  # mu_gap: of the floor it was fitted on
    summary = "rigid material between the rollers (Williams et al. 2002): μ'', roller share, per-wheel phase"
    params = (
        Param("mu_gap", "scalar", "(dimensionless friction coefficient)", 0.0, 10.0, "", MU_REASON,
              plausible=Range(0.1, 1.0, "dry friction of the rigid hub/frame material (metal, hard plastic) on a "
                                        "floor is 0.2-0.8 in engineering tables; Williams et al. (2002) measured "
                                        "0.47 (paper) and 0.56 (carpet); above 1 needs rubber or adhesion, which "
                                        "rigid material is not")),
        Param("roller_fraction", "scalar", "(dimensionless share of the roller pitch covered by roller)", 0.0, 1.0,
              "", "as roller_fraction", lo_open=True,
              plausible=Range(0.7, 1.0, "rollers cover most of the rim of a working omni wheel (0.9 for the "
                                        "Williams wheel); below 0.7 the wheel rides on rigid material for more "
                                        "than 30 % of a turn, a bump that is plain to see and hear")),
        Param("phase", "per_wheel", "rad (per wheel, within one roller pitch)", -2 * math.pi, 2 * math.pi, "rad",
              "per wheel; one wheel turn: every phase equals one within a pitch ≤ 2π"),
    )
    # Size = the rigid-material coefficient μ'' (roller fraction 0.9, random phases); "large" is the
    # paper's carpet value (μ' 0.15), "small" μ' 0.25.
    recovery_sizes = {"small": {"mu_gap": 0.4}, "large": {"mu_gap": 0.56}}
    tolerances = {"mu_gap": 0.1, "roller_fraction": 0.03, "phase": 0.1}  # phase: share of the pitch

    def check_robot(self, robot) -> None:
        if robot.has_angled_rollers:
            raise ValueError("effect 'roller_gap' applies to omni wheels only (rigid material between rollers in "
                             "the wheel plane); this robot has mecanum wheels (roller_angle ≠ 0), whose rollers "
                             "overlap and always touch the floor")

    def write_kernel(self, params, sp, wp, model) -> None:
        sp[SP_GAP] = (1.0 - params["roller_fraction"]) * sp[SP_PITCH]
        wp[:, WP_GAPW] = params["mu_gap"]
        wp[:, WP_GAPT] = params["mu_gap"]
        wp[:, WP_PHASE] = np.asarray(params["phase"], dtype=float)

    def scale_friction(self, params: dict, factor: float) -> dict:
        return {**params, "mu_gap": params["mu_gap"] * factor}

    def fit_dims(self, model) -> tuple[Dim, ...]:
        pitch = 2 * math.pi / model.robot.rollers
        return (Dim("mu_gap", 0.05, 1.5), Dim("roller_fraction", 0.6, 1.0),
                *[Dim(f"phase{i + 1}", 0.0, pitch, periodic=True) for i in range(model.n_wheels)])

    def from_fit(self, values, model) -> dict:
        return {"mu_gap": values[0], "roller_fraction": values[1], "phase": list(values[2:])}

    def null_fit(self, model) -> dict[str, float]:
        return {"roller_fraction": 1.0}  # no rigid material: the initial model

    def prior_fit(self, model) -> dict[str, float]:
        return {"mu_gap": model.surface.mu_gap, "roller_fraction": model.robot.roller_fraction}

    def synth_default(self, model, rng) -> dict:
        pitch = 2 * math.pi / model.robot.rollers
        return {"mu_gap": model.surface.mu_gap, "roller_fraction": model.robot.roller_fraction,
                "phase": [float(v) for v in rng.uniform(0, pitch, model.n_wheels)]}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        pitch = 2 * math.pi / model.robot.rollers
        d = np.mod(np.asarray(fitted["phase"]) - np.asarray(truth["phase"]) + pitch / 2, pitch) - pitch / 2
        return {"mu_gap": abs(fitted["mu_gap"] - truth["mu_gap"]),
                "roller_fraction": abs(fitted["roller_fraction"] - truth["roller_fraction"]),
                "phase": float(np.max(np.abs(d)) / pitch)}
