"""Evaluate a policy on an omni-gym environment over held-out seeds, with 95 % confidence intervals.

Episode i runs with ``env.reset(seed=seed + i)``. Per-episode metrics come from the ground truth in
``info`` (the policies never see it):

* ``tracking_rmse`` [m]: √(mean of info["tracking_error"]²) over the steps of the episode (after each
  action; the reset state, on the reference, is not counted). An episode that ends early (lost or
  collided) is averaged over the steps it ran: its final error tells that it was lost.
* ``final_position_error`` [m]: info["tracking_error"] at the last step.
* ``final_heading_error`` [rad]: |info["heading_error"]| at the last step.
* ``success``: info["is_success"] at the last step and the episode was not terminated early.
* ``episode_return``: the sum of the environment's own reward over the episode (the id's reward,
  ``docs/environments.md``; not a training wrapper's, so every policy on an id is scored alike): the
  figure SB3's ``evaluate_policy`` and the RL Zoo report. Higher is better.

Paired comparison (:func:`compare`, ``omni-gym evaluate --against``): both policies run on the same seeds,
so each seed gives both the same reference, lift-off schedule and sensor noise; the ratio of their mean
tracking RMSE gets a 95 % paired-bootstrap interval (resampling seeds, from a seeded Generator), beside
the share of episodes where the first policy tracks better.

Aggregates: the mean of each metric with a 95 % bootstrap percentile interval (:func:`bootstrap_ci`;
None for n = 1) and the success rate with a 95 % Wilson score interval. The metrics are errors, never
negative, and their distributions are skewed (a few lost episodes dominate): a Student-t interval
(mean ± t·s/√n) then reaches below zero, a bound no error can have. The percentile interval lies
inside [min, max] of the data, so it is never negative.

Plant in the loop (``plant=``, ``omni-gym evaluate --plant``): the environment draws the same references
and scores the same way, but its wheel commands drive a plant (:mod:`omni_gym.physics.plant`) instead
of its own world: the second generator with a model file's hidden effects, or a user's robot. The
environment's sensor models measure a simulated plant's motion with the same seeds, so a plant equal to
the environment's model gives the environment's own figures, bit for bit.

Scripted policies (:data:`agents.policies.POLICY_NAMES`) run with ``obs_mode="sensors"`` and
``action_mode="twist"``; asking for other modes in ``env_kwargs`` is an error.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Iterable, Iterator

import numpy as np

from agents.loaders import find_loader
from agents.rollout import Episode, run_episode

METRICS = ("tracking_rmse", "final_position_error", "final_heading_error")
Z95 = 1.959963984540054  # standard normal 97.5 % quantile
DEFAULT_SEED = 10_000  # held out: training environments use small seeds, validation 5000…
PROGRESS_EVERY_S = 10.0  # a progress line at most this often when stderr is not a terminal


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


def paired_bootstrap_ratio(num: np.ndarray, den: np.ndarray, rng: np.random.Generator,
                           resamples: int = BOOTSTRAP_RESAMPLES) -> tuple[list[float], float]:
    """Percentile bootstrap of mean(num)/mean(den), resampling seeds (pairs) with replacement.

    ``num[i]`` and ``den[i]`` come from the same seed. Returns the two-sided 95 % interval and the
    one-sided 95 % upper bound of the ratio. The draws come from ``rng`` (seed it: the same episodes then
    give the same interval).
    """
    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    idx = rng.integers(0, len(num), size=(resamples, len(num)))
    ratios = num[idx].mean(axis=1) / den[idx].mean(axis=1)
    return [float(np.quantile(ratios, 0.025)), float(np.quantile(ratios, 0.975))], float(np.quantile(ratios, 0.95))


def compare(a: dict, b: dict, metric: str = "tracking_rmse") -> dict:
    """Paired comparison of two :func:`evaluate` results on the same seeds (``a`` against ``b``).

    Returns ``metric``, ``ratio`` = mean(a)/mean(b) (below 1: ``a`` has the smaller error), its 95 %
    paired-bootstrap ``ci95`` (:func:`paired_bootstrap_ratio`, Generator seeded with
    :data:`BOOTSTRAP_SEED`), ``a_better`` / ``ties`` / ``b_better``: the share of seeds where ``a``'s value
    is lower / equal / higher, and ``episodes``. ValueError when the seeds differ.
    """
    sa, sb = a["per_episode"]["seed"], b["per_episode"]["seed"]
    if sa != sb:
        raise ValueError("a paired comparison needs the same seeds for both policies")
    x, y = np.array(a["per_episode"][metric], dtype=float), np.array(b["per_episode"][metric], dtype=float)
    ratio, ci = math.nan, None  # nan: b's errors are all zero, no ratio exists
    if y.mean() > 0:
        ratio = float(x.mean() / y.mean())
        if len(x) >= 2 and np.all(y >= 0) and np.any(y > 0):
            # A resample of only b-zero seeds has no ratio; errors are non-negative, so that needs all y = 0
            # on the drawn seeds: with a single non-zero y among n such draws exist, and give inf or nan.
            with np.errstate(divide="ignore", invalid="ignore"):
                ci, _ = paired_bootstrap_ratio(x, y, np.random.default_rng(BOOTSTRAP_SEED))
    return {"metric": metric, "ratio": ratio, "ci95": ci, "a_better": float(np.mean(x < y)),
            "ties": float(np.mean(x == y)), "b_better": float(np.mean(x > y)), "episodes": len(x)}


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
    out["episode_return"] = ci(np.array([e.episode_return for e in episodes]))
    wins = sum(e.success for e in episodes)
    out["success_rate"] = {"mean": wins / len(episodes), "successes": wins, "ci95": wilson_ci(wins, len(episodes))}
    out["terminated_rate"] = sum(e.terminated for e in episodes) / len(episodes)
    out["per_episode"] = {k: [e.metrics()[k] for e in episodes]
                          for k in ("seed", *METRICS, "episode_return", "success", "terminated", "reference_traction")}
    out["traction"] = traction_summary(episodes)
    return out


def traction_summary(episodes: list[Episode]) -> dict:
    """How many episodes' references asked more than the wheels' traction (their share of the friction set,
    ``info["reference_traction"]``, above 1), and the largest share; ``known`` counts the episodes that tell."""
    use = np.array([e.reference_traction for e in episodes], dtype=float)  # NaN where unknown
    known = np.isfinite(use)
    return {"known": int(known.sum()), "exceeded": int(np.sum(use[known] > 1.0)),
            "max": float(use[known].max()) if known.any() else None}


def traction_line(result: dict) -> str | None:
    """One line when some references asked more than the robot's traction (None otherwise)."""
    t = result.get("traction")
    if not t or not t["exceeded"]:
        return None
    return (f"note: {t['exceeded']} of {t['known']} references asked more than the wheels can transmit (up to "
            f"{t['max']:.2f} of the friction set, > 1 beyond the robot's traction): their errors measure the task "
            "as much as the controller (ref_traction > 0 slows such references down; docs/environments.md)")


