"""Identifiability: which parameters, and which combinations of them, the data determine.

At the final fit (every named effect at its all-run values) the open-loop residual vector r (every
observed pose component of every run, metres) is linearised in the fitted dimensions of all named
effects together (effects fitted one after another can trade against each other: per-wheel radius and
per-wheel distance enter the kinematics together). The Jacobian J = ∂r/∂u is taken by forward
differences in each dimension's unit coordinate u (its fit range mapped to [0, 1]), so the columns
are comparable. With J = U S Vᵀ (SVD) and σ_eff per component, the Gauss–Newton covariance of u is
σ_eff² V S⁻² Vᵀ: the combination vₖ (a column of V) is known to ±σ_eff/sₖ. σ_eff is the noise floor
when the fit leaves white noise; on real data the fit leaves model error, larger and correlated over
many rows, so σ_eff = max(floor, RMS left)·sqrt(τ), τ the residual's integrated autocorrelation time
in rows (:func:`autocorrelation_time`). A combination is
**identified** when its 95 % half-width 2σ/sₖ is at most ``identified`` (settings) of the fit range; a
parameter is identified when its own standard error (the diagonal of the covariance) passes the same
test. Parameters whose correlation magnitude exceeds ``confounded`` are reported as confounded
pairs. A value at its fit bound is never a measurement (the fit wants a value beyond the range: it
compensates another error). A named value that is not identified is not a measurement either: the
report says so (its value is only one point of a valley the data leave open), and gives the identified
combinations instead.

Wheel lift-off (event-inferred, no Jacobian) is left out; its rates carry bootstrap intervals.
Periodic dimensions (roller phases) are differenced like the others (their wrap does not matter
locally).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.fit.candidates import Candidate
from omni_gym.discrepancy.settings import IdentifiabilitySettings
from omni_gym.physics.model import SimModel

# The thresholds (identified, confounded, step, bound, merge_weight) are the fields of
# settings.IdentifiabilitySettings, recorded in result.json (settings.identifiability); a Linearisation carries them.


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


@dataclass(frozen=True)
class Linearisation:
    """The final fit linearised in every named deterministic effect's fitted dimensions.

    ``base``: per named effect its unit-cube point u*; ``r0``: the stacked residual there [m]
    (:func:`_stack`); ``J`` = d r / d u (rows of ``r0`` × dimensions); ``s``, ``vt``: its SVD;
    ``half``: 95 % half-width of each combination (row of ``vt``) and ``sd``: standard error of each
    dimension, both in unit-cube coordinates; ``sigma``: the noise floor [m]; ``sigma_eff`` [m], ``rms``
    [m] and ``tau`` [rows]: the inflated noise (module docstring)."""

    named: list[Named]
    base: list[np.ndarray]
    r0: np.ndarray
    J: np.ndarray
    s: np.ndarray
    vt: np.ndarray
    half: np.ndarray
    sd: np.ndarray
    corr: np.ndarray
    sigma: float
    sigma_eff: float
    rms: float
    tau: float
    cfg: IdentifiabilitySettings = IdentifiabilitySettings()

    @property
    def labels(self) -> list[tuple[str, str]]:
        """(effect, dimension name) of every column of ``J``."""
        return [(n.candidate.name, d.name) for n in self.named for d in n.candidate.dims]

    @property
    def dims(self) -> list:
        return [d for n in self.named for d in n.candidate.dims]

    @property
    def u(self) -> np.ndarray:
        """u* of all named effects, concatenated."""
        return np.concatenate(self.base)

    @property
    def own_identified(self) -> np.ndarray:
        """(dimensions,) True where the parameter's own 95 % half-width (2 sd) is within ``cfg.identified``."""
        return 2.0 * self.sd <= self.cfg.identified

    @property
    def identified(self) -> np.ndarray:
        """(combinations,) True where the combination's 95 % half-width is within ``cfg.identified``."""
        return self.half <= self.cfg.identified

    def at_bound(self) -> np.ndarray:
        """(dimensions,) True where u* sits at its fit bound (never for a periodic dimension)."""
        u = self.u
        b = self.cfg.bound
        return np.array([not d.periodic and bool(x <= b or x >= 1.0 - b) for d, x in zip(self.dims, u,
                                                                                                   strict=True)])


