"""``omni-gym gap``: localise, explain, add the effect, search the remaining gap again, show the staircase.

The search names one effect at a time (:func:`_search_step`: fit every candidate not yet named on top of
the current model, decide). A named effect is added to the model with its all-run fit and the next step
searches what is left, until the answer is ``none`` or ``unexplained``, the library is used up, or
``max_effects`` effects are named. A stochastic effect (``wheel_liftoff``) ends the search: with a random
contact process in the model, a deterministic fit of anything else is no longer possible.

Each step's baseline is the current model's all-run SSE (its earlier effects fitted on every run, the
held-out runs included), so a later effect must beat an optimistic baseline: the loop errs towards
stopping. The single-effect keys of ``result.json`` (``effect``, ``why``, ``params``, ``uncertainty``,
``ranking``) describe the first step; ``effects`` and ``steps`` the whole search; ``model`` and ``gap``
the final model.

Each step's candidate fits are independent, run on the chosen backend (:mod:`omni_gym.parallel`: this
process by default, local processes or Ray); on a parallel backend side by side, each fit's simulation
batches split into tasks finer than a candidate (:mod:`omni_gym.discrepancy.fit.fit_tasks`, which also
records each step's work and critical path in ``result.json``'s ``work``). A fit draws its random
numbers from its own generator, seeded from the gap seed, the step and the candidate's name
(:func:`fit_seed`), never from the worker or the order the fits finish in, so the result is the same
bit for bit on every backend and worker count. The driver's own generator (folds, the decision's
bootstrap, parameter intervals) draws only in the driver, in a fixed order.
"""

from __future__ import annotations

import math
import sys
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from omni_gym.discrepancy.data.dataset import Dataset, load_dataset, sessions_of
from omni_gym.discrepancy.data.folds import source_folds
from omni_gym.discrepancy.data.outliers import drop_outliers, find_outliers, outlier_rule
from omni_gym.discrepancy.data.segments import FIT_BUDGET, check_fit_budget, fit_data
from omni_gym.discrepancy.decide.decision import Decision, decide
from omni_gym.discrepancy.decide.score import heldout_table, heldout_whole_runs
from omni_gym.discrepancy.fit import identifiability, identified_fit, plausible
from omni_gym.discrepancy.fit.candidates import Candidate, candidates, not_applicable
from omni_gym.discrepancy.fit.events import EVENT_METHOD
from omni_gym.discrepancy.fit.fit_tasks import FitShared, FitTask, StepWork, run_fits, work_json
from omni_gym.discrepancy.fit.fitting import Evaluator, FitResult, max_ticks, param_intervals
from omni_gym.discrepancy.fit.kinematic_calibration import calibrate
from omni_gym.discrepancy.replay.localise import localise
from omni_gym.discrepancy.replay.measurement import START_WINDOW
from omni_gym.discrepancy.replay.residuals import count_components, geo_mse, run_sse
from omni_gym.discrepancy.replay.simulate import FIT_DT
from omni_gym.discrepancy.replay.start_trust import StartTrust, estimate_start_trust, with_start_trust
from omni_gym.discrepancy.report.finite import finite_json
from omni_gym.discrepancy.settings import GapSettings, accuracy_floor
from omni_gym.outputs import Output
from omni_gym.parallel import SERIAL, Backend, Executor, executor
from omni_gym.physics.effects.base import Dim
from omni_gym.physics.liftoff import contact_cases
from omni_gym.physics.model import SimModel
from omni_gym.progress import OFF, ProgressLines

STARTS = ("nominal", "kinematic", "tracker", "auto")  # gap's first model (``start``): see :func:`start_model`
KINEMATIC = "kinematic_calibration"  # the calibration's name as a hypothesis of the first step (_kinematic_fit)
MAX_EFFECTS = 3  # most effects one gap run names (each step fits the whole library again)
METRIC = ("held-out pose error beyond tracker noise [m]: sqrt(max(0, M - noise^2)), M the geometric mean over runs "
          "(weighted by observed rows) of each run's mean squared residual over x, y and heading x lever; each run is "
          "predicted by a fit that did not see it")


def gap(dataset: str | Path, out: str | Path | None = None, seed: int = 0, folds: int = 3,
        progress: bool | None = None, dt: float = FIT_DT, plots: bool = True, force: bool = False,
        max_effects: int = MAX_EFFECTS, fit_budget: float = FIT_BUDGET, backend: Backend = SERIAL,
        start: str | SimModel | None = "auto", settings: GapSettings | None = None) -> dict:
    """Run the workflow on ``dataset``; write the report folder ``out`` (if given); return the result.

    ``progress``: tqdm bar on stderr (None: only when stderr is a terminal; else a line per stage and,
    inside each long fit, a progress line with the time left at most every
    :data:`omni_gym.progress.PROGRESS_EVERY_S` seconds; False: nothing). Same seed, same result.
    ``max_effects`` (>= 1): most effects named one after another (module docstring).
    ``fit_budget`` [s]: most robot time fitted; a longer dataset is fitted on an even sample of its
    runs' segments (:mod:`omni_gym.discrepancy.data.segments`; ``math.inf``: always the whole runs).
    ``out`` is checked and locked before the work starts and appears complete or not at all
    (:class:`omni_gym.outputs.Output`): an existing report is refused unless ``force``; a report that
    is, contains or lies inside the dataset is refused.
    ``backend``: where the candidate fits run (:class:`omni_gym.parallel.Backend`; default this process,
    nothing to start); the result does not depend on it.
    ``start``: the first model, on top of which effects are searched: ``auto`` (the default, the command
    line's: the search starts from the dataset's model and, when every run has wheel odometry, the kinematic
    odometry calibration competes with the library's effects at the first step, scored on the same held-out
    folds; if it wins, the search goes on from it), ``nominal`` (the dataset's model, no calibration),
    ``kinematic`` (the calibration insisted on; needs wheel odometry), ``tracker`` (the calibration with the
    tracked frame fitted jointly over whole runs, as ``omni-gym calibrate --tracker`` writes it: its wheel
    diameters, size and ``tracker_offset`` kept, not searched again; needs wheel odometry), or a given
    :class:`SimModel` (e.g. a calibration made elsewhere: used for every fold as it is, its effects kept and
    not searched again; None: ``auto``); :func:`start_model`.
    ``settings``: the fit's, the event search's and the decision's settings (None: the defaults); recorded in
    full in result.json (``settings.fit``, ``settings.event_search``, ``settings.rules``).
    """
    if start is None:  # the default path
        start = "auto"
    if not isinstance(start, SimModel) and start not in STARTS:
        raise ValueError(f"start must be one of {', '.join(STARTS)}, got {start!r}")
    if isinstance(max_effects, bool) or not isinstance(max_effects, int) or max_effects < 1:
        raise ValueError(f"max_effects must be an integer >= 1, got {max_effects!r}")
    check_fit_budget(fit_budget)
    opts = GapOptions(dataset, None, seed, folds, progress, dt, plots, max_effects, fit_budget, backend, start,
                      GapSettings() if settings is None else settings)
    if out is None:
        return _gap(opts)
    with Output(Path(out), "dir", force=force, inputs=[dataset], marker="result.json", what="gap report") as tx:
        return _gap(replace(opts, out=tx.path))


