"""Tracker outliers: single pose rows that no motion of the robot and no tracker noise can explain.

A tracker sometimes reports a wrong pose for one frame (a marker swap, a reflection): a row that
jumps metres away and back. Left in, one such row can dominate a run's sum of squares and so the
fit and the decision. Each observed row k is compared with the straight line through its two
nearest other observed rows a, b of the same run (both neighbours, or the two before/after it at
the ends of the run), per component (x, y, heading × lever, in metres):

    e_k = p_k − (w_a·p_a + w_b·p_b),   w_a = (t_b − t_k)/(t_b − t_a),   w_b = (t_k − t_a)/(t_b − t_a).

Two things make e_k non-zero on good data:

* tracker noise: white noise of σ per row gives Var(e_k) = σ²·(1 + w_a² + w_b²);
* motion: the line misses a path with acceleration a by at most (a/2)·|t_k − t_a|·|t_k − t_b|, and a
  robot pushed only by floor friction accelerates at most μ·g (the heading channel, angular
  acceleration × lever, is bounded alike for a body whose mass sits within the lever). ``outlier_acceleration`` =
  2·g covers μ up to 2 (the library's stickiest surface).

A row is an outlier when |e_k| of some component exceeds both together:

    |e_k| > outlier_z·σ̂·sqrt(1 + w_a² + w_b²) + (outlier_acceleration/2)·|t_k − t_a|·|t_k − t_b|,

σ̂ the robust noise scale of the dataset (1.4826 × the median absolute e_k / sqrt(1 + w_a² + w_b²)
over all observed rows and components: the median ignores the few outliers themselves). ``outlier_z`` = 6:
for Gaussian noise, P(|z| > 6) = 2·10⁻⁹ per component, so a dataset of 10⁵ tracked components has
about a 2·10⁻⁴ chance of one false flag; the motion term keeps stick-slip and command steps, whose
accelerations stay below μ·g, from being flagged at any noise level (noise-free data included).

A jump of size J at row k also moves its neighbours' e by up to J/2, so rows are flagged one at a
time, worst first, each flagged row leaving the neighbour set before the next test (``outlier_max_share``
caps the flagged share of a run's rows: beyond it the data are not "a few outliers").

What is done with them (``drop_outliers``): a flagged row is treated as not observed (its pose cells
empty), as if the tracker had lost the robot for a frame: it enters neither the fit, the noise
estimate nor the localisation. A flagged first row (t = 0) takes the next observed pose instead:
every run starts at rest, so the two differ by at most outlier_acceleration·t²/2. The flagged rows are listed in
``result.json`` (``outliers``) and in ``report.md``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from omni_gym.discrepancy.data.dataset import Dataset, Run
from omni_gym.discrepancy.settings import DataSettings

# The thresholds (outlier_z, outlier_acceleration, outlier_max_share) are fields of
# settings.DataSettings, recorded in result.json (settings.data); the defaults are used where none is given.
_DEFAULT = DataSettings()
COMPONENTS = ("x", "y", "theta")


@dataclass(frozen=True)
class Outlier:
    """One flagged tracker row: run name, CSV row (row 1 is the header), time [s], the component with
    the largest excess, its deviation from the neighbours' line [m] and the threshold it broke [m]."""

    run: str
    row: int
    t: float
    component: str
    deviation: float | None
    threshold: float

    def to_json(self) -> dict:
        return asdict(self)


def _components(run: Run, lever: float) -> np.ndarray:
    """(K, 3) tracked x, y [m] and unwrapped heading × ``lever`` [m] (NaN where not observed)."""
    out = np.full((len(run.t), 3), np.nan)
    obs = run.observed
    out[obs, :2] = run.pose[obs, :2]
    out[obs, 2] = np.unwrap(run.pose[obs, 2]) * lever
    return out


