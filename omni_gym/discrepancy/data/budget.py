"""The fit budget of ``omni-gym gap`` and the segment length it gives (:mod:`omni_gym.discrepancy.data.segments`).

Kept apart from the segmenting itself so that the command line can show and check them without loading the
workflow (numba, the physics): ``omni-gym gap --help`` prints these numbers.
"""

from __future__ import annotations

FIT_BUDGET = 120.0  # s of robot time fitted at most (``gap --fit-budget``)
SEGMENT = 10.0  # s: longest segment (long enough for geometry and slip errors to grow well above tracker noise)
MIN_SEGMENT = 3.0  # s: shortest segment, however many runs share the budget
# s: smallest budget: one shortest segment from each of 2 runs (held-out scoring needs 2 source runs)
MIN_FIT_BUDGET = 2 * MIN_SEGMENT


def check_fit_budget(budget: float, name: str = "fit_budget") -> None:
    """Refuse a fit budget [s] below :data:`MIN_FIT_BUDGET` (or not a number); ``inf``: whole runs always.
    ``name``: how the caller spells it in the message (``--fit-budget`` on the command line)."""
    if isinstance(budget, bool) or not isinstance(budget, (int, float)) or not budget >= MIN_FIT_BUDGET:
        raise ValueError(f"{name} must be at least {MIN_FIT_BUDGET:g} s (a {MIN_SEGMENT:g} s segment, the shortest, "
                         f"from each of 2 runs) or inf (always whole runs), got {budget!r}")


def segment_seconds(budget: float, runs: int, segment: float = SEGMENT) -> float:
    """Segment length [s] for ``runs`` runs sharing ``budget`` s: budget / runs within [MIN_SEGMENT, segment]."""
    return float(min(segment, max(MIN_SEGMENT, budget / runs)))
