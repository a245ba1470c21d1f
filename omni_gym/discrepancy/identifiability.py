"""Identifiability: which parameters, and which combinations of them, the data determine.

At the final fit (every named effect at its all-run values) the open-loop residual vector r (every
observed pose component of every run, metres) is linearised in the fitted dimensions of all named
effects together (effects fitted one after another can trade against each other: per-wheel radius and
per-wheel distance enter the kinematics together). The Jacobian J = ∂r/∂u is taken by forward
differences in each dimension's unit coordinate u (its fit range mapped to [0, 1]), so the columns
are comparable. With J = U S Vᵀ (SVD) and tracker noise σ per component, the Gauss–Newton covariance
of u is σ² V S⁻² Vᵀ: the combination vₖ (a column of V) is known to ±σ/sₖ. A combination is
**identified** when its 95 % half-width 2σ/sₖ is at most :data:`IDENTIFIED` of the fit range; a
parameter is identified when its own standard error (the diagonal of the covariance) passes the same
test. Parameters whose correlation magnitude exceeds :data:`CONFOUNDED` are reported as confounded
pairs. A named value that is not identified is not a measurement: the report says so (its value is
only one point of a valley the data leave open), and gives the identified combinations instead.

Wheel lift-off (event-inferred, no Jacobian) is left out; its rates carry bootstrap intervals.
Periodic dimensions (roller phases) are differenced like the others (their wrap does not matter
locally).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.candidates import Candidate
from omni_gym.physics.model import SimModel

IDENTIFIED = 0.05  # largest 95 % half-width (share of the fit range) of an identified combination
CONFOUNDED = 0.9  # |correlation| above which two parameters are reported as confounded
STEP = 3e-3  # forward-difference step in the unit cube (the fits' own LM step)


@dataclass(frozen=True)
class Named:
    """One named effect of the final model: its candidate and its all-run fit in the unit cube."""

    candidate: Candidate
    u: np.ndarray


def _model(nominal: SimModel, named: list[Named], us: list[np.ndarray]) -> SimModel:
    m = nominal
    for n, u in zip(named, us, strict=True):
        m = m.with_effect(n.candidate.name, n.candidate.params(u))
    return m


def _stack(res: list[np.ndarray]) -> np.ndarray:
    """One vector of the finite residual components after each run's first row (as run_sse counts)."""
    return np.concatenate([r[1:][np.all(np.isfinite(r[1:]), axis=1)].ravel() for r in res])