@dataclass
class Step:
    """One step of the search: the candidates fitted on top of the current model and the decision."""

    fits: list[FitResult]
    decision: Decision
    work: StepWork | None = None  # the step's measured work (fit_tasks.StepWork)

    @property
    def partial(self) -> bool:
        """True when the step's effect beats its baseline but, with the effects before it, explains too
        little of the nominal gap to be named on its own (``decide``'s ``partial``)."""
        return self.decision.partial is not None

    @property
    def effect(self) -> str:
        """The effect added at this step (named or partial), else ``none``/``unexplained``."""
        return self.decision.partial if self.decision.partial is not None else self.decision.effect

    @property
    def fit(self) -> FitResult | None:
        """The added candidate's fit (None when the step ended the search with none/unexplained)."""
        return next((f for f in self.fits if f.candidate.name == self.effect), None)


FIT_STREAM = 1  # first spawn key of the fits' seeds (the driver's generator uses the root seed itself)


def fit_seed(seed: int, step: int, name: str) -> np.random.SeedSequence:
    """The seed of candidate ``name``'s fit at search ``step``: a child of the gap seed keyed by the step
    and the name (CRC-32, stable across processes and Python versions), so the fit draws the same numbers
    wherever and whenever it runs, and does not depend on which other candidates are fitted."""
    return np.random.SeedSequence(seed, spawn_key=(FIT_STREAM, step, zlib.crc32(name.encode())))


@dataclass(frozen=True)
class SearchRun:
    """What every step of one gap run's effect search shares (built once by :func:`_gap`).

    ``ev``: the evaluator of the fitted data; ``shared``: what every fit task needs (the evaluator, the
    runs' folds, the settings of the fit, the event search and the decision; sent to each worker once);
    ``n_comp``: (R,) residual components per run; ``sigma`` [m]: the decision's noise floor (None when
    unknown); ``rng``: the driver's generator (the decisions' bootstrap draws); ``seed``: the gap seed
    (each fit's own seed, :func:`fit_seed`); ``bar``: the tqdm progress bar; ``say``: the stage printer;
    ``ex``: where the fits run (None: in this process, with a progress tick per search round);
    ``refit``: effects the start model carries that are refitted from their current values
    (:func:`_from_current`), not from the effect's own null point; ``lines``: the progress lines inside each
    fit (:mod:`omni_gym.progress`; on where stderr is not a terminal).
    """

    ev: Evaluator
    shared: FitShared
    n_comp: np.ndarray
    sigma: float | None
    rng: np.random.Generator
    seed: int
    bar: Any
    say: Callable[[str], None]
    ex: Executor | None = None
    refit: tuple[str, ...] = ()
    lines: ProgressLines = OFF


def _search_step(search: SearchRun, base: SimModel, base_sse: np.ndarray, exclude: list[str], step: int,
                 reference_excess: float | None = None, extra: list[FitResult] | None = None) -> Step:
    """Fit every library candidate not in ``exclude`` on top of ``base`` (per-run SSE ``base_sse`` [m²])
    and decide, at search step ``step`` (1-based; the 70 % rule measured against ``reference_excess``
    [m], the nominal gap, from the second step on). ``extra``: hypotheses fitted elsewhere that compete in
    the same decision (the kinematic calibration, :func:`_kinematic_fit`).

    The fits run on ``search.ex``; the decision draws from ``search.rng`` in this process."""
    ev, n_comp, sigma, rng, refit = search.ev, search.n_comp, search.sigma, search.rng, search.refit
    bar, say, seed, ex, shared = search.bar, search.say, search.seed, search.ex, search.shared
    cands = [_from_current(c, base) if c.name in refit else c for c in candidates(base) if c.name not in exclude]
    cfg = shared.settings
    if step > 1:  # the bar's first total covered step 1 only
        bar.total += 1 + sum(max_ticks(c, cfg.fit) + 1 for c in cands)
        bar.refresh()
    tasks = [FitTask(c, base, fit_seed(seed, step, c.name)) for c in cands]
    prefix = f"step {step}: " if step > 1 else ""
    start = ev.simulated
    wall0 = time.perf_counter()
    parallel = ex is not None and not ex.backend.serial
    if parallel:
        say(f"{prefix}fitting {len(cands)} candidates side by side, their simulations as tasks on "
            f"{ex.backend.describe()}")
    finished = [0]
    ends: dict[int, int] = {}

    def started(i: int) -> None:
        if not parallel:
            say(f"{prefix}fitting candidate {i + 1}/{len(cands)} {cands[i].name}")
            bar.set_postfix_str(cands[i].name)
        ends[i] = bar.n + max_ticks(cands[i], cfg.fit) + 1

    def done(i: int) -> None:
        finished[0] += 1
        if parallel:
            say(f"{prefix}fitted candidate {finished[0]}/{len(cands)} {cands[i].name}")
            bar.set_postfix_str(cands[i].name)
            bar.update(1)  # its rounds ticked as they ran; the end of the step fills what converged early skipped
        else:
            bar.update(max(ends[i] - bar.n, 0))  # searches that converge early skip their remaining rounds

    # Per fit its own progress line: k of its most rounds (a fit that converges stops early, so the time left
    # errs long), or the lift-event inference's steps and batches (their number is not known in advance).
    loops = [search.lines.loop(f"{prefix}fitting {c.name}: lift events", None, "batches") if c.stochastic else
             search.lines.loop(f"{prefix}fitting {c.name}:", max_ticks(c, cfg.fit), "rounds") for c in cands]
    fits, simulated, works = run_fits(tasks, ev, ex, shared, tick=lambda: bar.update(1), started=started,
                                      finished=done, progress=loops)
    ev.simulated = start + simulated  # in place (this process) or counted by the workers
    fits = [*fits, *(extra or [])]
    say(f"{prefix}deciding")
    t0 = time.process_time()
    decision = decide(base_sse, fits, n_comp, sigma, rng, reference_excess=reference_excess, rules=cfg.rules)
    work = StepWork(fits=works, decide_s=time.process_time() - t0)
    bar.update(1)
    work.wall_s = time.perf_counter() - wall0
    return Step(fits=fits, decision=decision, work=work)


@dataclass(frozen=True)
class GapOptions:
    """One ``gap`` call's options (:func:`gap`'s arguments, checked); ``out`` the folder the report is written
    into as it is (the caller holds the transaction); ``competition``: set when the kinematic calibration
    won the first step of an ``auto`` run (:func:`_competition_json`): the search then runs again from the
    calibration (``start`` is ``kinematic``) and ``result.json``'s ``start`` records the competition."""

    dataset: str | Path
    out: Path | None
    seed: int
    folds: int
    progress: bool | None
    dt: float
    plots: bool
    max_effects: int
    fit_budget: float
    backend: Backend
    start: str | SimModel
    settings: GapSettings
    competition: dict | None = None


@dataclass
class DataStage:
    """Stage 1, the data and the folds: the source runs ``whole`` (the whole-run held-out score replays them),
    what is fitted (``fitted``: whole runs or segments within the fit budget), the fitted runs ``ds`` with the
    tracker outliers ``flagged`` dropped, the folds of the source runs (``fold_src``, by session when there
    are ``sessions``) and of the fitted runs (``fold_of``), the residual ``lever`` [m], the residual
    components per fitted run ``n_comp`` and the driver's generator ``rng``."""

    whole: Dataset
    fitted: Any  # omni_gym.discrepancy.data.segments.FitData
    ds: Dataset
    flagged: list
    sessions: list | None
    fold_src: np.ndarray
    fold_of: np.ndarray
    lever: float
    n_comp: np.ndarray
    rng: np.random.Generator
    start_trust: StartTrust | None = None  # how far replays trust the runs' start poses (replay.start_trust)


