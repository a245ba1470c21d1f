"""Explain a gap: fit every candidate effect, score it on held-out runs, decide.

Fitting is a batched, seeded, derivative-free search in each candidate's bounded parameter cube
(the roller phases make the cost multimodal, so gradients alone would stall): a scrambled Sobol
design shared by all fits, then shrinking local rounds around each fit's best point. Every point is
simulated on every run in one world, giving a table SSE[point, run]. A fit on a set of runs is the
point with the least SSE over those runs among the shared design and that fit's own refinements.

Held-out scoring: K folds by run. Fold k's fit sees only the other runs; its SSE on the runs of
fold k is that candidate's held-out error there. A candidate's held-out score is
N·ln(SSE_heldout/N) + p·ln(N) (BIC form; N residual components, p parameters).

Decision (thresholds in :data:`RULES`, why in ``docs/discrepancy.md``): a candidate must improve the
held-out error significantly (paired bootstrap over runs); it is named if it removes most of the
gap beyond tracker noise, else the outcome is ``unexplained``; ``none`` when nothing improves and
the nominal residual is at the noise level.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from omni_gym.discrepancy.dataset import Dataset
from omni_gym.discrepancy.events import PARAMS_PER_EVENT, EventFit, infer_events
from omni_gym.discrepancy.residuals import count_components, noise_estimate, run_sse, shooting_windows
from omni_gym.discrepancy.simulate import FIT_DT, Job, pose_residual, simulate_poses
from omni_gym.physics.model import SimModel

RULES = {
    "significance": 0.95,  # bootstrap share of run resamples in which the candidate beats nominal
    "min_improvement": 0.05,  # least held-out MSE reduction (share of nominal MSE) that counts
    "noise_margin": 0.3,  # MSE within (1 + margin)·σ̂² counts as noise-level
    "min_gap_reduction": 0.7,  # least reduction of the excess RMS for a named effect
    "ambiguity": 0.8,  # winner must beat a qualifying runner-up in this share of resamples
}
N_BOOT = 400
# Search rounds of fit_candidate (also the progress bound max_ticks): LM iterations of the all-run and
# fold fits, roller phase sweeps, valley line-search rounds.
ITERATIONS, FOLD_ITERATIONS, PHASE_SWEEPS, VALLEY_ROUNDS = 6, 4, 2, 3


@dataclass(frozen=True)
class Dim:
    """One fitted parameter: bounds [lo, hi] (log-spaced if ``log``; ``periodic`` wraps)."""

    name: str
    lo: float
    hi: float
    log: bool = False
    periodic: bool = False

    def value(self, u: float) -> float:
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))


@dataclass(frozen=True)
class Candidate:
    """A library effect with its fitted dimensions and how they map to the effect's parameters."""

    name: str
    dims: tuple[Dim, ...]
    build: Callable[[list[float]], dict]
    stochastic: bool = False

    @property
    def n_params(self) -> int:
        return len(self.dims)

    def params(self, u: np.ndarray) -> dict:
        return self.build([d.value(float(x)) for d, x in zip(self.dims, u, strict=True)])


def candidates(model: SimModel) -> list[Candidate]:
    """The effect library as fit candidates for ``model`` (bounds wide enough for real robots)."""
    n = model.n_wheels
    pitch = 2 * math.pi / model.robot.rollers
    lever = float(np.max(np.hypot(*model.robot.positions().T)))
    c = 0.4 * lever  # the centre of mass well inside the support polygon
    return [
        Candidate("roller_gap", (Dim("mu_gap", 0.05, 1.5), Dim("roller_fraction", 0.6, 1.0),
                                 *[Dim(f"phase{i + 1}", 0.0, pitch, periodic=True) for i in range(n)]),
                  lambda v: {"mu_gap": v[0], "roller_fraction": v[1], "phase": list(v[2:])}),
        Candidate("kinetic_friction", (Dim("ratio", 0.2, 1.0), Dim("v_s", 0.002, 0.3, log=True)),
                  lambda v: {"ratio": v[0], "v_s": v[1]}),
        Candidate("com_offset", (Dim("cx", -c, c), Dim("cy", -c, c)), lambda v: {"com": [v[0], v[1]]}),
        Candidate("wheel_radius", tuple(Dim(f"scale{i + 1}", 0.85, 1.15) for i in range(n)),
                  lambda v: {"scale": list(v)}),
        Candidate("motor_lag", (Dim("tau", 0.001, 0.5, log=True),), lambda v: {"tau": v[0]}),
        Candidate("wheel_liftoff", (Dim("lift_rate", 0.05, 5.0, log=True), Dim("recover_rate", 0.5, 50.0, log=True)),
                  lambda v: {"lift_rate": v[0], "recover_rate": v[1]}, stochastic=True),
    ]


