"""Random wheel lift-off: a seeded continuous-time Markov process over contact cases.

Phunopas & Inoue (2018), Table 2, list eight contact cases of a four-wheeled robot: all wheels down
(case 2), one wheel up (cases 3–6), a diagonal pair up (cases 7–8); case 1 (all up) is not used.
:func:`contact_cases` builds the same family for any n: all down, each single wheel up, and for even
n each diametrically opposite pair up.

The process sits in the all-down case until an exponential holding time with rate ``lift_rate``
[1/s] ends, then jumps to one of the lifted cases (uniformly); from a lifted case it returns to
all-down at rate ``recover_rate`` [1/s]. The stationary share of time with a wheel up is
lift_rate / (lift_rate + recover_rate).

Both rates lie in [0, :data:`RATE_MAX`]. A rate of 0 means that switch never happens: lift_rate = 0
keeps every wheel down; recover_rate = 0 (with lift_rate > 0) keeps a lifted wheel up until the next
reset. A switch that never happens has ``next_switch = inf``; a tiny rate may also give a finite but
astronomically late ``next_switch``, which the world treats as never (see
:meth:`omni_gym.physics.world.World._schedule_switch`).

:class:`ScheduledContactProcess` is the deterministic counterpart: it replays a fixed list of lift
events (the events inferred by :mod:`omni_gym.discrepancy.fit.events`) through the same interface.
"""

from __future__ import annotations

import math
from numbers import Real

import numpy as np

from omni_gym.bounds import RATE_MAX  # upper bound on lift_rate and recover_rate [1/s] (why: there)

OVERLAP_TOL = 1e-6  # s: scheduled events closer than this count as back to back (times are rounded to 1e-6 s)


