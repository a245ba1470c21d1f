"""``wheel_geometry``: each wheel's effective distance from the centre and its mounting angle.

The nominal layout puts wheel i at ``p_i`` (body frame) with positive drive direction ``d_i``. A real
robot's effective contact point is elsewhere (an omni wheel touches the floor on one roller or the
other, double rows, assembly tolerance), and a wheel may be yawed on its mount. The effect moves
wheel i to ``distance_i · p_i`` (radially, about the geometric centre) and yaws its drive direction by
``mount_i`` [rad] (counter-clockwise seen from above, about the wheel's vertical axis):

    p_i' = distance_i · p_i,        d_i' = R(mount_i) · d_i.

For a wheel whose drive is tangential, the rolling constraint r·ω_i = d_i'·v + ω·(p_i' × d_i') makes
``distance`` the per-wheel effective L of odometry calibration (OptiOdom's L) and ``mount`` a
misalignment that couples translation into the wheel's radial direction.
"""

from __future__ import annotations

import math

import numpy as np

from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.layout import WP_DX, WP_DY, WP_PX, WP_PY


class WheelGeometry(Effect):
    name = "wheel_geometry"
    summary = "per-wheel effective distance from the centre (the effective L) and mounting yaw"
    params = (
        Param("distance", "per_wheel", "(dimensionless, effective / nominal distance from the centre, per wheel)",
              0.5, 2.0, "", "per wheel; a contact point at half or twice the nominal distance is another robot",
              plausible=Range(0.95, 1.05, "an omni wheel's contact point moves by up to half a roller width "
                                          "between its rollers or rows (a few mm on a 0.2 m lever: 1-3 %); 5 % off "
                                          "is a wrong drawing, not an effective distance")),
        Param("mount", "per_wheel", "rad (yaw of the drive direction on its mount, counter-clockwise, per wheel)",
              -math.pi / 4, math.pi / 4, "rad",
              "per wheel; a wheel yawed by 45° is a different drive design (mecanum-like), not a misalignment",
              plausible=Range(-0.05, 0.05, "machined or printed motor mounts hold a wheel's yaw within about 1°; "
                                           "3° (0.05 rad) is visible by eye")),
    )
    recovery_sizes = {"small": {"distance": [1.0, 1.02, 1.0], "mount": [0.0, 0.0, 0.015]},
                      "large": {"distance": [1.0, 1.04, 0.99], "mount": [0.0, 0.0, 0.03]}}
    tolerances = {"distance": 0.01, "mount": 0.01}  # distance: scale; mount: rad

    def write_kernel(self, params, sp, wp, model) -> None:
        scale = np.asarray(params["distance"], dtype=float)
        wp[:, WP_PX] *= scale
        wp[:, WP_PY] *= scale
        yaw = np.asarray(params["mount"], dtype=float)
        c, s = np.cos(yaw), np.sin(yaw)
        dx, dy = wp[:, WP_DX].copy(), wp[:, WP_DY].copy()
        wp[:, WP_DX] = c * dx - s * dy
        wp[:, WP_DY] = s * dx + c * dy

    def fit_dims(self, model) -> tuple[Dim, ...]:
        n = model.n_wheels
        return (*[Dim(f"distance{i + 1}", 0.85, 1.15) for i in range(n)],
                *[Dim(f"mount{i + 1}", -0.1, 0.1) for i in range(n)])

    def from_fit(self, values, model) -> dict:
        n = model.n_wheels
        return {"distance": list(values[:n]), "mount": list(values[n:])}

    def null_fit(self, model) -> dict[str, float]:
        n = model.n_wheels
        return {**{f"distance{i + 1}": 1.0 for i in range(n)}, **{f"mount{i + 1}": 0.0 for i in range(n)}}

    def synth_default(self, model, rng) -> dict:
        n = model.n_wheels
        distance = np.ones(n)
        distance[1] = 1.04
        mount = np.zeros(n)
        mount[-1] = 0.03
        return {"distance": [float(v) for v in distance], "mount": [float(v) for v in mount]}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"distance": float(np.max(np.abs(np.asarray(fitted["distance"]) - truth["distance"]))),
                "mount": float(np.max(np.abs(np.asarray(fitted["mount"]) - truth["mount"])))}
