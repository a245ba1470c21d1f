"""Lift-event inference for the stochastic ``wheel_liftoff`` candidate.

Lift-off is a random process (:class:`omni_gym.liftoff.ContactProcess`); a dataset holds one
realisation of it, which no rate pair can reproduce by simulation. The held-out likelihood of the
rates marginalises the unobserved events. We approximate that integral by its largest term (MAP /
Laplace): the most likely event sequence of each run, plus a BIC cost of 3·ln N per inferred event
(start, end, lifted case) in the per-run likelihood units n_r·ln(SSE_r/n_r) of
:func:`omni_gym.discrepancy.explain.decide` (N = residual components of the dataset).

Search, per run (all runs batched, see :func:`infer_events`):

1. **Windows.** The multiple-shooting windows (``explain.shooting_windows``, 1 s, each restarted
   from the measured state) make an event show up locally. Per window, the nominal window and every
   single-event alternative on a coarse grid (lifted case × start every :data:`GRID_DT` × duration
   in :data:`DURATIONS`, clipped to the window) are simulated in one batched call over all windows.
   A window's best event is accepted when its gain n_w·ln(SSE_nominal/SSE_event) beats the event
   cost; a second greedy pass looks for one more event in the windows that accepted one.
2. **Refine** each accepted event's start and end on a local grid (one batched call).
3. **Join** events cut by a window boundary (same case, touching ends).
4. **Open loop.** Every run is replayed from its start with its schedule — the other candidates are
   scored by the open-loop full-run SSE, so this one is too. Event start/end are refined by a few
   coordinate rounds on the open-loop cost, events that do not pay their cost are dropped, and a
   run keeps its event set only if its open-loop likelihood gain beats the total cost.

Rates from events (maximum likelihood for exponential holding times): lift_rate = events / time
all wheels are down, recover_rate = 1 / mean lifted duration; with no event, the null point.

Times in this module are seconds on a job's local clock (0 = the job's first row) unless a name
says run time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from omni_gym.liftoff import contact_cases

GRID_DT = 0.05  # s: start grid of the window search (half the shortest duration)
DURATIONS = (0.05, 0.1, 0.2, 0.4)  # s: coarse lifted durations (mean holding 1/recover_rate ~ 0.2 s)
REFINE = (-0.03, -0.015, -0.005, 0.0, 0.005, 0.015, 0.03)  # s: local start/end shifts
OPEN_LOOP_ROUNDS = 2  # coordinate rounds of start/end refinement on the open-loop cost
PARAMS_PER_EVENT = 3  # start, end, lifted case

EVENT_METHOD = ("wheel_liftoff: MAP lift events per run (window grid search, open-loop refinement), BIC cost "
                "3 ln N per event; rates = MLE from the events (fold rates from training runs); the held-out "
                "score is a marginal-likelihood approximation (events inferred on held-out runs too)")

Event = tuple[float, float, int]  # (t_start [s], t_end [s], case index into contact_cases(n), >= 1)


class ScheduledContactProcess:
    """Contact mask that replays a fixed list of lift events (duck-types ContactProcess for the World).

    Args:
        n_wheels: number of wheels.
        events: (t_start, t_end, case) on the robot's local clock [s] (0 = its last reset),
            t_start < t_end, non-overlapping; case indexes ``cases`` (row 0 = all down is not a lift).
        cases: optional (k, n) bool masks, row 0 all down (default :func:`contact_cases`).
    """

    def __init__(self, n_wheels: int, events: list[Event] | tuple[Event, ...],
                 cases: np.ndarray | None = None) -> None:
        self.cases = contact_cases(n_wheels) if cases is None else np.asarray(cases, dtype=bool)
        evs = sorted((float(a), float(b), int(c)) for a, b, c in events)
        for i, (a, b, c) in enumerate(evs):
            if not (math.isfinite(a) and math.isfinite(b) and a < b):
                raise ValueError(f"event {i}: need finite t_start < t_end [s], got ({a}, {b})")
            if not 1 <= c < len(self.cases):
                raise ValueError(f"event {i}: case must be in 1..{len(self.cases) - 1}, got {c}")
            if i and a < evs[i - 1][1]:
                raise ValueError(f"events overlap at {a} s")
        self.events = evs
        # Switch list: (time, case after the switch).
        self._switches = [s for a, b, c in evs for s in ((a, c), (b, 0))]
        self.reset(0.0)

    def reset(self, t: float = 0.0) -> None:
        """All wheels down; the schedule restarts (its times are on the clock this reset zeroes)."""
        self.case = 0
        self._i = 0
        self.next_switch = self._switches[0][0] if self._switches else math.inf

    @property
    def mask(self) -> np.ndarray:
        return self.cases[self.case]

    def advance(self, t: float) -> bool:
        """Apply every scheduled switch at or before time t [s]; True if the mask changed."""
        changed = False
        while self.next_switch <= t:
            new = self._switches[self._i][1]
            changed |= new != self.case
            self.case = new
            self._i += 1
            self.next_switch = self._switches[self._i][0] if self._i < len(self._switches) else math.inf
        return changed


@dataclass
class EventFit:
    """Inferred lift events of every run and the open-loop fit they give."""

    events: list[list[Event]]  # per run, on the run's clock [s] (run.t[0] = 0)
    sse: np.ndarray  # (R,) open-loop SSE [m²] of each run replayed with its events
    gain: np.ndarray  # (R,) likelihood gain n_r·ln(SSE_nominal/SSE_events) (0 for runs without events)
    durations: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (R,) run lengths [s]

    def n_events(self, mask: np.ndarray | None = None) -> int:
        """Events in the runs of ``mask`` (all runs if None)."""
        return sum(len(e) for i, e in enumerate(self.events) if mask is None or mask[i])

    def rates(self, mask: np.ndarray | None = None) -> tuple[float, float] | None:
        """MLE (lift_rate, recover_rate) [1/s] from the events of the runs in ``mask``; None without events.

        Exponential holding times: lift_rate = events / all-down time, recover_rate = 1 / mean lifted
        duration (an event still lifted at a run's end is counted as if it ended there — a small
        bias toward faster recovery, accepted for simplicity).
        """
        sel = [i for i in range(len(self.events)) if mask is None or mask[i]]
        k = sum(len(self.events[i]) for i in sel)
        if k == 0:
            return None
        lifted = sum(b - a for i in sel for a, b, _ in self.events[i])
        down = float(sum(self.durations[i] for i in sel)) - lifted
        return k / max(down, 1e-6), k / max(lifted, 1e-6)

    def to_json(self, run_names: list[str], cases: np.ndarray) -> list[dict]:
        """Events for result.json: run, start/end [s, run clock], 1-based wheels lifted."""
        return [{"run": name, "start": round(a, 4), "end": round(b, 4),
                 "wheels_lifted": [int(w) + 1 for w in np.flatnonzero(~cases[c])]}
                for name, evs in zip(run_names, self.events, strict=True) for a, b, c in evs]


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
                 dt: float, windows: list[tuple] | None = None, max_batch: int = 3000,
                 counter: list[int] | None = None) -> EventFit:
    """MAP lift events of every run of ``ds`` (see the module docstring).

    Args:
        ds: the dataset; nominal: the nominal SimModel (no lift-off); lever [m]: heading lever.
        cost: likelihood cost of one event (BIC: 3·ln N) in n·ln(SSE/n) units.
        sse0: (R,) nominal open-loop SSE [m²]; n_comp: (R,) residual components per run.
        dt: physics substep [s]; windows: ``shooting_windows(ds)`` (computed if None).
        counter: optional one-element list to which the number of simulated robot-runs is added.
    """
    from omni_gym.discrepancy.explain import _sse, shooting_windows
    from omni_gym.discrepancy.simulate import Job, pose_residual, simulate_jobs

    runs = ds.runs
    R = len(runs)
    n_cases = len(contact_cases(ds.n_wheels))
    wins = shooting_windows(ds) if windows is None else windows
    count = counter if counter is not None else [0]

    def run_batch(jobs: list) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for i in range(0, len(jobs), max_batch):
            out += [p for p, _ in simulate_jobs(jobs[i:i + max_batch], dt=dt)]
        count[0] += len(jobs)
        return out

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
        return all(ev[1] <= a or ev[0] >= b for a, b, _ in taken)

    # 1. Coarse window search, then one more greedy event where one was accepted.
    tws = [float(runs[ri].t[k1] - runs[ri].t[k0]) for ri, k0, k1, _ in wins]
    base: list[list[Event]] = [[] for _ in wins]
    grids = [_window_grid(tw, n_cases) for tw in tws]
    best = window_search(base, grids)
    for wi, b in enumerate(best):
        if b is not None:
            base[wi].append(b[1])
    grids2 = [[ev for ev in grids[wi] if free(ev, base[wi])] if base[wi] else [] for wi in range(len(wins))]
    if any(grids2):
        best2 = window_search(base, grids2)
        for wi, b in enumerate(best2):
            if b is not None:
                base[wi].append(b[1])
                base[wi].sort()

    # 2. Local refinement of each window event's start and end (other events of the window fixed).
    for _ in range(1):
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

    # 3. Run clock, joining events cut by a window boundary.
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

    # 4. Open loop: refine, prune, keep only sets that pay for themselves.
    n = np.maximum(n_comp, 1)
    ends = [float(r.t[-1]) for r in runs]

    def open_loop(scheds: list[tuple[int, list[Event]]]) -> list[float]:
        if not scheds:
            return []
        poses = run_batch([Job(nominal, runs[ri], schedule=tuple(s)) for ri, s in scheds])
        return [_sse(pose_residual(runs[ri].pose, p, lever)) for (ri, _), p in zip(scheds, poses, strict=True)]

    def score(ri: int, s: float, k: int) -> float:
        """Penalised likelihood change vs nominal (lower is better)."""
        return float(n[ri] * math.log(max(s, 1e-30) / max(sse0[ri], 1e-30)) + cost * k)

    cur = [list(e) for e in per_run]
    cur_sse = np.array(sse0, dtype=float)
    live = [ri for ri in range(R) if cur[ri]]
    for ri, s in zip(live, open_loop([(ri, cur[ri]) for ri in live]), strict=True):
        cur_sse[ri] = s
    for _ in range(OPEN_LOOP_ROUNDS):
        # Sweep over event positions: event j of every run shifted (start/end) or removed, all runs in
        # one batch; events later in a run see the earlier ones already refined (open loop is causal).
        improved = False
        for j in range(max((len(e) for e in cur), default=0)):
            trials: list[tuple[int, list[Event]]] = []
            for ri in range(R):
                if j >= len(cur[ri]):
                    continue
                a, b, c = cur[ri][j]
                others = cur[ri][:j] + cur[ri][j + 1:]
                trials.append((ri, others))
                for da in REFINE:
                    for db in REFINE:
                        if da == 0.0 and db == 0.0:
                            continue
                        na, nb = max(a + da, 0.0), min(b + db, ends[ri])
                        if nb - na >= 0.01 and free((na, nb, c), others):
                            trials.append((ri, sorted([*others, (round(na, 6), round(nb, 6), c)])))
            if not trials:
                continue
            best_trial: dict[int, tuple[float, list[Event], float]] = {}
            for (ri, sched), s in zip(trials, open_loop(trials), strict=True):
                sc = score(ri, s, len(sched))
                if sc < score(ri, cur_sse[ri], len(cur[ri])) - 1e-9 and (ri not in best_trial
                                                                         or sc < best_trial[ri][0]):
                    best_trial[ri] = (sc, sched, s)
            for ri, (_, sched, s) in best_trial.items():
                cur[ri], cur_sse[ri] = list(sched), s
                improved = True
        if not improved:
            break
    gain = np.zeros(R)
    for ri in range(R):
        sc = score(ri, cur_sse[ri], len(cur[ri]))
        if cur[ri] and sc < 0:
            gain[ri] = n[ri] * math.log(max(sse0[ri], 1e-30) / max(cur_sse[ri], 1e-30))
        else:  # the set does not pay its cost: the run has no inferred event
            cur[ri], cur_sse[ri] = [], float(sse0[ri])
    return EventFit(events=cur, sse=cur_sse, gain=gain, durations=np.array(ends))
