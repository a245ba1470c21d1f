"""The final fit restricted to what the data determine (omni_gym.discrepancy.fit.identified_fit).

A linear stand-in for the simulator, so the test runs in milliseconds and the truth is known exactly:
residual = y − (a + b)·X − c·Z − e·W per run, with a dimension d that changes nothing and a regressor W
so small that e is known only to about ±0.1 of its range. The data determine a + b and c, not a − b and
not d; e only loosely, but far enough from its start value that the start is rejected. The search is
assumed to have left the fit at a point of the valley with a at its upper bound (what the real omni3 fit
did with a wheel distance).
"""

from __future__ import annotations

import numpy as np
import pytest

from omni_gym.discrepancy.fit.candidates import Candidate
from omni_gym.discrepancy.fit.identifiability import Named, linearise, summary
from omni_gym.discrepancy.fit.identified_fit import refit, statuses
from omni_gym.physics.effects import Dim

SIGMA = 1e-3  # white noise per residual component [m]
TRUTH = {"a": 0.5, "b": 0.5, "c": 0.7, "e": 0.9}  # a + b = 1 (only the sum shows), c, e
START = {"a": 0.2, "b": 0.2, "c": 0.5, "d": 0.3, "e": 0.1}  # the start model's values (the candidate's null point)
NAMES = ("a", "b", "c", "d", "e")


class _Model:
    """Stand-in for SimModel: carries the effect's parameters (with_effect as SimModel's)."""

    def __init__(self, params: dict | None = None) -> None:
        self.params = params or {}

    def with_effect(self, name: str, params: dict) -> _Model:
        return _Model(dict(params))