@dataclass
class StartStage:
    """Stage 2, the start hypotheses and the baseline they give: the start model ``first`` (the nominal model,
    with the kinematic calibration as a competing hypothesis when ``first.compete``), the evaluator ``ev``,
    the start model's residuals ``res0``, per-run SSE ``sse0`` [m²], the tracker noise ``tracker`` [m], the
    decision's floor ``sigma`` [m] with its parts, the effects that do not apply to the robot (``skipped``),
    the candidates of the first step (``cands``), the start model's gap beyond the floor ``excess0`` [m], and
    ``won``: the record of a calibration that won on whole runs (segmented data, :func:`_whole_run_competition`)."""

    first: StartModel
    ev: Evaluator
    res0: list
    sse0: np.ndarray
    tracker: float | None
    sigma: float | None
    noise_parts: dict
    skipped: dict
    cands: list[Candidate]
    excess0: float
    won: dict | None = None  # the calibration won on whole runs (segmented data): the search starts from it


@dataclass
class SearchStage:
    """Stage 3, the search: the effects added step by step (``steps``, their ``uncertainties``), the step that
    ended it (``last``), the localisation (``where``), each step's measured work, the CPU time inside the steps,
    and ``won``: the first step's record when the kinematic calibration won it (the search is then redone from
    it)."""

    steps: list[Step]
    uncertainties: list[dict]
    last: Step
    where: dict
    works: list[StepWork]
    steps_cpu: float
    won: dict | None = None


@dataclass
class Answer:
    """Stage 4, the decision on the whole search: the effects kept after the whole-run drift check and the
    identified refit (``steps``, ``uncertainties``, ``model``), the answer (``effect``, ``why``), the first
    step (its decision and ranking are the report's), the step that ended the search with none/unexplained
    (``final``, None otherwise), the per-run held-out SSE of the reported model (``after_sse``), the whole-run
    rows and drift record, and the identifiability JSON."""

    effect: str
    why: str
    steps: list[Step]
    uncertainties: list[dict]
    model: SimModel
    first_step: Step
    final: Step | None
    after_sse: np.ndarray
    rows: list
    drift: dict
    identifiability: dict | None


@dataclass
class GapResult:
    """What ``gap`` found, typed (``result.json`` is :meth:`to_json`; ``docs/formats.md``, "Gap report")."""

    effect: str
    why: str
    params: dict
    effects: list[str]
    not_applicable: dict
    steps: list[dict]
    identifiability: dict | None
    model: dict
    gap: dict
    ranking: list[dict]
    plausibility: dict
    outliers: dict
    start: dict
    heldout: dict
    score_nominal: float | None
    where: dict
    settings: dict
    dataset: dict
    work: dict
    ambiguous_with: list[dict] | None = None
    uncertainty: dict | None = None

    def to_json(self) -> dict:
        """result.json: standard JSON (a value that could not be computed is null, listed in ``non_finite``)."""
        out: dict = {"effect": self.effect, "why": self.why}
        if self.ambiguous_with:
            out["ambiguous_with"] = self.ambiguous_with
        out["params"] = self.params
        if self.uncertainty is not None:
            out["uncertainty"] = self.uncertainty
        for key in ("effects", "not_applicable", "steps", "identifiability", "model", "gap", "ranking",
                    "plausibility", "outliers", "start", "heldout", "score_nominal", "where", "settings", "dataset",
                    "work"):
            out[key] = getattr(self, key)
        out, bad = finite_json(out)
        if bad:
            out["non_finite"] = bad
        return out


def _gap(opts: GapOptions) -> dict:
    """The workflow of :func:`gap`, stage by stage: data and folds, start hypotheses, search, decision, result
    (and the report, into ``opts.out``)."""
    cpu0, wall0 = time.process_time(), time.perf_counter()  # the work record (fit_tasks.work_json)
    show = sys.stderr.isatty() if opts.progress is None else opts.progress
    say = _stage_printer(opts.progress is None and not show)  # redirected stderr: one line per stage
    lines = ProgressLines("gap", enabled=opts.progress is None and not show)  # ... and lines inside long fits
    data = _data_stage(opts, say)
    start = _start_stage(opts, data, say, lines)
    if start.won is not None:
        say("the kinematic calibration predicts held-out whole runs better; searching on top of it")
        return _gap(replace(opts, start="kinematic", competition=start.won))
    search = _search_stage(opts, data, start, say, show, lines)
    if search.won is not None:
        # The calibration won the first step: search again from it (its fold models score the held-out runs).
        say("the kinematic calibration wins the first step; searching on top of it")
        return _gap(replace(opts, start="kinematic", competition=search.won))
    answer = _decide_stage(opts, data, start, search, say, lines)
    result = _result(opts, data, start, search, answer, cpu0, wall0).to_json()
    if opts.out is not None:
        from omni_gym.discrepancy.report.report import write_report

        say("writing report")
        write_report(Path(opts.out), result, data.ds, start.first.model, answer.model, data.lever, opts.dt,
                     plots=opts.plots)
    return result


def _data_stage(opts: GapOptions, say: Callable[[str], None]) -> DataStage:
    """Load the dataset, choose what is fitted (whole runs or segments), make the folds, drop tracker outliers."""
    ds = load_dataset(opts.dataset)
    whole = ds
    if len(ds.runs) < 2:
        raise ValueError(f"{opts.dataset}: needs at least 2 runs (held-out scoring splits by run), got {len(ds.runs)}")
    fitted = fit_data(ds, opts.fit_budget)  # refuses a budget that leaves segments of fewer than 2 runs
    # Said after the checks: a dataset that is refused gives exactly one line (the error).
    say(f"loaded dataset {opts.dataset} ({len(ds.runs)} runs)")
    if fitted.segmented:
        say(f"fitting {fitted.describe()}")
    ds = fitted.dataset
    rng = np.random.default_rng(opts.seed)
    # Folds over the source runs (by session when the dataset records several), then their segments.
    sessions = sessions_of(whole.runs)
    fold_src = source_folds(len(whole.runs), rng, opts.folds, sessions)
    fold_of, fold_src = _compact_folds(fold_src, fitted.groups)
    lever = ds.model.robot.lever()  # the dataset's: the same residual metric whatever the start
    say(f"checking {len(ds.runs)} runs for tracker outliers")
    flagged = find_outliers(ds, lever, opts.settings.data)
    ds = drop_outliers(ds, flagged)  # flagged rows count as not observed (outliers.py)
    if flagged:
        say(f"{len(flagged)} outlier row(s) excluded: "
            + ", ".join(f"{o.run} row {o.row}" for o in flagged[:5]) + (" ..." if len(flagged) > 5 else ""))
    trust = None
    if opts.settings.data.start_window is not None:
        # Estimated on the whole runs, outliers dropped where the whole runs are what is fitted.
        trust = estimate_start_trust(whole if fitted.segmented else ds, opts.settings.data.start_window, opts.dt)
        whole, ds = with_start_trust(whole, trust), with_start_trust(ds, trust)
    return DataStage(whole, fitted, ds, flagged, sessions, fold_src, fold_of, lever, count_components(ds), rng,
                     trust)


