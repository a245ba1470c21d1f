"""What the linear wheel-to-twist map captures that the calibration with its tracked frame does not.

Per robot, on the training sessions of ``benchmarks/real_optiodom.py`` (the importer's defaults: the tracker's
clock): the kinematic calibration with the tracked frame (``calibrate(..., tracker=True)``) and the free linear
map (``fit_linear_map``), both fitted by whole-run dead reckoning against the tracker. The calibration's own
map from wheel travel to the tracked frame's displacement is A_cal = R(−ψ)·T(o)·W⁺ (W⁺ the pseudo-inverse of
the calibrated wheel matrix, T(o) the tracked point's lever, R(−ψ) the frame's yaw). Reported:

* the map's extra coupling in the tracked frame, A_lin·pinv(A_cal) − I (restricted to the wheel combinations
  that move an ideal robot): per cent-level scale and shear terms are what a per-wheel mounting error makes;
* for four wheels, what the map does with the one wheel combination that moves an ideal mecanum robot not at
  all (n with nᵀW = 0, the wheels "fighting"): A_lin·n, displacement per radian of that combination.

    python benchmarks/linear_map_coupling.py --out benchmarks/results/linear_map_coupling.md
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from real_optiodom import ROBOTS  # noqa: E402  (the benchmark's own split of sessions)

from omni_gym.discrepancy.data.importers.optiodom import nominal_model, read_sessions  # noqa: E402
from omni_gym.discrepancy.fit.kinematic_calibration import calibrate  # noqa: E402
from omni_gym.discrepancy.fit.linear_map import fit_linear_map  # noqa: E402
from omni_gym.record_paths import record_args  # noqa: E402


def frame_map(cal) -> np.ndarray:
    """A_cal (3, n): wheel travel [rad] → displacement of the tracked point in the tracked frame."""
    o, psi = np.asarray(cal.tracker["offset"]), float(cal.tracker["yaw"])
    lever = np.array([[1.0, 0.0, -o[1]], [0.0, 1.0, o[0]], [0.0, 0.0, 1.0]])
    turn = np.array([[np.cos(psi), np.sin(psi), 0.0], [-np.sin(psi), np.cos(psi), 0.0], [0.0, 0.0, 1.0]])
    return turn @ lever @ np.linalg.pinv(cal.geometry.wheel_matrix())


def matrix(m: np.ndarray, digits: int = 4) -> str:
    return "[" + "; ".join(" ".join(f"{v:+.{digits}f}" for v in row) for row in m) + "]"


def robot_lines(name: str) -> list[str]:
    robot = ROBOTS[name]
    metas, runs = read_sessions([robot.data / s for s in robot.train])
    nominal = nominal_model(metas[0])
    cal = calibrate(runs, nominal, tracker=True)
    lin = fit_linear_map(runs, nominal).matrix
    a_cal = frame_map(cal)
    W = cal.geometry.wheel_matrix()
    lines = [f"## {name} ({len(runs)} training runs)", "",
             f"Calibration with its tracked frame: D = {', '.join(f'{1e3 * d:.2f}' for d in cal.diameters)} mm, "
             f"{cal.size_name} = {1e3 * cal.L:.2f} mm, offset ({1e3 * cal.tracker['offset'][0]:.1f}, "
             f"{1e3 * cal.tracker['offset'][1]:.1f}) mm, yaw {1e3 * cal.tracker['yaw']:.1f} mrad; training position "
             f"RMS {1e3 * cal.train_position_rms:.1f} mm.", ""]
    project = np.eye(W.shape[0])
    if W.shape[0] > 3:
        null = np.linalg.svd(W)[0][:, -1]
        null = null * np.sign(null[0])
        project = project - np.outer(null, null)
        moved = lin @ null
        lines += [f"The wheel combination an ideal robot does not move with: n = {matrix(null[None, :], 3)} "
                  f"(nᵀW = 0). The linear map moves the tracked frame by ({moved[0]:+.4f} m, {moved[1]:+.4f} m, "
                  f"{moved[2]:+.4f} rad) per radian of it; its rows for the combinations that move an ideal robot "
                  f"are {matrix(np.linalg.norm(lin @ project, axis=1)[None, :], 4)} in norm.", ""]
    coupling = (lin @ project) @ np.linalg.pinv(a_cal) - np.eye(3)
    lines += ["Extra coupling of the linear map in the tracked frame, A_lin·pinv(A_cal) − I (rows: x [m], y [m], "
              "heading [rad]; columns: per m of x, per m of y, per rad of heading):", "",
              "```", matrix(coupling), "```", ""]
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=sorted(ROBOTS))
    parser.add_argument("--out", type=Path, default=None, help="markdown report")
    args = parser.parse_args(argv)
    t0 = time.monotonic()
    body = [line for name in args.robots for line in robot_lines(name)]
    recorded = record_args(argv if argv is not None else sys.argv[1:])
    command = "python benchmarks/linear_map_coupling.py" + ("" if argv is None and len(sys.argv) == 1 else " " +
                                                             " ".join(recorded))
    text = "\n".join(["# What the linear map captures beyond the calibration with its tracked frame", "",
                      f"`{command}` ({time.monotonic() - t0:.0f} s on 2 cores).", "", *body])
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