class _Evaluator:
    """Stand-in for fitting.Evaluator: residuals (K, 3) [m] of each model on each run, linear in a + b and c."""

    def __init__(self, runs: int = 4, rows: int = 200, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.X = [rng.normal(0.0, 0.05, (rows, 3)) for _ in range(runs)]
        self.Z = [rng.normal(0.0, 0.05, (rows, 3)) for _ in range(runs)]
        # e's 95 % half-width 2σ/(sqrt(runs·(rows − 1)·3)·0.4e-3) ≈ 0.1 of its range
        self.W = [rng.normal(0.0, 0.4e-3, (rows, 3)) for _ in range(runs)]
        self.y = [self._pred(TRUTH, x, z, w) + rng.normal(0.0, SIGMA, (rows, 3))
                  for x, z, w in zip(self.X, self.Z, self.W, strict=True)]

    @staticmethod
    def _pred(p: dict, x: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        return (p["a"] + p["b"]) * x + p["c"] * z + p["e"] * w

    def residuals(self, models: list[_Model]) -> list[list[np.ndarray]]:
        runs = list(zip(self.y, self.X, self.Z, self.W, strict=True))
        return [[y - self._pred(m.params, x, z, w) for y, x, z, w in runs] for m in models]


def _candidate() -> Candidate:
    dims = tuple(Dim(n, 0.0, 1.0) for n in NAMES)
    return Candidate("toy", dims, lambda v: dict(zip(NAMES, v, strict=True)), null=dict(START))


def test_undetermined_directions_go_back_to_the_start_and_nothing_stays_at_a_bound():
    cand = _candidate()
    ev = _Evaluator()
    # The search's point: on the valley floor (a + b = 1, c = 0.7, e = 0.9), but a at its bound and d anywhere.
    u_search = np.array([1.0, 0.0, 0.7, 0.9, 0.9])
    lin = linearise(ev, _Model(), [Named(cand, u_search)], SIGMA)
    assert lin is not None
    fit = refit(ev, _Model(), lin, np.array([0, 0, 1, 1]))
    assert fit is not None  # a − b and d are not determined: the fit changes
    a, b, c, d, e = (cand.dims[j].value(float(x)) for j, x in enumerate(fit.u_all[0]))
    # What the data determine is kept: a + b and c, to the fit's precision (the 95 % half-width of a + b
    # with 2400 components of 1 mm noise on regressors of 0.05 is about 0.002).
    assert a + b == pytest.approx(1.0, abs=0.01) and c == pytest.approx(0.7, abs=0.01)
    # What they do not is the start model's: a − b back to the start's 0 (the start has a = b), d at 0.3.
    assert a - b == pytest.approx(START["a"] - START["b"], abs=0.01)
    assert d == pytest.approx(START["d"], abs=1e-9)
    # e is not identified (±0.1 of its range) but its start (0.1) lies far outside its interval: the data
    # reject the start, so it stays fitted (within its 95 % half-width of the truth), reported as loose.
    assert e == pytest.approx(TRUTH["e"], abs=0.1)
    st = fit.status["toy"]
    assert st["identified"] == ["c"] and sorted(st["merged"]) == ["a", "b"]
    assert st["fixed"] == {"d": pytest.approx(0.3)}
    assert list(st["loose"]) == ["e"] and 0.05 < st["loose"]["e"] < 0.2  # its 95 % half-width, share of range
    assert st["at_bound"] == []
    # The report names the determined combination (a + b with equal weights), not a's value alone.
    assert any(sorted(t[0] for t in cmb["terms"]) == ["a", "b"] for cmb in st["combinations"]), st["combinations"]
    assert "determined only in combination: a, b" in st["line"] and "fixed at the start model's value: d" in st["line"]
    # Held-out: each fold's fit saw only the other fold's runs; a + b predicted to noise on the runs it did not see.
    assert fit.heldout.shape == (4,) and np.all(fit.heldout / (199 * 3) < 1.5 * SIGMA**2)
    # The summary's per-effect line is the status line when given.
    assert summary(lin, used=fit.status)["per_effect"]["toy"] == st["line"]


def test_nothing_changes_when_every_combination_is_identified():
    """Both sums and differences shown: a dimension per regressor, nothing confounded."""
    cand = Candidate("toy", (Dim("c", 0.0, 1.0),), lambda v: {"a": 0.5, "b": 0.5, "c": v[0], "d": 0.0, "e": 0.9},
                     null={"c": 0.5})
    ev = _Evaluator()
    lin = linearise(ev, _Model(), [Named(cand, np.array([0.7]))], SIGMA)
    assert refit(ev, _Model(), lin, np.array([0, 0, 1, 1])) is None
    assert statuses(lin)["toy"]["identified"] == ["c"]
    assert "every parameter pinned down" in statuses(lin)["toy"]["line"]


def test_a_bound_value_the_data_need_is_kept_and_said_to_be_at_its_bound():
    """The truth of e lies beyond its fit range (1.3 of a [0, 1] range, with a regressor large enough that
    the data demand it): the search stops at the bound. Holding e at its start value (0.1) would predict
    every run worse by far more than the 5 % tolerance, so the search's value stays, and the status says
    it sits at its bound with the held-out cost of holding it."""
    from omni_gym.discrepancy.replay.residuals import run_sse

    cand = _candidate()
    ev = _Evaluator()
    for w in ev.W:
        w *= 50.0  # e now identified (95 % half-width ≈ 0.002 of its range)
    truth = {**TRUTH, "e": 1.3}
    ev.y = [ev._pred(truth, x, z, w) + (y - ev._pred(TRUTH, x, z, w / 50.0))
            for y, x, z, w in zip(ev.y, ev.X, ev.Z, ev.W, strict=True)]  # same noise, e = 1.3
    u_search = np.array([0.5, 0.5, 0.7, 0.3, 1.0])  # e at its upper bound, the rest at the truth / start
    lin = linearise(ev, _Model(), [Named(cand, u_search)], SIGMA)
    search = ev.residuals([_Model(dict(zip(NAMES, u_search, strict=True)))])[0]
    search_sse = np.array([run_sse(r) for r in search])
    n_comp = np.full(4, 199 * 3)
    fit = refit(ev, _Model(), lin, np.array([0, 0, 1, 1]), search_sse, n_comp)
    assert fit is not None
    e = fit.u_all[0][4] if fit.changed else u_search[4]
    assert e == pytest.approx(1.0)  # the search's value stands
    st = fit.status["toy"]
    assert "e" in st["bound_cost"] and st["bound_cost"]["e"] > 0.05, st
    assert "kept there because holding it at the start model's value predicts the held-out runs worse" in st["line"]
    # Without the search's held-out error to compare with, the bound value is held at the start.
    held = refit(ev, _Model(), lin, np.array([0, 0, 1, 1]))
    assert held.changed and held.u_all[0][4] == pytest.approx(START["e"])
    assert "e" in held.status["toy"]["bound_fixed"]


def test_report_never_shows_a_bound_value_as_a_measurement():
    """report.md's fitted parameters: a value at its fit bound, or one the data determine only together with
    others, carries what it is; an identified one stands alone."""
    from omni_gym.discrepancy.report.report import _not_measured_lines, _param_lines

    status = {"identified": ["distance1"], "merged": [], "loose": {"mount1": 0.12}, "fixed": {"mount2": 0.0},
              "bound_fixed": {}, "kept": {}, "at_bound": [], "combinations": [], "bound_cost": {"distance2": 8.4},
              "line": "…"}
    lines = _param_lines("wheel_geometry", {"distance": [1.01, 1.15], "mount": [0.03, 0.0]}, status)
    assert lines[0].startswith("* `distance` = [1.01, 1.15 = its fit bound (the fit wants a value beyond it: not a")
    assert "1.01 (" not in lines[0]  # identified: the value alone
    assert "0.03 (not determined alone: not a measurement)" in lines[1]
    assert "0 (start value: not determined by the data)" in lines[1]
    warn = _not_measured_lines({"per_effect_status": {"wheel_geometry": status}})[0]
    assert "wheel_geometry.distance2" in warn and "wheel_geometry.mount1" in warn and "wheel_geometry.mount2" in warn
