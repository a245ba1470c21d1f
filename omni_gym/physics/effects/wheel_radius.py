"""``wheel_radius``: each wheel's effective rolling radius is ``scale`` times the nominal one."""

from __future__ import annotations

import numpy as np

from omni_gym.physics.effects.base import Dim, Effect, Param, Range
from omni_gym.physics.layout import WP_R


class WheelRadius(Effect):
    name = "wheel_radius"
    summary = "per-wheel effective rolling radius, as a scale of the nominal radius"
    params = (
        Param("scale", "per_wheel", "(dimensionless, effective / nominal radius, per wheel)", 0.5, 2.0, "",
              "per wheel; a wheel whose rolling radius differs by a factor 2 from its nominal radius is another wheel",
              plausible=Range(0.95, 1.05, "tyre or roller wear and compression change an effective rolling radius "
                                          "by a few per cent; 5 % off (2.5 mm on a 50 mm wheel) is a wrong wheel")),
    )
    recovery_sizes = {"small": {"scale": [1.0, 0.97, 1.0]}, "large": {"scale": [1.0, 0.94, 1.02]}}
    tolerances = {"scale": 0.01}

    def write_kernel(self, params, sp, wp, model) -> None:
        wp[:, WP_R] *= np.asarray(params["scale"], dtype=float)  # in place: mecanum_lateral scales it too

    def fit_dims(self, model) -> tuple[Dim, ...]:
        return tuple(Dim(f"scale{i + 1}", 0.85, 1.15) for i in range(model.n_wheels))

    def from_fit(self, values, model) -> dict:
        return {"scale": list(values)}

    def null_fit(self, model) -> dict[str, float]:
        return {d.name: 1.0 for d in self.fit_dims(model)}

    def synth_default(self, model, rng) -> dict:
        scale = np.ones(model.n_wheels)
        scale[1] = 0.95
        return {"scale": [float(v) for v in scale]}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"scale": float(np.max(np.abs(np.asarray(fitted["scale"]) - truth["scale"])))}