class Evaluator:
    """SSE per run of parameter points, by batched simulation (one world per call)."""

    def __init__(self, dataset: Dataset, lever: float, dt: float = FIT_DT, max_batch: int = 1500) -> None:
        self.ds = dataset
        self.lever = lever
        self.dt = dt
        self.max_batch = max_batch
        self.simulated = 0  # robot-runs simulated (for the report)
        self._windows: list[tuple] | None = None
        self._baseline: tuple | None = None

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

    def residuals(self, models: list[SimModel], shooting: bool = False) -> list[list[np.ndarray]]:
        """Per model, per run: residual (K, 3) [m] measured − simulated.

        ``shooting``: simulate the windows of :func:`shooting_windows` instead (each from the measured
        state at its start) and return, per run, the windows' residual rows stacked.
        """
        if shooting:
            return self._shooting_residuals(models)
        runs = self.ds.runs
        jobs = [Job(m, r) for m in models for r in runs]
        out = simulate_poses(jobs, self.dt, self.max_batch)
        self.simulated += len(jobs)
        R = len(runs)
        return [[pose_residual(run.pose, out[mi * R + ri], self.lever) for ri, run in enumerate(runs)]
                for mi in range(len(models))]

    def has_windows(self) -> bool:
        """True when some run is observed densely enough for multiple shooting."""
        return bool(self.windows)

    def _shooting_residuals(self, models: list[SimModel]) -> list[list[np.ndarray]]:
        wins = self.windows
        jobs = [Job(m, self.ds.runs[ri], k0=k0, k1=k1, state0=st) for m in models for ri, k0, k1, st in wins]
        out = simulate_poses(jobs, self.dt, self.max_batch)
        self.simulated += len(jobs)
        res = []
        W = len(wins)
        for mi in range(len(models)):
            per_run: list[list[np.ndarray]] = [[np.zeros((1, 3))] for _ in self.ds.runs]
            for wi, (ri, k0, k1, _) in enumerate(wins):
                run = self.ds.runs[ri]
                per_run[ri].append(pose_residual(run.pose[k0 + 1:k1 + 1], out[mi * W + wi][1:], self.lever))
            res.append([np.vstack(x) for x in per_run])
        return res


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
    # inferred lift event) and the inferred events (omni_gym.discrepancy.events.EventFit).
    n_params_eff: int | None = None
    event_fit: EventFit | None = None


def make_folds(n_runs: int, rng: np.random.Generator, k: int = 3) -> np.ndarray:
    """(R,) fold index of each run: K = min(k, R) folds of near-equal size, seeded order."""
    k = min(k, n_runs)
    order = rng.permutation(n_runs)
    folds = np.empty(n_runs, dtype=int)
    folds[order] = np.arange(n_runs) % k
    return folds


