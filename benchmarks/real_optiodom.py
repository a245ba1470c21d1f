"""Real OptiOdom logs, both robots: gap's extended model against kinematic odometry calibration.

    # one robot's tables (benchmarks/results/real_optiodom_<robot>.md, .json, .png, _model.json, _gap.json) and
    # the two-robot summary benchmarks/results/real_optiodom.md (from every real_optiodom_<robot>.json in --out):
    # gap on all 24 training runs of the robot, fitted within its default budget of 120 s of robot time
    python benchmarks/real_optiodom.py --robot omni4 --out benchmarks/results
    python benchmarks/real_optiodom.py --robot omni3 --out benchmarks/results
    # re-render from an earlier run's gap record (no gap run; the held-out replay only):
    python benchmarks/real_optiodom.py --robot omni3 --out DIR \
        --gap-model benchmarks/results/real_optiodom_omni3_gap.json
    # smaller variants: gap on N runs per training session cut to S seconds
    python benchmarks/real_optiodom.py --robot omni4 --gap-runs 4 --gap-seconds 20 --out DIR
    # smoke test: 4 training runs cut to 10 s, one 20 s run per held-out session (gap dominates the time)
    python benchmarks/real_optiodom.py --robot omni4 --quick

Robots (``data/optiodom-omni3``, ``data/optiodom-omni4``; their READMEs):

* omni3 (three omni wheels): training circular/221220201701 + square/221220201953 (24 runs); held out
  circular/221220201643, …1722, …1726, …1730 and joystick/211220201842;
* omni4 (four mecanum wheels): training circular/080920201015 + square/080920201810 (24 runs, day 1); held out
  square/080920201715 (day 1), circular/231220200440 and circular/231220200502 (day 2).

The training sessions are imported together with ``omni_gym.discrepancy.data.importers.optiodom`` (nominal model
from the metadata and the importer's documented assumptions for mass, inertia and surface). Models, all
fitted on the robot's training runs only:

* (a) nominal: simulated in our world (``omni_gym.discrepancy.replay.simulate``) at the workflow's FIT_DT;
* (b) kinematic: ``omni_gym.discrepancy.fit.kinematic_calibration`` (least squares over the wheel diameters and
  L for omni3, l1 + l2 for omni4), dead-reckoned from the encoders (an arc per control cycle);
* (c) kinematic, simulated: the calibration's SimModel in our world, as (a);
* (d) extended: the ``model`` that ``omni_gym.discrepancy.workflow.gap`` returns on the training
  dataset (starting from the nominal model), simulated as (a).

Each held-out run is replayed open loop from its start pose with its measured wheel speeds; the score is
the position RMS [m] over the run's tracked rows (Euclidean x, y error against motion capture; what
``omni-gym score`` reports). Per session the table gives the mean over its runs. Mass and inertia are not
published: (a)-(d) are repeated on one session with mass and inertia ×0.5 and ×2 (models not refitted).
Progress on stderr, one line per stage.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from omni_gym.angles import wrap_angle  # noqa: E402
from omni_gym.discrepancy.data.dataset import Run, write_dataset  # noqa: E402
from omni_gym.discrepancy.data.importers.optiodom import describe, nominal_model, read_sessions  # noqa: E402
from omni_gym.discrepancy.data.segments import FIT_BUDGET  # noqa: E402
from omni_gym.discrepancy.fit.kinematic_calibration import (  # noqa: E402
    KinematicCalibration,
    calibrate,
    dead_reckon,
    position_rms,
)
from omni_gym.discrepancy.replay.measurement import START_WINDOW  # noqa: E402
from omni_gym.discrepancy.replay.simulate import FIT_DT, Job, simulate_poses  # noqa: E402
from omni_gym.io import read_json  # noqa: E402
from omni_gym.physics.model import SimModel  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Robot:
    """One OptiOdom robot of the benchmark: its data folder, training and held-out sessions, and the held-out
    session of the mass/inertia check (the longest held-out circular one)."""

    name: str
    title: str
    data: Path
    train: tuple[str, ...]
    heldout: tuple[str, ...]
    mass_session: str


ROBOTS = {
    "omni3": Robot("omni3", "omni3: three omni wheels", ROOT / "data" / "optiodom-omni3",
                   ("circular/221220201701", "square/221220201953"),
                   ("circular/221220201643", "circular/221220201722", "circular/221220201726",
                    "circular/221220201730", "joystick/211220201842"), "circular/221220201643"),
    "omni4": Robot("omni4", "omni4: four mecanum wheels", ROOT / "data" / "optiodom-omni4",
                   ("circular/080920201015", "square/080920201810"),
                   ("square/080920201715", "circular/231220200440", "circular/231220200502"),
                   "circular/231220200440"),
}
MASS_FACTORS = (0.5, 2.0)
MODELS = ("nominal", "kinematic", "kinematic_sim", "extended")
# --quick: 2 training runs per session cut to QUICK_TRAIN s, the first held-out run of each session cut to
# QUICK_HELDOUT s (a smoke test of the whole pipeline, not a result).
QUICK_TRAIN, QUICK_HELDOUT = 10.0, 20.0


def say(msg: str) -> None:
    """A stage line on stderr (flushed: visible when piped to a log)."""
    print(f"real_optiodom: {msg}", file=sys.stderr, flush=True)


@dataclass
class Session:
    name: str
    runs: list[Run]


def cut(run: Run, seconds: float) -> Run:
    """The first ``seconds`` of ``run`` (the last kept row's command is 0: it ends the run)."""
    K = int(np.searchsorted(run.t, seconds, side="right"))
    K = max(K, 2)
    cmd = run.cmd[:K].copy()
    cmd[-1] = 0.0
    return Run(name=run.name, t=run.t[:K].copy(), cmd=cmd, pose=run.pose[:K].copy(),
               enc=None if run.enc is None else run.enc[:K].copy())


def load(robot: Robot, quick: bool) -> tuple[SimModel, list, list[Run], list[Session]]:
    """(nominal model, training metadata, training runs, held-out sessions) of ``robot``."""
    metas, train = read_sessions([robot.data / s for s in robot.train])
    nominal = nominal_model(metas[0])
    sessions = []
    for s in robot.heldout:
        m, runs = read_sessions([robot.data / s])
        # One robot configuration: the held-out sessions share the training nominal model.
        if m[0].robot_key() != metas[0].robot_key():
            raise ValueError(f"{s}: robot configuration differs from the training sessions")
        sessions.append(Session(s, runs))
    if quick:
        per = len(train) // len(robot.train)
        train = [cut(r, QUICK_TRAIN) for r in (train[0], train[per // 2], train[per], train[per + per // 2])]
        sessions = [Session(s.name, [cut(s.runs[0], QUICK_HELDOUT)]) for s in sessions]
    return nominal, metas, train, sessions


def gap_subset(robot: Robot, train: list[Run], runs: int | None, seconds: float | None) -> list[Run]:
    """The training runs gap sees: ``runs`` of each training session spread evenly (N = 4 of 12: runs 1, 4, 7,
    10), each cut to its first ``seconds``."""
    out = train
    if runs is not None:
        if runs < 1:
            raise ValueError(f"--gap-runs must be >= 1, got {runs}")
        out = []
        for s in robot.train:
            mine = [q for q in train if q.name.startswith(s.rsplit("/", 1)[-1] + "_")]
            # Spread over the session: its runs come in blocks of one path kind (direction of travel,
            # driving wheels), so the first N runs would show gap a single kind.
            picks = np.unique(np.floor(np.arange(min(runs, len(mine))) * len(mine) / min(runs, len(mine))))
            out += [mine[int(i)] for i in picks]
    if seconds is not None:
        out = [cut(r, seconds) for r in out]
    return out


def run_gap(nominal: SimModel, metas: list, train: list[Run], seed: int, fit_budget: float,
            start: str | SimModel | None = None, jobs: int = 1) -> tuple[dict, float]:
    """``gap`` on the training runs (written to a temporary dataset, each run's session recorded), from
    ``start`` (None: the dataset's nominal model; ``"kinematic"``: gap's own kinematic start, calibrated per
    held-out fold), on ``jobs`` local worker processes (the result does not depend on it); (result, wall
    time [s])."""
    from omni_gym.discrepancy.workflow import gap
    from omni_gym.parallel import SERIAL, backend_from_options

    with tempfile.TemporaryDirectory(prefix="real_optiodom_") as tmp:
        ds = Path(tmp) / "train"
        desc = describe(metas, len(train), nominal.robot.mass, nominal.robot.inertia, nominal.surface.name)
        write_dataset(ds, nominal.to_json(), desc, train)
        t0 = time.perf_counter()
        backend = SERIAL if jobs <= 1 else backend_from_options(jobs, None)
        result = gap(ds, None, seed=seed, progress=None, fit_budget=fit_budget, start=start, backend=backend)
        wall = time.perf_counter() - t0
    return result, wall


def named_effects(nominal: SimModel, model: SimModel) -> dict[str, dict]:
    """Effects of ``model`` that the nominal model does not have (or has with other parameters)."""
    return {k: v for k, v in model.effects.items() if nominal.effects.get(k) != v}


def with_mass(model: SimModel, factor: float) -> SimModel:
    """``model`` with mass and yaw inertia scaled by ``factor`` (the importer's I = 0.5·m·L² convention)."""
    r = model.robot
    return replace(model, robot=r.with_changes(mass=r.mass * factor, inertia=r.inertia * factor))


def score(sessions: list[Session], models: dict[str, SimModel], cal: KinematicCalibration,
          dt: float) -> tuple[dict, dict]:
    """Per session and model: the per-run position RMS [m]; and the predicted poses (for plots).

    ``models``: the simulated ones (nominal, kinematic_sim, extended); ``kinematic`` is dead reckoning.
    """
    runs = [(s.name, r) for s in sessions for r in s.runs]
    names = list(models)
    jobs = [Job(models[m], r) for _, r in runs for m in names]
    poses = simulate_poses(jobs, dt=dt, start_window=START_WINDOW)
    rms: dict[str, dict[str, list[float]]] = {s.name: {m: [] for m in MODELS} for s in sessions}
    pred: dict[tuple[str, str], dict[str, np.ndarray]] = {}
    g = cal.geometry
    for i, (sname, run) in enumerate(runs):
        p = {m: poses[i * len(names) + j] for j, m in enumerate(names)}
        p["kinematic"] = dead_reckon(run, g)
        pred[(sname, run.name)] = p
        for m in MODELS:
            if m in p:
                rms[sname][m].append(position_rms(run.pose, p[m]))
    return rms, pred


def residual_analysis(sessions: list[Session], pred: dict, nominal: SimModel, cal: KinematicCalibration) -> dict:
    """What the best held-out prediction leaves, per held-out session ("where, when, which wheel").

    * ``oracle``: a kinematic calibration fitted on the session itself (in-sample): its D, L and position
      RMS [m]. Where it differs from the training calibration, the effective geometry changed between
      sessions, which no fixed model can follow; its RMS is a floor for any kinematic model there.
    * ``growth``: position error of the extended model at 25, 50, 75 and 100 % of each run's time [m]
      (mean over runs): drift that grows steadily is a rate error (geometry, scale), error that jumps
      at certain times is an event.
    * ``heading_rms``: RMS heading error [rad] of the extended model (mean over runs); ``distance``: the
      mean distance driven per run [m] (a heading error turns into position error along it).
    """
    out = {}
    for s in sessions:
        oracle = calibrate(s.runs, nominal)
        growth, head, dist = [], [], []
        for r in s.runs:
            p = pred[(s.name, r.name)]["extended"]
            obs = np.flatnonzero(r.observed)
            e = np.hypot(*(r.pose[obs, :2] - p[obs, :2]).T)
            growth.append([e[min(len(e) - 1, int(q * (len(e) - 1)))] for q in (0.25, 0.5, 0.75, 1.0)])
            dh = wrap_angle(r.pose[obs, 2] - p[obs, 2])
            head.append(float(np.sqrt(np.mean(dh**2))))
            dist.append(float(np.sum(np.hypot(*np.diff(r.pose[obs, :2], axis=0).T))))
        out[s.name] = {"oracle_D": oracle.diameters.tolist(), "oracle_L": float(oracle.L),
                       "oracle_rms": float(oracle.train_position_rms),
                       "growth": np.mean(growth, axis=0).tolist(), "heading_rms": float(np.mean(head)),
                       "distance": float(np.mean(dist))}
    return out


def model_geometry(model: SimModel) -> tuple[np.ndarray, float]:
    """Effective wheel diameters (n,) [m] and the calibration's length [m] of a model, its effects applied
    (what the force kernel reads): the mean centre-to-wheel distance L for omni wheels, l1 + l2 =
    2·mean(|x_i| + |y_i|) for mecanum wheels at (±l1/2, ±l2/2)."""
    from omni_gym.physics.layout import WP_PX, WP_PY, WP_R

    _, wp = model.kernel_params()
    if model.robot.has_angled_rollers:
        return 2.0 * wp[:, WP_R], float(2.0 * np.mean(np.abs(wp[:, WP_PX]) + np.abs(wp[:, WP_PY])))
    return 2.0 * wp[:, WP_R], float(np.mean(np.hypot(wp[:, WP_PX], wp[:, WP_PY])))


def mm(v: float) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{1000 * v:.1f}"


def fmt_params(params: dict) -> str:
    def one(v):
        if isinstance(v, list):
            return "[" + ", ".join(one(x) for x in v) + "]"
        return f"{v:.4g}" if isinstance(v, float) else str(v)
    return ", ".join(f"{k} {one(v)}" for k, v in params.items())


def plot(out: Path, stem: str, robot: Robot, sessions: list[Session], pred: dict, n_train: int,
         start: str = "nominal") -> Path:
    """xy paths of the first run of every held-out session: motion capture and three models."""
    fig, axes = plt.subplots(1, len(sessions), figsize=(4 * len(sessions), 4.2))
    styles = {"nominal": ("tab:gray", "nominal (sim)"), "kinematic": ("tab:blue", "kinematic calibration"),
              "extended": ("tab:red", "extended model (sim)")}
    for ax, s in zip(np.atleast_1d(axes), sessions, strict=True):
        run = s.runs[0]
        ok = run.observed
        ax.plot(run.pose[ok, 0], run.pose[ok, 1], "k-", lw=2.0, label="motion capture")
        for m, (color, label) in styles.items():
            p = pred[(s.name, run.name)][m]
            # extended dashed: where gap added nothing it lies on its start model's curve, which shows through
            ax.plot(p[:, 0], p[:, 1], color=color, lw=1.2 if m == "extended" else 1.0,
                    ls="--" if m == "extended" else "-", label=label)
        ax.plot(*run.start_pose[:2], "ko", ms=4)
        ax.set_title(f"{s.name}\n{run.name.split('_')[-1]} ({run.t[-1]:.0f} s)", fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
    np.atleast_1d(axes)[0].set_ylabel("y [m]")
    np.atleast_1d(axes)[0].legend(fontsize=7, loc="best")
    fig.suptitle(f"{robot.title}: held-out OptiOdom runs replayed open loop from the start pose\n(kinematic "
                 f"calibration on {n_train} training runs; extended model: gap's, started from the {start} model, "
                 "dashed: it covers that model's curve where gap added nothing)", fontsize=10)
    fig.tight_layout()
    path = out / f"{stem}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", choices=sorted(ROBOTS), default=None,
                    help="which OptiOdom robot (real_optiodom.md in --out summarises every robot run there)")
    ap.add_argument("--summary", action="store_true",
                    help="only rewrite real_optiodom.md from the real_optiodom_<robot>.json records in --out")
    ap.add_argument("--quick", action="store_true",
                    help="few short runs: a smoke test of the whole pipeline (a few minutes: gap dominates)")
    ap.add_argument("--out", default=None, help="output folder (default benchmarks/results; --quick: a temporary "
                                                 "folder, printed)")
    ap.add_argument("--gap-model", default=None, help="reuse this model.json, gap result.json or the "
                                                       "real_optiodom_<robot>_gap.json an earlier run wrote (which "
                                                       "keeps gap's decision and wall time) instead of running gap")
    ap.add_argument("--seed", type=int, default=0, help="gap's seed")
    ap.add_argument("--gap-start", choices=("nominal", "kinematic"), default="nominal",
                    help="the model gap starts from: the nominal model (default) or the kinematic calibration "
                         "(gap --start kinematic: calibrated per held-out fold, folds by session, its diameters and "
                         "length refitted from the calibrated values, the other effects searched on top); the files "
                         "get the suffix _from_kinematic")
    ap.add_argument("--gap-runs", type=int, default=None, metavar="N",
                    help="give gap only N runs of each training session, spread evenly (default: all; the kinematic "
                         "calibration always uses every training run); for when gap on all 24 runs is too slow")
    ap.add_argument("--gap-seconds", type=float, default=None, metavar="S",
                    help="give gap only the first S seconds of each of its runs (default: whole runs)")
    ap.add_argument("--fit-budget", type=float, default=FIT_BUDGET, metavar="S",
                    help=f"gap's fit budget [s] of robot time (default {FIT_BUDGET:g}; omni-gym gap --fit-budget)")
    ap.add_argument("--jobs", type=int, default=1, metavar="N",
                    help="gap's local worker processes (omni-gym gap --jobs; the result does not depend on it)")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error(f"--jobs must be at least 1, got {args.jobs}")
    command = "python benchmarks/real_optiodom.py" + "".join(f" {a}" for a in (argv or sys.argv[1:]))
    out = Path(args.out) if args.out else (Path(tempfile.mkdtemp(prefix="real_optiodom_quick_")) if args.quick
                                           else ROOT / "benchmarks" / "results")
    out.mkdir(parents=True, exist_ok=True)
    dt = FIT_DT
    if args.summary:
        say(f"wrote {write_summary(out)}")
        return 0
    if args.robot is None:
        ap.error("--robot is required (or --summary)")

    robot = ROBOTS[args.robot]
    stem = f"real_optiodom_{robot.name}" + ("_from_kinematic" if args.gap_start == "kinematic" else "")
    say(f"{robot.name}: importing the training and held-out sessions" + (" (--quick: cut runs)" if args.quick else ""))
    nominal, metas, train, sessions = load(robot, args.quick)
    say(f"{len(train)} training runs ({sum(r.t[-1] for r in train):.0f} s), "
        f"{sum(len(s.runs) for s in sessions)} held-out runs in {len(sessions)} sessions")

    say("kinematic calibration on the training runs")
    t0 = time.perf_counter()
    cal = calibrate(train, nominal)
    cal_wall = time.perf_counter() - t0
    say(f"kinematic calibration: D = {np.round(1000 * cal.diameters, 2).tolist()} mm, L = {1000 * cal.L:.2f} mm, "
        f"training position RMS {mm(cal.nominal_position_rms)} -> {mm(cal.train_position_rms)} mm ({cal_wall:.1f} s)")

    gap_info: dict
    if args.gap_model:
        data = read_json(Path(args.gap_model))
        model_json = data["model"] if isinstance(data, dict) and "model" in data and "wheels" not in data else data
        extended = SimModel.from_json(model_json, where=args.gap_model)
        if isinstance(data, dict) and "gap_info" in data:  # a gap record this script wrote: keep its story
            gap_info = data["gap_info"]
            gap_info["source"] += f" (reused from {args.gap_model})"
        elif isinstance(data, dict) and "heldout" in data:  # a gap result.json: keep its decision and checks
            gap_info = {"source": f"reused the gap report {args.gap_model}", "wall": None, "effect": data["effect"],
                        "why": data["why"], "heldout": data["heldout"], "effects": data.get("effects"),
                        "start": (data.get("start") or {}).get("kind", "nominal")}
        else:
            gap_info = {"source": f"reused {args.gap_model}", "wall": None, "effect": None, "why": None}
        say(f"extended model from {args.gap_model} (gap not run)")
    else:
        gap_train = gap_subset(robot, train, args.gap_runs, args.gap_seconds)
        say(f"running gap on {len(gap_train)} training runs ({sum(r.t[-1] for r in gap_train):.0f} s; its stage "
            "lines follow)")
        result, wall = run_gap(nominal, metas, gap_train, args.seed, args.fit_budget,
                               start="kinematic" if args.gap_start == "kinematic" else None, jobs=args.jobs)
        extended = SimModel.from_json(result["model"], where="gap result")
        subset = "" if len(gap_train) == len(train) and args.gap_seconds is None else (
            f" on a subset of the training runs: {len(gap_train)} runs, {sum(r.t[-1] for r in gap_train):.0f} s "
            f"({', '.join(r.name for r in gap_train)}); the kinematic calibration used all {len(train)}")
        subset += f"; gap fitted {result['dataset']['fitted']['description']}"
        start_txt = ", start='kinematic'" if args.gap_start == "kinematic" else ""
        gap_info = {"source": f"omni_gym.discrepancy.workflow.gap(seed={args.seed}, "
                              f"fit_budget={args.fit_budget:g}{start_txt}){subset}", "wall": wall, "command": command,
                    "start": args.gap_start,
                    "effect": result["effect"], "why": result["why"], "gap": result["gap"],
                    "effects": result.get("effects"), "heldout": result.get("heldout"),
                    "steps": result.get("steps")}
        say(f"gap named {result['effect']!r} in {wall:.0f} s")
        (out / f"{stem}_model.json").write_text(json.dumps(result["model"], indent=1) + "\n")
        # gap's whole result and the table's story of it: --gap-model FILE re-renders the table from it.
        (out / f"{stem}_gap.json").write_text(json.dumps(
            {"model": result["model"], "gap_info": gap_info, "result": result}, indent=1) + "\n")
    start_model = cal.model if gap_info.get("start") == "kinematic" else nominal
    named = named_effects(start_model, extended)

    models = {"nominal": nominal, "kinematic_sim": cal.model, "extended": extended}
    say(f"replaying {sum(len(s.runs) for s in sessions)} held-out runs with {len(models)} simulated models "
        f"(dt {dt * 1000:g} ms) and the kinematic calibration")
    t0 = time.perf_counter()
    rms, pred = score(sessions, models, cal, dt)
    say(f"held-out replay done ({time.perf_counter() - t0:.0f} s)")

    mass_session = next((s for s in sessions if s.name == robot.mass_session), sessions[0])
    mass_rms = {}
    for f in MASS_FACTORS:
        say(f"mass and inertia x{f:g} on {mass_session.name}")
        scaled = {k: with_mass(m, f) for k, m in models.items()}
        mass_rms[f] = score([mass_session], scaled, cal, dt)[0][mass_session.name]
    mass_rms[1.0] = rms[mass_session.name]

    say("residual analysis (per-session kinematic calibrations)")
    left = residual_analysis(sessions, pred, nominal, cal)
    say("writing the table and the plot")
    png = plot(out, stem, robot, sessions, pred, len(train), gap_info.get("start", "nominal"))
    growth = error_growth(sessions, pred)
    growth_plot(out, stem, robot, growth)
    md = table(robot, stem, command, args.quick, nominal, cal, extended, named, gap_info, sessions, rms, mass_session,
               mass_rms, train, dt, left)
    (out / f"{stem}.md").write_text(md)
    (out / f"{stem}.json").write_text(json.dumps({
        "robot": robot.name, "command": command, "quick": args.quick, "dt": dt,
        "kinematic_calibration": cal.to_json(), "extended_effects": named,
        "gap": {k: v for k, v in gap_info.items() if k != "gap"} | {"gap": gap_info.get("gap")},
        "heldout": {s: {m: v for m, v in d.items()} for s, d in rms.items()},
        "runs": {s.name: [r.name for r in s.runs] for s in sessions},
        "mass_check": {"session": mass_session.name, "rms": {str(f): d for f, d in mass_rms.items()}},
        "residual_analysis": left, "error_growth": growth,
    }, indent=1) + "\n")
    summary = write_summary(out)
    say(f"wrote {out / (stem + '.md')}, {png} and {summary}")
    print(md)
    return 0


def table(robot: Robot, stem: str, command: str, quick: bool, nominal: SimModel, cal: KinematicCalibration,
          extended: SimModel, named: dict, gap_info: dict, sessions: list[Session], rms: dict, mass_session: Session,
          mass_rms: dict, train: list[Run], dt: float, left: dict) -> str:
    """The markdown of ``real_optiodom.md``."""
    lines = [f"<!-- made by: {command} -->",
             f"# Real OptiOdom logs, {robot.title}: extended model vs kinematic calibration", "",
             "Both robots' summary: [real_optiodom.md](real_optiodom.md).", ""]
    if quick:
        lines += ["**--quick smoke test: cut runs, not a result.**", ""]
    lines += [f"`{command}`", "",
              f"Training: {' + '.join(robot.train)} ({len(train)} runs, {sum(r.t[-1] for r in train):.0f} s of robot "
              "time). "
              "Every model is fitted on these runs only. Each held-out run is replayed open loop from its start pose "
              "with its measured wheel speeds; score: position RMS [mm] over the run's tracked rows (Euclidean x, y "
              "error against motion capture), mean over the session's runs. Simulated models: our world at "
              f"dt = {dt * 1000:g} ms (the workflow's FIT_DT). Nominal model: metadata geometry, assumed mass "
              f"{nominal.robot.mass:g} kg, inertia {nominal.robot.inertia:.4g} kg·m², surface {nominal.surface.name}.",
              "",
              "| held-out session | runs | nominal (sim) | kinematic | kinematic (sim) | extended (sim) | "
              "extended / kinematic |",
              "|---|---|---|---|---|---|---|"]
    ratios = []
    for s in sessions:
        d = {m: float(np.mean(v)) for m, v in rms[s.name].items()}
        ratio = d["extended"] / d["kinematic"]
        ratios.append(ratio)
        lines.append(f"| {s.name} | {len(s.runs)} | {mm(d['nominal'])} | {mm(d['kinematic'])} | "
                     f"{mm(d['kinematic_sim'])} | {mm(d['extended'])} | {ratio:.2f} |")
    met = all(r <= 1.0 for r in ratios)
    lines += ["", f"Goal (extended ≤ kinematic on every held-out session): **{'met' if met else 'not met'}** "
                  f"(ratios {', '.join(f'{r:.2f}' for r in ratios)}; stretch goal 0.8).", ""]
    lines += ["Per run (position RMS [mm]: nominal / kinematic / kinematic sim / extended):", ""]
    for s in sessions:
        cells = []
        for i, r in enumerate(s.runs):
            v = [rms[s.name][m][i] for m in MODELS]
            cells.append(f"{r.name.split('_')[-1]} ({r.t[-1]:.0f} s): " + " / ".join(mm(x) for x in v))
        lines.append(f"- {s.name}: " + "; ".join(cells))
    lines += ["", "## The models", "",
              f"**Kinematic calibration** (`omni_gym.discrepancy.fit.kinematic_calibration`): D = "
              f"{', '.join(f'{1000 * d:.2f}' for d in cal.diameters)} mm (nominal "
              f"{', '.join(f'{1000 * d:.1f}' for d in cal.nominal_diameters)}), L = {1000 * cal.L:.2f} mm (nominal "
              f"{1000 * cal.nominal_L:.1f}); training position RMS {mm(cal.nominal_position_rms)} → "
              f"{mm(cal.train_position_rms)} mm over {cal.rows} tracked rows.", ""]
    wall = gap_info.get("wall")
    start = gap_info.get("start", "nominal")
    lines.append(f"**Extended model** ({gap_info['source']}"
                 + (f"; wall time {wall:.0f} s = {wall / 60:.1f} min" if wall is not None else "") + "): "
                 + (f"decision `{gap_info['effect']}`. " if gap_info.get("effect") else "")
                 + (f"effects added to the {start} model: "
                    + "; ".join(f"`{k}` ({fmt_params(v)})" for k, v in
                                                                       named.items())
                    if named else f"no effect added (the extended model is the {start} model)") + ".")
    if gap_info.get("why"):
        lines += ["", f"gap's reason: {gap_info['why']}"]
    if named.keys() & {"wheel_radius", "wheel_geometry"}:
        d_ext, L_ext = model_geometry(extended)
        rel_d = np.max(np.abs(d_ext / cal.diameters - 1))
        rel_L = abs(L_ext / cal.L - 1)
        d_txt = ", ".join(f"{1000 * d:.2f}" for d in d_ext)
        lines += ["", f"Effective geometry of the extended model: D = {d_txt} mm, "
                      f"L = {1000 * L_ext:.2f} mm; against the kinematic fit: max |ΔD/D| {100 * rel_d:.2f} %, "
                      f"|ΔL/L| {100 * rel_L:.2f} % (goal: within 1 %: "
                      f"**{'met' if max(rel_d, rel_L) <= 0.01 else 'not met'}**)."]
    lines += ["", f"## Mass and inertia (not published) on {mass_session.name}", "",
              "Mass and yaw inertia scaled together (the import's I = 0.5·m·L²) in every simulated model; the models "
              "are not refitted. Mean position RMS [mm]:", "",
              "| mass, inertia | nominal (sim) | kinematic | kinematic (sim) | extended (sim) | extended / kinematic |",
              "|---|---|---|---|---|---|"]
    for f in sorted(mass_rms):
        d = {m: float(np.mean(v)) for m, v in mass_rms[f].items()}
        lines.append(f"| ×{f:g} ({nominal.robot.mass * f:g} kg) | {mm(d['nominal'])} | {mm(d['kinematic'])} | "
                     f"{mm(d['kinematic_sim'])} | {mm(d['extended'])} | {d['extended'] / d['kinematic']:.2f} |")
    lines += ["", "## What is left: where, when, which wheel", "",
              "Per held-out session: a kinematic calibration fitted on that session itself (in-sample, an oracle no "
              "model trained elsewhere can have) and its position RMS, the floor for any fixed kinematic model "
              "there; the extended model's position error at 25/50/75/100 % of the run (mean over runs); its RMS "
              "heading error and the mean distance driven.", "",
              "| held-out session | oracle D [mm] | oracle L [mm] | oracle RMS | extended error at 25/50/75/100 % "
              "[mm] | heading RMS [mrad] | distance [m] |", "|---|---|---|---|---|---|---|"]
    for s in sessions:
        a = left[s.name]
        lines.append(f"| {s.name} | {', '.join(f'{1000 * d:.2f}' for d in a['oracle_D'])} | "
                     f"{1000 * a['oracle_L']:.2f} | {mm(a['oracle_rms'])} | "
                     f"{' / '.join(mm(g) for g in a['growth'])} | {1000 * a['heading_rms']:.1f} | "
                     f"{a['distance']:.1f} |")
    lines += ["", f"Training calibration for comparison: D = {', '.join(f'{1000 * d:.2f}' for d in cal.diameters)} mm, "
                  f"L = {1000 * cal.L:.2f} mm."]
    h = gap_info.get("heldout") or {}
    if h.get("per_session"):
        names = list(h["mean"]["mean_position_rms"])
        lines += ["", f"## gap's own held-out check (training sessions, folds by {h.get('folds_by')})", "",
                  "Each training session replayed whole, open loop, by the models gap fitted without it (the kinematic "
                  "calibration too); mean position RMS [mm]. " + (h.get("drift_check") or {}).get("rule", ""), "",
                  "| fold session | runs | " + " | ".join(names) + " | extended / kinematic |",
                  "|---|---|" + "---|" * (len(names) + 1)]
        for b in [*h["per_session"], {**h["mean"], "session": "all"}]:
            m = b["mean_position_rms"]
            ratio = f"{m['extended'] / m['kinematic']:.2f}" if m.get("kinematic") else "-"
            lines.append(f"| {b['session']} | {b['runs']} | " + " | ".join(mm(m[n]) for n in names) + f" | {ratio} |")
    lines += ["", f"![held-out runs]({stem}.png)", "",
              "Error growth: mean position error [mm] against time since each run's start (1 s bins, mean over the "
              "session's runs), per held-out session:", "", f"![error growth]({stem}_growth.png)", ""]
    return "\n".join(lines)


GROWTH_BIN = 1.0  # s: error-growth bins


def error_growth(sessions: list[Session], pred: dict) -> dict:
    """Per held-out session and model: [[t [s], mean position error [m]], …] in GROWTH_BIN bins of the time
    since each run's start (mean over the runs that reach the bin)."""
    out: dict = {}
    for s in sessions:
        per: dict[str, dict[int, list[float]]] = {m: {} for m in MODELS}
        for r in s.runs:
            ok = r.observed
            bins = (r.t[ok] // GROWTH_BIN).astype(int)
            for m, p in pred[(s.name, r.name)].items():
                e = np.hypot(*(r.pose[ok, :2] - p[ok, :2]).T)
                for b in np.unique(bins):
                    per[m].setdefault(int(b), []).append(float(np.mean(e[bins == b])))
        out[s.name] = {m: [[(b + 0.5) * GROWTH_BIN, float(np.mean(v))] for b, v in sorted(c.items())]
                       for m, c in per.items() if c}
    return out


def growth_plot(out: Path, stem: str, robot: Robot, growth: dict) -> Path:
    """``{stem}_growth.png``: mean position error against time, one panel per held-out session."""
    return plot_growth(growth, f"{robot.title}: error growth on the held-out sessions, whole runs open loop",
                       out / f"{stem}_growth.png")


GROWTH_STYLE = {"nominal": ("tab:gray", ":"), "kinematic": ("tab:blue", "--"), "kinematic_sim": ("tab:cyan", "-."),
                "extended": ("tab:green", "-")}  # model -> (colour, line style)


def plot_growth(growth: dict, title: str, path: Path) -> Path:
    """Mean position error [mm] against time since each run's start [s], one panel per held-out session:
    ``growth`` maps session -> model -> [(t, error [m]), ...] (also used by ``heldout_sessions.py``)."""
    n = len(growth)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.2), squeeze=False)
    for ax, (name, curves) in zip(axes[0], growth.items(), strict=True):
        for m, pts in curves.items():
            a = np.array(pts)
            ax.plot(a[:, 0], 1e3 * a[:, 1], GROWTH_STYLE[m][1], color=GROWTH_STYLE[m][0], label=m)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("time since start [s]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("mean position error [mm]")
    axes[0][0].legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_summary(out: Path) -> Path:
    """``out/real_optiodom.md``: one row per held-out session of every robot whose ``real_optiodom_<robot>.json``
    is in ``out`` (mean position RMS [mm] per model, extended / kinematic, gap's wall time, the command)."""
    lines = ["# Real OptiOdom logs, both robots: extended model vs kinematic calibration", "",
             "Per held-out session: mean over its runs of the whole-run position RMS [mm] (open-loop replay from the "
             "start pose with the measured wheel speeds, Euclidean x, y error against motion capture: what "
             "`omni-gym score` computes). Every model is fitted on that robot's training sessions only: nominal "
             "(metadata geometry, simulated), kinematic calibration (dead reckoning), gap's extended model "
             "(simulated; gap starts from the model the column says: the nominal one, or the kinematic calibration's "
             "with its wheel diameters and size kept). Details, per-run values and plots: one file per robot, "
             "linked below.", "",
             "| robot | held-out session | runs | nominal | kinematic | extended | extended / kinematic | "
             "gap starts from | gap wall time |", "|---|---|---|---|---|---|---|---|---|"]
    commands = []
    found = []
    for name, variant in [(r, v) for r in sorted(ROBOTS) for v in ("", "_from_kinematic")]:
        path = out / f"real_optiodom_{name}{variant}.json"
        if not path.exists():
            continue
        rec = json.loads(path.read_text())
        found.append((name, variant))
        wall = rec["gap"].get("wall")
        wall_txt = "–" if wall is None else f"{wall:.0f} s ({wall / 60:.1f} min)"
        if rec["gap"].get("source", "").find("reused") >= 0:
            wall_txt += " (reused record)"
        quick = " **(--quick smoke test: not a result)**" if rec.get("quick") else ""
        for sname, d in rec["heldout"].items():
            m = {k: float(np.mean(v)) for k, v in d.items()}
            lines.append(f"| {name} | {sname} | {len(d['nominal'])} | {mm(m['nominal'])} | {mm(m['kinematic'])} | "
                         f"{mm(m['extended'])} | {m['extended'] / m['kinematic']:.3f} | "
                         f"{rec['gap'].get('start') or 'nominal'} | {wall_txt}{quick} |")
        commands.append(f"- {name}, gap from the {rec['gap'].get('start') or 'nominal'} model: `{rec['command']}`; "
                        + (f"gap run by `{rec['gap']['command']}`; " if rec["gap"].get("command") else "")
                        + f"extended model: {rec['gap'].get('source', '–')}")
    lines += ["", "Commands (what made each robot's files):", ""] + commands + [""]
    for name, variant in found:
        stem = f"real_optiodom_{name}{variant}"
        lines += [f"- {ROBOTS[name].title}" + (", gap from the kinematic calibration" if variant else "")
                  + f": [{stem}.md]({stem}.md)", "", f"![{stem}]({stem}.png)", ""]
    path = out / "real_optiodom.md"
    path.write_text("\n".join(lines) + "\n")
    return path


if __name__ == "__main__":
    sys.exit(main())