def linearise(ev, nominal: SimModel, named: list[Named], sigma: float | None,
              cfg: IdentifiabilitySettings | None = None) -> Linearisation | None:
    """Linearise the final fit (module docstring); None when there is nothing to analyse (no
    deterministic named effect or no noise estimate).

    ``ev``: the workflow's :class:`~omni_gym.discrepancy.fit.fitting.Evaluator`; ``sigma`` [m]: the noise
    floor per residual component; ``cfg``: the thresholds (None: the defaults), carried by the result.
    Costs one batch of 1 + (fitted dimensions) simulations of every run.
    """
    cfg = IdentifiabilitySettings() if cfg is None else cfg
    step = cfg.step
    named = [n for n in named if not n.candidate.stochastic]
    if not named or sigma is None or sigma <= 0:
        return None
    base = [n.u.copy() for n in named]
    models = [_model(nominal, named, base)]
    for i, n in enumerate(named):
        for j in range(n.candidate.n_params):
            us = [u.copy() for u in base]
            # step inwards at the upper bound, so the point stays in the fit range
            us[i][j] += step if us[i][j] + step <= 1.0 else -step
            models.append(_model(nominal, named, us))
    res = ev.residuals(models)
    r0 = _stack(res[0])
    # What the fit leaves is white tracker noise only if the model is right. On real data it is mostly
    # model error: larger than σ and correlated over many rows, so the data hold fewer independent
    # samples than rows. The covariance is inflated by (RMS left / σ)² · τ, τ the residual's integrated
    # autocorrelation time in rows (1 for white noise): a Gauss-Newton interval with the tracker's σ
    # would call every parameter of a real-robot fit "pinned down" (omni3: ±0.3 % of the range).
    rms = float(np.sqrt(np.mean(r0**2))) if r0.size else sigma
    tau = autocorrelation_time(res[0])
    sigma_eff = max(sigma, rms) * math.sqrt(tau)
    signs = np.array([1.0 if u[j] + step <= 1.0 else -1.0 for u in base for j in range(len(u))])
    J = np.column_stack([(_stack(r) - r0) / (step * s) for r, s in zip(res[1:], signs, strict=True)])
    _, s, vt = np.linalg.svd(J, full_matrices=False)
    # An exactly flat direction (a dimension that changes nothing) would give 1/0: floor s far below the
    # largest, so the covariance stays finite (that direction's interval is then simply huge).
    s_safe = np.maximum(s, max(1e-9 * float(s[0]) if s.size else 0.0, 1e-300))
    half = 2.0 * sigma_eff / s_safe  # 95 % half-width of each combination, unit-cube coordinates
    cov = (vt.T / s_safe**2) @ vt * sigma_eff**2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = cov / np.maximum(np.outer(sd, sd), 1e-300)
    return Linearisation(named=named, base=base, r0=r0, J=J, s=s, vt=vt, half=half, sd=sd, corr=corr, sigma=sigma,
                         sigma_eff=sigma_eff, rms=rms, tau=tau, cfg=cfg)


def analyse(ev, nominal: SimModel, named: list[Named], sigma: float | None) -> dict | None:
    """The identifiability of the named effects' parameters (module docstring) as JSON, or None when there
    is nothing to analyse: :func:`summary` of :func:`linearise`."""
    lin = linearise(ev, nominal, named, sigma)
    return None if lin is None else summary(lin)


def combination_text(lin: Linearisation, k: int) -> tuple[str, list[tuple[str, float]]]:
    """Combination k (row of ``vt``, largest weight 1) as text and its [name, weight] terms (|weight| >= 0.1)."""
    labels = lin.labels
    alone = len(lin.named) == 1
    v = lin.vt[k] / np.max(np.abs(lin.vt[k]))
    terms = [(f"{labels[j][1]}" if alone else f"{labels[j][0]}.{labels[j][1]}", float(v[j]))
             for j in np.argsort(-np.abs(v)) if abs(v[j]) >= lin.cfg.merge_weight]
    return _combo_text(terms), terms