def progress_lines(items: Iterable[int], total: int, what: str, every_s: float | None = None,
                   clock=time.monotonic) -> Iterator[int]:
    """``items``, with a line ``WHAT: k/N episodes, T s, about R s left`` on stderr after an item when at
    least ``every_s`` seconds (default :data:`PROGRESS_EVERY_S`) passed since the last line: progress where a
    bar cannot draw (a pipe, a log file). No line after the last item: the result follows."""
    every_s = PROGRESS_EVERY_S if every_s is None else every_s
    t0 = last = clock()
    for k, item in enumerate(items, 1):
        yield item
        now = clock()
        if now - last >= every_s and k < total:
            left = (now - t0) / k * (total - k)
            print(f"{what}: {k}/{total} episodes, {now - t0:.0f} s, about {left:.0f} s left", file=sys.stderr,
                  flush=True)
            last = now


def check_policy_name(policy: str) -> None:
    """A scripted policy name, or a model path some loader takes; else one line saying which it is not
    (:func:`agents.loaders.find_loader`)."""
    find_loader(policy)


def evaluate(policy: str, env_id: str, episodes: int, seed: int = DEFAULT_SEED, env_kwargs: dict | None = None,
             progress: bool | None = None, model_options=None, plant: Callable | None = None) -> dict:
    """Run ``episodes`` episodes of ``policy`` on seeds seed, seed+1, …; return the summary dict.

    Args:
        policy: one of :data:`~agents.policies.POLICY_NAMES`, or a trained model: our model directory
            (``meta.json`` + model zip), an RL Zoo output folder or a plain SB3 ``.zip`` (see
            :mod:`agents.sb3_policy`; it builds the environment and wrapper the model needs), or an RLlib
            model (our ``--backend rllib`` directory or a bare RLlib checkpoint; :mod:`agents.rllib.policy`).
            The first loader of :data:`agents.loaders.LOADERS` that accepts it builds it.
        env_id: a registered omni-gym id.
        episodes: number of episodes (≥ 1).
        seed: first seed (default :data:`DEFAULT_SEED`, held out from training and validation).
        env_kwargs: extra ``gym.make`` keywords.
        progress: True: a tqdm bar on stderr; False: nothing; None: the bar when stderr is a terminal,
            else a line every :data:`PROGRESS_EVERY_S` seconds (:func:`progress_lines`).
        model_options: :class:`agents.sb3_policy.ModelOptions` (algorithm, wrapper, ... of a plain SB3 zip).
        plant: a factory ``plant(core) -> Plant`` called once with the environment's ``TaskCore``: the episodes
            then drive that plant (:mod:`omni_gym.physics.plant`) instead of the environment's world.

    Returns a JSON-serialisable dict: ``policy``, ``env_id``, ``env_kwargs``, ``episodes``, ``seeds``
    ([first, last]), per metric and ``episode_return`` {mean, std, ci95}, ``success_rate`` {mean, successes, ci95},
    ``terminated_rate`` and ``per_episode`` lists.
    """
    loader = find_loader(policy)
    loader.check_options(policy, model_options)
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    from tqdm import tqdm

    env, pol = loader.load(policy, env_id, env_kwargs, model_options)  # the env the policy needs
    try:
        if plant is not None:
            core = env.unwrapped.core
            core.attach_plant(plant(core))
        bar = progress is True or (progress is None and sys.stderr.isatty())
        what = f"{policy} on {env_id}"
        seeds: Iterable[int] = range(episodes)
        if bar:
            seeds = tqdm(seeds, desc=what, file=sys.stderr, leave=False)
        elif progress is None:
            seeds = progress_lines(seeds, episodes, what)
        eps = [run_episode(env, pol, int(seed) + i) for i in seeds]
    finally:
        env.close()
    return {"policy": policy, "env_id": env_id, "env_kwargs": dict(env_kwargs or {}), "episodes": episodes,
            "seeds": [int(seed), int(seed) + episodes - 1], **summarize(eps)}