def max_ticks(cand: Candidate, iterations: int = ITERATIONS, fold_iterations: int = FOLD_ITERATIONS,
              phase_sweeps: int = PHASE_SWEEPS, valley_rounds: int = VALLEY_ROUNDS) -> int:
    """Most progress ticks :func:`fit_candidate` (same keyword values) makes for ``cand``: one per batch
    round (design, LM iteration, phase sweep, valley search)."""
    if cand.stochastic:
        return 0
    if any(d.periodic for d in cand.dims):
        return 1 + 2 * (phase_sweeps + iterations) + 1 + iterations + fold_iterations
    return 1 + iterations + valley_rounds * (1 + iterations) + fold_iterations


def fit_candidate(cand: Candidate, ev: Evaluator, nominal: SimModel, folds: np.ndarray,
                  rng: np.random.Generator, iterations: int = ITERATIONS, fold_iterations: int = FOLD_ITERATIONS,
                  starts: int = 2, phase_grid: int = 32, phase_sweeps: int = PHASE_SWEEPS, phase_starts: int = 2,
                  phase_restarts: int = 16, valley_rounds: int = VALLEY_ROUNDS,
                  tick: Callable[[], None] | None = None) -> FitResult:
    """Fit ``cand`` on all runs and on every fold's training runs (see the module docstring).

    1. A shared scrambled Sobol design, plus the effect's null point (so a fit is never worse than
       nominal on its training runs) and, for roller_gap, the nominal model's own μ'' and roller
       fraction.
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
    (:func:`_fit_events`).
    """
    if cand.stochastic:
        return _fit_events(cand, ev, nominal, folds)
    p = cand.n_params
    K = int(folds.max()) + 1
    R = len(folds)
    n0 = 16 if p <= 2 else 32 if p <= 4 else 64
    design = qmc.Sobol(p, scramble=True, seed=rng).random(n0)
    null = _null_point(cand, nominal)
    if null is not None:
        design = np.vstack([null, design])
    if cand.name == "roller_gap":
        prior = np.full(p, 0.5)
        prior[0] = np.clip((nominal.surface.mu_gap - cand.dims[0].lo) / (cand.dims[0].hi - cand.dims[0].lo), 0, 1)
        prior[1] = np.clip((nominal.robot.roller_fraction - cand.dims[1].lo) / (cand.dims[1].hi - cand.dims[1].lo),
                           0, 1)
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
    n_starts = phase_starts if periodic else starts
    free = [j for j in range(p) if j not in periodic]
    chosen: list[int] = []
    for i in rows[np.argsort(design_sse[rows].sum(axis=1))]:
        if len(chosen) == n_starts:
            break
        # Starts lie apart (0.3 in the unit cube), so several basins are tried, not one basin twice;
        # phases are searched from every start anyway, so only the other dimensions count.
        if all(np.max(np.abs(design[i, free] - design[c, free])) >= 0.3 for c in chosen):
            chosen.append(int(i))
    states = [{"t": K, "u": design[i].copy(), "res": design_res[i], "cost": float(design_sse[i].sum()),
               "lam": 1e-2} for i in chosen]
    lm = dict(evaluate=evaluate, train=train, pools_u=pools_u, pools_sse=pools_sse, cand=cand, h=3e-3, tick=tick)
    if periodic and ev.has_windows():
        # Phases: the cost is multimodal in each (a gap passes once per roller pitch). On one long
        # open-loop rollout a wrong phase of one wheel spoils the landscape of the others, so the
        # phases are searched on the multiple-shooting cost (windows restarted from measured states:
        # each wheel's gap contacts show up locally), from several starts whose other parameters
        # differ (a phase grid under a wrong μ'' or roller fraction can settle in a compromise).
        # Then LM on the open-loop cost, and one more phase sweep + LM from the best result: the
        # phases found under the start's μ'' are re-searched under the fitted one.
        _phase_search(states, periodic, phase_grid, phase_sweeps, evaluate, pools_u[K], pools_sse[K], tick)
        _levenberg_marquardt(states, iterations, **lm)
        kept = min(states, key=lambda s: s["cost"])
        # The shooting cost is biased by noisy start states (velocities from the tracker), so its fit
        # can sit in a neighbouring basin of the open-loop cost, where μ'', roller fraction and
        # phases have co-adjusted into a compromise (the basins are narrow and coupled: neither LM
        # nor a sweep of the phases alone leaves it). Restarts: the kept fit and `phase_restarts`
        # random phase vectors under its μ'' and roller fraction; coordinate descent on the
        # open-loop cost over all dimensions (μ'' and roller fraction on local grids, phases on a
        # coarse full grid); LM from the best three; a fine phase sweep + LM from the best.
        # Compute only: skipped when the kept fit explains less than RULES['min_improvement'] of the
        # nominal error (noise-level data, where no basin of the effect can matter).
        if kept["cost"] < (1.0 - RULES["min_improvement"]) * float(ev.nominal_baseline(nominal)[1].sum()):
            restarts = np.tile(kept["u"], (1 + phase_restarts, 1))
            restarts[1:, periodic] = rng.random((phase_restarts, len(periodic)))
            states = [{"u": u, "lam": 1e-2, "t": K} for u in restarts]
            _phase_search(states, periodic, phase_grid // 2, phase_sweeps, evaluate, pools_u[K], pools_sse[K], tick,
                          shooting=False, local=free)
            states = sorted(states, key=lambda s: s["cost"])[:3]
            _levenberg_marquardt(states, iterations, **lm)
            states = [dict(min(states, key=lambda s: s["cost"]))]
            _phase_search(states, periodic, phase_grid, 1, evaluate, pools_u[K], pools_sse[K], tick, shooting=False)
            _levenberg_marquardt(states, iterations, **lm)
        if kept["cost"] < states[0]["cost"]:
            states = [kept]
    else:
        _levenberg_marquardt(states, iterations, **lm)
        # Narrow curved valleys (a centre-of-mass offset that shifts load onto a wheel at the edge of
        # slip: ±0.5 mm across, tens of mm along) stop LM on small-scale roughness of the cost long
        # before the valley floor's minimum; line searches along the valley, then LM again.
        for _ in range(valley_rounds):
            if not _valley_search(states, **lm):
                break
            _levenberg_marquardt(states, iterations, **lm)
    i_all = int(np.argmin(np.vstack(pools_sse[K]).sum(axis=1)))
    u_all = np.vstack(pools_u[K])[i_all]
    a_sse = np.vstack(pools_sse[K])[i_all]
    best = min(states, key=lambda s: s["cost"])
    fold_states = []
    for k in range(K):
        pools_u[k].append(best["u"][None, :])
        pools_sse[k].append(np.array([[run_sse(r) for r in best["res"]]]))
        fold_states.append({"t": k, "u": best["u"].copy(), "res": best["res"],
                            "cost": float(sum(run_sse(r) for r, m in zip(best["res"], train[k], strict=True) if m)),
                            "lam": 1e-2})
    _levenberg_marquardt(fold_states, fold_iterations, **lm)
    heldout = np.zeros(R)
    fold_params = []
    for k in range(K):
        pu, ps = np.vstack(pools_u[k]), np.vstack(pools_sse[k])
        i = int(np.argmin(ps[:, train[k]].sum(axis=1)))
        heldout[folds == k] = ps[i, folds == k]
        fold_params.append(cand.params(pu[i]))
    return FitResult(candidate=cand, u_all=u_all, params_all=cand.params(u_all), sse_all=a_sse, heldout=heldout,
                     fold_params=fold_params, pool_u=np.vstack(pools_u[K]), pool_sse=np.vstack(pools_sse[K]))


