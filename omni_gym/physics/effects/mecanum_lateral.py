"""``mecanum_lateral``: a mecanum wheel's effective radius differs sideways from along its rolling direction.

With rigid rollers at γ to the wheel plane, a wheel of radius r turning at w [rad/s] constrains the
velocity of its centre v to v·(d + tan γ · z × d) = r·w (``docs/model.md``): a pure longitudinal motion
moves the body r·w per wheel radian, a pure lateral one r·w / tan γ (the same for γ = 45°). Real mecanum
rollers are rubber-covered and turn on bearings with friction: in a lateral motion every roller has to
roll (in a longitudinal one none does), and the loaded, compliant roller contact creeps along the
roller axis, so the body covers less ground sideways per wheel turn than forwards. The effect gives the
wheel two effective radii, r_lon along its rolling direction and r_lat = ``ratio`` · r_lon for the
travel its rollers make sideways, and keeps their mean at the radius the model had (nominal, or a
calibration's ``wheel_radius``):

    r_lon = r · 2 / (1 + ratio),   r_lat = r · 2·ratio / (1 + ratio),
    tan γ' = tan γ / ratio         (the effective roller angle; sign of γ kept).

The kernel sees r_lon as the wheel radius and γ' as the roller angle: pure longitudinal motion then
moves r_lon·w per radian, pure lateral motion r_lon·w / tan γ' = r_lat·w / tan γ. Keeping the mean makes
the effect orthogonal, to first order, to a common radius scale (``wheel_radius``): a kinematic
calibration on a mix of forward and sideways runs fits the mean radius, and this effect splits it.
Per-wheel radii cannot do this: on a mecanum layout pure forward and pure sideways motion turn the
wheels at the same speeds (up to signs), so any radius change scales both alike. The yaw lever of each
wheel, e·(z × p), changes with γ' too (the rolling direction e = d + tan γ'·z × d); for 45° rollers at
(±a, ±a) the yaw rate per wheel speed changes by 4·ratio/(1 + ratio)², 1 to second order (0.9995 at 0.956),
so a calibrated l1 + l2 stays valid. ``ratio`` = 1 is the rigid-roller model.

Mecanum robots only: a robot with omni wheels (γ = 0) refuses it (:meth:`MecanumLateral.check_robot`),
since tan 0 = 0 has no lateral travel to scale.
"""

from __future__ import annotations

import numpy as np

from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.layout import WP_COSG, WP_R, WP_SING


def effective_roller_angles(gamma: np.ndarray, ratio: float) -> np.ndarray:
    """Effective roller angles γ' [rad] (n,) with tan γ' = tan γ / ``ratio`` (module docstring)."""
    gamma = np.asarray(gamma, dtype=float)
    return np.arctan2(np.sin(gamma), ratio * np.cos(gamma))


class MecanumLateral(Effect):
    name = "mecanum_lateral"
    summary = ("mecanum wheels: effective radius sideways (roller direction) / along the rolling direction, "
               "their mean kept")
    params = (
        Param("ratio", "scalar", "(dimensionless, lateral / longitudinal effective radius, every wheel)",
              0.5, 2.0, "", "half or twice the longitudinal radius sideways is another roller angle (27° or "
                            "63° instead of 45°), not roller creep",
              plausible=Range(0.85, 1.03, "roller creep and bearing friction lose a few per cent of the lateral "
                                          "travel of a working mecanum wheel (measured 0.955 on the OptiOdom "
                                          "omni4 robot); more than 15 % is a seized roller, and rollers cannot "
                                          "gain more than a few per cent (contact point off the roller centre)")),
    )
    recovery_sizes = {"small": {"ratio": 0.97}, "large": {"ratio": 0.93}}
    # A 1 % ratio error is 5 mm over 1 m of sideways travel: the tracker noise and the fit's
    # other terms on the recovery runs are of that size.
    tolerances = {"ratio": 0.01}

    def check_robot(self, robot) -> None:
        if not robot.has_angled_rollers:
            raise ValueError("effect 'mecanum_lateral' applies to mecanum wheels only (roller_angle ≠ 0); this robot "
                             "has omni wheels, whose rollers give no lateral travel per wheel turn to scale")

    def write_kernel(self, params, sp, wp, model) -> None:
        ratio = float(params["ratio"])
        # The kernel reads the roller angle only through cos γ and sin γ (WP_COSG, WP_SING); an omni wheel
        # of a mixed robot (γ = 0) keeps γ' = 0 and with it the kernel's exact omni path. The radius is
        # scaled in place: wheel_radius (if any) writes its value whatever the order of the effects.
        angled = model.robot.roller_angles() != 0.0
        gamma = effective_roller_angles(model.robot.roller_angles(), ratio)
        wp[:, WP_COSG] = np.cos(gamma)
        wp[:, WP_SING] = np.sin(gamma)
        wp[angled, WP_R] *= 2.0 / (1.0 + ratio)

    def fit_dims(self, model) -> tuple[Dim, ...]:
        return (Dim("ratio", 0.8, 1.1),)

    def from_fit(self, values, model) -> dict:
        return {"ratio": float(values[0])}

    def null_fit(self, model) -> dict[str, float]:
        return {"ratio": 1.0}

    def synth_default(self, model, rng) -> dict:
        return {"ratio": 0.95}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"ratio": abs(float(fitted["ratio"]) - float(truth["ratio"]))}
