"""Random wheel lift-off: a seeded continuous-time Markov process over contact cases.

Phunopas & Inoue (2018), Table 2, list eight contact cases of a four-wheeled robot: all wheels down
(case 2), one wheel up (cases 3–6), a diagonal pair up (cases 7–8); case 1 (all up) is not used.
:func:`contact_cases` builds the same family for any n: all down, each single wheel up, and for even
n each diametrically opposite pair up.

The process sits in the all-down case until an exponential holding time with rate ``lift_rate``
[1/s] ends, then jumps to one of the lifted cases (uniformly); from a lifted case it returns to
all-down at rate ``recover_rate`` [1/s]. The stationary share of time with a wheel up is
lift_rate / (lift_rate + recover_rate).
"""

from __future__ import annotations

import numpy as np


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
        lift_rate: rate [1/s] of leaving the all-down case (0 disables lift-off).
        recover_rate: rate [1/s] of returning to all-down from a lifted case.
        rng: the generator every draw comes from.
        cases: optional (k, n) bool array of allowed masks, row 0 all-down (default
            :func:`contact_cases`).
    """

    def __init__(self, n_wheels: int, lift_rate: float, recover_rate: float, rng: np.random.Generator,
                 cases: np.ndarray | None = None) -> None:
        if not (np.isfinite(lift_rate) and lift_rate >= 0):
            raise ValueError(f"lift_rate must be a finite rate >= 0 [1/s], got {lift_rate}")
        if not (np.isfinite(recover_rate) and recover_rate > 0):
            raise ValueError(f"recover_rate must be a finite rate > 0 [1/s], got {recover_rate}")
        self.cases = contact_cases(n_wheels) if cases is None else np.asarray(cases, dtype=bool)
        if self.cases.ndim != 2 or self.cases.shape[1] != n_wheels or not self.cases[0].all():
            raise ValueError("cases must be a (k, n_wheels) bool array whose first row is all True")
        self.lift_rate = float(lift_rate)
        self.recover_rate = float(recover_rate)
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
        rate = self.lift_rate if self.case == 0 else self.recover_rate
        if rate <= 0 or len(self.cases) == 1:
            return np.inf
        return t + self.rng.exponential(1.0 / rate)

    def advance(self, t: float) -> bool:
        """Apply every switch due at or before time t [s]; True if the mask changed."""
        changed = False
        while self.next_switch <= t:
            switch_time = self.next_switch
            self.case = int(self.rng.integers(1, len(self.cases))) if self.case == 0 else 0
            self.next_switch = self._draw_holding(switch_time)
            changed = True
        return changed