def contact_cases(n: int) -> np.ndarray:
    """Contact masks (rows, True = touching) for an n-wheeled robot; row 0 is all wheels down."""
    cases = [np.ones(n, dtype=bool)]
    for i in range(n):
        m = np.ones(n, dtype=bool)
        m[i] = False
        cases.append(m)
    if n % 2 == 0 and n >= 4:
        for i in range(n // 2):
            m = np.ones(n, dtype=bool)
            m[i] = m[i + n // 2] = False
            cases.append(m)
    return np.array(cases)


# Phunopas & Inoue (2018) Table 2, cases 1..8 (W1..W4, 1 = touching), for documentation and tests.
PHUNOPAS_TABLE2 = np.array([
    [0, 0, 0, 0], [1, 1, 1, 1], [1, 1, 1, 0], [1, 0, 1, 1],
    [1, 1, 0, 1], [0, 1, 1, 1], [1, 0, 1, 0], [0, 1, 0, 1],
], dtype=bool)


class ContactProcess:
    """Seeded random contact mask over time for one robot.

    Args:
        n_wheels: number of wheels.
        lift_rate: rate [1/s] of leaving the all-down case, in [0, RATE_MAX] (0: never lifts).
        recover_rate: rate [1/s] of returning to all-down from a lifted case, in [0, RATE_MAX]
            (0: a lifted wheel stays up until the next reset).
        rng: the generator every draw comes from.
        cases: optional (k, n) bool array of allowed masks, row 0 all-down (default
            :func:`contact_cases`).
    """

    def __init__(self, n_wheels: int, lift_rate: float, recover_rate: float, rng: np.random.Generator,
                 cases: np.ndarray | None = None) -> None:
        self.lift_rate = check_rate("lift_rate", lift_rate)
        self.recover_rate = check_rate("recover_rate", recover_rate)
        self.cases = contact_cases(n_wheels) if cases is None else np.asarray(cases, dtype=bool)
        if self.cases.ndim != 2 or self.cases.shape[1] != n_wheels or not self.cases[0].all():
            raise ValueError("cases must be a (k, n_wheels) bool array whose first row is all True")
        self.rng = rng
        self.reset(0.0)

    def reset(self, t: float = 0.0) -> None:
        """All wheels down at time t [s]; draw the first switching time."""
        self.case = 0
        self.next_switch = self._draw_holding(t)

    @property
    def mask(self) -> np.ndarray:
        return self.cases[self.case]

    def _draw_holding(self, t: float) -> float:
        """Time [s] of the switch out of the current case entered at t [s]; +inf if it never comes."""
        rate = self.lift_rate if self.case == 0 else self.recover_rate
        if rate <= 0 or len(self.cases) == 1:
            return math.inf
        # 1/rate is +inf below ~5.6e-309 /s and the draw then inf (or NaN = 0·inf): both mean never.
        # The draw itself is the one this process has always made, so seeded sequences are unchanged.
        switch = t + self.rng.exponential(1.0 / rate)
        return switch if switch < math.inf else math.inf

    def advance(self, t: float) -> bool:
        """Apply every switch due at or before time t [s]; True if the mask changed.

        One iteration per switch: the loop runs about rate·(t − previous t) times, bounded because the
        rates are at most RATE_MAX; a switch that never comes (inf) ends it.
        """
        changed = False
        while self.next_switch <= t:
            switch_time = self.next_switch
            self.case = int(self.rng.integers(1, len(self.cases))) if self.case == 0 else 0
            self.next_switch = self._draw_holding(switch_time)
            changed = True
        return changed


class ScheduledContactProcess:
    """Contact mask that replays a fixed list of lift events (duck-types ContactProcess for the World).

    Args:
        n_wheels: number of wheels.
        events: (t_start, t_end, case) on the robot's local clock [s] (0 = its last reset),
            t_start < t_end, non-overlapping; case indexes ``cases`` (row 0 = all down is not a lift).
        cases: optional (k, n) bool masks, row 0 all down (default :func:`contact_cases`).
    """

    def __init__(self, n_wheels: int, events: list[tuple[float, float, int]] | tuple[tuple[float, float, int], ...],
                 cases: np.ndarray | None = None) -> None:
        self.cases = contact_cases(n_wheels) if cases is None else np.asarray(cases, dtype=bool)
        evs = sorted((float(a), float(b), int(c)) for a, b, c in events)
        for i, (a, b, c) in enumerate(evs):
            if not (math.isfinite(a) and math.isfinite(b) and a < b):
                raise ValueError(f"event {i}: need finite t_start < t_end [s], got ({a}, {b})")
            if not 1 <= c < len(self.cases):
                raise ValueError(f"event {i}: case must be in 1..{len(self.cases) - 1}, got {c}")
            if i and a < evs[i - 1][1]:
                if a < evs[i - 1][1] - OVERLAP_TOL:
                    raise ValueError(f"events overlap at {a} s")
                # Back-to-back events whose times were rounded differently (1e-6 s): one ends, the next starts.
                evs[i] = (evs[i - 1][1], b, c)
        self.events = evs
        # Switch list: (time, case after the switch).
        self._switches = [s for a, b, c in evs for s in ((a, c), (b, 0))]
        self.reset(0.0)

    def reset(self, t: float = 0.0) -> None:
        """All wheels down; the schedule restarts (its times are on the clock this reset zeroes)."""
        self.case = 0
        self._i = 0
        self.next_switch = self._switches[0][0] if self._switches else math.inf

    @property
    def mask(self) -> np.ndarray:
        return self.cases[self.case]

    def advance(self, t: float) -> bool:
        """Apply every scheduled switch at or before time t [s]; True if the mask changed."""
        changed = False
        while self.next_switch <= t:
            new = self._switches[self._i][1]
            changed |= new != self.case
            self.case = new
            self._i += 1
            self.next_switch = self._switches[self._i][0] if self._i < len(self._switches) else math.inf
        return changed


def check_rate(name: str, value: float) -> float:
    """``value`` as a float rate [1/s] in [0, RATE_MAX]; ValueError naming ``name`` otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Real):
        raise ValueError(f"{name} must be a number [1/s], got {value!r}")
    try:
        rate = float(value)
    except OverflowError:  # an int beyond the float range
        rate = math.inf
    if not 0.0 <= rate <= RATE_MAX:  # also refuses NaN
        raise ValueError(f"{name} must be in [0, {RATE_MAX:g}] [1/s], got {value!r}")
    return rate + 0.0  # -0.0 -> 0.0
