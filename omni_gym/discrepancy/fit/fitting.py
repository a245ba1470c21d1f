"""Fitting with folds: every candidate fitted on all runs and on each fold's training runs.

Each point is simulated on every run in one world (:class:`Evaluator`), giving a table SSE[point, run].
A fit starts from a scrambled Sobol design shared by all its searches (plus the effect's null point),
then runs the batched local searches of :mod:`.search` (roller-phase sweeps, Levenberg–Marquardt,
valley line searches) from the best design points. A fit on a set of runs is the point with the
least SSE over those runs among everything simulated for it.

Held-out errors: K folds by run or by recording session (:mod:`omni_gym.discrepancy.data.folds`), given by
the caller as each run's fold index. Fold k's fit sees only the other runs; its SSE on the runs of fold k
is that candidate's held-out error there (scored by :func:`omni_gym.discrepancy.decide.decision.decide`).
The stochastic ``wheel_liftoff`` is fitted by lift-event inference instead (:mod:`.events`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import qmc

from omni_gym.discrepancy.data.dataset import Dataset
from omni_gym.discrepancy.fit.candidates import Candidate, null_point, prior_point
from omni_gym.discrepancy.fit.events import PARAMS_PER_EVENT, EventFit, EventProblem, infer_events
from omni_gym.discrepancy.fit.search import (
    SearchContext,
    SearchState,
    levenberg_marquardt,
    phase_search,
    valley_search,
)
from omni_gym.discrepancy.replay.measurement import START_WINDOW
from omni_gym.discrepancy.replay.residuals import (
    channel_noise,
    count_components,
    noise_estimate,
    run_sse,
    shooting_windows,
)
from omni_gym.discrepancy.replay.simulate import FIT_DT, Job, pose_residual, simulate_poses
from omni_gym.discrepancy.settings import FitSettings, GapSettings
from omni_gym.physics.model import SimModel
from omni_gym.progress import Progress

# The search rounds of fit_candidate (LM iterations, starts, phase sweeps, valley rounds; also the progress
# bound max_ticks) are the fields of settings.FitSettings, recorded in result.json (settings.fit).


class Evaluator:
    """SSE per run of parameter points, by batched simulation (one world per call)."""

    def __init__(self, dataset: Dataset, lever: float, dt: float = FIT_DT, max_batch: int = 1500,
                 accuracy: float = 0.0, start_window: float = START_WINDOW) -> None:
        self.ds = dataset
        self.lever = lever
        self.dt = dt
        self.accuracy = accuracy  # [m] the simulator's validated accuracy, part of the floor (noise_floor)
        self.start_window = start_window  # [s] whole-run replays aligned to their first tracked rows
        self.max_batch = max_batch
        self.simulated = 0  # robot-runs simulated (for the report)
        self._windows: list[tuple] | None = None
        self._baseline: tuple | None = None
        self._floor: tuple | None = None

    @property
    def windows(self) -> list[tuple]:
        """The dataset's :func:`shooting_windows` (computed once)."""
        if self._windows is None:
            self._windows = shooting_windows(self.ds)
        return self._windows

    def nominal_baseline(self, nominal: SimModel) -> tuple[list[np.ndarray], np.ndarray, float | None]:
        """The nominal model's per-run residuals, per-run SSE [m²] and the tracker-noise estimate σ̂ [m]
        (simulated once per evaluator: the workflow and the event inference share them)."""
        if self._baseline is None:
            res0 = self.residuals([nominal])[0]
            self._baseline = (res0, np.array([run_sse(r) for r in res0]),
                              noise_estimate(res0, [r.t for r in self.ds.runs]))
        return self._baseline

    def noise_floor(self, nominal: SimModel) -> tuple[float | None, dict]:
        """The decision's noise floor [m] and its parts: sqrt(σ̂² + ε² + δ²), σ̂ the tracker noise
        (:func:`~omni_gym.discrepancy.replay.residuals.noise_estimate`), ε the RMS integration error of the
        fitting step ``dt`` itself (:meth:`integration_error`) and δ the simulator's validated accuracy against an
        independent integration (``accuracy``, :func:`omni_gym.discrepancy.settings.accuracy_floor`). Even an exact
        model leaves all three in the residual, so all belong to the floor a candidate cannot go below. None when
        σ̂ is unknown.

        Parts (dict): ``tracker`` σ̂, ``integration`` ε, ``accuracy`` δ, ``floor`` [m], ``noise`` sqrt(σ̂² + ε²)
        (the random part, which the identifiability analysis uses), ``channels`` the per-channel σ̂ (x, y,
        heading × lever) [m], ``note``.
        """
        if self._floor is None:
            res0, _, sigma = self.nominal_baseline(nominal)
            eps = self.integration_error(nominal)
            ch = channel_noise(res0, [r.t for r in self.ds.runs])
            noise = None if sigma is None else math.sqrt(sigma**2 + eps**2)
            floor = None if noise is None else math.sqrt(noise**2 + self.accuracy**2)
            self._floor = (floor, {
                "tracker": sigma, "integration": eps, "accuracy": self.accuracy, "noise": noise, "floor": floor,
                "channels": None if ch is None else [float(math.sqrt(v)) for v in ch],
                "note": "floor = sqrt(tracker^2 + integration^2 + accuracy^2) [m]: tracker noise from the residual's "
                        "second differences per channel (x, y, heading x lever; their mean square); integration: "
                        f"RMS error of the fitting step dt = {self.dt:g} s, 2 x (pose at dt - pose at dt/2) "
                        "(first-order integrator), nominal model, every run; accuracy: the simulator's validated "
                        "agreement with an independent integration of the same equations (settings.rules "
                        "accuracy_position, accuracy_heading), pooled like the residual"})
        return self._floor

    def integration_error(self, model: SimModel) -> float:
        """RMS [m] over observed pose components of the fitting step's own integration error on the
        dataset's runs (open loop, ``model``).

        The world's integrator is first order in ``dt`` (measured against the reference integrator on
        random twist steps: 0.16/0.07/0.03 mm RMS at 1/0.5/0.25 ms), so its error at ``dt`` is about
        2 × (pose at dt − pose at dt/2) (Richardson; that estimate gave 0.18 mm where the true error was
        0.16 mm). Costs one simulation of every run at dt and dt/2.
        """
        runs = self.ds.runs
        jobs = [Job(model, r) for r in runs]
        coarse = simulate_poses(jobs, self.dt, self.max_batch, self.start_window)
        fine = simulate_poses(jobs, self.dt / 2, self.max_batch, self.start_window)
        self.simulated += 2 * len(jobs)
        sse = sum(run_sse(np.where(r.observed[:, None], 2.0 * pose_residual(f, c, self.lever), np.nan))
                  for r, c, f in zip(runs, coarse, fine, strict=True))
        n = max(int(count_components(self.ds).sum()), 1)
        return float(math.sqrt(sse / n))

    def residuals(self, models: list[SimModel], shooting: bool = False) -> list[list[np.ndarray]]:
        """Per model, per run: residual (K, 3) [m] measured − simulated.

        ``shooting``: simulate the windows of :func:`shooting_windows` instead (each from the measured
        state at its start) and return, per run, the windows' residual rows stacked.

        The same as :meth:`assemble` of :meth:`job_residuals` over all :meth:`jobs`: a job's result does not
        depend on the other robots of its world, so the jobs may be simulated in any grouping (the
        parallel fit tasks of :mod:`omni_gym.discrepancy.fit.fit_tasks` split them) with the same bits.
        """
        jobs = self.jobs(models, shooting)
        flat = self.job_residuals(jobs, shooting)
        self.simulated += len(jobs)
        return self.assemble(len(models), flat, shooting)

    def jobs(self, models: list[SimModel], shooting: bool = False) -> list[Job]:
        """The simulation jobs of :meth:`residuals`, model-major: every run (or every shooting window)
        of ``models[0]``, then of ``models[1]``, ..."""
        if shooting:
            return [Job(m, self.ds.runs[ri], k0=k0, k1=k1, state0=st)
                    for m in models for ri, k0, k1, st in self.windows]
        return [Job(m, r) for m in models for r in self.ds.runs]

    def jobs_per_model(self, shooting: bool = False) -> int:
        """Jobs of one model in :meth:`jobs`: the runs, or the shooting windows."""
        return len(self.windows) if shooting else len(self.ds.runs)

    def job_residuals(self, jobs: list[Job], shooting: bool = False) -> list[np.ndarray]:
        """Per job of :meth:`jobs` (any contiguous part of them): its residual rows [m] (open loop: the
        run's (K, 3); shooting: the window's rows after its start)."""
        out = simulate_poses(jobs, self.dt, self.max_batch, self.start_window)
        if shooting:
            return [pose_residual(j.run.pose[j.k0 + 1:j.k1 + 1], p[1:], self.lever)
                    for j, p in zip(jobs, out, strict=True)]
        return [pose_residual(j.run.pose, p, self.lever) for j, p in zip(jobs, out, strict=True)]

    def assemble(self, n_models: int, flat: list[np.ndarray], shooting: bool = False) -> list[list[np.ndarray]]:
        """:meth:`residuals`' per-model, per-run lists from the :meth:`job_residuals` of all jobs."""
        R = len(self.ds.runs)
        if not shooting:
            return [flat[mi * R:(mi + 1) * R] for mi in range(n_models)]
        wins = self.windows
        W = len(wins)
        res = []
        for mi in range(n_models):
            per_run: list[list[np.ndarray]] = [[np.zeros((1, 3))] for _ in self.ds.runs]
            for wi, (ri, _, _, _) in enumerate(wins):
                per_run[ri].append(flat[mi * W + wi])
            res.append([np.vstack(x) for x in per_run])
        return res

    def has_windows(self) -> bool:
        """True when some run is observed densely enough for multiple shooting."""
        return bool(self.windows)

    def simulate(self, jobs: list[Job], dt: float, max_batch: int,
                 done: Callable[[int, int], None] | None = None) -> list[np.ndarray]:
        """Poses of any ``jobs`` (:func:`~omni_gym.discrepancy.replay.simulate.simulate_poses`), for searches that
        build their own jobs (the lift-event inference); not counted in ``simulated`` (the caller counts).
        ``done(j, m)``: progress, after each of the m worlds."""
        return simulate_poses(jobs, dt, max_batch, self.start_window, done=done)