def summary(lin: Linearisation, used: dict | None = None) -> dict:
    """The JSON of ``result.json``'s ``identifiability``: per parameter, combinations, confounded pairs and
    one line per effect. ``used``: what the identified refit did (:func:`omni_gym.discrepancy.fit.identified_fit.
    refit`'s per-effect status); the lines then say which parameters were fixed or merged."""
    labels, dims, sd, half = lin.labels, lin.dims, lin.sd, lin.half
    u_all = lin.u
    bound = lin.at_bound()
    params = []
    for k, ((eff, name), d) in enumerate(zip(labels, dims, strict=True)):
        params.append({"effect": eff, "param": name, "value": d.value(float(u_all[k])),
                       "half_width_95": 2.0 * sd[k] * (d.hi - d.lo) if not d.log else None,
                       "half_width_95_range_share": float(2.0 * sd[k]),
                       "at_bound": bool(bound[k]),
                       "identified": bool(2.0 * sd[k] <= lin.cfg.identified)})
    combos = []
    for k in range(len(lin.s)):
        text, terms = combination_text(lin, k)
        combos.append({"combination": text, "terms": terms,
                       "half_width_95_range_share": float(half[k]), "identified": bool(half[k] <= lin.cfg.identified)})
    corr = lin.corr
    pairs = [{"a": f"{labels[i][0]}.{labels[i][1]}", "b": f"{labels[j][0]}.{labels[j][1]}",
              "correlation": float(corr[i, j])}
             for i in range(len(labels)) for j in range(i + 1, len(labels)) if abs(corr[i, j]) > lin.cfg.confounded]
    per_effect = {}
    for n in lin.named:
        own = [p for p in params if p["effect"] == n.candidate.name]
        status = None if used is None else used.get(n.candidate.name)
        per_effect[n.candidate.name] = (_effect_line(n.candidate.name, own, combos, len(lin.named) == 1)
                                        if status is None else status["line"])
    sigma, rms, tau = lin.sigma, lin.rms, lin.tau
    return {"params": params, "combinations": combos, "confounded": pairs, "per_effect": per_effect,
            "n_identified": int(sum(c["identified"] for c in combos)), "n_params": len(labels),
            "sigma_eff": lin.sigma_eff, "rms_left": rms, "autocorrelation_rows": tau,
            "note": (f"Gauss-Newton at the final fit: J = d(residual)/d(unit coordinate of each fitted dimension), "
                     f"SVD; a combination or parameter is identified when its 95 % half-width (2 sigma_eff/s) is "
                     f"at most {lin.cfg.identified:g} of its fit range; sigma_eff = max(noise floor "
                     f"{1e3 * sigma:.3g} mm, RMS left {1e3 * rms:.3g} mm) x sqrt(autocorrelation time {tau:.3g} "
                     "rows) = "
                     f"{1e3 * lin.sigma_eff:.3g} mm; |correlation| > {lin.cfg.confounded:g}: confounded; a value at "
                     "its fit bound is never a measurement")}


def autocorrelation_time(res: list[np.ndarray], max_lag: int = 500, cut: float = 0.05) -> float:
    """Integrated autocorrelation time [rows] of per-run residuals (K, 3): 1 + 2·Σ ρ_k over lags until
    ρ_k first falls below ``cut`` (pooled over runs and channels, rows after each run's first; at least 1)."""
    series = []
    for r in res:
        x = r[1:]
        x = x[np.all(np.isfinite(x), axis=1)]
        if len(x) > 3:
            series.append(x - x.mean(axis=0))
    if not series:
        return 1.0
    var = sum(float(np.sum(x * x)) for x in series)
    if var <= 0:
        return 1.0
    tau = 1.0
    for k in range(1, max_lag + 1):
        num = sum(float(np.sum(x[:-k] * x[k:])) for x in series if len(x) > k)
        rho = num / var
        if rho < cut:
            break
        tau += 2.0 * rho
    return tau


def _combo_text(terms: list[tuple[str, float]]) -> str:
    out = ""
    for name, w in terms:
        sign = "-" if w < 0 else "+"
        mag = "" if math.isclose(abs(w), 1.0, abs_tol=0.005) else f"{abs(w):.2f}·"
        out += (f" {sign} " if out else ("-" if w < 0 else "")) + mag + name
    return out


def _effect_line(effect: str, own: list[dict], combos: list[dict], alone: bool) -> str:
    """One line: what the data pinned down of this effect and what they did not."""
    pinned = [p["param"] for p in own if p["identified"] and not p["at_bound"]]
    loose = [p["param"] for p in own if not p["identified"] and not p["at_bound"]]
    bound = [p["param"] for p in own if p["at_bound"]]
    tail = (f"; at its fit bound (the fit wants a value beyond the range: it compensates another error, not a "
            f"measurement): {', '.join(bound)}" if bound else "")
    if not loose:
        return f"{effect}: " + (f"every parameter pinned down ({', '.join(pinned)})" if not bound
                                else f"pinned down {', '.join(pinned) or 'nothing else'}") + tail
    prefix = "" if alone else f"{effect}."
    # identified combinations that involve a loose parameter: what the data do determine instead
    names = {prefix + p["param"] for p in own if not p["identified"]}
    ident = [c["combination"] for c in combos if c["identified"] and any(t[0] in names for t in c["terms"])]
    text = f"{effect}: pinned down {', '.join(pinned) if pinned else 'no single parameter'}; not determined: " \
           + ", ".join(loose)
    if ident:
        text += "; determined instead: " + "; ".join(ident[:3])
    return text + tail
