"""``mecanum_lateral``: a mecanum robot travels sideways less (or more) per wheel turn than forwards.

With rigid rollers at γ to the wheel plane, a wheel of radius r turning at w [rad/s] constrains the
velocity of its centre v to v·(d + tan γ · z × d) = r·w (``docs/model.md``): a pure longitudinal motion
moves the body r·w per wheel radian, a pure lateral one r·w / tan γ (the same for γ = 45°). Real mecanum
rollers are rubber-covered and turn on bearings with friction: in a lateral motion every roller has to
roll (in a longitudinal one none does), and the loaded, compliant roller contact creeps along the
roller axis, so the body covers less ground sideways than the rigid kinematics say. The effect scales
the lateral travel per wheel turn by ``scale`` (λ) and leaves the longitudinal one alone, through an
effective roller angle γ' on every wheel:

    tan γ' = tan γ / λ,   i.e. γ' = atan2(sin γ, λ·cos γ)  (the sign of γ kept).

Per-wheel radii cannot do this: on a mecanum layout pure forward and pure sideways motion turn the
wheels at the same speeds (up to signs), so any radius change scales both alike. ``scale`` = 1 is the
rigid-roller model. The yaw lever of each wheel, e·(z × p), changes with γ' too (the rolling direction
e = d + tan γ'·z × d): rotation in place is partly a lateral motion of every wheel.

Mecanum robots only: a robot with omni wheels (γ = 0) refuses it (:meth:`MecanumLateral.check_robot`),
since tan 0 = 0 has no lateral travel to scale.
"""

from __future__ import annotations

import numpy as np

from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.layout import WP_COSG, WP_SING


def effective_roller_angles(gamma: np.ndarray, scale: float) -> np.ndarray:
    """Effective roller angles γ' [rad] (n,) with tan γ' = tan γ / ``scale`` (module docstring)."""
    gamma = np.asarray(gamma, dtype=float)
    return np.arctan2(np.sin(gamma), scale * np.cos(gamma))


class MecanumLateral(Effect):
    name = "mecanum_lateral"
    summary = ("mecanum rollers: lateral travel per wheel turn scaled against the longitudinal one "
               "(effective roller angle)")
    params = (
        Param("scale", "scalar", "(dimensionless, lateral / longitudinal travel per wheel turn, against rigid rollers)",
              0.5, 2.0, "", "half or twice the rigid-roller lateral travel is another roller angle (27° or 63° "
                            "instead of 45°), not roller slip",
              plausible=Range(0.85, 1.03, "roller creep and bearing friction lose a few per cent of the lateral "
                                          "travel of a working mecanum wheel (measured 0.96-0.97 on the OptiOdom "
                                          "omni4 robot); more than 15 % is a seized roller, and rollers cannot "
                                          "gain more than a few per cent (contact point off the roller centre)")),
    )
    recovery_sizes = {"small": {"scale": 0.97}, "large": {"scale": 0.93}}
    # A 1 % lateral scale error is 10 mm over 1 m of sideways travel: the size of the tracker noise plus
    # the fit's other terms on the recovery runs.
    tolerances = {"scale": 0.01}

    def check_robot(self, robot) -> None:
        if not robot.has_angled_rollers:
            raise ValueError("effect 'mecanum_lateral' applies to mecanum wheels only (roller_angle ≠ 0); this robot "
                             "has omni wheels, whose rollers give no lateral travel per wheel turn to scale")

    def write_kernel(self, params, sp, wp, model) -> None:
        # The kernel reads the roller angle only through cos γ and sin γ (WP_COSG, WP_SING); an omni wheel
        # of a mixed robot (γ = 0) keeps γ' = 0 and with it the kernel's exact omni path.
        gamma = effective_roller_angles(model.robot.roller_angles(), float(params["scale"]))
        wp[:, WP_COSG] = np.cos(gamma)
        wp[:, WP_SING] = np.sin(gamma)

    def fit_dims(self, model) -> tuple[Dim, ...]:
        return (Dim("scale", 0.8, 1.1),)

    def from_fit(self, values, model) -> dict:
        return {"scale": float(values[0])}

    def null_fit(self, model) -> dict[str, float]:
        return {"scale": 1.0}

    def synth_default(self, model, rng) -> dict:
        return {"scale": 0.95}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"scale": abs(float(fitted["scale"]) - float(truth["scale"]))}