def _start_stage(opts: GapOptions, data: DataStage, say: Callable[[str], None],
                 lines: ProgressLines = OFF) -> StartStage:
    """The start model (and the kinematic hypothesis), its residuals and the decision's noise floor."""
    first = start_model(data.whole, data.fold_src, opts.start, opts.dt, lines)
    if first.kind == "kinematic":
        say(f"start: kinematic calibration ({first.describe()})")
    elif first.kind == "tracker":
        say(f"start: kinematic calibration with the tracked frame ({first.describe()})")
    elif first.kind == "given":
        say("starting from the given model" + (f" (keeping its {', '.join(first.excluded)})" if first.excluded else ""))
    say(f"simulating the {first.kind} model")
    rules = opts.settings.rules
    ev = Evaluator(data.ds, data.lever, dt=opts.dt, accuracy=accuracy_floor(rules, data.lever),
                   start_window=opts.settings.data.start_window)
    res0, sse0, tracker = ev.nominal_baseline(first.model)
    # The decision's floor: tracker noise, the fitting step's own integration error and the simulator's validated
    # accuracy, which an exact model would leave in the residual too (Evaluator.noise_floor).
    sigma, noise_parts = ev.noise_floor(first.model)
    cands = [c for c in candidates(first.model) if c.name not in first.excluded]
    skipped = not_applicable(first.model)  # e.g. roller_gap on mecanum wheels: never fitted, said in result.json
    if skipped:
        say(f"not tried (does not apply to this robot): {', '.join(skipped)}")
    excess0 = _excess(sse0, data.n_comp, sigma**2 if sigma is not None else 0.0)
    won = None
    if first.compete and data.fitted.segmented:
        first, won = _whole_run_competition(data, first, opts)
    return StartStage(first, ev, res0, sse0, tracker, sigma, noise_parts, skipped, cands, excess0, won)


def _whole_run_competition(data: DataStage, first: StartModel, opts: GapOptions) -> tuple[StartModel, dict | None]:
    """The kinematic hypothesis against the dataset's model when the fit sees segments: each source run replayed
    whole, open loop, by each fold's calibration and by the nominal model (the drift check's measure). Segments
    replayed from the tracked state cannot judge kinematics: a 2 % size error that turns the heading by a few
    mrad in 5 s drifts tens of mm over a minute (``docs/discrepancy.md``, "Score what the model is used for"), so
    the first step's segment score would hand the hypothesis to whichever effect fits segments best. Returns
    the start (the calibration no longer competing) and the record of a calibration that won, else None."""
    K = len(first.fold_models)
    rows = heldout_whole_runs(data.whole, data.fold_src, {"nominal": [first.nominal] * K,
                                                          KINEMATIC: first.kinematic_folds},
                              {"nominal": first.nominal, KINEMATIC: first.kinematic_all}, dt=opts.dt,
                              start_window=opts.settings.data.start_window)
    m = {n: float(np.mean([r.position_rms[n] for r in rows])) for n in ("nominal", KINEMATIC)}
    why = (f"the fit sees segments, so the calibration competed on whole runs replayed open loop: held-out "
           f"position RMS {1e3 * m[KINEMATIC]:.1f} mm against {1e3 * m['nominal']:.1f} mm for the nominal model")
    if m[KINEMATIC] < m["nominal"]:
        return first, {"winner": KINEMATIC, "named": False, "why": why, "ranking": [
            {"effect": n, "whole_run_position_rms": m[n]} for n in (KINEMATIC, "nominal")]}
    return replace(first, compete=False, why=why), None


def _search_stage(opts: GapOptions, data: DataStage, start: StartStage, say: Callable[[str], None],
                  show: bool, lines: ProgressLines = OFF) -> SearchStage:
    """Localise, then name effects step by step until none/unexplained, the library or ``max_effects`` is used up
    (module docstring); with the kinematic hypothesis competing at the first step."""
    from tqdm import tqdm

    settings, rules, first, ev, sigma = opts.settings, opts.settings.rules, start.first, start.ev, start.sigma
    n_comp, rng = data.n_comp, data.rng
    total = 2 + sum(max_ticks(c, settings.fit) + 1 for c in start.cands)
    steps: list[Step] = []
    uncertainties: list[dict] = []
    works: list[StepWork] = []
    steps_cpu = 0.0  # this process's CPU time inside the search steps (the rest is the run's serial part)
    won = None
    ev.windows  # noqa: B018 -- computed once here, before the evaluator is sent to the workers
    shared = FitShared(ev, data.fold_of, settings)
    with executor(opts.backend) as ex, \
            tqdm(total=total, desc="gap: fitting", file=sys.stderr, disable=not show, unit="batch") as bar:
        say("localising")
        where = localise(data.ds, first.model, data.lever, start.res0, dt=opts.dt, sigma=start.tracker)
        bar.update(1)
        model, base_sse = first.model, start.sse0
        search = SearchRun(ev, shared, n_comp, sigma, rng, opts.seed, bar, say, ex, first.refit, lines)
        kin = None  # the kinematic hypothesis, replayed only once a first step is searched at all
        while True:
            if sigma is not None and geo_mse(base_sse, n_comp) <= sigma**2 * (1 + rules.noise_margin):
                # The evidence rule (decide): a residual within the floor leaves nothing to explain, so no
                # candidate is fitted (the answer would be none whatever they gave).
                what = f"the {first.kind} model" + "".join(f" + {s.effect}" for s in steps)
                step = Step(fits=[], decision=Decision(effect="none", why=(
                    f"{what}: its residual ({1e3 * math.sqrt(geo_mse(base_sse, n_comp)):.2f} mm RMS) "
                    f"is within the noise floor ({1e3 * sigma:.2f} mm: tracker noise, integration error and the "
                    f"simulator's validated accuracy) by the margin ({100 * rules.noise_margin:.0f} % in MSE): "
                    "nothing beyond it to explain"), ranking=[]))
                break
            if first.compete and not steps and kin is None:
                kin = _kinematic_fit(ev, first, data.fold_of)
            cpu_step = time.process_time()
            step = _search_step(search, model, base_sse, [*first.excluded, *[s.effect for s in steps]], len(steps) + 1,
                                reference_excess=start.excess0 if steps else None,
                                extra=[kin] if kin is not None and not steps else [])
            steps_cpu += time.process_time() - cpu_step
            works.append(step.work)
            if kin is not None and not steps and step.effect == KINEMATIC:
                won = _competition_json(step)  # the search starts again from the calibration (_gap)
                break
            fit = step.fit
            if fit is None:  # none or unexplained: the search ends here
                break
            steps.append(step)
            uncertainties.append({
                "params_5_95": param_intervals(fit, rng),
                "fold_params": fit.fold_params,
                "note": "5-95 % range of the refit over bootstrap resamples of the runs; fold_params are the fits "
                        "each held-out fold was scored with",
            })
            model = model.with_effect(step.effect, fit.params_all)
            base_sse = fit.sse_all
            if len(steps) == opts.max_effects or fit.candidate.stochastic or len(steps) == len(start.cands):
                break
            say(f"{'named' if not step.partial else 'kept (partial)'} {step.effect}; searching the remaining gap")
        bar.update(max(bar.total - bar.n, 0))
    return SearchStage(steps, uncertainties, step, where, works, steps_cpu, won)