def format_table(result: dict) -> str:
    """A small text table of the summary (mean and 95 % CI per metric)."""
    kw = f", {result['env_kwargs']}" if result["env_kwargs"] else ""
    plant = result.get("plant")
    where = "" if plant is None else (f", driving the {plant['kind']} plant"
                                      + (f" of {plant['model']}" if plant.get("model") else "")
                                      + (f" with {plant['extra']}" if plant.get("extra") else ""))
    lines = [f"{result['policy']} on {result['env_id']}{where}, {result['episodes']} episodes, seeds "
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
    r = result["episode_return"]
    ci = "n/a" if r["ci95"] is None else f"[{r['ci95'][0]:.2f}, {r['ci95'][1]:.2f}]"
    lines.append(f"{'episode return':<26}{r['mean']:>10.2f}   {ci} (sum of the environment's reward; higher is "
                 f"better)")
    note = traction_line(result)
    if note is not None:
        lines.append(note)
    return "\n".join(lines)


def format_comparison(a: dict, b: dict, cmp: dict) -> str:
    """Two lines: the paired ratio of mean tracking RMSE with its interval, and the shares of seeds."""
    ci = "n/a (one episode)" if cmp["ci95"] is None else f"[{cmp['ci95'][0]:.3f}, {cmp['ci95'][1]:.3f}]"
    return "\n".join([
        f"paired on seeds {a['seeds'][0]}–{a['seeds'][1]}: {a['policy']} / {b['policy']}",
        f"  ratio of mean {cmp['metric']}: {cmp['ratio']:.3f}   95% CI {ci} (paired bootstrap over seeds; "
        f"below 1: {a['policy']} tracks better)",
        f"  episodes where {a['policy']} is better: {cmp['a_better']:.0%}, equal: {cmp['ties']:.0%}, worse: "
        f"{cmp['b_better']:.0%}"
        + ("  (the ratio of means weighs each episode by its error: a few large wins can outweigh more small "
           "losses, and the other way round)" if (cmp["ratio"] < 1) != (cmp["a_better"] > cmp["b_better"]) else "")])
