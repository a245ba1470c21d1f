"""Lift-event inference for the stochastic ``wheel_liftoff`` candidate.

Lift-off is a random process (:class:`omni_gym.physics.liftoff.ContactProcess`); a dataset holds one
realisation of it, which no rate pair can reproduce by simulation. The held-out likelihood of the
rates marginalises the unobserved events. We approximate that integral by its largest term (MAP /
Laplace): the most likely event sequence of each run, plus a BIC cost of 3·ln N per inferred event
(start, end, lifted case) in the per-run likelihood units n_r·ln(SSE_r/n_r) of
:func:`omni_gym.discrepancy.decide.decision.decide` (N = residual components of the dataset).

Search (all runs batched; :class:`EventInference`, one method per step, :func:`infer_events` runs it):

1. **Windows** (:meth:`~EventInference.search_windows`). The multiple-shooting windows
   (``residuals.shooting_windows``, 1 s, each restarted from the measured state) make an event show
   up locally. Per window, the nominal window and every single-event alternative on a coarse grid
   (lifted case × start every ``grid_dt`` × duration in ``durations``, clipped to the window)
   are simulated in one batched call over all windows. A window's best event is accepted when its
   gain n_w·ln(SSE_nominal/SSE_event) beats the event cost; greedy passes add up to
   ``window_events`` events per window; start/end are refined locally.
2. **Join and open loop** (:meth:`~EventInference.join_and_refine`). Events cut by a window boundary
   are joined (same case, touching ends), then every run is replayed **open loop** from its start
   with its schedule — the other candidates are scored by the open-loop full-run SSE, so this one is
   too — and each event's start/end is refined or the event dropped by coordinate sweeps (shifts
   ``refine_ol``) on the penalised open-loop score.
3. **Decoding and keep test** (:meth:`~EventInference.decode_and_keep`). Sequential decoding gives a
   second proposal per run: the open-loop residual is at noise level up to the first missing event,
   so walk forward in time, fitting one event where the residual first leaves the noise level. The
   better proposal per run is kept; runs still above the noise level get global "one more event
   anywhere" moves. (Both are skipped when the step-2 proposal is far above the adequacy limit of
   step 4, ``skip_factor``.) Then fine coordinate sweeps (``refine``, up to
   ``open_loop_rounds``), and a run keeps its events only if their open-loop likelihood gain
   beats their total cost.
4. **Evidence and adequacy** (:meth:`~EventInference.check_evidence`,
   :meth:`~EventInference.check_adequacy`). Events must beat the noise by the decision's rule: their
   likelihood gain, counted only above the decision's noise level (1 + ``noise_margin``)·σ² per
   component (no model is credited for fitting noise), must beat the BIC cost of a run's events, or
   the run keeps none.
   Lift-off says the nominal model is exact between events,
   so the MAP events must leave a noise-level residual; otherwise they are absorbing
   a continuous model error (e.g. a viscous drag) and are rejected (``adequacy``). Lift-off is also
   transient: events that keep a wheel lifted more than ``max_lifted_share`` of the moving time
   describe a persistent load change (a centre-of-mass offset unloads one wheel) and are rejected as
   well, and so are events whose lifted cases are not a plausible uniform draw (exact multinomial
   test, p < ``case_alpha``): the process lifts a random case, a systematic one-wheel effect
   lifts the same wheel every time.

Rates from events (:meth:`~EventInference.result` builds the :class:`EventFit`; maximum likelihood
for exponential holding times, :meth:`EventFit.rates`): lift_rate = events / time all wheels are
down, recover_rate = 1 / mean lifted duration; with no event, the null point.

The search's settings (grid steps, shifts, rounds, test levels) are the fields of
:class:`omni_gym.discrepancy.settings.EventSearchSettings`, named in ``code`` above; result.json records
them (``settings.event_search``).

Times in this module are seconds on a job's local clock (0 = the job's first row) unless a name
says run time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from omni_gym.discrepancy.data.dataset import Dataset, Run
from omni_gym.discrepancy.replay.residuals import geo_mse, run_sse, shooting_windows
from omni_gym.discrepancy.replay.simulate import Job, pose_residual, simulate_poses
from omni_gym.discrepancy.settings import EventSearchSettings
from omni_gym.physics.liftoff import OVERLAP_TOL, contact_cases
from omni_gym.physics.model import SimModel
from omni_gym.progress import Progress

PARAMS_PER_EVENT = 3  # fitted numbers per event: start, end, lifted case (the BIC count; not a setting)

EVENT_METHOD = ("wheel_liftoff: MAP lift events per run (window grid search, open-loop refinement), BIC cost "
                "3 ln N per event; rates = MLE from the events (fold rates from training runs); the held-out "
                "score is a marginal-likelihood approximation (events inferred on held-out runs too)")

Event = tuple[float, float, int]  # (t_start [s], t_end [s], case index into contact_cases(n), >= 1)


@dataclass
class EventFit:
    """Inferred lift events of every run and the open-loop fit they give."""

    events: list[list[Event]]  # per run, on the run's clock [s] (run.t[0] = 0)
    sse: np.ndarray  # (R,) open-loop SSE [m²] of each run replayed with its events
    gain: np.ndarray  # (R,) likelihood gain n_r·ln(SSE_nominal/SSE_events) (0 for runs without events)
    durations: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (R,) run lengths [s]
    moving: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (R,) time commanded to move [s]
    note: str = ""  # why inferred events were rejected (empty if they were kept or none were found)

    def n_events(self, mask: np.ndarray | None = None) -> int:
        """Events in the runs of ``mask`` (all runs if None)."""
        return sum(len(e) for i, e in enumerate(self.events) if mask is None or mask[i])

    def rates(self, mask: np.ndarray | None = None) -> tuple[float, float] | None:
        """MLE (lift_rate, recover_rate) [1/s] from the events of the runs in ``mask``; None without events."""
        w = np.ones(len(self.events)) if mask is None else np.asarray(mask, dtype=float)
        return self.rates_weighted(w)

    def rates_weighted(self, weights: np.ndarray) -> tuple[float, float] | None:
        """Rate MLEs with run ``weights`` (R,) (a bootstrap resample counts a run as often as drawn).

        Exponential holding times: lift_rate = events / exposure, recover_rate = events / lifted
        time. Exposure is the all-down time *while the robot is commanded to move*: at rest a
        lifted wheel changes nothing in the pose, so lifts there are unobservable and that time
        carries no information about the rate (counting it biased lift_rate low by the ~30 % rest
        share of the synthetic maneuvers). An event still lifted at a run's end counts as ending
        there (slight bias toward faster recovery).
        """
        k = float(sum(wi * len(e) for wi, e in zip(weights, self.events, strict=True)))
        if k == 0:
            return None
        lifted = float(sum(wi * sum(b - a for a, b, _ in e) for wi, e in zip(weights, self.events, strict=True)))
        moving = self.moving if self.moving.size else self.durations
        down = float(np.dot(weights, moving)) - lifted
        return k / max(down, 1e-3), k / max(lifted, 1e-6)

    def to_json(self, run_names: list[str], cases: np.ndarray) -> list[dict]:
        """Events for result.json: run, start/end [s, run clock], 1-based wheels lifted."""
        return [{"run": name, "start": round(a, 4), "end": round(b, 4),
                 "wheels_lifted": [int(w) + 1 for w in np.flatnonzero(~cases[c])]}
                for name, evs in zip(run_names, self.events, strict=True) for a, b, c in evs]


def case_uniformity(events: list[list[Event]], n_cases: int) -> float:
    """Exact p-value of the lifted-case counts under a uniform draw over the n_cases - 1 lifted cases.

    p = total multinomial probability of the count vectors no more probable than the observed one
    (exact test; chi-square approximation when there are too many count vectors to enumerate).
    """
    from itertools import combinations

    from scipy.stats import chisquare

    m = n_cases - 1
    obs = np.bincount([c - 1 for e in events for _, _, c in e], minlength=m)
    k = int(obs.sum())
    if k == 0 or m < 2:
        return 1.0
    if math.comb(k + m - 1, m - 1) > 200_000:
        return float(chisquare(obs).pvalue)

    def logp(counts: np.ndarray) -> float:
        return math.lgamma(k + 1) - sum(math.lgamma(int(c) + 1) for c in counts) - k * math.log(m)

    lp_obs = logp(obs)
    total = 0.0
    for bars in combinations(range(k + m - 1), m - 1):  # stars and bars: every count vector
        edges = (-1, *bars, k + m - 1)
        counts = np.diff(edges) - 1
        lp = logp(counts)
        if lp <= lp_obs + 1e-9:
            total += math.exp(lp)
    return min(1.0, total)


def _window_grid(tw: float, n_cases: int, cfg: EventSearchSettings) -> list[Event]:
    """Single-event alternatives in a window of length tw [s] (clipped to it, deduplicated) on the coarse grid
    of ``cfg`` (``grid_dt`` × ``durations``)."""
    out = set()
    for s in np.arange(0.0, tw - 1e-9, cfg.grid_dt):
        for d in cfg.durations:
            e = min(s + d, tw)
            if e - s >= 0.02:  # shorter lifts move the robot by less than tracker noise
                for c in range(1, n_cases):
                    out.add((round(float(s), 6), round(float(e), 6), c))
    return sorted(out)


def _free(ev: Event, taken: list[Event]) -> bool:
    """True if ``ev`` overlaps none of the ``taken`` events (back to back within OVERLAP_TOL is allowed)."""
    return all(ev[1] <= a + OVERLAP_TOL or ev[0] >= b - OVERLAP_TOL for a, b, _ in taken)


Trial = tuple[int, list[Event]]  # (run index, candidate schedule on the run clock [s])
Scored = tuple[float, list[Event], np.ndarray]  # (score, schedule, open-loop residual (K, 3) [m]) of a trial


@dataclass
class _RunFits:
    """Working state of steps 2-3: the current events of every run and the open-loop fit they give."""

    events: list[list[Event]]  # per run, on the run clock [s]
    sse: np.ndarray  # (R,) open-loop SSE [m²] of each run replayed with its events
    res: list[np.ndarray | None]  # per run: open-loop residual (K, 3) [m]; None while never simulated

    def copy(self) -> _RunFits:
        """Snapshot: new event lists and SSE array (residual arrays are shared; they are never modified)."""
        return _RunFits([list(e) for e in self.events], self.sse.copy(), list(self.res))

    def set(self, ri: int, events: list[Event], sse: float, res: np.ndarray | None) -> None:
        """Run ri's events, open-loop SSE [m²] and residual [m]."""
        self.events[ri], self.sse[ri], self.res[ri] = events, sse, res

    def take(self, ri: int, other: _RunFits) -> None:
        """Run ri's entry of ``other`` (the event list itself, not a copy)."""
        self.set(ri, other.events[ri], other.sse[ri], other.res[ri])


