"""``com_offset``: the centre of mass sits at ``com`` [m] (body frame) instead of the nominal one.

It moves the wheel loads (static balance, :mod:`omni_gym.physics.loads`) and the point the body
rotates about. Judged plausible by the loads it leaves, not by a range of coordinates: that relates
the offset to the wheelbase whatever the wheel layout.
"""

from __future__ import annotations

import numpy as np

from omni_gym.physics.effects.base import Dim, Effect, Flag, Param, Range
from omni_gym.physics.layout import SP_CX, SP_CY
from omni_gym.physics.loads import static_loads

MIN_LOAD_SHARE = 1.0 / 3.0
LOAD_SHARE_WHY = ("a centre of mass that leaves a wheel less than a third of its equal load share is a large fraction "
                  "of the support polygon (for three wheels at distance L, an offset of L/3 away from a wheel): a "
                  "chassis that close to unloading a wheel is seen on the bench, not found in a fit")
LOAD_SHARE = "least wheel load share"


class ComOffset(Effect):
    name = "com_offset"
    summary = "centre of mass away from the geometric centre (moves wheel loads and the rotation point)"
    params = (
        Param("com", "xy", "m (x, y of the centre of mass, body frame)", -10.0, 10.0, "m",
              "each coordinate, as com"),
    )
    recovery_sizes = {"small": {"com": [0.008, -0.005]}, "large": {"com": [0.015, -0.01]}}
    tolerances = {"com": 0.002}  # m

    def write_kernel(self, params, sp, wp, model) -> None:
        sp[SP_CX], sp[SP_CY] = np.asarray(params["com"], dtype=float)

    def fit_dims(self, model) -> tuple[Dim, ...]:
        lever = model.robot.lever()
        c = 0.4 * lever  # the centre of mass well inside the support polygon
        return (Dim("cx", -c, c), Dim("cy", -c, c))

    def from_fit(self, values, model) -> dict:
        return {"com": [values[0], values[1]]}

    def null_fit(self, model) -> dict[str, float]:
        com = model.com  # the model's centre of mass as it stands (nominal, or already offset)
        return {"cx": float(com[0]), "cy": float(com[1])}

    def synth_default(self, model, rng) -> dict:
        return {"com": [0.015, -0.01]}

    def param_error(self, truth, fitted, model) -> dict[str, float]:
        return {"com": float(np.hypot(*(np.asarray(fitted["com"]) - truth["com"])))}

    def extra_ranges(self) -> dict[str, Range]:
        return {LOAD_SHARE: Range(MIN_LOAD_SHARE, 1.0, LOAD_SHARE_WHY)}

    def extra_flags(self, params, model) -> list[Flag]:
        """Flag a centre of mass that leaves some wheel less than MIN_LOAD_SHARE of its equal share."""
        if "com" not in params:
            return []
        com = params["com"]
        r = model.robot
        loads = static_loads(r.positions(), np.asarray(com, dtype=float), r.mass, model.gravity)
        share = float(np.min(loads) / (r.mass * model.gravity / r.n_wheels))
        if share >= MIN_LOAD_SHARE:
            return []
        lever = r.lever()
        why = f"{LOAD_SHARE_WHY}; |com| = {float(np.hypot(*com)) / lever:.2f} of the lever {lever:.3f} m"
        return [Flag(self.name, LOAD_SHARE, share, MIN_LOAD_SHARE, 1.0, why)]
