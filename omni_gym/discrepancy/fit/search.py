"""Batched local searches in a candidate's unit cube: roller-phase sweeps, Levenberg–Marquardt, valley lines.

Every search round simulates the trial points of all live searches in one batch (one world). A
search is a :class:`SearchState` (its point, residuals, training error and damping); the arguments
all searches of one fit share are a :class:`SearchContext` (the evaluator, the training-run masks of
every target, the point pools each round adds to). :func:`levenberg_marquardt` and
:func:`valley_search` minimise the training error of the stacked residuals; :func:`phase_search`
sweeps single coordinates on grids (the roller phases make the cost multimodal, so gradients alone
would stall).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from omni_gym.discrepancy.fit.candidates import Candidate, to_cube


class Evaluate(Protocol):
    """Per-run SSE (P, R) [m²] and per-point, per-run residuals (K, 3) [m] of the unit-cube points ``us``
    (P, p), open loop or (``shooting``) on the multiple-shooting windows."""

    def __call__(self, us: np.ndarray, shooting: bool = False) -> tuple[np.ndarray, list[list[np.ndarray]]]: ...


@dataclass
class SearchState:
    """One local search: its current point and how good it is on its target's training runs.

    ``res`` and ``cost`` are unset (None, inf) for a search that :func:`phase_search` has yet to score.
    """

    t: int  # target: index into SearchContext.train / pools_u / pools_sse
    u: np.ndarray  # (p,) current point in the unit cube
    res: list[np.ndarray] | None = None  # per run: open-loop residual (K, 3) [m] at u
    cost: float = math.inf  # open-loop SSE [m²] at u over the target's training runs
    lam: float = 1e-2  # Levenberg–Marquardt damping
    done: bool = False  # LM converged or gave up (set by levenberg_marquardt)
    scost: float = math.inf  # sweep cost of phase_search at u (shooting or open loop) [m²]


@dataclass
class SearchContext:
    """What every search of one fit shares (one candidate, one evaluator)."""

    evaluate: Evaluate
    train: list[np.ndarray]  # per target: (R,) bool, the runs its training error sums over
    pools_u: list[list[np.ndarray]]  # per target: every point simulated for it, (n, p) blocks
    pools_sse: list[list[np.ndarray]]  # per target: their per-run SSE, (n, R) blocks [m²]
    cand: Candidate
    h: float  # forward-difference step in the unit cube
    tick: Callable[[], None] | None  # progress: called once per batch round


def phase_search(states: list[SearchState], periodic: list[int], grid: int, sweeps: int, ctx: SearchContext,
                 target: int, shooting: bool = True, local: list[int] = (), width: float = 0.06,
                 local_points: int = 9) -> None:
    """Coordinate sweeps for every search in ``states``, one batch per dimension: each dimension in
    ``local`` on ``local_points`` points within ±``width`` (unit cube) of the search's value, then
    each periodic dimension on a full grid of ``grid`` points; a search keeps the best point. The
    sweep cost is the multiple-shooting one (``shooting``) or the open-loop one. Each search then
    moves to its result, re-scored on the open-loop cost (added to the pool of ``target``).
    """
    evaluate = ctx.evaluate
    start = np.array([st.u for st in states])
    scost = evaluate(start, shooting=shooting)[0].sum(axis=1)
    for st, c in zip(states, scost, strict=True):
        st.scost = float(c)
    offsets = np.linspace(-width, width, local_points)
    for _ in range(sweeps):
        for j in [*local, *periodic]:
            grids = []
            for st in states:
                values = np.clip(st.u[j] + offsets, 0.0, 1.0) if j in local else (np.arange(grid) + 0.5) / grid
                g = np.tile(st.u, (len(values), 1))
                g[:, j] = values
                grids.append(g)
            cost = evaluate(np.concatenate(grids), shooting=shooting)[0].sum(axis=1).reshape(len(states), -1)
            for st, g, c in zip(states, grids, cost, strict=True):
                i = int(np.argmin(c))
                if c[i] < st.scost:
                    st.u = g[i].copy()
                    st.scost = float(c[i])
        if ctx.tick:
            ctx.tick()
    us = np.array([st.u for st in states])
    m_sse, m_res = evaluate(us)
    ctx.pools_u[target].append(us)
    ctx.pools_sse[target].append(m_sse)
    for st, sse, res in zip(states, m_sse, m_res, strict=True):
        st.res = res
        st.cost = float(sse.sum())


def _jacobians(states: list[SearchState], ctx: SearchContext) -> tuple[list, np.ndarray, list[np.ndarray]]:
    """Forward-difference Jacobians of every search in ``states`` in one batch: per search the p
    points u ± h·e_j (stepping down where u + h would leave the cube), their (p·S, R) SSE, and the
    Jacobian of the stacked training-run residuals (:func:`_stack`) with respect to u."""
    p, h = ctx.cand.n_params, ctx.h
    fd, signs = [], []
    for st in states:
        sgn = np.where(st.u + h <= 1.0, 1.0, -1.0)
        fd.append(st.u + np.diag(sgn * h))
        signs.append(sgn)
    fd_sse, fd_res = ctx.evaluate(np.concatenate(fd))
    jacs = []
    for si, st in enumerate(states):
        mask = ctx.train[st.t]
        r0 = _stack(st.res, mask)
        jacs.append(np.column_stack([(_stack(fd_res[si * p + j], mask) - r0) / (signs[si][j] * h) for j in range(p)]))
    return fd, fd_sse, jacs


def levenberg_marquardt(states: list[SearchState], iterations: int, ctx: SearchContext) -> None:
    """Batched LM steps for every search in ``states`` (updated in place).

    Per iteration: forward-difference Jacobians (p points per search) in one batch, then three
    damping levels per search in a second batch; a search keeps the best trial if it lowers its
    training error and stops when a tiny step gains less than 0.01 % (far below what matters for
    the thresholds of settings.DecisionRules) or the damping has grown past use.
    """
    p = ctx.cand.n_params
    train = ctx.train
    damping = (0.1, 1.0, 10.0)
    nd = len(damping)
    for st in states:
        st.done = False
    for _ in range(iterations):
        live = [st for st in states if not st.done]
        if not live:
            break
        fd, fd_sse, jacs = _jacobians(live, ctx)
        trials = []
        for st, J in zip(live, jacs, strict=True):
            r0 = _stack(st.res, train[st.t])
            # r = measured − simulated(u); the Gauss–Newton step solves (JᵀJ + λ·diag JᵀJ) δ = −Jᵀr.
            A = J.T @ J
            g = J.T @ r0
            dg = np.diag(A).copy() + 1e-12
            for f in damping:
                try:
                    step = np.linalg.solve(A + st.lam * f * np.diag(dg), -g)
                except np.linalg.LinAlgError:
                    step = np.zeros(p)
                trials.append(to_cube(ctx.cand, st.u + step))
        tr_u = np.array(trials)
        tr_sse, tr_res = ctx.evaluate(tr_u)
        for si, st in enumerate(live):
            t, mask = st.t, train[st.t]
            ctx.pools_u[t] += [fd[si], tr_u[nd * si:nd * si + nd]]
            ctx.pools_sse[t] += [fd_sse[si * p:(si + 1) * p], tr_sse[nd * si:nd * si + nd]]
            costs = tr_sse[nd * si:nd * si + nd][:, mask].sum(axis=1)
            j = int(np.argmin(costs))
            if costs[j] < st.cost:
                st.done = bool(costs[j] > (1.0 - 1e-4) * st.cost
                               and np.max(np.abs(tr_u[nd * si + j] - st.u)) < 1e-3)
                st.u = tr_u[nd * si + j]
                st.res = tr_res[nd * si + j]
                st.cost = float(costs[j])
                st.lam = max(st.lam * 0.3 * damping[j], 1e-6)
            else:
                st.lam *= 10.0
                st.done = st.lam > 1e4
        if ctx.tick:
            ctx.tick()


VALLEY_STEPS = np.array([0.005, 0.01, 0.02, 0.04, 0.08, 0.16, 0.32, 0.64])  # unit cube


def valley_search(states: list[SearchState], ctx: SearchContext) -> bool:
    """One line search per search in ``states`` along its valley: the direction of least curvature
    of the Gauss–Newton Hessian JᵀJ (forward differences), at :data:`VALLEY_STEPS` both ways, in one
    batch; a search moves to the best point if it lowers its training error. True if any moved."""
    p = ctx.cand.n_params
    fd, fd_sse, jacs = _jacobians(states, ctx)
    lines = []
    for st, J in zip(states, jacs, strict=True):
        v = np.linalg.eigh(J.T @ J)[1][:, 0]  # eigenvalues ascending: the flattest direction
        steps = np.concatenate([VALLEY_STEPS, -VALLEY_STEPS])
        lines.append(np.array([to_cube(ctx.cand, st.u + s * v) for s in steps]))
    ln_sse, ln_res = ctx.evaluate(np.concatenate(lines))
    moved = False
    m = len(VALLEY_STEPS) * 2
    for si, st in enumerate(states):
        t, mask = st.t, ctx.train[st.t]
        ctx.pools_u[t] += [fd[si], lines[si]]
        ctx.pools_sse[t] += [fd_sse[si * p:(si + 1) * p], ln_sse[si * m:(si + 1) * m]]
        costs = ln_sse[si * m:(si + 1) * m][:, mask].sum(axis=1)
        j = int(np.argmin(costs))
        if costs[j] < st.cost:
            st.u = lines[si][j]
            st.res = ln_res[si * m + j]
            st.cost = float(costs[j])
            st.lam = 1e-2
            moved = True
    if ctx.tick:
        ctx.tick()
    return moved


def _stack(per_run: list[np.ndarray], mask: np.ndarray) -> np.ndarray:
    """Residual components of the runs in ``mask`` (observed rows after t = 0), flattened; NaN as 0."""
    return np.concatenate([np.nan_to_num(r[1:]).ravel() for r, m in zip(per_run, mask, strict=True) if m])