@dataclass(frozen=True)
class EventProblem:
    """The lift-event inference problem of one dataset (what :class:`EventInference` searches on).

    ds: the dataset; nominal: the nominal SimModel (no lift-off); lever [m]: heading lever.
    cost: likelihood cost of one event (BIC: 3·ln N) in n·ln(SSE/n) units.
    sse0: (R,) nominal open-loop SSE [m²]; n_comp: (R,) residual components per run.
    dt: physics substep [s]; sigma: tracker noise estimate [m] (None: step 3 skips its sequential
    decoding and global moves, step 4 its noise-level check).
    adequacy: largest row-weighted geometric-mean MSE with the events, in units of σ̂², for the events
    to be kept (step 4; None: no check).
    windows: ``shooting_windows(ds)`` (computed if None).
    """

    ds: Dataset
    nominal: SimModel
    lever: float
    cost: float
    sse0: np.ndarray
    n_comp: np.ndarray
    dt: float
    sigma: float | None = None
    adequacy: float | None = None
    windows: list[tuple] | None = None


class EventInference:
    """MAP lift events of every run of a dataset: the search of the module docstring, one method per step.

    :meth:`run` calls the steps in order (1 :meth:`search_windows`, 2 :meth:`join_and_refine`,
    3 :meth:`decode_and_keep`, 4 :meth:`check_adequacy`) and returns :meth:`result`. Every step
    simulates its candidates in as few batched calls as the step's dependencies allow; the order of
    the simulated jobs is part of the result (batching can change the last bits), so do not reorder them.

    Args:
        problem: the dataset, nominal model, event cost, nominal SSE, noise and adequacy limit
            (:class:`EventProblem`).
        settings: the search's grids, shifts, rounds and test levels (None: the defaults).
        simulate: optional ``simulate(jobs, dt, max_batch)`` to use instead of ``simulate_poses`` (the same
            poses, e.g. simulated as parallel tasks: :mod:`omni_gym.discrepancy.fit.fit_tasks`).
        counter: optional one-element list to which the number of simulated robot-runs is added.
        max_batch: most jobs per simulate call.
        progress: the search's progress (its step, the batches simulated, and within a batch the worlds or
            tasks done); None: none. ``simulate`` must then take ``done`` (as ``simulate_poses``).
    """

    STEPS = ("window search", "join and refine", "decoding and keep test", "evidence and adequacy")

    def __init__(self, problem: EventProblem, settings: EventSearchSettings | None = None,
                 simulate: Callable[..., list[np.ndarray]] | None = None, counter: list[int] | None = None,
                 max_batch: int = 3000, progress: Progress | None = None) -> None:
        ds, nominal, lever, cost = problem.ds, problem.nominal, problem.lever, problem.cost
        sse0, n_comp, dt, sigma = problem.sse0, problem.n_comp, problem.dt, problem.sigma
        windows, adequacy = problem.windows, problem.adequacy
        self.simulate = simulate_poses if simulate is None else simulate
        self.cfg = EventSearchSettings() if settings is None else settings
        self.ds, self.nominal, self.lever, self.cost = ds, nominal, lever, cost
        self.sse0, self.n_comp, self.dt, self.sigma = sse0, n_comp, dt, sigma
        self.max_batch, self.adequacy = max_batch, adequacy
        self.progress = progress
        self._what = "" if progress is None else progress.what
        self.runs: list[Run] = ds.runs
        self.R = len(self.runs)
        self.n_cases = len(contact_cases(ds.n_wheels))
        self.wins: list[tuple] = shooting_windows(ds) if windows is None else windows  # (run, k0, k1, state0)
        self.count: list[int] = counter if counter is not None else [0]  # simulated robot-runs
        self.n: np.ndarray = np.maximum(n_comp, 1)  # (R,) residual components, at least 1
        self.ends: list[float] = [float(r.t[-1]) for r in self.runs]  # (R,) run lengths [s]
        # Working state, filled by the steps in order.
        self.tws: list[float] = []  # step 1: window lengths [s]
        self.win_events: list[list[Event]] = []  # step 1: per window, on the window clock [s]
        self.fits = _RunFits([[] for _ in range(self.R)], np.array(sse0, dtype=float), [None] * self.R)  # steps 2-3
        self.gain = np.zeros(self.R)  # step 3: (R,) likelihood gain of the kept events
        self.moving = np.zeros(0)  # step 4: (R,) time commanded to move [s]
        self.note = ""  # step 4: why the events were rejected

    def run(self) -> EventFit:
        """All steps in order; the EventFit."""
        self._step(1)
        self.search_windows()
        self._step(2)
        self.join_and_refine()
        self._step(3)
        self.decode_and_keep()
        self._step(4)
        self.check_evidence()
        self.check_adequacy()
        return self.result()

    def _step(self, i: int) -> None:
        """Name step ``i`` (1-based) in the progress lines."""
        if self.progress is not None:
            self.progress.rename(f"{self._what} step {i}/{len(self.STEPS)} ({self.STEPS[i - 1]}):")

    # ---- simulation and scores -------------------------------------------------------------------------

    def _run_batch(self, jobs: list[Job]) -> list[np.ndarray]:
        """Simulated poses of ``jobs`` (one batched call), counted."""
        self.count[0] += len(jobs)
        if self.progress is None:
            return self.simulate(jobs, self.dt, self.max_batch)
        poses = self.simulate(jobs, self.dt, self.max_batch, done=self.progress.inner("parts"))
        self.progress.update()
        return poses

    def _win_sse(self, wi: int, pose: np.ndarray) -> float:
        """SSE [m²] of window wi's simulated ``pose`` (rows after its start) against the measurement."""
        ri, k0, k1, _ = self.wins[wi]
        r = pose_residual(self.runs[ri].pose[k0 + 1:k1 + 1], pose[1:], self.lever)
        r = r[np.all(np.isfinite(r), axis=1)]
        return float(np.sum(r * r))

    def _win_n(self, wi: int) -> int:
        """Residual components of window wi (3 per observed row after its start)."""
        ri, k0, k1, _ = self.wins[wi]
        return 3 * int(np.all(np.isfinite(self.runs[ri].pose[k0 + 1:k1 + 1]), axis=1).sum())

    def _open_loop(self, scheds: list[Trial]) -> list[np.ndarray]:
        """Open-loop residual (K, 3) [m] of each (run, schedule), one batched call."""
        if not scheds:
            return []
        poses = self._run_batch([Job(self.nominal, self.runs[ri], schedule=tuple(s)) for ri, s in scheds])
        return [pose_residual(self.runs[ri].pose, p, self.lever) for (ri, _), p in zip(scheds, poses, strict=True)]

    def _score(self, ri: int, s: float, k: int) -> float:
        """Penalised likelihood change vs nominal of run ri with open-loop SSE s [m²] and k events (lower is
        better)."""
        return float(self.n[ri] * math.log(max(s, 1e-30) / max(self.sse0[ri], 1e-30)) + self.cost * k)

    def _current_score(self, ri: int) -> float:
        """Penalised score of run ri's current events."""
        return self._score(ri, self.fits.sse[ri], len(self.fits.events[ri]))

    def _geo_ratio(self) -> float:
        """Row-weighted geometric-mean MSE of the current events, in units of sigma^2."""
        return geo_mse(self.fits.sse, self.n_comp) / self.sigma**2

    # ---- step 1: windows -------------------------------------------------------------------------------

    def search_windows(self) -> None:
        """Step 1: coarse single-event search per window; then, greedily, more events in the windows that
        accepted one; then local refinement of each event's start and end. Sets ``win_events``."""
        self.tws = [float(self.runs[ri].t[k1] - self.runs[ri].t[k0]) for ri, k0, k1, _ in self.wins]
        self.win_events = [[] for _ in self.wins]
        base = self.win_events
        grids = [_window_grid(tw, self.n_cases, self.cfg) for tw in self.tws]
        open_w = list(range(len(self.wins)))
        for _ in range(self.cfg.window_events):
            sub = [[ev for ev in grids[wi] if _free(ev, base[wi])] if wi in open_w else []
                   for wi in range(len(self.wins))]
            if not any(sub):
                break
            best = self._window_search(sub)
            open_w = [wi for wi, b in enumerate(best) if b is not None]
            for wi in open_w:
                base[wi] = sorted([*base[wi], best[wi][1]])
        self._refine_window_events()

    def _window_search(self, grids: list[list[Event]]) -> list[tuple[float, Event] | None]:
        """Per window: best (gain, event) added to its current events, or None (one batched call)."""
        base = self.win_events
        jobs, owner = [], []
        for wi, (ri, k0, k1, st) in enumerate(self.wins):
            if not grids[wi]:
                continue
            for ev in [None, *grids[wi]]:
                sched = tuple(base[wi]) if ev is None else tuple(sorted([*base[wi], ev]))
                jobs.append(Job(self.nominal, self.runs[ri], k0=k0, k1=k1, state0=st, schedule=sched))
                owner.append((wi, ev))
        poses = self._run_batch(jobs)
        best: list[tuple[float, Event] | None] = [None] * len(self.wins)
        ref: dict[int, float] = {}  # window -> SSE [m²] of its current events
        for (wi, ev), pose in zip(owner, poses, strict=True):
            s = self._win_sse(wi, pose)
            if ev is None:
                ref[wi] = s
                continue
            n = self._win_n(wi)
            gain = n * math.log(max(ref[wi], 1e-30) / max(s, 1e-30))
            if gain > self.cost and (best[wi] is None or gain > best[wi][0]):
                best[wi] = (gain, ev)
        return best

    def _refine_window_events(self) -> None:
        """Each window event's start and end shifted by ``refine`` (other events of the window fixed), one batch."""
        base = self.win_events
        ref_grids: list[list[tuple[float, float, int, int]]] = [[] for _ in self.wins]  # (start, end, case, j)
        for wi, evs in enumerate(base):
            for j, (a, b, c) in enumerate(evs):
                others = evs[:j] + evs[j + 1:]
                for da in self.cfg.refine:
                    for db in self.cfg.refine:
                        na, nb = max(a + da, 0.0), min(b + db, self.tws[wi])
                        if nb - na >= 0.01 and _free((na, nb, c), others):
                            ref_grids[wi].append((round(na, 6), round(nb, 6), c, j))
        if not any(ref_grids):
            return
        jobs, owner = [], []
        for wi, (ri, k0, k1, st) in enumerate(self.wins):
            for a, b, c, j in ref_grids[wi]:
                sched = tuple(sorted([*base[wi][:j], (a, b, c), *base[wi][j + 1:]]))
                jobs.append(Job(self.nominal, self.runs[ri], k0=k0, k1=k1, state0=st, schedule=sched))
                owner.append((wi, j, (a, b, c)))
        poses = self._run_batch(jobs)
        pick: dict[tuple[int, int], tuple[float, Event]] = {}  # (window, event) -> (SSE [m²], refined event)
        for (wi, j, ev), pose in zip(owner, poses, strict=True):
            s = self._win_sse(wi, pose)
            if (wi, j) not in pick or s < pick[(wi, j)][0]:
                pick[(wi, j)] = (s, ev)
        # Coordinates refined independently per event, applied together (events rarely interact).
        for (wi, j), (_, ev) in pick.items():
            base[wi][j] = ev
        for wi in range(len(self.wins)):
            base[wi].sort()

    # ---- step 2: join and open loop --------------------------------------------------------------------

    def join_and_refine(self) -> None:
        """Step 2: window events joined on the run clock, replayed open loop, refined/pruned (``refine_ol``)."""
        per_run = self._join_windows()
        self.fits = _RunFits([list(e) for e in per_run], np.array(self.sse0, dtype=float), [None] * self.R)
        live = [ri for ri in range(self.R) if self.fits.events[ri]]
        for ri, r in zip(live, self._open_loop([(ri, self.fits.events[ri]) for ri in live]), strict=True):
            self.fits.sse[ri], self.fits.res[ri] = run_sse(r), r
        self._refine_sweep(self.cfg.refine_ol)

    def _join_windows(self) -> list[list[Event]]:
        """Per run: the window events on the run clock [s], joining those cut by a window boundary."""
        per_run: list[list[Event]] = [[] for _ in range(self.R)]
        for wi, (ri, k0, _k1, _) in enumerate(self.wins):
            t0 = float(self.runs[ri].t[k0])
            for a, b, c in self.win_events[wi]:
                a, b = a + t0, b + t0
                prev = per_run[ri][-1] if per_run[ri] else None
                if prev is not None and prev[2] == c and a - prev[1] <= self.cfg.grid_dt / 2 + 1e-9:
                    per_run[ri][-1] = (prev[0], b, c)
                elif prev is not None and a < prev[1]:
                    per_run[ri][-1] = (prev[0], a, prev[2])
                    per_run[ri].append((a, b, c))
                else:
                    per_run[ri].append((a, b, c))
        return per_run

    def _accept(self, trials: list[Trial]) -> bool:
        """Simulate the trials (one batch); each run takes its best trial if it lowers the score."""
        fits = self.fits
        best_trial: dict[int, Scored] = {}
        for (ri, sched), r in zip(trials, self._open_loop(trials), strict=True):
            sc = self._score(ri, run_sse(r), len(sched))
            if sc < self._current_score(ri) - 1e-9 and (ri not in best_trial or sc < best_trial[ri][0]):
                best_trial[ri] = (sc, sched, r)
        for ri, (_, sched, r) in best_trial.items():
            fits.set(ri, list(sched), run_sse(r), r)
        return bool(best_trial)

    def _refine_sweep(self, shifts: tuple[float, ...], only: set[int] | None = None) -> bool:
        """Event j of every run (of ``only``) shifted (start/end by ``shifts`` [s]) or removed, j = 0, 1, ...:
        one batch per position; later events see the earlier ones already refined (open loop is causal)."""
        cur = self.fits.events
        improved = False
        for j in range(max((len(e) for e in cur), default=0)):
            trials: list[Trial] = []
            for ri in range(self.R):
                if j >= len(cur[ri]) or (only is not None and ri not in only):
                    continue
                a, b, c = cur[ri][j]
                others = cur[ri][:j] + cur[ri][j + 1:]
                trials.append((ri, others))
                for da in shifts:
                    for db in shifts:
                        na, nb = max(a + da, 0.0), min(b + db, self.ends[ri])
                        if (da or db) and nb - na >= 0.01 and _free((na, nb, c), others):
                            trials.append((ri, sorted([*others, (round(na, 6), round(nb, 6), c)])))
            if trials:
                improved |= self._accept(trials)
        return improved

    # ---- step 3: sequential decoding, global moves, keep test ------------------------------------------

    def decode_and_keep(self) -> None:
        """Step 3: sequential proposal and global moves (skipped far from the noise level), fine sweeps,
        per-run keep test. Sets ``gain``."""
        # The costly moves only refine a proposal; when the step-2 proposal leaves the data far from the
        # noise level (a continuous model error, not lift-off) they cannot pass the adequacy check of
        # step 4, so they are skipped (compute only).
        sigma = self.sigma
        if sigma is not None and sigma > 0 and (self.adequacy is None
                                                or self._geo_ratio() <= self.cfg.skip_factor * self.adequacy):
            self._keep_better(*self._sequential_decoding())
            for _ in range(self.cfg.add_rounds):
                if not self._add_one_event():
                    break
        for _ in range(self.cfg.open_loop_rounds):
            if not self._refine_sweep(self.cfg.refine):
                break
        self._keep_test()

    def _first_deviation(self, ri: int, r: np.ndarray) -> float | None:
        """Run time [s] where the open-loop residual ``r`` of run ri first leaves the noise level."""
        z = np.nan_to_num(np.sum(r[1:] ** 2, axis=1)) / (3 * self.sigma**2)
        m = np.convolve(z, np.ones(self.cfg.dev_rows) / self.cfg.dev_rows, mode="valid")  # mean over dev_rows rows
        hit = np.flatnonzero(m > self.cfg.dev_level)
        return None if hit.size == 0 else float(self.runs[ri].t[1 + hit[0]])

    def _local_best(self, trials: list[Trial], tds: dict[int, float]) -> dict[int, Scored]:
        """Per run: (local score, schedule, residual) of the best trial on rows t <= td + ``seq_horizon``
        (td: the run's deviation time [s] in ``tds``).

        Local score: n_loc·ln(SSE_loc) + cost·events, so a new event must pay its cost locally."""
        out: dict[int, Scored] = {}
        for (ri, sched), r in zip(trials, self._open_loop(trials), strict=True):
            rows = self.runs[ri].t[1:] <= tds[ri] + self.cfg.seq_horizon
            rr = r[1:][rows]
            rr = rr[np.all(np.isfinite(rr), axis=1)]
            nl = max(rr.size, 1)
            sc = nl * math.log(max(float(np.sum(rr * rr)), 1e-30)) + self.cost * len(sched)
            if ri not in out or sc < out[ri][0]:
                out[ri] = (sc, sched, r)
        return out

    def _sequential_decoding(self) -> tuple[list[list[Event]], list[np.ndarray]]:
        """Sequential (causal) decoding on the open-loop residual: per run, the events and their residual.

        The residual is at noise level up to the first missing event, so walk forward in time and fit one
        event where the residual first leaves the noise level, scored on the rows up to ``seq_horizon`` after
        that point (later, still missing events would only blur the comparison)."""
        R, ends, n_cases = self.R, self.ends, self.n_cases
        seq: list[list[Event]] = [[] for _ in range(R)]
        active = set(range(R))
        seq_res: list[np.ndarray] = self._open_loop([(ri, []) for ri in range(R)])
        for _ in range(self.cfg.seq_max_events):
            tds: dict[int, float] = {}  # run -> deviation time [s] the new event is scored around
            trials: list[Trial] = []
            for ri in sorted(active):
                td = self._first_deviation(ri, seq_res[ri])
                last = seq[ri][-1][1] if seq[ri] else 0.0
                if td is None or last >= ends[ri] - 0.05:
                    active.discard(ri)
                    continue
                td = max(td, last)  # an imperfect last event: look right after it
                tds[ri] = td
                trials.append((ri, list(seq[ri])))
                for s0 in np.arange(max(td - 0.5, last), min(td + self.cfg.seq_ahead, ends[ri]), self.cfg.grid_dt):
                    for d in (*self.cfg.durations, 0.8):
                        e = min(s0 + d, ends[ri])
                        for c in range(1, n_cases):
                            touching = seq[ri] and seq[ri][-1][2] == c and s0 - last < 0.01
                            if e - s0 >= 0.02 and not touching:  # touching same-case: the extension below
                                trials.append((ri, [*seq[ri], (round(float(s0), 6), round(float(e), 6), c)]))
                if seq[ri]:  # or the last event lasts longer (one event, no extra cost)
                    a0, _, c0 = seq[ri][-1]
                    for d in (*self.cfg.durations, 0.8):
                        trials.append((ri, [*seq[ri][:-1], (a0, round(min(last + d, ends[ri]), 6), c0)]))
            if not trials:
                break
            best = self._local_best(trials, tds)
            # Refine the new event's start/end on the same local cost.
            trials = []
            for ri, (_, sched, _) in best.items():
                if sched == seq[ri]:
                    continue
                a0, b0, c0 = sched[-1]
                lo = sched[-2][1] if len(sched) > 1 else 0.0
                for da in self.cfg.refine_ol:
                    for db in self.cfg.refine_ol:
                        na, nb = max(a0 + da, lo), min(b0 + db, ends[ri])
                        if nb - na >= 0.01:
                            trials.append((ri, [*sched[:-1], (round(na, 6), round(nb, 6), c0)]))
            best.update(self._local_best(trials, tds))
            for ri in list(active):
                if ri not in best or best[ri][1] == seq[ri]:  # nothing pays its cost: the run is done
                    active.discard(ri)
                    continue
                seq[ri] = best[ri][1]
                seq_res[ri] = best[ri][2]
            if not active:
                break
        return seq, seq_res

    def _keep_better(self, seq: list[list[Event]], seq_res: list[np.ndarray]) -> None:
        """Refine the sequential proposal too (``refine_ol``), then keep per run the better (penalised, whole-run)
        of it and the current (step-2) events."""
        fits = self.fits
        win_state = fits.copy()
        for ri in range(self.R):
            fits.set(ri, list(seq[ri]), run_sse(seq_res[ri]), seq_res[ri])
        self._refine_sweep(self.cfg.refine_ol)
        for ri in range(self.R):
            if self._score(ri, win_state.sse[ri], len(win_state.events[ri])) <= self._current_score(ri):
                fits.take(ri, win_state)

    def _add_one_event(self) -> bool:
        """One round of global moves; True if some run's events changed.

        Runs still above the noise level try one more event anywhere on the coarse grid (replacing the events
        it overlaps), scored on the whole run. An added event often pays only once its neighbours have moved,
        so the ``add_top`` best additions of each run are each refined (one sweep) before they are compared with
        the current events."""
        fits, n = self.fits, self.n
        trials: list[Trial] = []
        for ri in range(self.R):
            if fits.sse[ri] <= self.cfg.add_level * n[ri] * self.sigma**2:
                continue
            for ev in _window_grid(self.ends[ri], self.n_cases, self.cfg):
                trials.append((ri, sorted([*(x for x in fits.events[ri] if _free(x, [ev])), ev])))
        if not trials:
            return False
        ranked: dict[int, list[Scored]] = {}  # run -> (score, schedule, residual) per trial
        for (ri, sched), r in zip(trials, self._open_loop(trials), strict=True):
            ranked.setdefault(ri, []).append((self._score(ri, run_sse(r), len(sched)), sched, r))
        saved = fits.copy()
        best_final = {ri: (self._current_score(ri), fits.events[ri], fits.sse[ri], fits.res[ri]) for ri in ranked}
        for k in range(self.cfg.add_top):
            for ri, lst in ranked.items():
                lst.sort(key=lambda x: x[0])
                if k < len(lst):
                    fits.set(ri, list(lst[k][1]), run_sse(lst[k][2]), lst[k][2])
                else:
                    fits.take(ri, saved)
            self._refine_sweep(self.cfg.refine_ol, only=set(ranked))
            for ri in ranked:
                sc = self._current_score(ri)
                if sc < best_final[ri][0] - 1e-9:
                    best_final[ri] = (sc, list(fits.events[ri]), fits.sse[ri], fits.res[ri])
        changed = False
        for ri, (_, ev_, s_, r_) in best_final.items():
            changed |= ev_ != saved.events[ri]
            fits.set(ri, list(ev_), s_, r_)
        return changed

    def _keep_test(self) -> None:
        """A run keeps its events only if their open-loop likelihood gain beats their total cost."""
        fits = self.fits
        self.gain = np.zeros(self.R)
        for ri in range(self.R):
            sc = self._current_score(ri)
            if fits.events[ri] and sc < 0:
                self.gain[ri] = self.n[ri] * math.log(max(self.sse0[ri], 1e-30) / max(fits.sse[ri], 1e-30))
            else:  # the set does not pay its cost: the run has no inferred event
                fits.events[ri], fits.sse[ri] = [], float(self.sse0[ri])

    # ---- step 4: adequacy ------------------------------------------------------------------------------

    def check_evidence(self) -> None:
        """Step 4a: a run's events must beat the noise by the decision's evidence rule, or the run keeps none.

        A residual within the decision's noise level, (1 + ``noise_margin``)·σ² per component
        (``adequacy``·σ² here), is what an exact model leaves, and no effect is credited for trimming it: a
        deterministic effect cannot be (its score is a held-out prediction, and noise is not predictable),
        and the decision calls such a nominal residual noise. Events are fitted in-sample, so they can trim
        it; their gain is therefore counted only above that level: n_r·ln(max(SSE_nominal, f_r) /
        max(SSE_events, f_r)), f_r = adequacy·n_r·σ², and it must beat the events' BIC cost. A lifted wheel
        for 0.05-0.2 s moves the robot 7-200 mm off its path, far above the level; events in a run at noise
        level (with nothing hidden: the world's sub-millimetre disagreement with an independent integrator)
        gain nothing above it. The test is per run, not per event: a run with real lifts is far above the
        level, and its small lifts stay with its large ones (a per-event test dropped them at 3 mm tracker
        noise and biased the lift rate low)."""
        sigma, adequacy = self.sigma, self.adequacy
        if sigma is None or sigma <= 0 or adequacy is None or not any(self.fits.events):
            return
        fits = self.fits
        for ri in range(self.R):
            if not fits.events[ri]:
                continue
            f = adequacy * self.n[ri] * sigma**2  # [m²]
            gain = self.n[ri] * math.log(max(float(self.sse0[ri]), f) / max(float(fits.sse[ri]), f))
            if gain <= self.cost * len(fits.events[ri]):
                fits.set(ri, [], float(self.sse0[ri]), None)
                self.gain[ri] = 0.0

    def check_adequacy(self) -> None:
        """Step 4: reject all events if they leave more than noise, keep wheels lifted too long, or lift
        non-uniform cases. Sets ``moving`` and ``note`` (and clears the events when rejected)."""
        # Lift-off says the nominal model is exact between events, so the MAP events must explain the data
        # to the tracker-noise level. If they leave more (row-weighted geometric-mean MSE > adequacy·σ̂²,
        # the decision's metric), the events are absorbing some other, continuous model error (a viscous
        # drag is fitted by "coasting" pulses): the candidate then keeps no event.
        # Time each run is commanded to move (a command row holds until the next row).
        cur, sigma, adequacy = self.fits.events, self.sigma, self.adequacy
        self.moving = np.array([float(np.sum(np.diff(r.t)[np.any(np.abs(r.cmd[:-1]) > 0, axis=1)]))
                                for r in self.runs])
        note = ""
        lifted = sum(b - a for e in cur for a, b, _ in e)
        share = lifted / max(float(self.moving.sum()), 1e-9)
        if adequacy is not None and sigma is not None and sigma > 0 and any(cur) and self._geo_ratio() > adequacy:
            note = (f"{sum(len(e) for e in cur)} inferred events rejected: with them the held-out MSE is "
                    f"{self._geo_ratio():.2f} x the tracker-noise variance (lift-off alone would leave noise; "
                    f"limit {adequacy:g})")
        elif any(cur) and share > self.cfg.max_lifted_share:
            # Lift-off is an excursion from the all-down state. Wheels "lifted" most of the time describe
            # a persistent load change (a centre-of-mass offset unloads one wheel), not lift-off.
            note = (f"{sum(len(e) for e in cur)} inferred events rejected: they keep wheels lifted "
                    f"{100 * share:.0f} % of the moving time (lift-off is transient; limit "
                    f"{100 * self.cfg.max_lifted_share:.0f} %)")
        p_cases = case_uniformity(cur, self.n_cases)
        if not note and p_cases < self.cfg.case_alpha:
            # The process lifts a uniformly drawn case; events that (almost) all lift the same wheel
            # mimic a systematic one-wheel effect (a centre-of-mass offset unloads one wheel).
            counts = np.bincount([c for e in cur for _, _, c in e], minlength=self.n_cases)[1:]
            note = (f"{sum(len(e) for e in cur)} inferred events rejected: their lifted cases {counts.tolist()} "
                    f"are not a uniform draw (p = {p_cases:.2g} < {self.cfg.case_alpha:g}); lift-off lifts a "
                    "random case")
        self.note = note
        if note:
            self.fits = _RunFits([[] for _ in range(self.R)], np.array(self.sse0, dtype=float), [None] * self.R)
            self.gain = np.zeros(self.R)

    # ---- rates -----------------------------------------------------------------------------------------

    def result(self) -> EventFit:
        """The EventFit of the current state (its rates are the MLE from the events)."""
        return EventFit(events=self.fits.events, sse=self.fits.sse, gain=self.gain, durations=np.array(self.ends),
                        moving=self.moving, note=self.note)


def infer_events(problem: EventProblem, settings: EventSearchSettings | None = None,
                 simulate: Callable[..., list[np.ndarray]] | None = None, counter: list[int] | None = None,
                 max_batch: int = 3000, progress: Progress | None = None) -> EventFit:
    """MAP lift events of every run of ``problem.ds`` (see the module docstring and :class:`EventInference` for
    the arguments)."""
    return EventInference(problem, settings, simulate=simulate, counter=counter, max_batch=max_batch,
                          progress=progress).run()
