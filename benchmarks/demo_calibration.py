"""Real logs in, a calibrated simulator out: the demo of omni-gym's calibration path on both bundled robots.

For each robot of the bundled OptiOdom data (``data/optiodom-omni3``, three omni wheels;
``data/optiodom-omni4``, four mecanum wheels) this does what ``omni-gym import optiodom`` +
``omni-gym calibrate`` + ``omni-gym score`` do from the command line:

1. read the robot's training sessions and one held-out session from another recording;
2. fit the kinematic calibration (effective wheel diameters and the robot's length) on the training runs;
3. replay every held-out run open loop, from its start pose with its measured wheel speeds, with the
   nominal model (the metadata's geometry) and with the calibrated one, and compare with motion capture.

Writes into ``--out`` (default ``out/demo/``, untracked): ``calibration.md`` (position RMS per robot, nominal
vs calibrated, on held-out runs) and ``calibration_<robot>.png`` (measured, nominal and calibrated paths of
one held-out run, and the position error against time). Usage::

    python benchmarks/demo_calibration.py [--out out/demo] [--quick]

``--quick`` fits on every third training run and replays only the first 20 s of one held-out run (a smoke
test of the pipeline; its numbers are not a result). ``benchmarks/real_optiodom.py`` is the full study:
every held-out session of both robots, hand-driven runs included, where the calibration helps less.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from real_optiodom import cut  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

from omni_gym.discrepancy.data.dataset import Dataset  # noqa: E402
from omni_gym.discrepancy.data.importers.optiodom import nominal_model, read_sessions  # noqa: E402
from omni_gym.discrepancy.decide.score import score_models  # noqa: E402
from omni_gym.discrepancy.fit.kinematic_calibration import calibrate  # noqa: E402
from omni_gym.outputs import write_text_atomic  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"


@dataclass(frozen=True)
class RobotCase:
    """One bundled robot: its data folder, training sessions and the held-out session shown."""

    name: str
    folder: str
    train: tuple[str, ...]
    heldout: str
    what: str


CASES = (
    RobotCase("omni3", "optiodom-omni3", ("circular/221220201701", "square/221220201953"),
              "circular/221220201643", "three omni wheels; held out: circles from another session"),
    RobotCase("omni4", "optiodom-omni4", ("circular/080920201015", "square/080920201810"),
              "circular/231220200502", "four mecanum wheels; held out: circles recorded on another day"),
)
QUICK_HELDOUT = 20.0  # s, --quick replay length


@dataclass
class CaseResult:
    case: RobotCase
    train_runs: int
    heldout_runs: int
    nominal_rms: float  # m, mean over held-out runs
    calibrated_rms: float  # m
    fitted: str
    seconds: float


def run_case(case: RobotCase, out: Path, quick: bool) -> CaseResult:
    start = time.perf_counter()
    root = DATA / case.folder
    metas, train = read_sessions([root / s for s in case.train])
    held_metas, held = read_sessions([root / case.heldout])
    if quick:  # every third training run (both path families stay in), 20 s of one held-out run
        train = train[::3]
        held = [cut(held[0], QUICK_HELDOUT)]
    nominal = nominal_model(held_metas[0])  # the held-out session's own metadata (Li, Di)
    cal = calibrate(train, nominal_model(metas[0]))
    calibrated = cal.model
    ds = Dataset(path=root / case.heldout, model=nominal, model_json=nominal.to_json(), description=case.what,
                 runs=held)
    scores = score_models(ds, {"nominal": nominal, "calibrated": calibrated})
    rms = {m: float(np.mean([s.position_rms for s in scores if s.model == m])) for m in ("nominal", "calibrated")}
    _plot(case, ds, nominal, calibrated, out)
    fitted = (f"D = [{', '.join(f'{1e3 * d:.2f}' for d in cal.diameters)}] mm, "
              f"{cal.size_name} = {1e3 * cal.L:.1f} mm")
    return CaseResult(case, len(train), len(held), rms["nominal"], rms["calibrated"], fitted,
                      time.perf_counter() - start)


def _plot(case: RobotCase, ds: Dataset, nominal, calibrated, out: Path) -> None:
    from omni_gym.discrepancy.replay.measurement import START_WINDOW
    from omni_gym.discrepancy.replay.simulate import Job, simulate_poses

    run = ds.runs[0]
    sim = simulate_poses([Job(nominal, run), Job(calibrated, run)], start_window=START_WINDOW)
    fig, (ax_path, ax_err) = plt.subplots(1, 2, figsize=(11, 4.6))
    ax_path.plot(run.pose[:, 0], run.pose[:, 1], color="black", lw=2, label="measured (motion capture)")
    for poses, label, colour in ((sim[0], "nominal model", "tab:red"), (sim[1], "calibrated model", "tab:blue")):
        ax_path.plot(poses[:, 0], poses[:, 1], color=colour, lw=1.2, label=label)
        err = np.hypot(*(poses[:, :2] - run.pose[:, :2]).T)
        ax_err.plot(run.t, 1e3 * err, color=colour, label=label)
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.set_xlabel("x [m]")
    ax_path.set_ylabel("y [m]")
    ax_path.set_title(f"{case.name}: held-out run {run.name}, open-loop replay")
    ax_path.legend(loc="best", fontsize=8)
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("position error [mm]")
    ax_err.set_ylim(bottom=0)
    ax_err.set_title("distance from the measured pose")
    ax_err.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / f"calibration_{case.name}.png", dpi=100)
    plt.close(fig)


def markdown(results: list[CaseResult], quick: bool, argv: list[str]) -> str:
    lines = [
        "# Real logs in, a calibrated simulator out",
        "",
        f"`python benchmarks/demo_calibration.py {' '.join(argv)}`".replace("  ", " "),
        "",
        "Kinematic calibration fitted on each robot's training sessions, scored on a held-out session by open-loop "
        "replay of its measured wheel speeds (mean position RMS against motion capture over the held-out runs)."
        + (" **--quick: shortened runs, a smoke test, not a result.**" if quick else ""),
        "",
        "| robot | training runs | held-out session | held-out runs | nominal [mm] | calibrated [mm] | ratio "
        "| fitted |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(f"| {r.case.name} ({r.case.what}) | {r.train_runs} | `{r.case.heldout}` | {r.heldout_runs} | "
                     f"{1e3 * r.nominal_rms:.1f} | {1e3 * r.calibrated_rms:.1f} | "
                     f"{r.calibrated_rms / r.nominal_rms:.2f} | {r.fitted} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="out/demo", help="output folder (default out/demo, untracked)")
    parser.add_argument("--quick", action="store_true", help="shortened runs: a smoke test of the pipeline")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for case in CASES:
        print(f"calibrating {case.name} on {', '.join(case.train)} ...", file=sys.stderr, flush=True)
        r = run_case(case, out, args.quick)
        print(f"{case.name}: held-out position RMS {1e3 * r.nominal_rms:.1f} mm nominal -> "
              f"{1e3 * r.calibrated_rms:.1f} mm calibrated ({r.seconds:.0f} s)", flush=True)
        results.append(r)
    shown = list(argv if argv is not None else sys.argv[1:])
    write_text_atomic(out / "calibration.md", markdown(results, args.quick, shown))
    print(f"wrote {out / 'calibration.md'} and calibration_*.png", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