@dataclass
class FitResult:
    """One candidate's fits: per fold and on all runs, with held-out errors and uncertainty."""

    candidate: Candidate
    u_all: np.ndarray
    params_all: dict
    sse_all: np.ndarray  # (R,) per-run SSE of the all-run fit
    heldout: np.ndarray  # (R,) per-run SSE of the fold fit that did not see the run
    fold_params: list[dict]
    pool_u: np.ndarray  # points available to the all-run fit
    pool_sse: np.ndarray  # their (P, R) SSE
    # Stochastic candidate only: effective parameter count for the BIC penalty (2 rates + 3 per
    # inferred lift event) and the inferred events (omni_gym.discrepancy.fit.events.EventFit).
    n_params_eff: int | None = None
    event_fit: EventFit | None = None


def max_ticks(cand: Candidate, fit: FitSettings | None = None) -> int:
    """Most progress ticks :func:`fit_candidate` (with the same ``fit`` settings; None: the defaults) makes
    for ``cand``: one per batch round (design, LM iteration, phase sweep, valley search)."""
    fit = FitSettings() if fit is None else fit
    iterations, fold_iterations = fit.iterations, fit.fold_iterations
    phase_sweeps, valley_rounds = fit.phase_sweeps, fit.valley_rounds
    if cand.stochastic:
        return 0
    if any(d.periodic for d in cand.dims):
        return 1 + 2 * (phase_sweeps + iterations) + 1 + iterations + fold_iterations
    return 1 + iterations + valley_rounds * (1 + iterations) + fold_iterations