def _decide_stage(opts: GapOptions, data: DataStage, start: StartStage, search: SearchStage,
                  say: Callable[[str], None], lines: ProgressLines = OFF) -> Answer:
    """The whole-run drift check, the identified refit, and the answer."""
    settings, rules, first, ev = opts.settings, opts.settings.rules, start.first, start.ev
    n_comp, sigma, competition = data.n_comp, start.sigma, opts.competition
    steps, uncertainties, step = list(search.steps), list(search.uncertainties), search.last
    nominal = first.model
    model = nominal
    for s in steps:
        model = model.with_effect(s.effect, s.fit.params_all)
    say("scoring whole runs open loop (held-out drift)")
    rows, drift = _drift_check(data.whole, data.fold_src, first, steps, opts.dt, gate=data.fitted.segmented,
                               start_window=settings.data.start_window)
    searched = list(steps)  # before the drift check: the first step's decision and ranking stay the report's
    if drift["dropped"]:
        say(f"dropped (worse whole-run held-out drift): {', '.join(drift['dropped'])}")
        kept = [s.effect for s in steps].index(drift["dropped"][0])  # that effect and every later one
        drift["dropped_params"] = {s.effect: s.fit.params_all for s in steps[kept:]}
        steps, uncertainties = steps[:kept], uncertainties[:kept]
        model = nominal
        for s in steps:
            model = model.with_effect(s.effect, s.fit.params_all)
        step = steps[-1] if steps else step
    # What the data determine of the named effects' parameters (identifiability.py: one batch for the
    # Jacobian), and the final fit restricted to it (identified_fit.py: undetermined directions held at
    # the start model, a few LM batches); model.json, params and the held-out scores use the refit.
    say("identifiability of the named effects")
    lin = identifiability.linearise(ev, nominal, [identifiability.Named(s.fit.candidate, s.fit.u_all)
                                                  for s in steps], start.noise_parts["noise"],
                                    settings.identifiability)
    det = [s for s in steps if not s.fit.candidate.stochastic]
    refit = (identified_fit.refit(ev, nominal, lin, data.fold_of, det[-1].fit.heldout, n_comp, settings.fit,
                                  lines=lines) if lin is not None else None)
    ident_json = None
    if lin is not None:
        status = refit.status if refit is not None else identified_fit.statuses(lin)
        ident_json = {**identifiability.summary(lin, used=status), "per_effect_status": status,
                      "refit": refit is not None and refit.changed,
                      "search_params": {s.effect: s.fit.params_all for s in steps},
                      "refit_note": identified_fit.NOTE}
    if refit is not None and refit.changed:
        say("refitted in the identified subspace")
        steps = _with_refit(steps, lin, refit)
        model = nominal
        for s in steps:
            model = model.with_effect(s.effect, s.fit.params_all)
        step = steps[-1] if step.fit is not None else step
        rows, _ = _drift_check(data.whole, data.fold_src, first, steps, opts.dt, gate=False,
                               start_window=settings.data.start_window)  # the models actually reported
        drift["rows"] = "per_run and per_session: the identified refit's models (the check itself: the search's)"
    first_step = searched[0] if searched else step
    final = step if step.fit is None else None  # the none/unexplained answer that ended the search, if one did
    if drift["dropped"]:
        final = None
    decision = first_step.decision
    noise_var = sigma**2 if sigma is not None else 0.0
    after_sse = steps[-1].fit.heldout if steps else start.sse0
    # The answer: the first effect when the effects found together remove enough of the nominal gap
    # (the last step's decision applied the 70 % rule to the whole chain), else the first step's own
    # answer (none/unexplained), or unexplained for a chain that ran out of candidates short of it.
    if steps and not steps[-1].partial:
        effect, why = steps[0].effect, steps[0].decision.why if len(steps) == 1 else _chain_why(steps)
    elif drift["dropped"] and not steps:
        effect = "unexplained"
        why = (f"{' + '.join(drift['dropped'])} named on the fitted segments, but the whole runs replayed open loop "
               f"drift more with it than without on held-out runs ({drift['why']}); model.json is the {first.kind} "
               "model")
    elif steps:
        effect = "unexplained"
        share = 1 - _excess(after_sse, n_comp, noise_var) / start.excess0 if start.excess0 > 0 else 0.0
        why = (f"{' + '.join(s.effect for s in steps)} " + ("together remove" if len(steps) > 1 else "removes")
               + f" only {100 * share:.0f} % of the gap beyond noise on held-out runs (needs "
               f"{100 * rules.min_gap_reduction:.0f} %); model.json carries "
               + ("them" if len(steps) > 1 else "it"))
    elif competition is not None and competition["named"] and decision.effect == "none":
        # The calibration won the first step and nothing beyond the floor is left on top of it.
        effect, why = KINEMATIC, f"{competition['why']}; {decision.why}"
    else:
        effect, why = decision.effect, decision.why
    return Answer(effect, why, steps, uncertainties, model, first_step, final, after_sse, rows, drift, ident_json)


def _result(opts: GapOptions, data: DataStage, start: StartStage, search: SearchStage, answer: Answer,
            cpu0: float, wall0: float) -> GapResult:
    """The typed result of the stages (``cpu0``, ``wall0``: the run's start, for the work record)."""
    ds, n_comp, sigma, first = data.ds, data.n_comp, start.sigma, start.first
    decision = answer.first_step.decision
    steps = answer.steps
    noise_var = sigma**2 if sigma is not None else 0.0
    N = float(n_comp.sum())
    sse0, after_sse = start.sse0, answer.after_sse
    uncertainty = answer.uncertainties[0] if steps else None
    if sigma is None:
        uncertainty = {**(uncertainty or {}), "noise": (
            "tracker noise cannot be estimated (too few consecutive observed rows): gap values include noise, "
            "and a gap left by an effect cannot be told from noise")}
    m0, m1 = geo_mse(sse0, n_comp), geo_mse(after_sse, n_comp)
    before, after = start.excess0, _excess(after_sse, n_comp, noise_var)
    gap_json = {"metric": METRIC, "before": before, "after": after,
                "reduction": 1.0 - after / before if before > 0 else 0.0,
                "rms_before": math.sqrt(m0), "rms_after": math.sqrt(m1),
                "pooled_rms_before": math.sqrt(sse0.sum() / N), "pooled_rms_after": math.sqrt(after_sse.sum() / N),
                "noise": start.tracker, "noise_floor": sigma, "noise_components": start.noise_parts,
                "heldout_runs": len(ds.runs),
                "per_run": [{"run": r.name, "fold": int(k), "rms_before": _rms(a, n), "rms_after": _rms(b, n)}
                            for r, k, a, b, n in zip(ds.runs, data.fold_of, sse0, after_sse, n_comp, strict=True)]}
    by_name = {f.candidate.name: f for f in answer.first_step.fits}
    ranking = decision.ranking
    for entry in ranking:
        f = by_name.get(entry["effect"])
        if f is not None and f.event_fit is not None:
            # The stochastic candidate's inferred lift events (its held-out score counts them).
            entry["n_params_effective"] = f.n_params_eff
            entry["events"] = f.event_fit.to_json([r.name for r in ds.runs], contact_cases(ds.n_wheels))
            if f.event_fit.note:
                entry["events_note"] = f.event_fit.note
        _annotate(entry, decision.nominal_excess_rms, first.model)
    flags = [fl for s in steps for fl in plausible.check(s.effect, s.fit.params_all, first.model)]
    folds_by = "session" if data.sessions is not None else "run"
    cpu = time.process_time() - cpu0
    return GapResult(
        effect=answer.effect, why=answer.why, ambiguous_with=decision.ambiguous_with or None,
        params=steps[0].fit.params_all if steps else {}, uncertainty=uncertainty,
        effects=[s.effect for s in steps], not_applicable=start.skipped,
        steps=_steps_json(steps, answer.uncertainties, answer.final, sse0, n_comp, noise_var),
        identifiability=answer.identifiability, model=answer.model.to_json(), gap=gap_json, ranking=ranking,
        plausibility={
            "flags": [fl.to_json() for fl in flags],
            "ranges": plausible.ranges_json(),
            "note": "flags: fitted values of the named effects outside a physically plausible range (flagging only, "
                    "the fit is not changed); each ranking entry lists its own under 'implausible'"},
        outliers={"rows": [o.to_json() for o in data.flagged], "rule": outlier_rule(opts.settings.data)},
        start={**first.to_json(), "competition": opts.competition,
               "alignment": None if data.start_trust is None else data.start_trust.to_json()},
        heldout={"metric": HELDOUT_METRIC, "folds_by": folds_by, **heldout_table(answer.rows),
                 "per_run": [r.to_json() for r in answer.rows], "drift_check": answer.drift},
        score_nominal=decision.score_nominal, where=search.where,
        settings={"seed": opts.seed, "folds": int(data.fold_of.max()) + 1, "dt": opts.dt, "lever": data.lever,
                  "start": "auto" if opts.competition is not None else opts.start, "folds_by": folds_by,
                  "max_effects": opts.max_effects,
                  "fit_budget": None if math.isinf(opts.fit_budget) else float(opts.fit_budget),  # None: no limit
                  "liftoff": EVENT_METHOD, **opts.settings.to_json(), "robot_runs_simulated": start.ev.simulated},
        dataset={"path": str(opts.dataset), "runs": data.fitted.source_runs, "description": ds.description,
                 "fitted": data.fitted.to_json()},
        # Measured (the one part of result.json that differs from run to run): the steps' tasks, total work and
        # critical paths, and what W workers could reach (fit_tasks.work_json).
        work=work_json(search.works, max(cpu - search.steps_cpu, 0.0), time.perf_counter() - wall0,
                       opts.backend.describe(), driver_cpu_s=cpu))


