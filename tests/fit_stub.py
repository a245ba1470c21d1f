"""A held-out fit as :func:`omni_gym.discrepancy.decide.decision.decide` reads it (its ``HeldOutFit`` protocol), for
tests that check the decision on made-up per-run errors."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.fit.candidates import Candidate


@dataclass
class FitStub:
    candidate: Candidate
    params_all: dict
    heldout: np.ndarray  # (R,) per-run held-out SSE [m²]
    n_params_eff: int | None = None
