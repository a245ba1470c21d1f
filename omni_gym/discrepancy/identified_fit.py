"""The final fit restricted to what the data determine: undetermined directions held at the start model.

After the search, :mod:`.identifiability` linearises the final fit u* (every named deterministic effect's
fitted dimensions, unit-cube coordinates) and splits the parameter space by the SVD of the scaled
Jacobian J = U S Vᵀ into identified combinations (rows vₖ of Vᵀ with 95 % half-width 2σ_eff/sₖ within
:data:`~.identifiability.IDENTIFIED` of the range) and the rest. Along an unidentified direction the
data barely change the residual, so where the search left the fit there (often at a bound, where it
compensates another error) is chance, not a measurement.

**Choice: the fit is re-done in the identified subspace**, u = u₀ + B·c, B the identified combinations
(columns), u₀ the start model's values (the candidate's null point: the nominal model's, or the
kinematic calibration's when the search started from it), c fitted by Levenberg–Marquardt on all runs
(and, for the held-out scores, on each fold's training runs, warm-started at the all-run fit, as the
search's fold fits are). Fixing every parameter that is not identified *on its own* and re-fitting the
others was the alternative; it throws away what the data do determine when parameters are only
determined together: on the omni3 robot no single wheel distance or scale is identified, yet their
ratios are (−scale1 + 0.94·scale2 − …, ±3 % of the range), and fixing them all would return the start
model. The subspace fit keeps those ratios and holds only the undetermined directions at the start.

Per parameter the outcome is one of (``status``):

* ``identified``: its own 95 % half-width is within the threshold; fitted (in the subspace).
* ``merged``: not identified alone, but in an identified combination (weight at least
  :data:`~.identifiability.MERGE_WEIGHT` of the largest); it moves only along that combination, and the
  report gives the combination, not the value, as what the data determined.
* ``fixed``: in no identified combination (or at its fit bound after the subspace fit, which then is
  re-done without it): held at the start model's value.
* ``kept``: neither identified nor with a start value (a dimension the effect's null point leaves
  open, e.g. a roller phase at μ'' = μ): it stays where the search left it and is reported as not
  determined.

When every combination is identified, nothing changes (no extra simulation). The refit costs a few LM
iterations, each (combinations + 3) replays of every run per target (all runs and each fold).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.candidates import to_cube
from omni_gym.discrepancy.identifiability import BOUND, MERGE_WEIGHT, Linearisation, combination_text
from omni_gym.discrepancy.residuals import run_sse
from omni_gym.physics.model import SimModel

NOTE = ("parameters not determined by the data are held at the start model's values and the determined "
        "combinations refitted (u = u0 + B c, B the identified combinations; all runs, and each fold's training "
        "runs for the held-out scores); per_effect_status: identified, merged (determined only in the listed "
        "combinations), fixed (start value), kept (no start value: left where the search put it); search_params: "
        "the search's values before the refit")
ITERATIONS = 4  # LM iterations of the all-run and fold fits in the subspace
STEP = 3e-3  # forward-difference step along each combination (unit-cube length)
BOUND_PASSES = 2  # most re-fits after fixing parameters that the subspace fit put at a bound


@dataclass
class IdentifiedFit:
    """The refit: per named effect its unit-cube point on all runs (``u_all``) and per fold (``u_folds``
    [fold][effect]), the per-run SSE [m²] of the all-run fit (``sse_all``) and of the fold fit that did not
    see the run (``heldout``), and per effect what happened to each parameter (``status``: JSON)."""

    u_all: list[np.ndarray]
    u_folds: list[list[np.ndarray]]
    sse_all: np.ndarray
    heldout: np.ndarray
    status: dict


def start_point(lin: Linearisation) -> tuple[np.ndarray, np.ndarray]:
    """(u₀, has_start): the start model's unit-cube point of every dimension (the candidate's null point,
    then its prior start, for dimensions the null point names) and whether it has one."""
    u0, has = [], []
    for n, u in zip(lin.named, lin.base, strict=True):
        c = n.candidate
        values = {**(c.prior or {}), **(c.null or {})}
        for j, d in enumerate(c.dims):
            has.append(d.name in values)
            u0.append(float(np.clip(d.unit(values[d.name]), 0.0, 1.0)) if d.name in values else float(u[j]))
    return np.array(u0), np.array(has)


def _split(u: np.ndarray, lin: Linearisation) -> list[np.ndarray]:
    out, i = [], 0
    for n in lin.named:
        p = n.candidate.n_params
        out.append(to_cube(n.candidate, u[i:i + p]))
        i += p
    return out


def _models(start: SimModel, lin: Linearisation, us: list[np.ndarray]) -> list[SimModel]:
    out = []
    for u in us:
        m = start
        for n, part in zip(lin.named, _split(u, lin), strict=True):
            m = m.with_effect(n.candidate.name, n.candidate.params(part))
        out.append(m)
    return out


def _stack(res: list[np.ndarray], mask: np.ndarray) -> np.ndarray:
    """Finite residual components after each run's first row, of the runs in ``mask`` (as run_sse counts)."""
    return np.concatenate([r[1:][np.all(np.isfinite(r[1:]), axis=1)].ravel()
                           for r, m in zip(res, mask, strict=True) if m] or [np.zeros(0)])


