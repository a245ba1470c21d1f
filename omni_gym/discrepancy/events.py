"""Lift-event inference for the stochastic ``wheel_liftoff`` candidate.

Lift-off is a random process (:class:`omni_gym.physics.liftoff.ContactProcess`); a dataset holds one
realisation of it, which no rate pair can reproduce by simulation. The held-out likelihood of the
rates marginalises the unobserved events. We approximate that integral by its largest term (MAP /
Laplace): the most likely event sequence of each run, plus a BIC cost of 3·ln N per inferred event
(start, end, lifted case) in the per-run likelihood units n_r·ln(SSE_r/n_r) of
:func:`omni_gym.discrepancy.explain.decide` (N = residual components of the dataset).

Search (all runs batched, see :func:`infer_events`):

1. **Windows.** The multiple-shooting windows (``residuals.shooting_windows``, 1 s, each restarted
   from the measured state) make an event show up locally. Per window, the nominal window and every
   single-event alternative on a coarse grid (lifted case × start every :data:`GRID_DT` × duration
   in :data:`DURATIONS`, clipped to the window) are simulated in one batched call over all windows.
   A window's best event is accepted when its gain n_w·ln(SSE_nominal/SSE_event) beats the event
   cost; greedy passes add up to :data:`WINDOW_EVENTS` events per window; start/end are refined
   locally.
2. **Join** events cut by a window boundary (same case, touching ends), then go **open loop**:
   every run is replayed from its start with its schedule — the other candidates are scored by the
   open-loop full-run SSE, so this one is too — and each event's start/end is refined or the event
   dropped by coordinate sweeps on the penalised open-loop score.
3. **Sequential decoding** (second proposal per run): the open-loop residual is at noise level up to
   the first missing event, so walk forward in time, fitting one event where the residual first
   leaves the noise level. The better proposal per run is kept; runs still above the noise level get
   global "one more event anywhere" moves; a run keeps its events only if their open-loop
   likelihood gain beats their total cost.
4. **Adequacy.** Lift-off says the nominal model is exact between events, so the MAP events must
   leave a noise-level residual; otherwise they are absorbing a continuous model error (e.g. a
   viscous drag) and are rejected (``adequacy``). Lift-off is also transient: events that keep a
   wheel lifted more than :data:`MAX_LIFTED_SHARE` of the moving time describe a persistent load
   change (a centre-of-mass offset unloads one wheel) and are rejected as well, and so are events
   whose lifted cases are not a plausible uniform draw (exact multinomial test, p < :data:`CASE_ALPHA`):
   the process lifts a random case, a systematic one-wheel effect lifts the same wheel every time.

Rates from events (maximum likelihood for exponential holding times): lift_rate = events / time
all wheels are down, recover_rate = 1 / mean lifted duration; with no event, the null point.

Times in this module are seconds on a job's local clock (0 = the job's first row) unless a name
says run time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from omni_gym.discrepancy.residuals import geo_mse, run_sse, shooting_windows
from omni_gym.discrepancy.simulate import Job, pose_residual, simulate_poses
from omni_gym.physics.liftoff import OVERLAP_TOL, contact_cases

GRID_DT = 0.05  # s: start grid of the window search (half the shortest duration)
DURATIONS = (0.05, 0.1, 0.2, 0.4)  # s: coarse lifted durations (mean holding 1/recover_rate ~ 0.2 s)
REFINE = (-0.03, -0.015, -0.005, 0.0, 0.005, 0.015, 0.03)  # s: local start/end shifts
REFINE_OL = (-0.15, -0.08, -0.03, -0.01, 0.0, 0.01, 0.03, 0.08, 0.15)  # s: wider shifts for the first open-loop sweep
OPEN_LOOP_ROUNDS = 2  # fine coordinate rounds of start/end refinement on the open-loop cost
WINDOW_EVENTS = 3  # most events per 1 s window of the window search (greedy, one per batched pass)
ADD_ROUNDS = 3  # rounds of the global "one more event" move...
ADD_LEVEL = 1.2  # ...for runs whose open-loop MSE is above this multiple of sigma^2...
ADD_TOP = 3  # ...trying each run's 3 best additions, each refined before the comparison
CASE_ALPHA = 0.01  # reject events whose lifted cases are this unlikely under the uniform draw (step 4)
MAX_LIFTED_SHARE = 0.5  # most of the moving time that inferred events may keep a wheel lifted (step 4)
SKIP_FACTOR = 3.0  # skip the sequential/global moves when the window proposal is above 3 x the adequacy limit
SEQ_MAX_EVENTS = 12  # most events per run of the sequential open-loop decoding
SEQ_AHEAD = 0.1  # s: new events start up to this long after the deviation point...
SEQ_HORIZON = 0.5  # s: ...and are scored on the rows up to this long after it
DEV_ROWS, DEV_LEVEL = 10, 2.0  # deviation: mean z^2 over 10 rows (0.2 s) above 2 (about 4 sd for noise)
PARAMS_PER_EVENT = 3  # start, end, lifted case

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


def _window_grid(tw: float, n_cases: int) -> list[Event]:
    """Single-event alternatives in a window of length tw [s] (clipped to it, deduplicated)."""
    out = set()
    for s in np.arange(0.0, tw - 1e-9, GRID_DT):
        for d in DURATIONS:
            e = min(s + d, tw)
            if e - s >= 0.02:  # shorter lifts move the robot by less than tracker noise
                for c in range(1, n_cases):
                    out.add((round(float(s), 6), round(float(e), 6), c))
    return sorted(out)


def infer_events(ds, nominal, lever: float, cost: float, sse0: np.ndarray, n_comp: np.ndarray,
                 dt: float, sigma: float | None = None, windows: list[tuple] | None = None, max_batch: int = 3000,
                 counter: list[int] | None = None, adequacy: float | None = None) -> EventFit:
    """MAP lift events of every run of ``ds`` (see the module docstring).

    Args:
        ds: the dataset; nominal: the nominal SimModel (no lift-off); lever [m]: heading lever.
        cost: likelihood cost of one event (BIC: 3·ln N) in n·ln(SSE/n) units.
        sse0: (R,) nominal open-loop SSE [m²]; n_comp: (R,) residual components per run.
        dt: physics substep [s]; sigma: tracker noise estimate [m] (None: no repair step).
        windows: ``shooting_windows(ds)`` (computed if None).
        counter: optional one-element list to which the number of simulated robot-runs is added.
        adequacy: largest row-weighted geometric-mean MSE with the events, in units of σ̂², for the
            events to be kept (step 4; None: no check).
    """

    runs = ds.runs
    R = len(runs)
    n_cases = len(contact_cases(ds.n_wheels))
    wins = shooting_windows(ds) if windows is None else windows
    count = counter if counter is not None else [0]

    def run_batch(jobs: list) -> list[np.ndarray]:
        count[0] += len(jobs)
        return simulate_poses(jobs, dt, max_batch)

    def win_sse(wi: int, pose: np.ndarray) -> float:
        ri, k0, k1, _ = wins[wi]
        r = pose_residual(runs[ri].pose[k0 + 1:k1 + 1], pose[1:], lever)
        r = r[np.all(np.isfinite(r), axis=1)]
        return float(np.sum(r * r))

    def win_n(wi: int) -> int:
        ri, k0, k1, _ = wins[wi]
        return 3 * int(np.all(np.isfinite(runs[ri].pose[k0 + 1:k1 + 1]), axis=1).sum())

    def window_search(base: list[list[Event]], grids: list[list[Event]]) -> list[tuple[float, Event] | None]:
        """Per window: best (gain, event) added to its ``base`` events, or None (one batched call)."""
        jobs, owner = [], []
        for wi, (ri, k0, k1, st) in enumerate(wins):
            if not grids[wi]:
                continue
            for ev in [None, *grids[wi]]:
                sched = tuple(base[wi]) if ev is None else tuple(sorted([*base[wi], ev]))
                jobs.append(Job(nominal, runs[ri], k0=k0, k1=k1, state0=st, schedule=sched))
                owner.append((wi, ev))
        poses = run_batch(jobs)
        best: list[tuple[float, Event] | None] = [None] * len(wins)
        ref: dict[int, float] = {}
        for (wi, ev), pose in zip(owner, poses, strict=True):
            s = win_sse(wi, pose)
            if ev is None:
                ref[wi] = s
                continue
            n = win_n(wi)
            gain = n * math.log(max(ref[wi], 1e-30) / max(s, 1e-30))
            if gain > cost and (best[wi] is None or gain > best[wi][0]):
                best[wi] = (gain, ev)
        return best

    def free(ev: Event, taken: list[Event]) -> bool:
        return all(ev[1] <= a + OVERLAP_TOL or ev[0] >= b - OVERLAP_TOL for a, b, _ in taken)

    # 1. Windows: coarse search; then, greedily, more events in the windows that accepted one.
    tws = [float(runs[ri].t[k1] - runs[ri].t[k0]) for ri, k0, k1, _ in wins]
    base: list[list[Event]] = [[] for _ in wins]
    grids = [_window_grid(tw, n_cases) for tw in tws]
    open_w = list(range(len(wins)))
    for _ in range(WINDOW_EVENTS):
        sub = [[ev for ev in grids[wi] if free(ev, base[wi])] if wi in open_w else [] for wi in range(len(wins))]
        if not any(sub):
            break
        best = window_search(base, sub)
        open_w = [wi for wi, b in enumerate(best) if b is not None]
        for wi in open_w:
            base[wi] = sorted([*base[wi], best[wi][1]])

    # 1 (cont.). Local refinement of each window event's start and end (other events of the window fixed).
    ref_grids: list[list[Event]] = [[] for _ in wins]
    for wi, evs in enumerate(base):
        for j, (a, b, c) in enumerate(evs):
            others = evs[:j] + evs[j + 1:]
            for da in REFINE:
                for db in REFINE:
                    na, nb = max(a + da, 0.0), min(b + db, tws[wi])
                    if nb - na >= 0.01 and free((na, nb, c), others):
                        ref_grids[wi].append((round(na, 6), round(nb, 6), c, j))
    if any(ref_grids):
        jobs, owner = [], []
        for wi, (ri, k0, k1, st) in enumerate(wins):
            for a, b, c, j in ref_grids[wi]:
                sched = tuple(sorted([*base[wi][:j], (a, b, c), *base[wi][j + 1:]]))
                jobs.append(Job(nominal, runs[ri], k0=k0, k1=k1, state0=st, schedule=sched))
                owner.append((wi, j, (a, b, c)))
        poses = run_batch(jobs)
        pick: dict[tuple[int, int], tuple[float, Event]] = {}
        for (wi, j, ev), pose in zip(owner, poses, strict=True):
            s = win_sse(wi, pose)
            if (wi, j) not in pick or s < pick[(wi, j)][0]:
                pick[(wi, j)] = (s, ev)
        # Coordinates refined independently per event, applied together (events rarely interact).
        for (wi, j), (_, ev) in pick.items():
            base[wi][j] = ev
        for wi in range(len(wins)):
            base[wi].sort()

    # 2. Join on the run clock the events cut by a window boundary.
    per_run: list[list[Event]] = [[] for _ in range(R)]
    for wi, (ri, k0, _k1, _) in enumerate(wins):
        t0 = float(runs[ri].t[k0])
        for a, b, c in base[wi]:
            a, b = a + t0, b + t0
            prev = per_run[ri][-1] if per_run[ri] else None
            if prev is not None and prev[2] == c and a - prev[1] <= GRID_DT / 2 + 1e-9:
                per_run[ri][-1] = (prev[0], b, c)
            elif prev is not None and a < prev[1]:
                per_run[ri][-1] = (prev[0], a, prev[2])
                per_run[ri].append((a, b, c))
            else:
                per_run[ri].append((a, b, c))

    # 2 (cont.). Open loop: refine, prune, keep only sets that pay for themselves.
    n = np.maximum(n_comp, 1)
    ends = [float(r.t[-1]) for r in runs]

    def open_loop(scheds: list[tuple[int, list[Event]]]) -> list[np.ndarray]:
        """Open-loop residual (K, 3) [m] of each (run, schedule)."""
        if not scheds:
            return []
        poses = run_batch([Job(nominal, runs[ri], schedule=tuple(s)) for ri, s in scheds])
        return [pose_residual(runs[ri].pose, p, lever) for (ri, _), p in zip(scheds, poses, strict=True)]

    def score(ri: int, s: float, k: int) -> float:
        """Penalised likelihood change vs nominal (lower is better)."""
        return float(n[ri] * math.log(max(s, 1e-30) / max(sse0[ri], 1e-30)) + cost * k)

    cur = [list(e) for e in per_run]
    cur_sse = np.array(sse0, dtype=float)
    cur_res: list[np.ndarray | None] = [None] * R
    live = [ri for ri in range(R) if cur[ri]]
    for ri, r in zip(live, open_loop([(ri, cur[ri]) for ri in live]), strict=True):
        cur_sse[ri], cur_res[ri] = run_sse(r), r

    def accept(trials: list[tuple[int, list[Event]]]) -> bool:
        """Simulate the trials (one batch); each run takes its best trial if it lowers the score."""
        best_trial: dict[int, tuple[float, list[Event], np.ndarray]] = {}
        for (ri, sched), r in zip(trials, open_loop(trials), strict=True):
            sc = score(ri, run_sse(r), len(sched))
            if sc < score(ri, cur_sse[ri], len(cur[ri])) - 1e-9 and (ri not in best_trial or sc < best_trial[ri][0]):
                best_trial[ri] = (sc, sched, r)
        for ri, (_, sched, r) in best_trial.items():
            cur[ri], cur_sse[ri], cur_res[ri] = list(sched), run_sse(r), r
        return bool(best_trial)

    def refine_sweep(shifts: tuple[float, ...], only: set[int] | None = None) -> bool:
        """Event j of every run shifted (start/end) or removed, j = 0, 1, ...: one batch per position;
        later events see the earlier ones already refined (open loop is causal)."""
        improved = False
        for j in range(max((len(e) for e in cur), default=0)):
            trials: list[tuple[int, list[Event]]] = []
            for ri in range(R):
                if j >= len(cur[ri]) or (only is not None and ri not in only):
                    continue
                a, b, c = cur[ri][j]
                others = cur[ri][:j] + cur[ri][j + 1:]
                trials.append((ri, others))
                for da in shifts:
                    for db in shifts:
                        na, nb = max(a + da, 0.0), min(b + db, ends[ri])
                        if (da or db) and nb - na >= 0.01 and free((na, nb, c), others):
                            trials.append((ri, sorted([*others, (round(na, 6), round(nb, 6), c)])))
            if trials:
                improved |= accept(trials)
        return improved

    def first_deviation_of(ri: int, r: np.ndarray) -> float | None:
        """Run time [s] where the open-loop residual ``r`` of run ri first leaves the noise level."""
        z = np.nan_to_num(np.sum(r[1:] ** 2, axis=1)) / (3 * sigma**2)
        m = np.convolve(z, np.ones(DEV_ROWS) / DEV_ROWS, mode="valid")  # mean over DEV_ROWS rows
        hit = np.flatnonzero(m > DEV_LEVEL)
        return None if hit.size == 0 else float(runs[ri].t[1 + hit[0]])

    def local_best(trials: list[tuple[int, list[Event]]], props: dict) -> dict:
        """Per run: (local score, schedule, residual) of the best trial on rows t <= td + SEQ_HORIZON.

        Local score: n_loc·ln(SSE_loc) + cost·events, so a new event must pay its cost locally."""
        out: dict[int, tuple[float, list[Event], np.ndarray]] = {}
        for (ri, sched), r in zip(trials, open_loop(trials), strict=True):
            rows = runs[ri].t[1:] <= props[ri][0] + SEQ_HORIZON
            rr = r[1:][rows]
            rr = rr[np.all(np.isfinite(rr), axis=1)]
            nl = max(rr.size, 1)
            sc = nl * math.log(max(float(np.sum(rr * rr)), 1e-30)) + cost * len(sched)
            if ri not in out or sc < out[ri][0]:
                out[ri] = (sc, sched, r)
        return out

    refine_sweep(REFINE_OL)

    def geo_ratio() -> float:
        """Row-weighted geometric-mean MSE of the current events, in units of sigma^2."""
        return geo_mse(cur_sse, n_comp) / sigma**2

    # The costly moves below only refine a proposal; when the window proposal leaves the data far
    # from the noise level (a continuous model error, not lift-off) they cannot pass the adequacy
    # check of step 4, so they are skipped (compute only).
    if sigma is not None and sigma > 0 and (adequacy is None or geo_ratio() <= SKIP_FACTOR * adequacy):
        # 3. Sequential (causal) decoding on the open-loop residual, as a second proposal per run: the
        # residual is at noise level up to the first missing event, so walk forward in time and fit
        # one event where the residual first leaves the noise level, scored on the rows up to
        # SEQ_HORIZON after that point (later, still missing events would only blur the comparison).
        seq: list[list[Event]] = [[] for _ in range(R)]
        seq_res: list[np.ndarray | None] = [None] * R
        active = set(range(R))
        zero = [(ri, []) for ri in range(R)]
        for ri, r in zip(range(R), open_loop(zero), strict=True):
            seq_res[ri] = r
        for _ in range(SEQ_MAX_EVENTS):
            props: dict[int, tuple[float, list[Event]]] = {}
            trials = []
            for ri in sorted(active):
                td = first_deviation_of(ri, seq_res[ri])
                last = seq[ri][-1][1] if seq[ri] else 0.0
                if td is None or last >= ends[ri] - 0.05:
                    active.discard(ri)
                    continue
                td = max(td, last)  # an imperfect last event: look right after it
                props[ri] = (td, [])
                trials.append((ri, list(seq[ri])))
                for s0 in np.arange(max(td - 0.5, last), min(td + SEQ_AHEAD, ends[ri]), GRID_DT):
                    for d in (*DURATIONS, 0.8):
                        e = min(s0 + d, ends[ri])
                        for c in range(1, n_cases):
                            touching = seq[ri] and seq[ri][-1][2] == c and s0 - last < 0.01
                            if e - s0 >= 0.02 and not touching:  # touching same-case: the extension below
                                trials.append((ri, [*seq[ri], (round(float(s0), 6), round(float(e), 6), c)]))
                if seq[ri]:  # or the last event lasts longer (one event, no extra cost)
                    a0, _, c0 = seq[ri][-1]
                    for d in (*DURATIONS, 0.8):
                        trials.append((ri, [*seq[ri][:-1], (a0, round(min(last + d, ends[ri]), 6), c0)]))
            if not trials:
                break
            best = local_best(trials, props)
            # Refine the new event's start/end on the same local cost.
            trials = []
            for ri, (_, sched, _) in best.items():
                if sched == seq[ri]:
                    continue
                a0, b0, c0 = sched[-1]
                lo = sched[-2][1] if len(sched) > 1 else 0.0
                for da in REFINE_OL:
                    for db in REFINE_OL:
                        na, nb = max(a0 + da, lo), min(b0 + db, ends[ri])
                        if nb - na >= 0.01:
                            trials.append((ri, [*sched[:-1], (round(na, 6), round(nb, 6), c0)]))
            best.update(local_best(trials, props))
            for ri in list(active):
                if ri not in best or best[ri][1] == seq[ri]:  # nothing pays its cost: the run is done
                    active.discard(ri)
                    continue
                seq[ri] = best[ri][1]
                seq_res[ri] = best[ri][2]
            if not active:
                break
        # Refine the sequential proposal too, then keep per run the better (penalised, whole-run) one.
        win_state = ([list(e) for e in cur], cur_sse.copy(), list(cur_res))
        for ri in range(R):
            cur[ri], cur_sse[ri], cur_res[ri] = list(seq[ri]), run_sse(seq_res[ri]), seq_res[ri]
        refine_sweep(REFINE_OL)
        for ri in range(R):
            w_ev, w_sse, w_res = win_state[0][ri], win_state[1][ri], win_state[2][ri]
            if score(ri, w_sse, len(w_ev)) <= score(ri, cur_sse[ri], len(cur[ri])):
                cur[ri], cur_sse[ri], cur_res[ri] = w_ev, w_sse, w_res
        # Global moves for runs still above the noise level: one more event anywhere on the coarse grid
        # (replacing the events it overlaps), scored on the whole run. An added event often pays only
        # once its neighbours have moved, so the ADD_TOP best additions of each run are each refined
        # (one sweep) before they are compared with the current events.
        for _ in range(ADD_ROUNDS):
            trials = []
            for ri in range(R):
                if cur_sse[ri] <= ADD_LEVEL * n[ri] * sigma**2:
                    continue
                for ev in _window_grid(ends[ri], n_cases):
                    trials.append((ri, sorted([*(x for x in cur[ri] if free(x, [ev])), ev])))
            if not trials:
                break
            ranked: dict[int, list[tuple[float, list[Event], np.ndarray]]] = {}
            for (ri, sched), r in zip(trials, open_loop(trials), strict=True):
                ranked.setdefault(ri, []).append((score(ri, run_sse(r), len(sched)), sched, r))
            saved = ([list(e) for e in cur], cur_sse.copy(), list(cur_res))
            best_final = {ri: (score(ri, cur_sse[ri], len(cur[ri])), cur[ri], cur_sse[ri], cur_res[ri])
                          for ri in ranked}
            for k in range(ADD_TOP):
                for ri, lst in ranked.items():
                    lst.sort(key=lambda x: x[0])
                    if k < len(lst):
                        cur[ri], cur_sse[ri], cur_res[ri] = list(lst[k][1]), run_sse(lst[k][2]), lst[k][2]
                    else:
                        cur[ri], cur_sse[ri], cur_res[ri] = saved[0][ri], saved[1][ri], saved[2][ri]
                refine_sweep(REFINE_OL, only=set(ranked))
                for ri in ranked:
                    sc = score(ri, cur_sse[ri], len(cur[ri]))
                    if sc < best_final[ri][0] - 1e-9:
                        best_final[ri] = (sc, list(cur[ri]), cur_sse[ri], cur_res[ri])
            changed = False
            for ri, (_, ev_, s_, r_) in best_final.items():
                changed |= ev_ != saved[0][ri]
                cur[ri], cur_sse[ri], cur_res[ri] = list(ev_), s_, r_
            if not changed:
                break
    for _ in range(OPEN_LOOP_ROUNDS):
        if not refine_sweep(REFINE):
            break
    gain = np.zeros(R)
    for ri in range(R):
        sc = score(ri, cur_sse[ri], len(cur[ri]))
        if cur[ri] and sc < 0:
            gain[ri] = n[ri] * math.log(max(sse0[ri], 1e-30) / max(cur_sse[ri], 1e-30))
        else:  # the set does not pay its cost: the run has no inferred event
            cur[ri], cur_sse[ri] = [], float(sse0[ri])
    # 4. Adequacy: lift-off says the nominal model is exact between events, so the MAP events must
    # explain the data to the tracker-noise level. If they leave more (row-weighted geometric-mean MSE
    # > adequacy·σ̂², the decision's metric), the events are absorbing some other, continuous model
    # error (a viscous drag is fitted by "coasting" pulses): the candidate then keeps no event.
    # Time each run is commanded to move (a command row holds until the next row).
    moving = np.array([float(np.sum(np.diff(r.t)[np.any(np.abs(r.cmd[:-1]) > 0, axis=1)])) for r in runs])
    note = ""
    lifted = sum(b - a for e in cur for a, b, _ in e)
    share = lifted / max(float(moving.sum()), 1e-9)
    if adequacy is not None and sigma is not None and sigma > 0 and any(cur) and geo_ratio() > adequacy:
        note = (f"{sum(len(e) for e in cur)} inferred events rejected: with them the held-out MSE is "
                f"{geo_ratio():.2f} x the tracker-noise variance (lift-off alone would leave noise; limit "
                f"{adequacy:g})")
    elif any(cur) and share > MAX_LIFTED_SHARE:
        # Lift-off is an excursion from the all-down state. Wheels "lifted" most of the time describe
        # a persistent load change (a centre-of-mass offset unloads one wheel), not lift-off.
        note = (f"{sum(len(e) for e in cur)} inferred events rejected: they keep wheels lifted {100 * share:.0f} % "
                f"of the moving time (lift-off is transient; limit {100 * MAX_LIFTED_SHARE:.0f} %)")
    p_cases = case_uniformity(cur, n_cases)
    if not note and p_cases < CASE_ALPHA:
        # The process lifts a uniformly drawn case; events that (almost) all lift the same wheel
        # mimic a systematic one-wheel effect (a centre-of-mass offset unloads one wheel).
        counts = np.bincount([c for e in cur for _, _, c in e], minlength=n_cases)[1:]
        note = (f"{sum(len(e) for e in cur)} inferred events rejected: their lifted cases {counts.tolist()} "
                f"are not a uniform draw (p = {p_cases:.2g} < {CASE_ALPHA:g}); lift-off lifts a random case")
    if note:
        cur, cur_sse, gain = [[] for _ in range(R)], np.array(sse0, dtype=float), np.zeros(R)
    return EventFit(events=cur, sse=cur_sse, gain=gain, durations=np.array(ends), moving=moving, note=note)