def analyse(ev, nominal: SimModel, named: list[Named], sigma: float | None) -> dict | None:
    """The identifiability of the named effects' parameters (module docstring), or None when there is
    nothing to analyse (no deterministic named effect or no noise estimate).

    ``ev``: the workflow's :class:`~omni_gym.discrepancy.fitting.Evaluator`; ``sigma`` [m]: the noise
    floor per residual component. Costs one batch of 1 + (fitted dimensions) simulations of every run.
    """
    named = [n for n in named if not n.candidate.stochastic]
    if not named or sigma is None or sigma <= 0:
        return None
    base = [n.u.copy() for n in named]
    labels = [(n.candidate.name, d.name) for n in named for d in n.candidate.dims]
    models = [_model(nominal, named, base)]
    for i, n in enumerate(named):
        for j in range(n.candidate.n_params):
            us = [u.copy() for u in base]
            # step inwards at the upper bound, so the point stays in the fit range
            us[i][j] += STEP if us[i][j] + STEP <= 1.0 else -STEP
            models.append(_model(nominal, named, us))
    res = ev.residuals(models)
    r0 = _stack(res[0])
    signs = np.array([1.0 if u[j] + STEP <= 1.0 else -1.0 for u in base for j in range(len(u))])
    J = np.column_stack([(_stack(r) - r0) / (STEP * s) for r, s in zip(res[1:], signs, strict=True)])
    _, s, vt = np.linalg.svd(J, full_matrices=False)
    s_safe = np.maximum(s, 1e-300)
    half = 2.0 * sigma / s_safe  # 95 % half-width of each combination, unit-cube coordinates
    cov = (vt.T / s_safe**2) @ vt * sigma**2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = cov / np.maximum(np.outer(sd, sd), 1e-300)
    dims = [d for n in named for d in n.candidate.dims]
    params = []
    for k, ((eff, name), d) in enumerate(zip(labels, dims, strict=True)):
        u = float(np.concatenate(base)[k])
        params.append({"effect": eff, "param": name, "value": d.value(u),
                       "half_width_95": 2.0 * sd[k] * (d.hi - d.lo) if not d.log else None,
                       "half_width_95_range_share": float(2.0 * sd[k]),
                       "at_bound": bool(u <= 1e-3 or u >= 1.0 - 1e-3),
                       "identified": bool(2.0 * sd[k] <= IDENTIFIED)})
    combos = []
    for k in range(len(s)):
        v = vt[k] / np.max(np.abs(vt[k]))  # largest weight 1
        terms = [(f"{labels[j][1]}" if len(named) == 1 else f"{labels[j][0]}.{labels[j][1]}", float(v[j]))
                 for j in np.argsort(-np.abs(v)) if abs(v[j]) >= 0.1]
        combos.append({"combination": _combo_text(terms), "terms": terms,
                       "half_width_95_range_share": float(half[k]), "identified": bool(half[k] <= IDENTIFIED)})
    pairs = [{"a": f"{labels[i][0]}.{labels[i][1]}", "b": f"{labels[j][0]}.{labels[j][1]}",
              "correlation": float(corr[i, j])}
             for i in range(len(labels)) for j in range(i + 1, len(labels)) if abs(corr[i, j]) > CONFOUNDED]
    per_effect = {}
    for n in named:
        own = [p for p in params if p["effect"] == n.candidate.name]
        per_effect[n.candidate.name] = _effect_line(n.candidate.name, own, combos, len(named) == 1)
    return {"params": params, "combinations": combos, "confounded": pairs, "per_effect": per_effect,
            "n_identified": int(sum(c["identified"] for c in combos)), "n_params": len(labels),
            "note": (f"Gauss-Newton at the final fit: J = d(residual)/d(unit coordinate of each fitted dimension), "
                     f"SVD; a combination or parameter is identified when its 95 % half-width (2 sigma/s) is at "
                     f"most {IDENTIFIED:g} of its fit range (sigma = the noise floor {1e3 * sigma:.3g} mm); "
                     f"|correlation| > {CONFOUNDED:g}: confounded")}


def _combo_text(terms: list[tuple[str, float]]) -> str:
    out = ""
    for name, w in terms:
        sign = "-" if w < 0 else "+"
        mag = "" if math.isclose(abs(w), 1.0, abs_tol=0.005) else f"{abs(w):.2f}·"
        out += (f" {sign} " if out else ("-" if w < 0 else "")) + mag + name
    return out


def _effect_line(effect: str, own: list[dict], combos: list[dict], alone: bool) -> str:
    """One line: what the data pinned down of this effect and what they did not."""
    pinned = [p["param"] for p in own if p["identified"]]
    loose = [p["param"] + (" (at its fit bound)" if p["at_bound"] else "") for p in own if not p["identified"]]
    if not loose:
        return f"{effect}: every parameter pinned down ({', '.join(pinned)})"
    prefix = "" if alone else f"{effect}."
    # identified combinations that involve a loose parameter: what the data do determine instead
    names = {prefix + p["param"] for p in own if not p["identified"]}
    ident = [c["combination"] for c in combos if c["identified"] and any(t[0] in names for t in c["terms"])]
    text = f"{effect}: pinned down {', '.join(pinned) if pinned else 'no single parameter'}; not determined: " \
           + ", ".join(loose)
    if ident:
        text += "; determined instead: " + "; ".join(ident[:3])
    return text