HELDOUT_METRIC = ("whole-run open-loop position RMS [m] (Euclidean x, y error over a run's tracked rows, the "
                  "measure of omni-gym score), each run replayed from its start pose by the models fitted without "
                  "its fold; per session and over all runs: the mean over runs")


@dataclass
class StartModel:
    """gap's first model and, per held-out fold, the same model fitted without that fold's runs.

    ``kind``: ``nominal``, ``kinematic``, ``tracker`` (the calibration with the tracked frame) or ``given`` (a
    model passed in); ``model``: fitted on all runs;
    ``fold_models[k]``: fitted on the source runs outside fold k (the same model for every fold when ``kind``
    is nominal or given);
    ``excluded``: effects of a given start model, kept as they are (not searched again); ``refit``: the
    kinematic calibration's effects, searched again in the simulator from the calibrated values;
    ``calibration``/``fold_calibrations``: the kinematic fits (JSON).
    ``nominal``: the dataset's model; ``kinematic_folds``: the kinematic fold models whenever the runs
    have wheel odometry (for the side-by-side comparison), else None.
    """

    kind: str
    nominal: SimModel
    model: SimModel
    fold_models: list[SimModel]
    excluded: tuple[str, ...] = ()
    refit: tuple[str, ...] = ()
    calibration: dict | None = None
    fold_calibrations: list[dict] | None = None
    kinematic_folds: list[SimModel] | None = None
    kinematic_all: SimModel | None = None
    why: str = ""
    compete: bool = False  # auto: the calibration is a hypothesis of the first step (_kinematic_fit)

    def describe(self) -> str:
        c = self.calibration
        if c is None:
            return "nominal model"
        t = c.get("tracker")
        frame = ("" if t is None else f", tracked frame offset ({1e3 * t['offset'][0]:.1f}, "
                 f"{1e3 * t['offset'][1]:.1f}) mm, yaw {1e3 * t['yaw']:.1f} mrad")
        return (f"D = [{', '.join(f'{1e3 * d:.2f}' for d in c['diameters'])}] mm, {c['size_name']} = "
                f"{1e3 * c['L']:.2f} mm{frame} on all {c['runs']} runs")

    def to_json(self) -> dict:
        return {"kind": self.kind, "model": self.model.to_json(), "kept_effects": list(self.excluded),
                "refit_effects": list(self.refit),
                "why": self.why, "calibration": self.calibration, "fold_calibrations": self.fold_calibrations,
                "note": "the search started from this model; 'nominal' in gap, ranking and steps means it (the "
                        "dataset's own model is 'nominal' in heldout)"}


def _from_current(cand: Candidate, model: SimModel) -> Candidate:
    """``cand`` with its null point at the values ``model`` already has for the effect (e.g. the kinematic
    calibration's wheel scales), so the fit starts there and is never worse on its training runs than
    ``model``; unchanged when the effect's parameters do not map onto the candidate's dimensions."""
    params = model.effects.get(cand.name)
    if not params:
        return cand
    null = {}
    for d in cand.dims:
        key = d.name.rstrip("0123456789")
        value = params.get(d.name, params.get(key))
        if isinstance(value, (list, tuple)) and key != d.name:
            value = value[int(d.name[len(key):]) - 1]
        if not isinstance(value, (int, float)):
            return cand
        null[d.name] = float(value)
    return replace(cand, null=null)


def _has_odometry(ds: Dataset) -> bool:
    return all(r.enc is not None and np.all(np.isfinite(r.enc)) for r in ds.runs)


def start_model(ds: Dataset, fold_src: np.ndarray, start: str | SimModel, dt: float = FIT_DT,
                lines: ProgressLines = OFF) -> StartModel:
    """The first model of the search (``start``: ``nominal``, ``kinematic`` or ``auto``) on the source runs
    ``ds`` with folds ``fold_src`` (-1: a run in no fold).

    The kinematic calibration (:func:`omni_gym.discrepancy.fit.kinematic_calibration.calibrate`: effective wheel
    diameters and L or l1 + l2 by dead reckoning) is fitted on all runs for the model the search extends,
    and on each fold's training runs for that fold's held-out scores, so no held-out run informs the
    kinematic model it is scored with. ValueError (one line) for ``kinematic`` without wheel odometry.

    ``auto`` starts from the nominal model with ``compete`` set: the calibration is then one hypothesis of the
    first search step (:func:`_kinematic_fit`), scored on the held-out folds like every library effect. Dead
    reckoning assumes rolling wheels; on a robot that slips hard (the synthetic recovery robot's random twist
    steps: 73 mm dead-reckoning RMS where the simulator's nominal replay is 1.4 mm) the calibration fits the
    slip and absorbs part of a physical effect, so it must win against the effects, not start before them.
    ``lines``: progress lines of the calibrations (one per fold and one on all runs).
    """
    nominal = ds.model
    K = int(fold_src.max()) + 1
    odometry = _has_odometry(ds)
    if start in ("kinematic", "tracker") and not odometry:
        bad = next(r.name for r in ds.runs if r.enc is None or not np.all(np.isfinite(r.enc)))
        raise ValueError(f"{ds.path}: run {bad} has no complete wheel odometry (enc1 … enc{ds.n_wheels}): a "
                         f"{start} start dead-reckons from measured wheel angles")
    if not odometry:
        if isinstance(start, SimModel):
            return StartModel("given", nominal, start, [start] * K, excluded=tuple(start.effects),
                              why="the model given (the same for every fold)")
        return StartModel("nominal", nominal, nominal, [nominal] * K,
                          why="the runs have no wheel odometry: no kinematic calibration")
    try:
        cal, fold_cals = _calibrations(ds, fold_src, nominal, tracker=False, lines=lines)
    except ValueError as exc:  # e.g. no convergence on sparse observations
        if start in ("kinematic", "tracker"):
            raise ValueError(f"{ds.path}: {start} start: {exc}") from None
        first = start if isinstance(start, SimModel) else nominal
        return StartModel("given" if isinstance(start, SimModel) else "nominal", nominal, first, [first] * K,
                          excluded=tuple(start.effects) if isinstance(start, SimModel) else (),
                          why=f"no kinematic calibration of these runs ({exc})")
    kin_folds = [c.model for c in fold_cals]
    if isinstance(start, SimModel):
        return StartModel("given", nominal, start, [start] * K, excluded=tuple(start.effects),
                          calibration=cal.to_json(), fold_calibrations=[c.to_json() for c in fold_cals],
                          kinematic_folds=kin_folds, kinematic_all=cal.model,
                          why="the model given (the same for every fold: fitted on which runs, gap cannot know)")
    if start == "tracker":
        return _tracker_start(ds, fold_src, nominal, cal, fold_cals, lines)
    if start in ("nominal", "auto"):
        return StartModel("nominal", nominal, nominal, [nominal] * K, calibration=cal.to_json(),
                          fold_calibrations=[c.to_json() for c in fold_cals], kinematic_folds=kin_folds,
                          kinematic_all=cal.model, compete=start == "auto",
                          why="the kinematic calibration competes with the library's effects at the first step "
                              "(scored on the same held-out folds)" if start == "auto" else
                              "start nominal asked for (the kinematic calibration is scored beside it)")
    # The calibration's own effects are searched again, in the simulator, from the calibrated values (their
    # null point is the calibration: a refit is never worse on its training runs than the start).
    refit = tuple(e for e in ("wheel_radius", "wheel_geometry") if e in cal.model.effects)
    return StartModel("kinematic", nominal, cal.model, kin_folds, refit=refit, calibration=cal.to_json(),
                      fold_calibrations=[c.to_json() for c in fold_cals], kinematic_folds=kin_folds,
                      kinematic_all=cal.model,
                      why="effects are searched on top of the kinematic calibration (fitted on each fold's "
                          "training runs for held-out scores)")


