"""Units and plausible ranges of the effect library's parameters (flagging only: fits are not changed).

The fit bounds of ``explain.candidates`` are deliberately wide (a search must be able to reach a
value to show it is wrong). A fitted value can lie inside them and still be physically odd; such a
value usually means the effect absorbed some other error, or the nominal model is off elsewhere.
:func:`check` lists the fitted values outside the ranges below; the report, ``result.json``
(``plausibility``) and the CLI summary show them. Each range says why (also in ``docs/discrepancy.md``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from omni_gym.physics.loads import static_loads
from omni_gym.physics.model import SimModel

# Effect → parameter → unit (every key of model.EFFECT_PARAMS).
UNITS: dict[str, dict[str, str]] = {
    "roller_gap": {"mu_gap": "(dimensionless friction coefficient)",
                   "roller_fraction": "(dimensionless share of the roller pitch covered by roller)",
                   "phase": "rad (per wheel, within one roller pitch)"},
    "kinetic_friction": {"ratio": "(dimensionless, mu_kinetic / mu_static)", "v_s": "m/s (Stribeck velocity)"},
    "com_offset": {"com": "m (x, y of the centre of mass, body frame)"},
    "wheel_radius": {"scale": "(dimensionless, effective / nominal radius, per wheel)"},
    "motor_lag": {"tau": "s (first-order time constant)"},
    "wheel_liftoff": {"lift_rate": "1/s (rate of lifting a wheel from all-down)",
                      "recover_rate": "1/s (rate of setting it down again)"},
}


@dataclass(frozen=True)
class Range:
    """Plausible closed interval [lo, hi] of a parameter (per element for per-wheel lists) and why."""

    lo: float
    hi: float
    why: str


RANGES: dict[str, dict[str, Range]] = {
    "roller_gap": {
        "mu_gap": Range(0.1, 1.0, "dry friction of the rigid hub/frame material (metal, hard plastic) on a floor is "
                                  "0.2-0.8 in engineering tables; Williams et al. (2002) measured 0.47 (paper) and "
                                  "0.56 (carpet); above 1 needs rubber or adhesion, which rigid material is not"),
        "roller_fraction": Range(0.7, 1.0, "rollers cover most of the rim of a working omni wheel (0.9 for the "
                                           "Williams wheel); below 0.7 the wheel rides on rigid material for more "
                                           "than 30 % of a turn, a bump that is plain to see and hear"),
    },
    "kinetic_friction": {
        "ratio": Range(0.5, 1.0, "mu_kinetic / mu_static of dry contacts (rubber, plastic, metal on floors) is "
                                 "0.5-1 in friction tables; above 1 is not a Stribeck drop at all"),
        "v_s": Range(0.001, 0.1, "Stribeck velocities of dry and boundary-lubricated contacts are 1e-3 to 1e-1 m/s "
                                 "(Armstrong-Helouvry et al., Automatica 1994)"),
    },
    "wheel_radius": {
        "scale": Range(0.95, 1.05, "tyre or roller wear and compression change an effective rolling radius by a "
                                   "few per cent; 5 % off (2.5 mm on a 50 mm wheel) is a wrong wheel"),
    },
    "motor_lag": {
        "tau": Range(0.0, 0.2, "small geared DC drives under speed control reach a set speed within 200 ms "
                               "(mechanical time constant of the motor with the reflected wheel inertia, a few "
                               "to 100 ms); 0 is the ideal actuator of the nominal model"),
    },
    "wheel_liftoff": {
        "lift_rate": Range(0.0, 2.0, "more than two lifts per second on a floor is chatter (a suspension or a "
                                     "rocking chassis), not the occasional lift-off of Phunopas & Inoue (2018); "
                                     "the library's environments use 0.5/s"),
        "recover_rate": Range(1.0, 20.0, "mean lifted durations of 50 ms-1 s: shorter lifts do not move the pose "
                                         "beyond tracker noise, a wheel up for longer than 1 s is a persistent "
                                         "unloading (a centre-of-mass offset), not a lift"),
    },
}
# com_offset is judged by its effect on the wheel loads (static balance, omni_gym.physics.loads), which
# relates the offset to the wheelbase whatever the wheel layout.
COM_MIN_LOAD_SHARE = 1.0 / 3.0
COM_WHY = ("a centre of mass that leaves a wheel less than a third of its equal load share is a large fraction of "
           "the support polygon (for three wheels at distance L, an offset of L/3 away from a wheel): a chassis "
           "that close to unloading a wheel is seen on the bench, not found in a fit")


@dataclass(frozen=True)
class Flag:
    """A fitted value outside its plausible range (``value``: the offending element for lists)."""

    effect: str
    param: str
    value: float
    lo: float
    hi: float
    why: str

    def to_json(self) -> dict:
        return asdict(self)

    def text(self) -> str:
        return f"{self.param} = {self.value:.4g} outside the plausible [{self.lo:.4g}, {self.hi:.4g}]"


def check(effect: str, params: dict, model: SimModel) -> list[Flag]:
    """Flags for the fitted ``params`` of ``effect`` on the nominal ``model`` (empty: all plausible)."""
    flags = []
    if effect == "com_offset" and "com" in params:
        flags += _check_com(params["com"], model)
    for key, rng in RANGES.get(effect, {}).items():
        values = params.get(key)
        if values is None:
            continue
        items = list(enumerate(values, start=1)) if isinstance(values, list) else [(None, values)]
        for i, v in items:
            v = float(v)
            if not (math.isfinite(v) and rng.lo <= v <= rng.hi):
                name = key if i is None else f"{key}[{i}]"
                flags.append(Flag(effect, name, v, rng.lo, rng.hi, rng.why))
    return flags


def _check_com(com: list, model: SimModel) -> list[Flag]:
    """Flag a centre of mass that leaves some wheel less than COM_MIN_LOAD_SHARE of its equal share."""
    r = model.robot
    loads = static_loads(r.positions(), np.asarray(com, dtype=float), r.mass, model.gravity)
    share = float(np.min(loads) / (r.mass * model.gravity / r.n_wheels))
    if share >= COM_MIN_LOAD_SHARE:
        return []
    lever = float(np.max(np.hypot(*r.positions().T)))
    why = f"{COM_WHY}; |com| = {float(np.hypot(*com)) / lever:.2f} of the lever {lever:.3f} m"
    return [Flag("com_offset", "least wheel load share", share, COM_MIN_LOAD_SHARE, 1.0, why)]


def ranges_json() -> dict:
    """The plausible ranges for ``result.json`` (effect → parameter → [lo, hi, why])."""
    out = {e: {k: [r.lo, r.hi, r.why] for k, r in d.items()} for e, d in RANGES.items()}
    out["com_offset"] = {"least wheel load share": [COM_MIN_LOAD_SHARE, 1.0, COM_WHY]}
    return out