def _phase_search(states: list[dict], periodic: list[int], grid: int, sweeps: int, evaluate,
                  pool_u: list, pool_sse: list, tick, shooting: bool = True, local: list[int] = (),
                  width: float = 0.06, local_points: int = 9) -> None:
    """Coordinate sweeps for every search in ``states``, one batch per dimension: each dimension in
    ``local`` on ``local_points`` points within ±``width`` (unit cube) of the search's value, then
    each periodic dimension on a full grid of ``grid`` points; a search keeps the best point. The
    sweep cost is the multiple-shooting one (``shooting``) or the open-loop one. Each search then
    moves to its result, re-scored on the open-loop cost (added to the pool).
    """
    start = np.array([st["u"] for st in states])
    scost = evaluate(start, shooting=shooting)[0].sum(axis=1)
    for st, c in zip(states, scost, strict=True):
        st["scost"] = float(c)
    offsets = np.linspace(-width, width, local_points)
    for _ in range(sweeps):
        for j in [*local, *periodic]:
            grids = []
            for st in states:
                values = np.clip(st["u"][j] + offsets, 0.0, 1.0) if j in local else (np.arange(grid) + 0.5) / grid
                g = np.tile(st["u"], (len(values), 1))
                g[:, j] = values
                grids.append(g)
            cost = evaluate(np.concatenate(grids), shooting=shooting)[0].sum(axis=1).reshape(len(states), -1)
            for st, g, c in zip(states, grids, cost, strict=True):
                i = int(np.argmin(c))
                if c[i] < st["scost"]:
                    st.update(u=g[i].copy(), scost=float(c[i]))
        if tick:
            tick()
    us = np.array([st["u"] for st in states])
    m_sse, m_res = evaluate(us)
    pool_u.append(us)
    pool_sse.append(m_sse)
    for st, sse, res in zip(states, m_sse, m_res, strict=True):
        st.update(res=res, cost=float(sse.sum()))