def _line_deviation(t: np.ndarray, p: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the observed rows ``idx`` (≥ 3): deviation e (m, 3) of each row from the line through its
    two nearest others, the noise factor sqrt(1 + w_a² + w_b²) (m,) and |t_k − t_a|·|t_k − t_b| (m,) [s²]."""
    m = idx.size
    j = np.arange(m)
    a = np.clip(j - 1, 0, m - 3)  # the row before (or the first two rows for the first row)
    a = np.where(j == m - 1, m - 3, a)
    b = np.where(j == 0, 1, np.where(j == m - 1, m - 2, j + 1))
    a = np.where(j == 0, 2, a)  # first row: extrapolate from rows 1 and 2
    ta, tb, tk = t[idx[a]], t[idx[b]], t[idx]
    wa = (tb - tk) / (tb - ta)
    wb = (tk - ta) / (tb - ta)
    with np.errstate(over="ignore", invalid="ignore"):
        e = p[idx] - (wa[:, None] * p[idx[a]] + wb[:, None] * p[idx[b]])
    return e, np.sqrt(1.0 + wa**2 + wb**2), np.abs(tk - ta) * np.abs(tk - tb)


def noise_scale(ds: Dataset, lever: float) -> float:
    """Robust tracker-noise scale σ̂ [m] from every run's line deviations (0 when too few rows)."""
    vals = []
    for run in ds.runs:
        idx = np.flatnonzero(run.observed)
        if idx.size < 3:
            continue
        e, f, _ = _line_deviation(run.t, _components(run, lever), idx)
        vals.append((e / f[:, None]).ravel())
    if not vals:
        return 0.0
    z = np.concatenate(vals)
    z = z[np.isfinite(z)]
    return float(1.4826 * np.median(np.abs(z))) if z.size else 0.0


def find_outliers(ds: Dataset, lever: float, cfg: DataSettings | None = None) -> list[Outlier]:
    """Flag tracker outlier rows in every run of ``ds`` (criterion in the module docstring; ``cfg``: its
    thresholds, None: the defaults)."""
    cfg = _DEFAULT if cfg is None else cfg
    sigma = noise_scale(ds, lever)
    found = []
    for run in ds.runs:
        found += _run_outliers(run, lever, sigma, cfg)
    return found


def _excess(run: Run, p: np.ndarray, keep: np.ndarray, sigma: float, cfg: DataSettings) -> tuple[np.ndarray, ...]:
    """Rows ``idx`` kept, their deviation e (m, 3) [m], threshold (m,) [m] and excess |e|/threshold (m, 3)."""
    idx = np.flatnonzero(keep)
    e, f, span = _line_deviation(run.t, p, idx)
    limit = cfg.outlier_z * sigma * f + 0.5 * cfg.outlier_acceleration * span
    with np.errstate(invalid="ignore", over="ignore"):
        excess = np.where(np.isfinite(e), np.abs(e) / limit[:, None], np.inf)  # a non-finite cell is an outlier
    return idx, e, limit, excess


def _run_outliers(run: Run, lever: float, sigma: float, cfg: DataSettings) -> list[Outlier]:
    """Flag rows of one run, one at a time. A jump J at row k also puts about J/2 into its
    neighbours' tests (J/2 against a line through k): among the rows over the threshold, the one
    whose removal leaves its neighbourhood (±3 rows) least in excess is the outlier (at the end of a
    run, the outlier's own test is a weaker extrapolation and does not always have the top excess)."""
    p = _components(run, lever)
    keep = run.observed.copy()
    cap = max(1, int(cfg.outlier_max_share * keep.sum()))
    out = []
    while len(out) < cap and keep.sum() >= 4:  # a line through two others needs a third row to test
        idx, e, limit, excess = _excess(run, p, keep, sigma, cfg)
        row_ex = excess.max(axis=1)
        over = np.flatnonzero(row_ex > 1.0)
        if not over.size:
            break
        best, best_key = -1, None
        for j in over[np.argsort(-row_ex[over])][:6]:
            trial = keep.copy()
            trial[idx[j]] = False
            if trial.sum() < 3:
                continue
            idx2, _, _, ex2 = _excess(run, p, trial, sigma, cfg)
            near = np.abs(np.searchsorted(idx2, idx[j]) - np.arange(idx2.size)) <= 3
            key = (float(ex2[near].max()) if near.any() else 0.0, -float(row_ex[j]))
            if best_key is None or key < best_key:
                best, best_key = int(j), key
        if best < 0:
            break
        c = int(np.argmax(excess[best]))
        k = int(idx[best])
        dev = float(e[best, c])
        out.append(Outlier(run=run.name, row=k + 2, t=float(run.t[k]), component=COMPONENTS[c],
                           deviation=dev if math.isfinite(dev) else None, threshold=float(limit[best])))
        keep[k] = False
    return sorted(out, key=lambda o: o.row)


def drop_outliers(ds: Dataset, outliers: list[Outlier]) -> Dataset:
    """A copy of ``ds`` with the outlier rows' poses not observed (a flagged first row takes the next
    observed pose: runs start at rest). ``ds`` itself is not changed."""
    if not outliers:
        return ds
    runs = []
    for run in ds.runs:
        rows = [o.row - 2 for o in outliers if o.run == run.name]
        if not rows:
            runs.append(run)
            continue
        pose = run.pose.copy()
        pose[rows] = np.nan
        if 0 in rows:
            nxt = np.flatnonzero(np.all(np.isfinite(pose), axis=1))
            if nxt.size:
                pose[0] = pose[nxt[0]]
        runs.append(replace(run, pose=pose))
    return replace(ds, runs=runs)


def outlier_rule(cfg: DataSettings | None = None) -> str:
    """The criterion in words, with ``cfg``'s thresholds (result.json's ``outliers.rule``)."""
    cfg = _DEFAULT if cfg is None else cfg
    return (f"a tracked row is an outlier when one pose component (x, y, heading x lever) lies farther from the "
            f"line through its two nearest observed rows than {cfg.outlier_z:g} robust noise standard deviations plus "
            f"the largest path deviation a friction-limited motion (acceleration {cfg.outlier_acceleration:.1f} "
            "m/s^2) can make; flagged rows are treated as not observed (a flagged first row takes the next observed "
            "pose); 'row' is the CSV row (row 1 is the header)")