def _calibrations(ds: Dataset, fold_src: np.ndarray, nominal: SimModel, tracker: bool,
                  lines: ProgressLines = OFF) -> tuple:
    """The kinematic calibration (with the tracked frame when ``tracker``) on all runs of ``ds``, and on each
    fold's training runs (the runs outside fold k); ValueError as :func:`calibrate`. ``lines``: progress."""
    K = int(fold_src.max()) + 1
    progress = lines.loop("kinematic calibration" + (" with the tracked frame" if tracker else "") + ":", K + 1,
                          "fits")
    whole = calibrate(ds.runs, nominal, tracker=tracker)
    progress.update()
    folds = []
    for k in range(K):
        folds.append(calibrate([r for r, f in zip(ds.runs, fold_src, strict=True) if f != k], nominal,
                               tracker=tracker))
        progress.update()
    return whole, folds


def _tracker_start(ds: Dataset, fold_src: np.ndarray, nominal: SimModel, cal, fold_cals: list,
                   lines: ProgressLines = OFF) -> StartModel:
    """The ``tracker`` start: the kinematics and the tracked frame (offset, yaw) fitted jointly by dead
    reckoning over whole runs (:func:`calibrate` with ``tracker=True``, what ``omni-gym calibrate --tracker``
    writes), on all runs and on each fold's training runs. Its effects are kept as fitted (the search adds
    others on top); the plain kinematic calibration ``cal``/``fold_cals`` stays the side-by-side baseline."""
    try:
        joint, fold_joint = _calibrations(ds, fold_src, nominal, tracker=True, lines=lines)
    except ValueError as exc:
        raise ValueError(f"{ds.path}: tracker start: {exc}") from None
    return StartModel("tracker", nominal, joint.model, [c.model for c in fold_joint],
                      excluded=tuple(joint.model.effects), calibration=joint.to_json(),
                      fold_calibrations=[c.to_json() for c in fold_joint],
                      kinematic_folds=[c.model for c in fold_cals], kinematic_all=cal.model,
                      why="effects are searched on top of the kinematic calibration with the tracked frame, fitted "
                          "jointly over whole runs (on each fold's training runs for held-out scores; its "
                          "effects are kept as fitted)")


@dataclass(frozen=True)
class _Calibration:
    """``build`` of the kinematic hypothesis's candidate: its parameters are fitted by dead reckoning, not by
    the search, so every point gives the all-run calibration's values (a picklable callable)."""

    params: dict

    def __call__(self, values: list[float]) -> dict:
        return self.params


def _calibration_params(cal: dict) -> dict:
    """The calibration's fitted values as a ranking shows them: effective diameters [m] and L or l1+l2 [m]."""
    return {"diameters": list(cal["diameters"]), cal["size_name"]: cal["L"]}


def _kinematic_fit(ev: Evaluator, first: StartModel, fold_of: np.ndarray) -> FitResult:
    """The kinematic calibration as a hypothesis of the first search step, scored like every library effect:
    each fitted run (or segment) replayed in the simulator by the calibration fitted without its fold (held-out
    SSE) and by the all-run calibration (``sse_all``). Its parameters (the effective diameters and L or
    l1 + l2) count in the decision's BIC penalty; they are fitted by dead reckoning
    (:func:`~omni_gym.discrepancy.fit.kinematic_calibration.calibrate`), so the search does not move them."""
    models = [first.kinematic_all, *first.kinematic_folds]
    sse = np.array([[run_sse(r) for r in per] for per in ev.residuals(models)])  # (1 + K, R)
    heldout = np.array([sse[1 + k, r] for r, k in enumerate(fold_of)])
    cal = first.calibration
    dims = (*(Dim(f"diameter{i + 1}", 0.5 * d, 1.5 * d) for i, d in enumerate(cal["nominal_diameters"])),
            Dim(cal["size_name"], 0.5 * cal["nominal_L"], 1.5 * cal["nominal_L"]))
    params = _calibration_params(cal)
    cand = Candidate(KINEMATIC, dims, _Calibration(params))
    u = cand.point({**{f"diameter{i + 1}": d for i, d in enumerate(cal["diameters"])}, cal["size_name"]: cal["L"]})
    return FitResult(candidate=cand, u_all=u, params_all=params, sse_all=sse[0], heldout=heldout,
                     fold_params=[_calibration_params(c) for c in first.fold_calibrations], pool_u=u[None, :],
                     pool_sse=sse[:1])


def _competition_json(step: Step) -> dict:
    """What result.json's ``start.competition`` records of a first step the calibration won: whether it was
    named (else kept as a partial explanation), why, and the step's ranking."""
    d = step.decision
    return {"winner": KINEMATIC, "named": d.partial is None, "why": d.why, "ranking": _short_ranking(step)}