def _fit_events(cand: Candidate, ev: Evaluator, nominal: SimModel, folds: np.ndarray) -> FitResult:
    """wheel_liftoff by MAP lift-event inference (omni_gym.discrepancy.events).

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
    _, sse0, sigma = ev.nominal_baseline(nominal)  # the same σ̂ the workflow reports
    counter = [0]
    efit = infer_events(ds, nominal, ev.lever, PARAMS_PER_EVENT * math.log(N), sse0, n_comp, ev.dt,
                        sigma=sigma, windows=ev.windows, counter=counter,
                        adequacy=1.0 + RULES["noise_margin"])  # "noise level" as the decision defines it
    ev.simulated += counter[0]
    null = _null_point(cand, nominal)

    def point(mask: np.ndarray | None) -> np.ndarray:
        rates = efit.rates(mask)
        if rates is None:
            return null
        u = np.array([(math.log(v) - math.log(d.lo)) / (math.log(d.hi) - math.log(d.lo))
                      for d, v in zip(cand.dims, rates, strict=True)])
        return np.clip(u, 0.0, 1.0)  # the candidate's bounds (rates outside them are clipped)

    u_all = point(None)
    K = int(folds.max()) + 1
    fold_params = [cand.params(point(folds != k)) for k in range(K)]
    return FitResult(candidate=cand, u_all=u_all, params_all=cand.params(u_all), sse_all=efit.sse.copy(),
                     heldout=efit.sse.copy(), fold_params=fold_params, pool_u=u_all[None, :],
                     pool_sse=efit.sse[None, :].copy(),
                     n_params_eff=cand.n_params + PARAMS_PER_EVENT * efit.n_events(), event_fit=efit)


def _jacobians(states: list[dict], evaluate, train, p: int, h: float) -> tuple[list, np.ndarray, list[np.ndarray]]:
    """Forward-difference Jacobians of every search in ``states`` in one batch: per search the p
    points u ± h·e_j (stepping down where u + h would leave the cube), their (p·S, R) SSE, and the
    Jacobian of the stacked training-run residuals (``_stack``) with respect to u."""
    fd, signs = [], []
    for st in states:
        sgn = np.where(st["u"] + h <= 1.0, 1.0, -1.0)
        fd.append(st["u"] + np.diag(sgn * h))
        signs.append(sgn)
    fd_sse, fd_res = evaluate(np.concatenate(fd))
    jacs = []
    for si, st in enumerate(states):
        mask = train[st["t"]]
        r0 = _stack(st["res"], mask)
        jacs.append(np.column_stack([(_stack(fd_res[si * p + j], mask) - r0) / (signs[si][j] * h) for j in range(p)]))
    return fd, fd_sse, jacs


def _levenberg_marquardt(states: list[dict], iterations: int, evaluate, train, pools_u, pools_sse, cand, h,
                         tick) -> None:
    """Batched LM steps for every search in ``states`` (dicts t, u, res, cost, lam; updated in place).

    Per iteration: forward-difference Jacobians (p points per search) in one batch, then three
    damping levels per search in a second batch; a search keeps the best trial if it lowers its
    training error and stops when a tiny step gains less than 0.01 % (far below what matters for
    the decision thresholds of RULES) or the damping has grown past use.
    """
    p = cand.n_params
    damping = (0.1, 1.0, 10.0)
    nd = len(damping)
    for st in states:
        st["done"] = False
    for _ in range(iterations):
        live = [st for st in states if not st["done"]]
        if not live:
            break
        fd, fd_sse, jacs = _jacobians(live, evaluate, train, p, h)
        trials = []
        for st, J in zip(live, jacs, strict=True):
            r0 = _stack(st["res"], train[st["t"]])
            # r = measured − simulated(u); the Gauss–Newton step solves (JᵀJ + λ·diag JᵀJ) δ = −Jᵀr.
            A = J.T @ J
            g = J.T @ r0
            dg = np.diag(A).copy() + 1e-12
            for f in damping:
                try:
                    step = np.linalg.solve(A + st["lam"] * f * np.diag(dg), -g)
                except np.linalg.LinAlgError:
                    step = np.zeros(p)
                trials.append(_to_cube(cand, st["u"] + step))
        tr_u = np.array(trials)
        tr_sse, tr_res = evaluate(tr_u)
        for si, st in enumerate(live):
            t, mask = st["t"], train[st["t"]]
            pools_u[t] += [fd[si], tr_u[nd * si:nd * si + nd]]
            pools_sse[t] += [fd_sse[si * p:(si + 1) * p], tr_sse[nd * si:nd * si + nd]]
            costs = tr_sse[nd * si:nd * si + nd][:, mask].sum(axis=1)
            j = int(np.argmin(costs))
            if costs[j] < st["cost"]:
                st["done"] = bool(costs[j] > (1.0 - 1e-4) * st["cost"]
                                  and np.max(np.abs(tr_u[nd * si + j] - st["u"])) < 1e-3)
                st.update(u=tr_u[nd * si + j], res=tr_res[nd * si + j], cost=float(costs[j]),
                          lam=max(st["lam"] * 0.3 * damping[j], 1e-6))
            else:
                st["lam"] *= 10.0
                st["done"] = st["lam"] > 1e4
        if tick:
            tick()


VALLEY_STEPS = np.array([0.005, 0.01, 0.02, 0.04, 0.08, 0.16, 0.32, 0.64])  # unit cube


def _valley_search(states: list[dict], evaluate, train, pools_u, pools_sse, cand, h, tick) -> bool:
    """One line search per search in ``states`` along its valley: the direction of least curvature
    of the Gauss–Newton Hessian JᵀJ (forward differences), at :data:`VALLEY_STEPS` both ways, in one
    batch; a search moves to the best point if it lowers its training error. True if any moved."""
    p = cand.n_params
    fd, fd_sse, jacs = _jacobians(states, evaluate, train, p, h)
    lines = []
    for st, J in zip(states, jacs, strict=True):
        v = np.linalg.eigh(J.T @ J)[1][:, 0]  # eigenvalues ascending: the flattest direction
        steps = np.concatenate([VALLEY_STEPS, -VALLEY_STEPS])
        lines.append(np.array([_to_cube(cand, st["u"] + s * v) for s in steps]))
    ln_sse, ln_res = evaluate(np.concatenate(lines))
    moved = False
    m = len(VALLEY_STEPS) * 2
    for si, st in enumerate(states):
        t, mask = st["t"], train[st["t"]]
        pools_u[t] += [fd[si], lines[si]]
        pools_sse[t] += [fd_sse[si * p:(si + 1) * p], ln_sse[si * m:(si + 1) * m]]
        costs = ln_sse[si * m:(si + 1) * m][:, mask].sum(axis=1)
        j = int(np.argmin(costs))
        if costs[j] < st["cost"]:
            st.update(u=lines[si][j], res=ln_res[si * m + j], cost=float(costs[j]), lam=1e-2)
            moved = True
    if tick:
        tick()
    return moved


def _stack(per_run: list[np.ndarray], mask: np.ndarray) -> np.ndarray:
    """Residual components of the runs in ``mask`` (observed rows after t = 0), flattened; NaN as 0."""
    return np.concatenate([np.nan_to_num(r[1:]).ravel() for r, m in zip(per_run, mask, strict=True) if m])


def _to_cube(cand: Candidate, u: np.ndarray) -> np.ndarray:
    out = u.copy()
    for j, d in enumerate(cand.dims):
        out[j] = np.mod(out[j], 1.0) if d.periodic else np.clip(out[j], 0.0, 1.0)
    return out


def _null_point(cand: Candidate, nominal: SimModel) -> np.ndarray | None:
    """Unit-cube point at which the effect changes nothing (None when the family has none)."""
    lo = {d.name: d.lo for d in cand.dims}
    hi = {d.name: d.hi for d in cand.dims}
    if cand.name == "kinetic_friction":
        null = {"ratio": 1.0}
    elif cand.name == "roller_gap":
        null = {"roller_fraction": 1.0}  # no rigid material: the initial model
    elif cand.name == "com_offset":
        null = {"cx": float(nominal.com[0]), "cy": float(nominal.com[1])}
    elif cand.name == "motor_lag":
        null = {"tau": lo["tau"]}
    elif cand.name == "wheel_liftoff":
        null = {"lift_rate": lo["lift_rate"], "recover_rate": hi["recover_rate"]}
    elif cand.name == "wheel_radius":
        null = {d.name: 1.0 for d in cand.dims}
    else:
        null = None
    if null is None:
        return None
    u = np.full(cand.n_params, 0.5)
    for j, d in enumerate(cand.dims):
        if d.name in null:
            v = null[d.name]
            u[j] = ((math.log(v) - math.log(d.lo)) / (math.log(d.hi) - math.log(d.lo)) if d.log
                    else (v - d.lo) / (d.hi - d.lo))
    if cand.name == "kinetic_friction":
        u[1] = 0.5  # v_s is irrelevant at ratio 1
    return np.clip(u, 0.0, 1.0)


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
    null = [fit.candidate.dims[0].lo, fit.candidate.dims[1].hi]
    v = np.array([ef.rates_weighted(np.bincount(row, minlength=R).astype(float)) or null for row in idx])
    return {d.name: [float(np.percentile(v[:, j], 5)), float(np.percentile(v[:, j], 95))]
            for j, d in enumerate(fit.candidate.dims)}


def _share_better(gain: np.ndarray) -> float:
    """Share of bootstrap resamples with a positive gain among those without a tie (0.5 if all tie)."""
    decided = gain != 0
    return float(np.mean(gain[decided] > 0)) if decided.any() else 0.5


def decide(nominal_sse: np.ndarray, fits: list[FitResult], n_comp: np.ndarray, sigma: float | None,
           rng: np.random.Generator) -> dict:
    """Rank candidates by penalised held-out score and choose the outcome (see module docstring).

    Per-run Gaussian likelihood: run r with n_r residual components and held-out SSE_r contributes
    n_r·ln(SSE_r/n_r); a candidate's score adds p·ln(N). Per-run variances keep one run that a
    slightly-off fit sends onto a different path (stick-slip is that sensitive) from outweighing
    all the others, as it would in one pooled sum of squares.
    """
    N = float(n_comp.sum())
    R = len(n_comp)
    n = np.maximum(n_comp, 1)
    L0 = n * np.log(np.maximum(nominal_sse, 1e-30) / n)
    mse0 = math.exp(L0.sum() / N)  # n-weighted geometric mean of the per-run MSE
    noise_var = sigma**2 if sigma is not None else 0.0
    boot = np.stack([np.bincount(row, minlength=R) for row in rng.integers(0, R, (N_BOOT, R))])
    ranking = []
    Ls = []
    for f in fits:
        L = n * np.log(np.maximum(f.heldout, 1e-30) / n)
        Ls.append(L)
        mse = math.exp(L.sum() / N)
        gain = boot @ (L0 - L)  # (N_BOOT,) log-likelihood gain over nominal in each resample
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
                                           and ranking[i]["p_better_than_nominal"] >= RULES["significance"]
                                           and ranking[i]["improvement"] >= RULES["min_improvement"])
    # Stability: the share of run resamples in which each candidate has the best held-out likelihood.
    wins = np.argmin(np.stack([boot @ L for L in Ls]), axis=0)
    for i in range(len(fits)):
        ranking[i]["stability"] = float(np.mean(wins == i))
    excess0 = math.sqrt(max(mse0 - noise_var, 0.0))
    nominal_at_noise = sigma is not None and mse0 <= noise_var * (1 + RULES["noise_margin"])
    best = order[0]
    rb = ranking[best]
    out = {"nominal_rms": math.sqrt(mse0), "nominal_excess_rms": excess0, "noise": sigma, "score_nominal": score0,
           "ranking": [ranking[i] for i in order], "best": rb["effect"]}
    reduction = 1.0 - rb["excess_rms"] / excess0 if excess0 > 0 else 0.0
    best_at_noise = sigma is not None and rb["heldout_rms"] ** 2 <= noise_var * (1 + RULES["noise_margin"])
    if not rb["beats_nominal"]:
        if nominal_at_noise or sigma is None:
            out["effect"] = "none"
            out["why"] = ("no candidate improves the held-out error significantly"
                          + (" and the nominal residual is at the tracker-noise level" if nominal_at_noise else ""))
        else:
            out["effect"] = "unexplained"
            out["why"] = (f"the nominal residual ({1e3 * math.sqrt(mse0):.2f} mm RMS) is well above the tracker "
                          f"noise ({1e3 * sigma:.2f} mm) and no candidate improves it significantly")
        return out
    if reduction < RULES["min_gap_reduction"] and not best_at_noise:
        out["effect"] = "unexplained"
        out["why"] = (f"the best candidate, {rb['effect']}, removes only {100 * reduction:.0f} % of the gap beyond "
                      f"noise on held-out runs (needs {100 * RULES['min_gap_reduction']:.0f} %)")
        return out
    out["effect"] = rb["effect"]
    out["why"] = (f"{rb['effect']} removes {100 * reduction:.0f} % of the held-out gap beyond noise and beats "
                  f"the nominal model in {100 * rb['p_better_than_nominal']:.0f} % of run resamples")
    # Ambiguity: a qualifying runner-up that the winner does not beat reliably across resamples.
    amb = []
    for i in order[1:]:
        ri = ranking[i]
        if not ri["beats_nominal"]:
            continue
        red_i = 1.0 - ri["excess_rms"] / excess0 if excess0 > 0 else 0.0
        pairwise = float(np.mean(boot @ (Ls[i] - Ls[best]) > 0))
        if red_i >= RULES["min_gap_reduction"] and pairwise < RULES["ambiguity"]:
            amb.append({"effect": ri["effect"], "p_winner_better": pairwise})
    if amb:
        out["ambiguous_with"] = amb
        out["why"] += ("; cannot be told apart from " + ", ".join(a["effect"] for a in amb)
                       + " on this data")
    return out
