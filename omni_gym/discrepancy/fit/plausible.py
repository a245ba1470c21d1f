"""Units and plausible ranges of the effect library's parameters (flagging only: fits are not changed).

The fit bounds (each effect's ``fit_dims``) are deliberately wide (a search must be able to reach a
value to show it is wrong). A fitted value can lie inside them and still be physically odd; such a
value usually means the effect absorbed some other error, or the nominal model is off elsewhere.
:func:`check` lists the fitted values outside the ranges; the report, ``result.json``
(``plausibility``) and the CLI summary show them. The ranges, each with why, live with their effects
(:mod:`omni_gym.physics.effects`; also in ``docs/discrepancy.md``).
"""

from __future__ import annotations

from omni_gym.physics.effects import REGISTRY, Flag, Range
from omni_gym.physics.model import SimModel

# Effect → parameter → unit and meaning, as the report and the CLI print them.
UNITS: dict[str, dict[str, str]] = {name: {p.key: p.unit for p in e.params} for name, e in REGISTRY.items()}
# Effect → parameter → plausible range (effects judged only by derived quantities have none here).
RANGES: dict[str, dict[str, Range]] = {name: e.plausible_ranges() for name, e in REGISTRY.items()
                                       if e.plausible_ranges()}

__all__ = ["RANGES", "UNITS", "Flag", "Range", "check", "ranges_json"]


def check(effect: str, params: dict, model: SimModel) -> list[Flag]:
    """Flags for the fitted ``params`` of ``effect`` on the nominal ``model`` (empty: all plausible)."""
    return REGISTRY[effect].flags(params, model) if effect in REGISTRY else []


def ranges_json() -> dict:
    """The plausible ranges for ``result.json`` (effect → parameter → [lo, hi, why]): per-parameter
    ranges first, then the ranges of derived quantities (``com_offset``'s least wheel load share)."""
    out = {e: {k: [r.lo, r.hi, r.why] for k, r in d.items()} for e, d in RANGES.items()}
    for name, effect in REGISTRY.items():
        extra = effect.extra_ranges()
        if extra:
            out.setdefault(name, {}).update({k: [r.lo, r.hi, r.why] for k, r in extra.items()})
    return out