def _compact_folds(fold_src: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(fold of each fitted run, fold of each source run) with the folds that hold a fitted run numbered
    0..K-1; a source run whose fold holds no fitted segment gets -1 (no fit saw it)."""
    seg = fold_src[groups]
    present = np.unique(seg)
    remap = np.full(int(fold_src.max()) + 1, -1)
    remap[present] = np.arange(len(present))
    return remap[seg], remap[fold_src]


def _drift_check(whole: Dataset, fold_src: np.ndarray, first: StartModel, steps: list[Step], dt: float,
                 gate: bool, start_window: float | None = START_WINDOW) -> tuple[list, dict]:
    """The drift-aware held-out score: every source run replayed whole, open loop, by the nominal model, the
    kinematic calibration (with odometry) and the start model with the named effects one after another
    (each fold's own fits: fold params on top of the fold's start model).

    ``gate`` (the fit saw segments, not whole runs): a named effect is kept only while it makes the mean
    whole-run held-out position RMS of no session (of all runs, without sessions) worse than the chain
    before it; the first that does is dropped
    with every later one. A stochastic effect is replayed without its random process (its deterministic
    part: nothing), so it is never judged here. Returns the per-run rows (models ``nominal``,
    ``kinematic``, ``extended``) and the check's record.
    """
    K = len(first.fold_models)
    det = [s for s in steps if not s.fit.candidate.stochastic]
    chain_folds = [list(first.fold_models)]
    chain_all = [first.model]
    for s in det:
        chain_folds.append([m.with_effect(s.effect, s.fit.fold_params[k]) for k, m in enumerate(chain_folds[-1])])
        chain_all.append(chain_all[-1].with_effect(s.effect, s.fit.params_all))
    fold_models: dict[str, list[SimModel]] = {"nominal": [first.nominal] * K}
    all_models: dict[str, SimModel] = {"nominal": first.nominal}
    if first.kinematic_folds is not None:
        fold_models["kinematic"] = first.kinematic_folds
        all_models["kinematic"] = first.kinematic_all
    for j, (mf, ma) in enumerate(zip(chain_folds, chain_all, strict=True)):
        fold_models[f"chain{j}"], all_models[f"chain{j}"] = mf, ma
    rows = heldout_whole_runs(whole, fold_src, fold_models, all_models, dt=dt, start_window=start_window)
    means = [float(np.mean([r.position_rms[f"chain{j}"] for r in rows])) for j in range(len(chain_folds))]
    groups = list(dict.fromkeys(r.session for r in rows))  # sessions (one group of None without them)
    per_group = [[float(np.mean([r.position_rms[f"chain{j}"] for r in rows if r.session == g])) for g in groups]
                 for j in range(len(chain_folds))]
    keep = len(det)
    if gate:
        for j in range(1, len(means)):
            # Worse on any held-out session is worse: the model is used on sessions it never saw.
            if any(a > b for a, b in zip(per_group[j], per_group[j - 1], strict=True)):
                keep = j - 1
                break
    dropped = [s.effect for s in det[keep:]]
    for r in rows:  # the reported columns: extended = the kept chain
        for d in (r.position_rms, r.final_error):
            d["extended"] = d[f"chain{keep}"]
            for j in range(len(chain_folds)):
                d.pop(f"chain{j}")
    why = ", ".join(f"{1e3 * m:.1f} mm" for m in means)
    return rows, {"rule": "segments fitted: a named effect is kept only while the mean whole-run held-out position "
                          "RMS of no session grows (checked in the order named)" if gate else
                          "whole runs fitted: the fit's held-out score already includes whole-run drift",
                  "chain": [first.kind] + [s.effect for s in det], "mean_position_rms": means,
                  "sessions": groups, "session_mean_position_rms": per_group,
                  "dropped": dropped, "why": f"mean whole-run held-out position RMS along the chain: {why}"}


def _with_refit(steps: list[Step], lin: identifiability.Linearisation, refit: identified_fit.IdentifiedFit
                ) -> list[Step]:
    """``steps`` with each deterministic effect's fit replaced by the identified refit's values (all-run and
    per fold); the last deterministic step also takes the refit's per-run SSE and held-out SSE (the model
    with every refitted effect). Earlier steps keep the search's SSE (the staircase is the search's record)."""
    index = {n.candidate.name: i for i, n in enumerate(lin.named)}
    last = max((i for i, s in enumerate(steps) if s.effect in index), default=-1)
    out = []
    for i, s in enumerate(steps):
        f = s.fit
        if s.effect not in index:
            out.append(s)
            continue
        j = index[s.effect]
        cand = f.candidate
        new = replace(f, u_all=refit.u_all[j], params_all=cand.params(refit.u_all[j]),
                      fold_params=[cand.params(us[j]) for us in refit.u_folds])
        if i == last:
            new = replace(new, sse_all=refit.sse_all.copy(), heldout=refit.heldout.copy())
        out.append(Step(fits=[new if g is f else g for g in s.fits], decision=s.decision))
    return out


def _chain_why(steps: list[Step]) -> str:
    """Why for a chain of effects: the last step's decision, which judged the whole chain."""
    names = " + ".join(s.effect for s in steps)
    return f"{names}: {steps[-1].decision.why} (with the effects before it in the model)"


def _excess(sse: np.ndarray, n_comp: np.ndarray, noise_var: float) -> float:
    """The decision metric (:data:`METRIC`) of per-run SSE ``sse`` [m]."""
    return math.sqrt(max(geo_mse(sse, n_comp) - noise_var, 0.0))


def _steps_json(steps: list[Step], uncertainties: list[dict], final: Step | None, sse0: np.ndarray,
                n_comp: np.ndarray, noise_var: float) -> list[dict]:
    """The staircase: per named effect its parameters and the held-out gap beyond noise before and after
    it; then the answer that ended the search (``none``/``unexplained``, with why), if one did."""
    out = []
    before = first = _excess(sse0, n_comp, noise_var)
    for i, (s, u) in enumerate(zip(steps, uncertainties, strict=True), start=1):
        after = _excess(s.fit.heldout, n_comp, noise_var)
        # gap_share: the share of the initial gap beyond noise this step removed (the report's outcome heading)
        share = (before - after) / first if first > 0 else None
        out.append({"step": i, "effect": s.effect, "status": "partial" if s.partial else "named",
                    "why": s.decision.why, "params": s.fit.params_all,
                    "gap_before": before, "gap_after": after, "gap_share": share, "params_5_95": u["params_5_95"],
                    "ranking": _short_ranking(s)})
        before = after
    if final is not None:
        out.append({"step": len(steps) + 1, "effect": final.effect, "status": "end", "why": final.decision.why,
                    "gap_before": before, "gap_after": before,
                    "ranking": _short_ranking(final)})
    return out


def _short_ranking(step: Step) -> list[dict]:
    """A step's ranking as ``steps`` shows it: effect, held-out RMS [m], whether it beat its baseline."""
    return [{"effect": r["effect"], "heldout_rms": r["heldout_rms"], "beats_nominal": r["beats_nominal"]}
            for r in step.decision.ranking]


def _rms(sse: float, n: int) -> float | None:
    return float(math.sqrt(sse / n)) if n else None


def _annotate(entry: dict, nominal_excess: float, nominal) -> None:
    """Add to a ranking entry the share of the nominal gap beyond noise it removes (the measure the
    decision's 70 % rule uses; ``improvement`` is the MSE reduction of the 5 % rule) and the fitted
    values outside their plausible range, for candidates that beat nominal (the fit of one that does not
    is no evidence of anything, and a lift-off fit without events sits at its null point)."""
    entry["gap_reduction"] = 1.0 - entry["excess_rms"] / nominal_excess if nominal_excess > 0 else 0.0
    flags = plausible.check(entry["effect"], entry["params"], nominal) if entry["beats_nominal"] else []
    entry["implausible"] = [fl.text() for fl in flags]


def _stage_printer(enabled: bool) -> Callable[[str], None]:
    """One line per stage on stderr, flushed (for logs and pipes, where the tqdm bar is off)."""
    def say(message: str) -> None:
        if enabled:
            print(f"gap: {message}", file=sys.stderr, flush=True)
    return say