def refit(ev, start: SimModel, lin: Linearisation, fold_of: np.ndarray) -> IdentifiedFit | None:
    """The fit in the identified subspace (module docstring); None when every combination is identified
    (the search's fit stands as it is). ``ev``: the workflow's Evaluator; ``start``: the model the named
    effects were fitted on top of; ``fold_of`` (R,): each run's fold."""
    ident = lin.identified
    if ident.all():
        return None
    u_star = lin.u
    u0, has = start_point(lin)
    own = lin.own_identified
    V = lin.vt[ident]  # (m, p) identified combinations
    weight = (np.max(np.abs(V) / np.max(np.abs(V), axis=1, keepdims=True), axis=0) if len(V)
              else np.zeros(len(u_star)))
    fixed = has & (weight < MERGE_WEIGHT) & ~own
    kept = ~has & (weight < MERGE_WEIGHT) & ~own
    for _ in range(1 + BOUND_PASSES):
        fit = _subspace_fit(ev, start, lin, V, fixed | kept, np.where(has, u0, u_star), fold_of)
        u = np.concatenate(fit[0])
        dims = lin.dims
        at = np.array([not d.periodic and (x <= BOUND or x >= 1.0 - BOUND) for d, x in zip(dims, u, strict=True)])
        newly = at & has & ~own & ~fixed
        if not newly.any():
            break
        fixed = fixed | newly  # never a named value at a bound: the data did not determine it there
    u_all, u_folds, sse_all, heldout = fit
    status = statuses(lin, u, fixed, kept)
    return IdentifiedFit(u_all=u_all, u_folds=u_folds, sse_all=sse_all, heldout=heldout, status=status)


def _subspace_fit(ev, start: SimModel, lin: Linearisation, V: np.ndarray, held: np.ndarray, u_ref: np.ndarray,
                  fold_of: np.ndarray) -> tuple:
    """LM over c in u = u_ref + B c, B = Vᵀ with the ``held`` rows zeroed, on all runs and every fold's
    training runs. Starts: the projection of u* onto the subspace and the linearised least-squares
    solution (from the analysis' Jacobian, no simulation); each target starts from the better on its runs."""
    B = V.T.copy()
    B[held] = 0.0
    m = B.shape[1]
    R = len(fold_of)
    K = int(fold_of.max()) + 1
    masks = [fold_of != k for k in range(K)] + [np.ones(R, dtype=bool)]
    u_star = lin.u

    def point(c: np.ndarray) -> np.ndarray:
        return np.concatenate(_split(u_ref + B @ c, lin))

    def simulate(cs: list[np.ndarray]) -> list[list[np.ndarray]]:
        return ev.residuals(_models(start, lin, [point(c) for c in cs]))

    def cost(res: list[np.ndarray], mask: np.ndarray) -> float:
        return float(sum(run_sse(r) for r, k in zip(res, mask, strict=True) if k))

    if m:
        c_proj = np.linalg.lstsq(B, u_star - u_ref, rcond=None)[0]
        c_lin = -np.linalg.lstsq(lin.J @ B, lin.r0 + lin.J @ (u_ref - u_star), rcond=None)[0]
        starts = [c_proj, c_lin, 0.5 * (c_proj + c_lin)]
    else:
        starts = [np.zeros(0)]
    res0 = simulate(starts)
    states = []
    for mask in masks:
        i = int(np.argmin([cost(r, mask) for r in res0]))
        states.append({"c": starts[i].copy(), "res": res0[i], "cost": cost(res0[i], mask), "lam": 1e-2})
    for _ in range(ITERATIONS if m else 0):
        # Jacobian of every target in one batch
        cs = [st["c"] + STEP * e for st in states for e in np.eye(m)]
        res = simulate(cs)
        trials = []
        for t, (st, mask) in enumerate(zip(states, masks, strict=True)):
            r0 = _stack(st["res"], mask)
            J = np.column_stack([(_stack(res[t * m + i], mask) - r0) / STEP for i in range(m)])
            A, g = J.T @ J, J.T @ r0
            for lam in (st["lam"] / 10, st["lam"], st["lam"] * 10):
                step = np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-12), -g)
                trials.append((t, lam, st["c"] + step))
        res_t = simulate([c for _, _, c in trials])
        for (t, lam, c), r in zip(trials, res_t, strict=True):
            st = states[t]
            cst = cost(r, masks[t])
            if cst < st["cost"]:
                st.update(c=c, res=r, cost=cst, lam=max(lam, 1e-6), improved=True)
        for st in states:
            if not st.pop("improved", False):
                st["lam"] *= 10
    u_all = _split(point(states[K]["c"]), lin)
    u_folds = [_split(point(st["c"]), lin) for st in states[:K]]
    sse_all = np.array([run_sse(r) for r in states[K]["res"]])
    heldout = np.zeros(R)
    for k in range(K):
        heldout[fold_of == k] = [run_sse(r) for r, f in zip(states[k]["res"], fold_of, strict=True) if f == k]
    return u_all, u_folds, sse_all, heldout


