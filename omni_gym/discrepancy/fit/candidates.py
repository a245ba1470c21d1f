"""The effect library as fit candidates: each effect's fitted dimensions, their bounds and the null point.

Every registered effect (:data:`omni_gym.physics.effects.REGISTRY`, in its order) is one candidate;
the dimensions, the map from their values to the effect's parameters, the null point and an optional
prior start are the effect's own (its module in ``omni_gym/physics/effects/``).

A candidate's parameters live in the unit cube [0, 1]^p: :meth:`Dim.value` maps a coordinate to the
parameter's bounds (log-spaced or linear; periodic dimensions wrap). :func:`null_point` is the point at
which an effect changes nothing (a fit that includes it is never worse than nominal on its training runs).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from omni_gym.physics.effects import REGISTRY, Dim, Effect
from omni_gym.physics.model import SimModel

__all__ = ["Candidate", "Dim", "candidates", "not_applicable", "null_point", "prior_point", "to_cube"]


@dataclass(frozen=True)
class Candidate:
    """A library effect with its fitted dimensions and how they map to the effect's parameters.

    ``null`` and ``prior``: dimension values (by :attr:`Dim.name`) of the null point and of an extra
    start, from the effect (None: it has none); dimensions they leave out sit mid-range.
    """

    name: str
    dims: tuple[Dim, ...]
    build: Callable[[list[float]], dict]
    stochastic: bool = False
    null: dict[str, float] | None = None
    prior: dict[str, float] | None = None

    @property
    def n_params(self) -> int:
        return len(self.dims)

    def params(self, u: np.ndarray) -> dict:
        return self.build([d.value(float(x)) for d, x in zip(self.dims, u, strict=True)])

    def point(self, values: dict[str, float]) -> np.ndarray:
        """Unit-cube point with the given dimension values (others 0.5), clipped to the cube."""
        u = np.full(self.n_params, 0.5)
        for j, d in enumerate(self.dims):
            if d.name in values:
                u[j] = d.unit(values[d.name])
        return np.clip(u, 0.0, 1.0)


@dataclass(frozen=True)
class _FromFit:
    """``build`` of a library candidate: the effect's parameters from dimension values on ``model``
    (a picklable callable, so a candidate and its fit travel to worker processes, omni_gym.parallel)."""

    effect: Effect
    model: SimModel

    def __call__(self, values: list[float]) -> dict:
        return self.effect.from_fit(values, self.model)


def _candidate(effect: Effect, model: SimModel) -> Candidate:
    return Candidate(effect.name, effect.fit_dims(model), _FromFit(effect, model),
                     stochastic=effect.stochastic, null=effect.null_fit(model), prior=effect.prior_fit(model))


def candidates(model: SimModel) -> list[Candidate]:
    """The effect library as fit candidates for ``model`` (bounds wide enough for real robots): every
    effect that applies to its robot (:meth:`Effect.applies_to`; e.g. ``roller_gap`` not on mecanum
    wheels), in the library's order."""
    return [_candidate(effect, model) for effect in REGISTRY.values() if effect.applies_to(model.robot)]


def not_applicable(model: SimModel) -> dict[str, str]:
    """The library effects :func:`candidates` leaves out for ``model``: name → the effect's one-line reason."""
    out = {}
    for effect in REGISTRY.values():
        try:
            effect.check_robot(model.robot)
        except ValueError as exc:
            out[effect.name] = str(exc)
    return out


def null_point(cand: Candidate) -> np.ndarray | None:
    """Unit-cube point at which the effect changes nothing for the model the candidate was made for
    (:func:`candidates`); None when the family has none."""
    return None if cand.null is None else cand.point(cand.null)


def prior_point(cand: Candidate) -> np.ndarray | None:
    """Unit-cube point of the effect's extra start (roller_gap: the nominal μ'' and roller share), or None."""
    return None if cand.prior is None else cand.point(cand.prior)


def to_cube(cand: Candidate, u: np.ndarray) -> np.ndarray:
    """``u`` moved into the unit cube: periodic dimensions wrapped, the others clipped (a copy)."""
    out = u.copy()
    for j, d in enumerate(cand.dims):
        out[j] = np.mod(out[j], 1.0) if d.periodic else np.clip(out[j], 0.0, 1.0)
    return out
