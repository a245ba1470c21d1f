"""The final fit restricted to what the data determine: undetermined directions held at the start model.

After the search, :mod:`.identifiability` linearises the final fit u* (every named deterministic effect's
fitted dimensions, unit-cube coordinates) and splits the parameter space by the SVD of the scaled
Jacobian J = U S Vᵀ into combinations vₖ (rows of Vᵀ), each known to a 95 % half-width hₖ = 2σ_eff/sₖ.
A combination is identified when hₖ is within ``identified`` (settings) of the range.

**Choice: the fit is re-done in a subspace**, u = u₀ + B·c, u₀ the start model's values (the
candidate's null point: the nominal model's, or the kinematic calibration's when the search started from
it), B the combinations fitted, c by Levenberg–Marquardt on all runs and, for the held-out scores, on
each fold's training runs (warm-started at the all-run fit, as the search's fold fits are). A combination
is **held** at the start (left out of B) when it is not identified *and* the start lies inside its 95 %
interval, |vₖ·(u* − u₀)| ≤ hₖ: the data neither pin it down nor ask to move away from the start, so where
the search left it is chance. A combination that is not identified but whose interval excludes the start
stays fitted: the data reject the start along it, if not precisely (holding every unidentified
combination at the start cost the omni3 fit 5.2 → 9.8 mm RMS on its training segments).

Fixing every parameter that is not identified *on its own* and re-fitting the others was the
alternative; it throws away what the data determine when parameters are determined only together (per-
wheel radius and distance enter the kinematics together: their ratios can be identified when neither
is), and could return the start model where the data clearly say otherwise.

**Bounds.** A value at its fit bound is never a measurement (the fit wants a value beyond the range, to
compensate another error). A parameter the fit puts at a bound is held at the start value and the fit
re-done (``bound_passes``). That may cost prediction: when the refit's held-out MSE is more than
``held_out_tolerance`` above the search's, the data reject the start value there, the parameter keeps
the search's value and the report says it sits at its bound, compensating another error, with the cost
of holding it measured (``bound_cost``): on the omni3 robot a wheel distance at the 1.15 bound, held at 1,
made four of five held-out sessions' whole-run position RMS worse (mean 54.5 → 68.0 mm; the kinematic
calibration: 60.5 mm).

Per parameter the outcome is one of (``status``):

* ``identified``: its own 95 % half-width is within the threshold; fitted.
* ``merged``: not identified alone, in an identified combination (weight at least
  ``merge_weight`` of the largest): it moves only along that combination, and the
  report gives the combination, not the value, as what the data determined.
* ``loose``: in a combination that is fitted but not identified: the data move it away from the start
  but leave it uncertain (its 95 % half-width, share of the range, is given); not a measurement.
* ``fixed``: in no fitted combination: held at the start model's value.
* ``bound_fixed``: put at its fit bound by the search or the refit: held at the start model's value.
* ``kept``: in no fitted combination and without a start value (a dimension the effect's null point
  leaves open, e.g. a roller phase at μ'' = μ): it stays where the search left it, reported as not
  determined.

When nothing is held and nothing is at a bound, nothing changes (no extra simulation). The refit costs a
few LM iterations, each (combinations + 3) replays of every run per target (all runs and each fold).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from omni_gym.discrepancy.fit.candidates import to_cube
from omni_gym.discrepancy.fit.identifiability import Linearisation, combination_text
from omni_gym.discrepancy.replay.residuals import geo_mse, run_sse
from omni_gym.discrepancy.settings import FitSettings
from omni_gym.physics.model import SimModel
from omni_gym.progress import OFF, ProgressLines

NOTE = ("parameters not determined by the data are held at the start model's values and the determined "
        "combinations refitted (u = u0 + B c, B the identified combinations; all runs, and each fold's training "
        "runs for the held-out scores); per_effect_status: identified, merged (determined only in the listed "
        "combinations), fixed (start value), kept (no start value: left where the search put it); search_params: "
        "the search's values before the refit")
# The forward-difference step, the bound margin, the merge weight, the bound passes and the held-out tolerance
# are the fields of settings.IdentifiabilitySettings (recorded in result.json); the Linearisation carries them.


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
    changed: bool = True  # False: the search's values stand (only the status says more)
    bound_fixed: np.ndarray | None = None  # (p,) parameters held at the start because the fit put them at a bound


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


def refit(ev, start: SimModel, lin: Linearisation, fold_of: np.ndarray, search_heldout: np.ndarray | None = None,
          n_comp: np.ndarray | None = None, fit: FitSettings | None = None,
          lines: ProgressLines = OFF) -> IdentifiedFit | None:
    """The fit with the undetermined directions and the parameters at a fit bound held at the start model
    (module docstring); None when nothing is held (every combination identified or away from the start, no
    parameter at a bound): the search's fit stands as it is. ``ev``: the workflow's Evaluator; ``start``:
    the model the named effects were fitted on top of; ``fold_of`` (R,): each run's fold.

    ``search_heldout`` (R,) [m²] and ``n_comp`` (R,): the search's per-run held-out SSE and residual
    components. With them, holding the parameters at a bound must not cost more than
    ``held_out_tolerance`` of the search's held-out MSE (row-weighted geometric mean, the decision's
    metric); when it does, the data reject the start value there (the bound value compensates another
    error that the model needs compensated): those parameters keep the search's values, reported as at
    their bound with the cost measured (``bound_cost``). ``fit``: the LM iterations of the subspace fits
    (``identified_iterations``; None: the defaults). ``lines``: a progress line per LM iteration of each
    subspace fit (:mod:`omni_gym.progress`)."""
    iterations = (FitSettings() if fit is None else fit).identified_iterations
    u_star = lin.u
    u0, has = start_point(lin)
    u_ref = np.where(has, u0, u_star)
    held_dir = held_directions(lin, u_ref)
    bound = lin.at_bound() & has
    if not held_dir.any() and not bound.any():
        return None
    out = _refit(ev, start, lin, fold_of, u_ref, has, held_dir, iterations, lines=lines)
    bound = out.bound_fixed
    if search_heldout is None or n_comp is None or not bound.any():
        return out
    cost = geo_mse(out.heldout, n_comp) / max(geo_mse(search_heldout, n_comp), 1e-30) - 1.0
    if cost <= lin.cfg.held_out_tolerance:
        return out
    # The data reject the start value of the bound parameters: keep them where the search put them.
    u_keep = np.where(bound, u_star, u_ref)
    kept = (_refit(ev, start, lin, fold_of, u_keep, has & ~bound, held_dir, iterations, keep=bound, lines=lines)
            if held_dir.any() else None)
    if kept is not None and geo_mse(kept.heldout, n_comp) > (1.0 + lin.cfg.held_out_tolerance) * geo_mse(search_heldout,
                                                                                                      n_comp):
        kept = None  # holding the undetermined directions costs too (not expected: the start is inside them)
    status = kept.status if kept is not None else statuses(lin)
    labels, dims = lin.labels, lin.dims
    u_final = np.concatenate(kept.u_all) if kept is not None else u_star
    for j in np.flatnonzero(bound):
        if dims[j].periodic or lin.cfg.bound < u_final[j] < 1.0 - lin.cfg.bound:
            continue  # kept at the search's value, which is inside the range: its status says the rest
        eff, name = labels[j]
        st = status[eff]
        st.setdefault("bound_cost", {})[name] = float(cost)
        # one outcome per parameter: at its bound, not also loose, merged or identified
        st["loose"].pop(name, None)
        st["merged"] = [k for k in st["merged"] if k != name]
        st["identified"] = [k for k in st["identified"] if k != name]
        st["at_bound"] = [k for k in st["at_bound"] if k != name]
        st["line"] = _line(eff, st)
    if kept is None:
        return IdentifiedFit(u_all=list(lin.base), u_folds=[], sse_all=np.zeros(0), heldout=search_heldout.copy(),
                             status=status, changed=False)
    kept.status = status
    return kept




def _refit(ev, start: SimModel, lin: Linearisation, fold_of: np.ndarray, u_ref: np.ndarray, has: np.ndarray,
           held_dir: np.ndarray, iterations: int, keep: np.ndarray | None = None,
           lines: ProgressLines = OFF) -> IdentifiedFit:
    """One refit: the combinations not in ``held_dir`` fitted from ``u_ref``; parameters in no fitted
    combination held at ``u_ref`` (``has``: they have a start value; ``keep``: held at ``u_ref`` whatever
    else, as the search's values); parameters the fit puts at a bound are held at the start and the fit
    re-done (``bound_passes``; ``bound_fixed`` of the result). ``iterations``: LM iterations of each
    subspace fit."""
    own = lin.own_identified
    keep = np.zeros(len(u_ref), dtype=bool) if keep is None else keep
    V = lin.vt[~held_dir]  # (m, p) the combinations fitted
    weight = _weights(V, len(u_ref))
    at_bound = np.zeros(len(u_ref), dtype=bool)
    fixed = has & (weight < lin.cfg.merge_weight) & ~own
    kept = ~has & ~keep & (weight < lin.cfg.merge_weight) & ~own
    for _ in range(1 + lin.cfg.bound_passes):
        fit = _subspace_fit(ev, start, lin, V, fixed | kept | keep, u_ref, fold_of, iterations, lines)
        u = np.concatenate(fit[0])
        dims = lin.dims
        b = lin.cfg.bound
        at = np.array([not d.periodic and (x <= b or x >= 1.0 - b) for d, x in zip(dims, u, strict=True)])
        newly = at & has & ~fixed & ~keep
        if not newly.any():
            break
        # Never a named value at a bound: there the fit wants a value beyond the range, to compensate
        # another error; the parameter is held at the start model's value and the rest refitted.
        fixed, at_bound = fixed | newly, at_bound | newly
    u_all, u_folds, sse_all, heldout = fit
    status = statuses(lin, u, fixed, kept, held_dir, at_bound)
    return IdentifiedFit(u_all=u_all, u_folds=u_folds, sse_all=sse_all, heldout=heldout, status=status,
                         bound_fixed=at_bound)


def held_directions(lin: Linearisation, u_ref: np.ndarray) -> np.ndarray:
    """(combinations,) True for a combination that is not identified and along which the start point
    ``u_ref`` lies inside the search fit's 95 % interval: the data neither pin it down nor ask to move away
    from the start (along a combination that is not identified but whose interval excludes the start, the
    data do reject the start: holding it there cost the omni3 fit 5.2 → 9.8 mm RMS, so it stays fitted)."""
    delta = lin.vt @ (lin.u - u_ref)
    return ~lin.identified & (np.abs(delta) <= lin.half)


def _weights(V: np.ndarray, p: int) -> np.ndarray:
    """(p,) each dimension's largest weight in the rows of ``V`` (each row scaled to largest weight 1)."""
    if not len(V):
        return np.zeros(p)
    return np.max(np.abs(V) / np.max(np.abs(V), axis=1, keepdims=True), axis=0)


def _subspace_fit(ev, start: SimModel, lin: Linearisation, V: np.ndarray, held: np.ndarray, u_ref: np.ndarray,
                  fold_of: np.ndarray, iterations: int, lines: ProgressLines = OFF) -> tuple:
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
    progress = lines.loop("identified refit:", iterations if m else 0, "iterations")
    for _ in range(iterations if m else 0):
        # Jacobian of every target in one batch
        cs = [st["c"] + lin.cfg.step * e for st in states for e in np.eye(m)]
        res = simulate(cs)
        trials = []
        for t, (st, mask) in enumerate(zip(states, masks, strict=True)):
            r0 = _stack(st["res"], mask)
            J = np.column_stack([(_stack(res[t * m + i], mask) - r0) / lin.cfg.step for i in range(m)])
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
        progress.update()
    u_all = _split(point(states[K]["c"]), lin)
    u_folds = [_split(point(st["c"]), lin) for st in states[:K]]
    sse_all = np.array([run_sse(r) for r in states[K]["res"]])
    heldout = np.zeros(R)
    for k in range(K):
        heldout[fold_of == k] = [run_sse(r) for r, f in zip(states[k]["res"], fold_of, strict=True) if f == k]
    return u_all, u_folds, sse_all, heldout


def statuses(lin: Linearisation, u: np.ndarray | None = None, fixed: np.ndarray | None = None,
             kept: np.ndarray | None = None, held_dir: np.ndarray | None = None,
             bound_fixed: np.ndarray | None = None) -> dict:
    """Per named effect (JSON): each parameter's outcome (module docstring: ``identified``, ``merged``,
    ``loose``, ``fixed`` and ``kept`` with the values used), ``at_bound`` (identified parameters the fit put
    at a bound: the fit wants a value beyond the range), the identified combinations that involve the merged
    ones, and the report's one ``line``. Defaults: the search's fit u* with nothing fixed or held
    (:func:`refit` changed nothing)."""
    u = lin.u if u is None else u
    p = len(u)
    fixed = np.zeros(p, dtype=bool) if fixed is None else fixed
    kept = np.zeros(p, dtype=bool) if kept is None else kept
    held_dir = np.zeros(len(lin.s), dtype=bool) if held_dir is None else held_dir
    own = lin.own_identified
    bound_fixed = np.zeros(p, dtype=bool) if bound_fixed is None else bound_fixed
    labels, dims = lin.labels, lin.dims
    ident_rows = np.flatnonzero(lin.identified)
    w_loose = _weights(lin.vt[~lin.identified & ~held_dir], p)
    out: dict = {}
    for n in lin.named:
        name = n.candidate.name
        idx = [j for j, (e, _) in enumerate(labels) if e == name]
        entry: dict = {"identified": [], "merged": [], "loose": {}, "fixed": {}, "bound_fixed": {}, "kept": {},
                       "at_bound": [], "combinations": []}
        for j in idx:
            pname, value = labels[j][1], dims[j].value(float(u[j]))
            if bound_fixed[j]:  # the search (or the refit) put it at its fit bound: held at the start
                entry["bound_fixed"][pname] = {"value": value, "search_value": dims[j].value(float(lin.u[j]))}
            elif fixed[j]:
                entry["fixed"][pname] = value
            elif own[j]:
                entry["identified"].append(pname)
                if not dims[j].periodic and (u[j] <= lin.cfg.bound or u[j] >= 1.0 - lin.cfg.bound):
                    entry["at_bound"].append(pname)
            elif kept[j]:
                entry["kept"][pname] = value
            elif w_loose[j] >= lin.cfg.merge_weight:
                entry["loose"][pname] = float(2.0 * lin.sd[j])  # 95 % half-width, share of the fit range
            else:
                entry["merged"].append(pname)
        for k in ident_rows:
            text, terms = combination_text(lin, int(k))
            w = np.abs(lin.vt[k]) / np.max(np.abs(lin.vt[k]))
            if any(labels[j][1] in entry["merged"] and w[j] >= lin.cfg.merge_weight for j in idx):
                entry["combinations"].append({"combination": text, "terms": terms,
                                              "half_width_95_range_share": float(lin.half[k])})
        entry["line"] = _line(name, entry)
        out[name] = entry
    return out


def _line(effect: str, e: dict) -> str:
    """One line: what the data pinned down of this effect and what they did not (and what was done)."""
    cost = e.get("bound_cost", {})
    bound = [k for k in e["at_bound"] if k not in cost]
    pinned = [k for k in e["identified"] if k not in e["at_bound"] and k not in cost]
    if pinned and not (e["merged"] or e["loose"] or e["fixed"] or e["bound_fixed"] or e["kept"] or e["at_bound"]
                       or cost):
        parts = [f"every parameter pinned down ({', '.join(pinned)})"]
    else:
        parts = [f"pinned down {', '.join(pinned)}" if pinned else "pinned down no single parameter"]
    if bound:
        parts.append("at its fit bound (the fit wants a value beyond the range: it compensates another error, not a "
                     f"measurement): {', '.join(bound)}")
    if cost:
        parts.append("at its fit bound (the fit wants a value beyond the range, compensating another error: not a "
                     "measurement), kept there because holding it at the start model's value predicts the held-out "
                     "runs worse (held-out MSE " + ", ".join(f"{k} +{100 * v:.0f} %" for k, v in cost.items()) + ")")
    if e["merged"]:
        combos = "; ".join(c["combination"] for c in e["combinations"][:3])
        parts.append(f"determined only in combination: {', '.join(e['merged'])} (fitted along {combos}; "
                     "their separate values are not measurements)")
    if e["loose"]:
        parts.append("only loosely determined (the data move it away from the start model but leave it uncertain; "
                     "not a measurement): " + ", ".join(f"{k} (±{100 * v:.0f} % of its range)"
                                                       for k, v in e["loose"].items()))
    if e["bound_fixed"]:
        parts.append("at its fit bound in the search (the fit wanted a value beyond the range, compensating another "
                     "error: not a measurement), held at the start model's value: "
                     + ", ".join(f"{k} = {v['value']:.4g} (search: {v['search_value']:.4g})"
                                 for k, v in e["bound_fixed"].items()))
    if e["fixed"]:
        parts.append("not determined, fixed at the start model's value: "
                     + ", ".join(f"{k} = {v:.4g}" for k, v in e["fixed"].items()))
    if e["kept"]:
        parts.append("not determined, left where the search put it (no start value): "
                     + ", ".join(f"{k} = {v:.4g}" for k, v in e["kept"].items()))
    return f"{effect}: " + "; ".join(parts)