def fit_candidate(cand: Candidate, ev: Evaluator, nominal: SimModel, folds: np.ndarray,
                  rng: np.random.Generator, settings: GapSettings | None = None,
                  tick: Callable[[], None] | None = None, progress: Progress | None = None) -> FitResult:
    """Fit ``cand`` on all runs and on every fold's training runs (see the module docstring).

    1. A shared scrambled Sobol design, plus the effect's null point (so a fit is never worse than
       nominal on its training runs) and the effect's prior start, if it has one (roller_gap: the
       nominal model's own μ'' and roller fraction).
    2. All-run fit: from the ``starts`` best design points that lie apart; roller phases searched
       on a grid of the multiple-shooting cost, then batched Levenberg–Marquardt, then restarts on the
       open-loop cost (``phase_restarts`` random phase vectors: coordinate descent over all
       dimensions, LM from the best three) and a final phase sweep + LM.
    3. Fold fits: Levenberg–Marquardt on the fold's training runs, warm-started at the all-run fit.
       A fold fit is the point with the least training error among the design, the warm start and
       its own steps. The warm start is the one channel by which held-out runs inform a fold fit:
       it picks the basin (narrow roller-phase basins defeated independent per-fold searches on
       two thirds of the data); everything the fold fit then does uses its training runs only.

    The stochastic candidate (wheel_liftoff) is fitted by lift-event inference instead
    (:func:`_fit_events`). ``settings``: the rounds above (``settings.fit``), the event search's and the
    decision's noise level (None: the defaults). ``tick``: called after each batch round (at most
    :func:`max_ticks`); ``progress``: the fit's progress, one item per batch round (the lift-event inference:
    its steps and batches).
    """
    settings = GapSettings() if settings is None else settings
    if progress is not None:
        progress.start()
    if cand.stochastic:
        return _fit_events(cand, ev, nominal, folds, settings, progress)
    if progress is not None:
        tick = _both(tick, progress.update)
    fs = settings.fit
    iterations, fold_iterations, starts, phase_grid = fs.iterations, fs.fold_iterations, fs.starts, fs.phase_grid
    phase_sweeps, phase_starts, phase_restarts = fs.phase_sweeps, fs.phase_starts, fs.phase_restarts
    valley_rounds = fs.valley_rounds
    p = cand.n_params
    K = int(folds.max()) + 1
    R = len(folds)
    n0 = 16 if p <= 2 else 32 if p <= 4 else 64
    design = qmc.Sobol(p, scramble=True, seed=rng).random(n0)
    null = null_point(cand)
    if null is not None:
        design = np.vstack([null, design])
    prior = prior_point(cand)
    if prior is not None:
        # An effect's prior start (roller_gap: the nominal model's own μ'' and roller fraction) stands in
        # for most of the Sobol design: kept are the prior, the null point and a quarter of the design.
        design = np.vstack([prior, design[:1 + n0 // 4]])

    def evaluate(us: np.ndarray, shooting: bool = False) -> tuple[np.ndarray, list[list[np.ndarray]]]:
        res = ev.residuals([nominal.with_effect(cand.name, cand.params(u)) for u in us], shooting)
        return np.array([[run_sse(r) for r in per_run] for per_run in res]), res

    design_sse, design_res = evaluate(design)
    if tick:
        tick()
    # Targets 0..K-1: the folds' training runs; target K: all runs.
    train = [folds != k for k in range(K)] + [np.ones(R, dtype=bool)]
    pools_u = [[design] for _ in train]
    pools_sse = [[design_sse] for _ in train]
    periodic = [j for j, d in enumerate(cand.dims) if d.periodic]
    # With phases the search starts away from the null point (where phases do nothing).
    rows = np.arange(len(design)) if not periodic or null is None else np.flatnonzero(np.any(design != null, axis=1))
    # Low-dimensional candidates are cheap per start and can have several basins in directions (a 16 mm
    # centre-of-mass offset at -55 deg was fitted at (31.9, 1.3) mm from the two best design points):
    # they start LM from low_dim_starts design points that lie apart.
    n_starts = phase_starts if periodic else (max(starts, fs.low_dim_starts) if p <= fs.low_dim else starts)
    free = [j for j in range(p) if j not in periodic]
    chosen: list[int] = []
    for i in rows[np.argsort(design_sse[rows].sum(axis=1))]:
        if len(chosen) == n_starts:
            break
        # Starts lie apart (0.3 in the unit cube), so several basins are tried, not one basin twice;
        # phases are searched from every start anyway, so only the other dimensions count.
        if all(np.max(np.abs(design[i, free] - design[c, free])) >= 0.3 for c in chosen):
            chosen.append(int(i))
    states = [SearchState(t=K, u=design[i].copy(), res=design_res[i], cost=float(design_sse[i].sum()), lam=1e-2)
              for i in chosen]
    ctx = SearchContext(evaluate=evaluate, train=train, pools_u=pools_u, pools_sse=pools_sse, cand=cand, h=3e-3,
                        tick=tick)
    if periodic and ev.has_windows():
        # Phases: the cost is multimodal in each (a gap passes once per roller pitch). On one long
        # open-loop rollout a wrong phase of one wheel spoils the landscape of the others, so the
        # phases are searched on the multiple-shooting cost (windows restarted from measured states:
        # each wheel's gap contacts show up locally), from several starts whose other parameters
        # differ (a phase grid under a wrong μ'' or roller fraction can settle in a compromise).
        # Then LM on the open-loop cost, and one more phase sweep + LM from the best result: the
        # phases found under the start's μ'' are re-searched under the fitted one.
        phase_search(states, periodic, phase_grid, phase_sweeps, ctx, K)
        levenberg_marquardt(states, iterations, ctx)
        kept = min(states, key=lambda s: s.cost)
        # The shooting cost is biased by noisy start states (velocities from the tracker), so its fit
        # can sit in a neighbouring basin of the open-loop cost, where μ'', roller fraction and
        # phases have co-adjusted into a compromise (the basins are narrow and coupled: neither LM
        # nor a sweep of the phases alone leaves it). Restarts: the kept fit and `phase_restarts`
        # random phase vectors under its μ'' and roller fraction; coordinate descent on the
        # open-loop cost over all dimensions (μ'' and roller fraction on local grids, phases on a
        # coarse full grid); LM from the best three; a fine phase sweep + LM from the best.
        # Compute only: skipped when the kept fit explains less than rules.min_improvement of the
        # nominal error (noise-level data, where no basin of the effect can matter).
        if kept.cost < (1.0 - settings.rules.min_improvement) * float(ev.nominal_baseline(nominal)[1].sum()):
            restarts = np.tile(kept.u, (1 + phase_restarts, 1))
            restarts[1:, periodic] = rng.random((phase_restarts, len(periodic)))
            states = [SearchState(t=K, u=u, lam=1e-2) for u in restarts]  # scored by phase_search
            phase_search(states, periodic, phase_grid // 2, phase_sweeps, ctx, K, shooting=False, local=free)
            states = sorted(states, key=lambda s: s.cost)[:3]
            levenberg_marquardt(states, iterations, ctx)
            states = [replace(min(states, key=lambda s: s.cost))]  # a copy
            phase_search(states, periodic, phase_grid, 1, ctx, K, shooting=False)
            levenberg_marquardt(states, iterations, ctx)
        if kept.cost < states[0].cost:
            states = [kept]
    else:
        levenberg_marquardt(states, iterations, ctx)
        # Narrow curved valleys (a centre-of-mass offset that shifts load onto a wheel at the edge of
        # slip: ±0.5 mm across, tens of mm along) stop LM on small-scale roughness of the cost long
        # before the valley floor's minimum; line searches along the valley, then LM again.
        for _ in range(valley_rounds):
            if not valley_search(states, ctx):
                break
            levenberg_marquardt(states, iterations, ctx)
    i_all = int(np.argmin(np.vstack(pools_sse[K]).sum(axis=1)))
    u_all = np.vstack(pools_u[K])[i_all]
    a_sse = np.vstack(pools_sse[K])[i_all]
    best = min(states, key=lambda s: s.cost)
    fold_states = []
    for k in range(K):
        pools_u[k].append(best.u[None, :])
        pools_sse[k].append(np.array([[run_sse(r) for r in best.res]]))
        fold_states.append(SearchState(
            t=k, u=best.u.copy(), res=best.res,
            cost=float(sum(run_sse(r) for r, m in zip(best.res, train[k], strict=True) if m)), lam=1e-2))
    levenberg_marquardt(fold_states, fold_iterations, ctx)
    heldout = np.zeros(R)
    fold_params = []
    for k in range(K):
        pu, ps = np.vstack(pools_u[k]), np.vstack(pools_sse[k])
        i = int(np.argmin(ps[:, train[k]].sum(axis=1)))
        heldout[folds == k] = ps[i, folds == k]
        fold_params.append(cand.params(pu[i]))
    return FitResult(candidate=cand, u_all=u_all, params_all=cand.params(u_all), sse_all=a_sse, heldout=heldout,
                     fold_params=fold_params, pool_u=np.vstack(pools_u[K]), pool_sse=np.vstack(pools_sse[K]))


def _both(first: Callable[[], None] | None, second: Callable[[], None]) -> Callable[[], None]:
    """A tick that calls ``first`` (if any), then ``second``."""
    def tick() -> None:
        if first is not None:
            first()
        second()
    return tick


def _fit_events(cand: Candidate, ev: Evaluator, nominal: SimModel, folds: np.ndarray,
                settings: GapSettings, progress: Progress | None = None) -> FitResult:
    """wheel_liftoff by MAP lift-event inference (omni_gym.discrepancy.fit.events).

    Every run's events are inferred with the BIC cost 3·ln N per event (N residual components of the
    dataset); the candidate's per-run SSE is the open-loop replay of the run with its events. Rates
    are the exponential-holding-time MLEs from the events: on all runs for the reported fit, and on
    each fold's training runs for that fold's parameters.

    **The held-out score is a marginal-likelihood approximation, not a pure prediction.** The events
    are latent variables of each run, so they are inferred on every run — held-out runs included —
    and only the rates come from training runs. The likelihood of a held-out run integrates over its
    events; its MAP term, with each event charged its BIC cost (carried into :func:`decide` through
    ``n_params_eff`` = 2 rates + 3 per event), approximates that integral. The event cost does not
    depend on the fold's rates, so the inferred events are the same in every fold.
    """
    ds = ev.ds
    n_comp = count_components(ds)
    N = float(max(n_comp.sum(), 2))
    _, sse0, _ = ev.nominal_baseline(nominal)
    sigma, _ = ev.noise_floor(nominal)  # the noise floor the decision uses (tracker noise and integration error)
    counter = [0]
    problem = EventProblem(ds, nominal, ev.lever, PARAMS_PER_EVENT * math.log(N), sse0, n_comp, ev.dt, sigma=sigma,
                           adequacy=1.0 + settings.rules.noise_margin,  # "noise level" as the decision defines it
                           windows=ev.windows)
    efit = infer_events(problem, settings.event_search, simulate=ev.simulate, counter=counter, progress=progress)
    ev.simulated += counter[0]
    null = null_point(cand)

    def point(mask: np.ndarray | None) -> np.ndarray:
        rates = efit.rates(mask)
        if rates is None:
            return null
        # The candidate's bounds (rates outside them are clipped).
        return cand.point({d.name: v for d, v in zip(cand.dims, rates, strict=True)})

    u_all = point(None)
    K = int(folds.max()) + 1
    fold_params = [cand.params(point(folds != k)) for k in range(K)]
    return FitResult(candidate=cand, u_all=u_all, params_all=cand.params(u_all), sse_all=efit.sse.copy(),
                     heldout=efit.sse.copy(), fold_params=fold_params, pool_u=u_all[None, :],
                     pool_sse=efit.sse[None, :].copy(),
                     n_params_eff=cand.n_params + PARAMS_PER_EVENT * efit.n_events(), event_fit=efit)


def param_intervals(fit: FitResult, rng: np.random.Generator, n_boot: int = 200) -> dict:
    """Bootstrap over runs: 5-95 % interval of each fitted dimension (refit = argmin over the pool).

    For the event-inferred candidate the refit is the rate MLE from the resampled runs' events.
    """
    R = fit.pool_sse.shape[1]
    idx = rng.integers(0, R, (n_boot, R))
    if fit.event_fit is not None:
        return _event_rate_intervals(fit, idx)
    w = np.stack([np.bincount(row, minlength=R) for row in idx])  # (n_boot, R) run weights
    best = np.argmin(w @ fit.pool_sse.T, axis=1)
    vals = np.array([[d.value(float(x)) for d, x in zip(fit.candidate.dims, fit.pool_u[b], strict=True)]
                     for b in best])
    return {d.name: [float(np.percentile(vals[:, j], 5)), float(np.percentile(vals[:, j], 95))]
            for j, d in enumerate(fit.candidate.dims)}


def _event_rate_intervals(fit: FitResult, idx: np.ndarray) -> dict:
    """5-95 % bootstrap range of the event-based rates (resamples without events: the null point)."""
    ef = fit.event_fit
    R = len(ef.events)
    null = [fit.candidate.null[d.name] for d in fit.candidate.dims]  # the rates at the effect's null point
    v = np.array([ef.rates_weighted(np.bincount(row, minlength=R).astype(float)) or null for row in idx])
    return {d.name: [float(np.percentile(v[:, j], 5)), float(np.percentile(v[:, j], 95))]
            for j, d in enumerate(fit.candidate.dims)}
