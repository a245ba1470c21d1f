"""Settings of the discrepancy workflow: one frozen dataclass per stage, recorded in full in result.json.

- :class:`EventSearchSettings`: the lift-event search of the stochastic candidate
  (:mod:`omni_gym.discrepancy.fit.events`, its module docstring names the steps).
- :class:`FitSettings`: the search rounds of a deterministic candidate's fit
  (:func:`omni_gym.discrepancy.fit.fitting.fit_candidate`).
- :class:`DecisionRules`: the thresholds of the decision (:func:`omni_gym.discrepancy.decide.decision.decide`;
  why each value, ``docs/discrepancy.md``).
- :class:`DataSettings`: tracker outliers and the start alignment of whole runs.
- :class:`IdentifiabilitySettings`: what counts as determined by the data, and the refit in that subspace.
- :class:`GapSettings`: all of them together, as ``gap`` takes them and ``result.json`` records them
  (``settings.event_search``, ``settings.fit``, ``settings.rules``, ``settings.data``,
  ``settings.identifiability``; :meth:`GapSettings.to_json`).

The defaults are the values every committed result was made with; a report is reproduced from its
``result.json`` by passing the recorded values back (``GapSettings.from_json``). This module imports
nothing of the workflow, so every stage can read its own settings from here.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields


@dataclass(frozen=True)
class EventSearchSettings:
    """Lift-event search (:class:`omni_gym.discrepancy.fit.events.EventInference`); times in seconds.

    Attributes:
        grid_dt: s, start grid of the window search (half the shortest duration).
        durations: s, coarse lifted durations of the window search (mean holding 1/recover_rate ~ 0.2 s).
        refine: s, local start/end shifts of the window refinement and the fine open-loop sweeps.
        refine_ol: s, wider shifts of the first open-loop sweeps (and of the sequential decoding).
        open_loop_rounds: fine coordinate rounds of start/end refinement on the open-loop cost.
        window_events: most events per 1 s window of the window search (greedy, one per batched pass).
        add_rounds: rounds of the global "one more event" move ...
        add_level: ... for runs whose open-loop MSE is above this multiple of σ² (dimensionless) ...
        add_top: ... trying each run's this many best additions, each refined before the comparison.
        case_alpha: reject events whose lifted cases are this unlikely under the uniform draw (p-value).
        max_lifted_share: most of the moving time (share, 0-1) that inferred events may keep a wheel lifted.
        skip_factor: skip the sequential/global moves when the window proposal is above this multiple of
            the adequacy limit (dimensionless).
        seq_max_events: most events per run of the sequential open-loop decoding.
        seq_ahead: s, new sequential events start up to this long after the deviation point ...
        seq_horizon: s, ... and are scored on the rows up to this long after it.
        dev_rows: rows of the moving mean of z² that detects a deviation (10 rows: 0.2 s at 50 Hz).
        dev_level: that mean z² above which the residual has left the noise (2: about 4 sd for noise).
    """

    grid_dt: float = 0.05
    durations: tuple[float, ...] = (0.05, 0.1, 0.2, 0.4)
    refine: tuple[float, ...] = (-0.03, -0.015, -0.005, 0.0, 0.005, 0.015, 0.03)
    refine_ol: tuple[float, ...] = (-0.15, -0.08, -0.03, -0.01, 0.0, 0.01, 0.03, 0.08, 0.15)
    open_loop_rounds: int = 2
    window_events: int = 3
    add_rounds: int = 3
    add_level: float = 1.2
    add_top: int = 3
    case_alpha: float = 0.01
    max_lifted_share: float = 0.5
    skip_factor: float = 3.0
    seq_max_events: int = 12
    seq_ahead: float = 0.1
    seq_horizon: float = 0.5
    dev_rows: int = 10
    dev_level: float = 2.0


@dataclass(frozen=True)
class FitSettings:
    """Search rounds of :func:`omni_gym.discrepancy.fit.fitting.fit_candidate` (counts, no units).

    Attributes:
        iterations: Levenberg–Marquardt iterations of the all-run fit (also bounds the progress ticks).
        fold_iterations: LM iterations of each fold fit.
        starts: design points (that lie apart) the all-run local search starts from.
        phase_grid: grid points per roller phase of the multiple-shooting phase search.
        phase_sweeps: roller phase sweeps.
        phase_starts: best phase-grid points kept per phase.
        phase_restarts: random phase vectors of the open-loop restarts.
        valley_rounds: valley line-search rounds.
        low_dim: candidates with at most this many fitted dimensions start from ``low_dim_starts``
            design points instead of ``starts``.
        low_dim_starts: see ``low_dim``.
        identified_iterations: LM iterations of the final refit in the identified subspace
            (:func:`omni_gym.discrepancy.fit.identified_fit.refit`), on all runs and per fold.
    """

    iterations: int = 6
    fold_iterations: int = 4
    starts: int = 2
    phase_grid: int = 32
    phase_sweeps: int = 2
    phase_starts: int = 2
    phase_restarts: int = 16
    valley_rounds: int = 3
    low_dim: int = 3
    low_dim_starts: int = 4
    identified_iterations: int = 4


@dataclass(frozen=True)
class DecisionRules:
    """Thresholds of :func:`omni_gym.discrepancy.decide.decision.decide` (shares are 0-1, dimensionless).

    Attributes:
        significance: bootstrap share of run resamples in which the candidate beats nominal.
        min_improvement: least held-out MSE reduction (share of nominal MSE) that counts.
        noise_margin: an MSE within (1 + margin)·σ̂² counts as noise level.
        min_gap_reduction: least reduction of the excess RMS for a named effect.
        ambiguity: the winner must beat a qualifying runner-up in this share of resamples.
        min_step_reduction: multi-effect search: a candidate that beats the step's baseline but removes
            less than ``min_gap_reduction`` of the original gap is kept as a partial explanation (and the
            search goes on) if it removes at least this share of the gap left at its step.
        n_boot: bootstrap resamples of the runs (count).
        min_chain_share: a later step's effect must remove at least this share of the first model's gap beyond
            the floor: what a large first effect leaves is also where the simulator's accuracy is least, and an
            effect that trims a per cent of it is not evidence of a second physical cause.
        accuracy_position: m, the simulator's validated accuracy in x and y against an independent integration
            of the same equations, part of the noise floor (:func:`accuracy_floor`): a residual of that size
            between two integrators is the simulator's own accuracy, not a missing effect.
        accuracy_heading: rad, the same in heading.
    """

    significance: float = 0.95
    min_improvement: float = 0.05
    noise_margin: float = 0.3
    min_gap_reduction: float = 0.7
    ambiguity: float = 0.8
    min_step_reduction: float = 0.3
    n_boot: int = 400
    min_chain_share: float = 0.05
    accuracy_position: float = 0.5e-3
    accuracy_heading: float = 1.0e-3


def accuracy_floor(rules: DecisionRules, lever: float) -> float:
    """The simulator's validated accuracy as RMS per residual component [m]: x and y at
    ``rules.accuracy_position``, heading × ``lever`` [m] at ``rules.accuracy_heading``, pooled over the three
    components as the residual pools them."""
    return ((2.0 * rules.accuracy_position**2 + (lever * rules.accuracy_heading) ** 2) / 3.0) ** 0.5


@dataclass(frozen=True)
class DataSettings:
    """How the data are read before any fit (:mod:`omni_gym.discrepancy.data.outliers`,
    :func:`omni_gym.discrepancy.replay.measurement.align_to_start_window`).

    Attributes:
        outlier_z: robust standard deviations of tracker noise beyond which a row is an outlier.
        outlier_acceleration: m/s², the largest acceleration floor friction can give (μ ≤ 2): a path may
            deviate from the line through its neighbours by this much without being flagged.
        outlier_max_share: most rows of a run flagged (share, 0-1): beyond that the tracker itself is broken.
        start_window: s, the first tracked rows of a whole run that its replay is aligned to.
    """

    outlier_z: float = 6.0
    outlier_acceleration: float = 2.0 * 9.81
    outlier_max_share: float = 0.05
    start_window: float = 0.2


@dataclass(frozen=True)
class IdentifiabilitySettings:
    """What the data determine of the named effects (:mod:`omni_gym.discrepancy.fit.identifiability`) and the
    refit in that subspace (:mod:`omni_gym.discrepancy.fit.identified_fit`).

    Attributes:
        identified: largest 95 % half-width (share of the fit range) of an identified combination or parameter.
        confounded: |correlation| above which two parameters are reported as confounded.
        step: forward-difference step in the unit cube (the fits' own LM step).
        bound: unit-cube distance from a bound within which a value counts as at its fit bound.
        merge_weight: least |weight| (largest weight 1) of a parameter that a combination is said to involve.
        bound_passes: most refits after fixing parameters that the subspace fit put at a bound.
        held_out_tolerance: most held-out MSE increase (share) accepted for holding bound parameters at the
            start model's values.
    """

    identified: float = 0.05
    confounded: float = 0.9
    step: float = 3e-3
    bound: float = 1e-3
    merge_weight: float = 0.1
    bound_passes: int = 2
    held_out_tolerance: float = 0.05


@dataclass(frozen=True)
class GapSettings:
    """Every setting of a ``gap`` run that changes its answer, one object per stage: the data (outliers,
    start alignment), the fit, the lift-event search, the decision and the identifiability analysis."""

    event_search: EventSearchSettings = field(default_factory=EventSearchSettings)
    fit: FitSettings = field(default_factory=FitSettings)
    rules: DecisionRules = field(default_factory=DecisionRules)
    data: DataSettings = field(default_factory=DataSettings)
    identifiability: IdentifiabilitySettings = field(default_factory=IdentifiabilitySettings)

    def to_json(self) -> dict:
        """Every stage's settings in full, for result.json (tuples become lists)."""
        return {f.name: asdict(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_json(cls, d: dict) -> GapSettings:
        """The settings recorded by :meth:`to_json` (result.json's ``settings``; keys absent: defaults).

        Raises ValueError naming an unknown key (``settings.fit.iteration``, say)."""
        parts = {}
        for f in fields(cls):
            kind = type(getattr(cls(), f.name))
            known = {g.name for g in fields(kind)}
            got = d.get(f.name, {})
            bad = sorted(set(got) - known)
            if bad:
                raise ValueError(f"settings.{f.name}.{bad[0]}: unknown setting (known: {', '.join(sorted(known))})")
            parts[f.name] = kind(**{k: tuple(v) if isinstance(v, list) else v for k, v in got.items()})
        return cls(**parts)
