"""Evaluate a policy on an omni-gym environment over held-out seeds, with 95 % confidence intervals.

Episode i runs with ``env.reset(seed=seed + i)``. Per-episode metrics come from the ground truth in
``info`` (the policies never see it):

* ``tracking_rmse`` [m]: √(mean of info["tracking_error"]²) over the steps of the episode (after each
  action; the reset state, on the reference, is not counted). An episode that ends early (lost or
  collided) is averaged over the steps it ran: its final error tells that it was lost.
* ``final_position_error`` [m]: info["tracking_error"] at the last step.
* ``final_heading_error`` [rad]: |info["heading_error"]| at the last step.
* ``success``: info["is_success"] at the last step and the episode was not terminated early.

Aggregates: the mean of each metric with a 95 % bootstrap percentile interval (:func:`bootstrap_ci`;
None for n = 1) and the success rate with a 95 % Wilson score interval. The metrics are errors, never
negative, and their distributions are skewed (a few lost episodes dominate): a Student-t interval
(mean ± t·s/√n) then reaches below zero, a bound no error can have. The percentile interval lies
inside [min, max] of the data, so it is never negative.

Scripted policies (:data:`agents.policies.POLICY_NAMES`) run with ``obs_mode="sensors"`` and
``action_mode="twist"``; asking for other modes in ``env_kwargs`` is an error.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np

from agents.policies import POLICY_NAMES, make_policy
from agents.rllib.policy import build as build_rllib
from agents.rllib.policy import is_rllib_model
from agents.rollout import Episode, make_env, run_episode
from agents.sb3_policy import build

METRICS = ("tracking_rmse", "final_position_error", "final_heading_error")
Z95 = 1.959963984540054  # standard normal 97.5 % quantile


def mean_ci(values: np.ndarray, level: float = 0.95) -> dict:
    """Mean, sample std and the two-sided Student-t confidence interval of the mean (None if n < 2)."""
    from scipy import stats

    x = np.asarray(values, dtype=float)
    n = len(x)
    mean = float(np.mean(x))
    if n < 2:
        return {"mean": mean, "std": None, "ci95": None}
    sd = float(np.std(x, ddof=1))
    half = float(stats.t.ppf(0.5 + level / 2.0, n - 1)) * sd / math.sqrt(n)
    return {"mean": mean, "std": sd, "ci95": [mean - half, mean + half]}


BOOTSTRAP_RESAMPLES = 10_000
BOOTSTRAP_SEED = 0  # fixed: the same episodes always give the same interval


def bootstrap_ci(values: np.ndarray, level: float = 0.95, resamples: int = BOOTSTRAP_RESAMPLES) -> dict:
    """Mean, sample std and a bootstrap percentile confidence interval of the mean (None if n < 2).

    The interval is the (1 − level)/2 and (1 + level)/2 quantiles of the means of ``resamples`` resamples
    (with replacement, from a generator with a fixed seed, so the result is a function of the data). For
    non-negative data (errors) it is never negative, unlike the Student-t interval, and it follows the
    skew of the data. With few values (n ≲ 10) it is somewhat narrower than its nominal level, as any
    percentile bootstrap.
    """
    x = np.asarray(values, dtype=float)
    n = len(x)
    mean = float(np.mean(x))
    if n < 2:
        return {"mean": mean, "std": None, "ci95": None}
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    means = np.empty(resamples)
    chunk = max(1, 2_000_000 // n)  # bounded memory for long evaluations
    for start in range(0, resamples, chunk):
        stop = min(resamples, start + chunk)
        means[start:stop] = x[rng.integers(0, n, size=(stop - start, n))].mean(axis=1)
    lo, hi = np.quantile(means, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return {"mean": mean, "std": float(np.std(x, ddof=1)), "ci95": [float(lo), float(hi)]}


def wilson_ci(successes: int, n: int, z: float = Z95) -> list[float]:
    """Wilson score interval for a binomial proportion (95 % with the default z)."""
    if n < 1:
        raise ValueError("wilson_ci needs n >= 1")
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return [max(0.0, centre - half), min(1.0, centre + half)]


def summarize(episodes: list[Episode], interval: str = "bootstrap") -> dict:
    """Aggregate metrics (mean and 95 % CI) and the per-episode values.

    ``interval``: "bootstrap" (percentile interval, never outside the observed values, so never
    negative for errors; what ``omni-gym evaluate`` prints) or "t" (Student-t, what the committed
    benchmark tables were made with, kept so that their commands reproduce them).
    """
    if interval not in ("bootstrap", "t"):
        raise ValueError(f"interval must be 'bootstrap' or 't', got {interval!r}")
    ci = bootstrap_ci if interval == "bootstrap" else mean_ci
    out = {m: ci(np.array([getattr(e, m) for e in episodes])) for m in METRICS}
    wins = sum(e.success for e in episodes)
    out["success_rate"] = {"mean": wins / len(episodes), "successes": wins, "ci95": wilson_ci(wins, len(episodes))}
    out["terminated_rate"] = sum(e.terminated for e in episodes) / len(episodes)
    out["per_episode"] = {k: [e.metrics()[k] for e in episodes] for k in ("seed", *METRICS, "success", "terminated")}
    return out


def evaluate(policy: str, env_id: str, episodes: int, seed: int, env_kwargs: dict | None = None,
             progress: bool | None = None, model_options=None) -> dict:
    """Run ``episodes`` episodes of ``policy`` on seeds seed, seed+1, …; return the summary dict.

    Args:
        policy: one of :data:`~agents.policies.POLICY_NAMES`, or a trained model: our model directory
            (``meta.json`` + model zip), an RL Zoo output folder or a plain SB3 ``.zip`` (see
            :mod:`agents.sb3_policy`; it builds the environment and wrapper the model needs), or an RLlib
            model (our ``--backend rllib`` directory or a bare RLlib checkpoint; :mod:`agents.rllib.policy`).
        env_id: a registered omni-gym id.
        episodes: number of episodes (≥ 1).
        seed: first seed.
        env_kwargs: extra ``gym.make`` keywords.
        progress: tqdm bar on stderr (None: only when stderr is a terminal).
        model_options: :class:`agents.sb3_policy.ModelOptions` (algorithm, wrapper, ... of a plain SB3 zip).

    Returns a JSON-serialisable dict: ``policy``, ``env_id``, ``env_kwargs``, ``episodes``, ``seeds``
    ([first, last]), per metric {mean, std, ci95}, ``success_rate`` {mean, successes, ci95},
    ``terminated_rate`` and ``per_episode`` lists.
    """
    scripted = policy in POLICY_NAMES
    if not scripted and not os.path.isdir(policy) and not policy.endswith(".zip"):
        if os.path.exists(policy):
            raise ValueError(f"policy {policy!r}: not a model (a model directory, an RL Zoo folder or an SB3 .zip)")
        raise ValueError(f"unknown policy {policy!r}; choose one of {', '.join(POLICY_NAMES)} or a saved model path")
    if scripted and model_options is not None and model_options.given():
        raise ValueError(f"{model_options.given()[0]} applies to a trained model, not to the scripted policy "
                         f"{policy!r}")
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    from tqdm import tqdm

    if scripted:
        env = make_env(env_id, env_kwargs)
    elif is_rllib_model(policy):  # an RLlib checkpoint (agents/rllib): no SB3 options apply
        if model_options is not None and model_options.given():
            raise ValueError(f"{model_options.given()[0]} applies to an SB3 model, not to the RLlib model {policy}")
        env, pol = build_rllib(policy, env_id, env_kwargs)
    else:  # a trained model: it knows (or the options say) its observation mode and wrapper
        env, pol = build(policy, env_id, env_kwargs, model_options)
    try:
        if scripted:
            pol = make_policy(policy, env)
        eps = [run_episode(env, pol, int(seed) + i)
               for i in tqdm(range(episodes), desc=f"{policy} on {env_id}", file=sys.stderr, disable=progress is False
                             or (progress is None and not sys.stderr.isatty()), leave=False)]
    finally:
        env.close()
    return {"policy": policy, "env_id": env_id, "env_kwargs": dict(env_kwargs or {}), "episodes": episodes,
            "seeds": [int(seed), int(seed) + episodes - 1], **summarize(eps)}


def format_table(result: dict) -> str:
    """A small text table of the summary (mean and 95 % CI per metric)."""
    kw = f", {result['env_kwargs']}" if result["env_kwargs"] else ""
    lines = [f"{result['policy']} on {result['env_id']}, {result['episodes']} episodes, seeds "
             f"{result['seeds'][0]}–{result['seeds'][1]}{kw}",
             f"{'metric':<26}{'mean':>10}   95% CI (bootstrap percentile: errors are never negative)"]
    units = {"tracking_rmse": "m", "final_position_error": "m", "final_heading_error": "rad"}
    for m in METRICS:
        r = result[m]
        ci = "n/a" if r["ci95"] is None else f"[{r['ci95'][0]:.4f}, {r['ci95'][1]:.4f}]"
        lines.append(f"{m + ' [' + units[m] + ']':<26}{r['mean']:>10.4f}   {ci}")
    s = result["success_rate"]
    lines.append(f"{'success rate':<26}{s['mean']:>10.3f}   [{s['ci95'][0]:.3f}, {s['ci95'][1]:.3f}] (Wilson)")
    lines.append(f"{'terminated early':<26}{result['terminated_rate']:>10.3f}")
    return "\n".join(lines)
