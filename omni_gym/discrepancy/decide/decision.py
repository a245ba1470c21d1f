"""Decision: rank the fitted candidates by held-out score and name the effect, or none, or unexplained.

A candidate's held-out score is Σ_r n_r·ln(SSE_r/n_r) + p·ln(N) (BIC form; SSE_r the held-out error of run r
from :mod:`omni_gym.discrepancy.fit.fitting`, n_r its residual components, N their sum, p parameters). Thresholds in
:class:`omni_gym.discrepancy.settings.DecisionRules`, why in ``docs/discrepancy.md``: a candidate must
improve the held-out error significantly (paired bootstrap over runs); it is named if it removes most of the
gap beyond tracker noise, else the outcome is ``unexplained``; ``none`` when nothing improves and the
nominal residual is at the noise level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from omni_gym.discrepancy.fit.candidates import Candidate
from omni_gym.discrepancy.settings import DecisionRules


class HeldOutFit(Protocol):
    """What :func:`decide` reads of a fit (:class:`omni_gym.discrepancy.fit.fitting.FitResult`; a protocol here
    so that the decision does not depend on how a fit is made)."""

    candidate: Candidate
    params_all: dict  # the all-run fit's effect parameters
    heldout: np.ndarray  # (R,) per-run SSE [m²] of the fold fit that did not see the run
    n_params_eff: int | None  # BIC parameter count when it differs from the candidate's dimensions


@dataclass(frozen=True)
class Decision:
    """The outcome of :func:`decide` (result.json copies its ``effect``, ``why``, ``ranking``, ``score_nominal``).

    ``effect``: the named effect, or ``none`` / ``unexplained``; ``why``: one sentence for the report.
    ``ranking``: one row per candidate, best held-out score first (JSON rows: effect, score, held-out
    RMS [m], ...; the workflow annotates them). ``best``: the top-ranked candidate. ``nominal_rms`` [m]:
    the baseline's held-out RMS (row-weighted geometric mean); ``nominal_excess_rms`` [m]: its part beyond
    the noise floor ``noise`` [m]; ``score_nominal``: the baseline's score (Σ n_r·ln(SSE_r/n_r)).
    ``partial``: the effect kept as a partial explanation (``unexplained`` outcome of a multi-effect
    search step) with the share of the step's gap it removes, ``step_reduction``; ``ambiguous_with``: the
    qualifying runner-ups the winner is not told apart from (effect, p_winner_better). The fields after
    ``ranking`` are None (empty) where the outcome has none: a search that ends at the noise floor without
    fitting builds a Decision from ``effect``, ``why`` and an empty ranking.
    """

    effect: str
    why: str
    ranking: list[dict]
    best: str | None = None
    nominal_rms: float | None = None
    nominal_excess_rms: float | None = None
    noise: float | None = None
    score_nominal: float | None = None
    partial: str | None = None
    step_reduction: float | None = None
    ambiguous_with: list[dict] = field(default_factory=list)


def _share_better(gain: np.ndarray) -> float:
    """Share of bootstrap resamples with a positive gain among those without a tie (0.5 if all tie)."""
    decided = gain != 0
    return float(np.mean(gain[decided] > 0)) if decided.any() else 0.5


def decide(nominal_sse: np.ndarray, fits: list[HeldOutFit], n_comp: np.ndarray, sigma: float | None,
           rng: np.random.Generator, reference_excess: float | None = None,
           rules: DecisionRules | None = None) -> Decision:
    """Rank candidates by penalised held-out score and choose the outcome (see the module docstring).

    ``nominal_sse``: the baseline's per-run SSE (the nominal model, or in a multi-effect search the
    model with the effects named so far). ``sigma`` [m]: the noise floor, RMS per residual component
    that even an exact model leaves (the workflow passes sqrt(tracker noise² + the fitting step's
    integration error²), :meth:`omni_gym.discrepancy.fit.fitting.Evaluator.noise_floor`); None when unknown.
    ``reference_excess`` [m]: the gap beyond noise the
    ``min_gap_reduction`` rule is measured against (default: the baseline's own; a multi-effect search
    passes the nominal model's). When the best candidate beats the baseline but falls short of that
    rule while removing at least ``min_step_reduction`` of the baseline's own gap, the outcome is
    ``unexplained`` with ``partial`` naming it (the workflow may add it and search on).

    Per-run Gaussian likelihood: run r with n_r residual components and held-out SSE_r contributes
    n_r·ln(SSE_r/n_r); a candidate's score adds p·ln(N). Per-run variances keep one run that a
    slightly-off fit sends onto a different path (stick-slip is that sensitive) from outweighing
    all the others, as it would in one pooled sum of squares.

    ``rules``: the thresholds (None: the defaults, :class:`DecisionRules`).
    """
    rules = DecisionRules() if rules is None else rules
    N = float(n_comp.sum())
    R = len(n_comp)
    n = np.maximum(n_comp, 1)
    L0 = n * np.log(np.maximum(nominal_sse, 1e-30) / n)
    mse0 = math.exp(L0.sum() / N)  # n-weighted geometric mean of the per-run MSE
    noise_var = sigma**2 if sigma is not None else 0.0
    boot = np.stack([np.bincount(row, minlength=R) for row in rng.integers(0, R, (rules.n_boot, R))])
    ranking = []
    Ls = []
    for f in fits:
        L = n * np.log(np.maximum(f.heldout, 1e-30) / n)
        Ls.append(L)
        mse = math.exp(L.sum() / N)
        gain = boot @ (L0 - L)  # (n_boot,) log-likelihood gain over nominal in each resample
        ranking.append({
            "effect": f.candidate.name,
            "score": float(L.sum() + (f.n_params_eff or f.candidate.n_params) * math.log(N)),
            "heldout_rms": math.sqrt(mse),
            "pooled_rms": math.sqrt(f.heldout.sum() / N),
            "excess_rms": math.sqrt(max(mse - noise_var, 0.0)),
            "improvement": 1.0 - mse / mse0 if mse0 > 0 else 0.0,
            # A resample made only of runs the candidate leaves exactly as nominal (runs in which no
            # lift event was inferred) is a tie and carries no evidence: ties are dropped, as in a
            # sign test (all ties: 0.5).
            "p_better_than_nominal": _share_better(gain),
            "n_params": f.candidate.n_params,
            "params": f.params_all,
        })
    score0 = float(L0.sum())
    order = sorted(range(len(fits)), key=lambda i: ranking[i]["score"])
    for i in order:
        ranking[i]["beats_nominal"] = bool(ranking[i]["score"] < score0
                                           and ranking[i]["p_better_than_nominal"] >= rules.significance
                                           and ranking[i]["improvement"] >= rules.min_improvement)
    # Stability: the share of run resamples in which each candidate has the best held-out likelihood.
    wins = np.argmin(np.stack([boot @ L for L in Ls]), axis=0)
    for i in range(len(fits)):
        ranking[i]["stability"] = float(np.mean(wins == i))
    excess_base = math.sqrt(max(mse0 - noise_var, 0.0))
    excess0 = excess_base if reference_excess is None else reference_excess
    nominal_at_noise = sigma is not None and mse0 <= noise_var * (1 + rules.noise_margin)
    best = order[0]
    rb = ranking[best]
    out = Decision(effect="", why="", ranking=[ranking[i] for i in order], best=rb["effect"],
                   nominal_rms=math.sqrt(mse0), nominal_excess_rms=excess_base, noise=sigma, score_nominal=score0)
    reduction = 1.0 - rb["excess_rms"] / excess0 if excess0 > 0 else 0.0
    # A deterministic candidate that predicts held-out runs to the noise level is right whatever share of the
    # gap that is. A stochastic one's "held-out" error is in-sample with its inferred events, which can trim
    # any residual down to the noise (with nothing hidden, lift events absorbed the smooth drift of a noisy
    # start pose: 44 % of the gap, the rest at noise level); so it must remove min_gap_reduction of the gap
    # like every other effect, and is never kept as a partial explanation.
    stochastic = fits[best].candidate.stochastic
    best_at_noise = (sigma is not None and not stochastic
                     and rb["heldout_rms"] ** 2 <= noise_var * (1 + rules.noise_margin))
    if nominal_at_noise:
        # The evidence rule, one for every effect: only a residual beyond the floor can be evidence of a missing
        # effect. A baseline within it leaves nothing to explain, however well a candidate trims the noise.
        also = (f"; {rb['effect']} lowers the held-out MSE by {100 * rb['improvement']:.0f} %, within that floor"
                if rb["beats_nominal"] else "")
        return replace(out, effect="none", why=(
            f"the nominal residual ({1e3 * math.sqrt(mse0):.2f} mm RMS) is within the noise floor "
            f"({1e3 * sigma:.2f} mm: tracker noise, integration error and the simulator's validated accuracy) "
            f"by the margin ({100 * rules.noise_margin:.0f} % in MSE): nothing beyond it to explain{also}"))
    chain_share = (excess_base - rb["excess_rms"]) / excess0 if excess0 > 0 else 0.0
    if reference_excess is not None and rb["beats_nominal"] and chain_share < rules.min_chain_share:
        # A later step: the effect must explain a real share of the first model's gap, not polish what is left.
        return replace(out, effect="none", why=(
            f"the best candidate, {rb['effect']}, removes only {100 * chain_share:.1f} % of the first model's gap "
            f"beyond noise (a later effect needs {100 * rules.min_chain_share:.0f} %)"))
    if not rb["beats_nominal"]:
        if sigma is None:
            return replace(out, effect="none", why="no candidate improves the held-out error significantly")
        return replace(out, effect="unexplained", why=(
            f"the nominal residual ({1e3 * math.sqrt(mse0):.2f} mm RMS) is well above the noise "
            f"floor ({1e3 * sigma:.2f} mm: tracker noise, integration error and the simulator's validated accuracy) "
            "and no candidate improves it significantly"))
    if reduction < rules.min_gap_reduction and not best_at_noise:
        out = replace(out, effect="unexplained", why=(
            f"the best candidate, {rb['effect']}, removes only {100 * reduction:.0f} % of the gap beyond "
            f"noise on held-out runs (needs {100 * rules.min_gap_reduction:.0f} %)"))
        step_reduction = 1.0 - rb["excess_rms"] / excess_base if excess_base > 0 else 0.0
        if step_reduction >= rules.min_step_reduction and not stochastic:
            out = replace(out, partial=rb["effect"], step_reduction=step_reduction)
        return out
    why = (f"{rb['effect']} removes {100 * reduction:.0f} % of the held-out gap beyond noise and beats "
           f"the nominal model in {100 * rb['p_better_than_nominal']:.0f} % of run resamples")
    # Ambiguity: a qualifying runner-up that the winner does not beat reliably across resamples.
    amb = []
    for i in order[1:]:
        ri = ranking[i]
        if not ri["beats_nominal"]:
            continue
        red_i = 1.0 - ri["excess_rms"] / excess0 if excess0 > 0 else 0.0
        pairwise = float(np.mean(boot @ (Ls[i] - Ls[best]) > 0))
        if red_i >= rules.min_gap_reduction and pairwise < rules.ambiguity:
            amb.append({"effect": ri["effect"], "p_winner_better": pairwise})
    if amb:
        why += "; cannot be told apart from " + ", ".join(a["effect"] for a in amb) + " on this data"
    return replace(out, effect=rb["effect"], why=why, ambiguous_with=amb)