def statuses(lin: Linearisation, u: np.ndarray | None = None, fixed: np.ndarray | None = None,
             kept: np.ndarray | None = None) -> dict:
    """Per named effect (JSON): each parameter's outcome (module docstring: ``identified``, ``merged``,
    ``fixed`` and ``kept`` with the values used), ``at_bound`` (identified parameters the fit put at a bound:
    the fit wants a value beyond the range), the identified combinations that involve the merged ones, and
    the report's one ``line``. Defaults: the search's fit u* with nothing fixed (every combination
    identified, :func:`refit` changed nothing)."""
    u = lin.u if u is None else u
    p = len(u)
    fixed = np.zeros(p, dtype=bool) if fixed is None else fixed
    kept = np.zeros(p, dtype=bool) if kept is None else kept
    own = lin.own_identified
    labels, dims = lin.labels, lin.dims
    ident_rows = np.flatnonzero(lin.identified)
    out: dict = {}
    for n in lin.named:
        name = n.candidate.name
        idx = [j for j, (e, _) in enumerate(labels) if e == name]
        entry: dict = {"identified": [], "merged": [], "fixed": {}, "kept": {}, "at_bound": [], "combinations": []}
        for j in idx:
            pname, value = labels[j][1], dims[j].value(float(u[j]))
            if own[j]:
                entry["identified"].append(pname)
                if not dims[j].periodic and (u[j] <= BOUND or u[j] >= 1.0 - BOUND):
                    entry["at_bound"].append(pname)
            elif fixed[j]:
                entry["fixed"][pname] = value
            elif kept[j]:
                entry["kept"][pname] = value
            else:
                entry["merged"].append(pname)
        for k in ident_rows:
            text, terms = combination_text(lin, int(k))
            if any(labels[j][1] in entry["merged"] and abs(lin.vt[k, j]) / np.max(np.abs(lin.vt[k])) >= MERGE_WEIGHT
                   for j in idx):
                entry["combinations"].append({"combination": text, "terms": terms,
                                              "half_width_95_range_share": float(lin.half[k])})
        entry["line"] = _line(name, entry)
        out[name] = entry
    return out


def _line(effect: str, e: dict) -> str:
    """One line: what the data pinned down of this effect and what they did not (and what was done)."""
    if e["identified"] and not (e["merged"] or e["fixed"] or e["kept"]):
        parts = [f"every parameter pinned down ({', '.join(e['identified'])})"]
    else:
        parts = [f"pinned down {', '.join(e['identified'])}" if e["identified"] else "pinned down no single parameter"]
    if e["at_bound"]:
        parts.append("at its fit bound (the fit wants a value beyond the range: it compensates another error, not a "
                     f"measurement): {', '.join(e['at_bound'])}")
    if e["merged"]:
        combos = "; ".join(c["combination"] for c in e["combinations"][:3])
        parts.append(f"determined only in combination: {', '.join(e['merged'])} (fitted along {combos}; "
                     "their separate values are not measurements)")
    if e["fixed"]:
        parts.append("not determined, fixed at the start model's value: "
                     + ", ".join(f"{k} = {v:.4g}" for k, v in e["fixed"].items()))
    if e["kept"]:
        parts.append("not determined, left where the search put it (no start value): "
                     + ", ".join(f"{k} = {v:.4g}" for k, v in e["kept"].items()))
    return f"{effect}: " + "; ".join(parts)
