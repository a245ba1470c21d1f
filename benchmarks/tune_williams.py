"""Choose the Williams robot's undocumented parameters toward the paper's own simulation results.

Our copy of Williams et al. (2002) lost the front-wheel angle δ and the maneuver duration. This
script fits both so that our simulation of the paper's maneuver reproduces the seven figures the
paper reports for its simulations (initial/paper: x short 14 mm, y drift 9 mm, heading 0.016 rad;
roller_gap/paper: 53 mm, 22 mm, 0.111 rad; roller_gap/carpet: heading 0.558 rad). The loss is the sum
of squared log ratios of magnitudes, plus a penalty unless the robot stays drivable along x on carpet
(:func:`drivable_penalty`). L, r, m and I stay at their documented assumptions.

    python benchmarks/tune_williams.py --out benchmarks/results
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from tqdm import tqdm

import omni_gym.physics.robot as robots
from omni_gym.physics.friction import SURFACES
from omni_gym.physics.model import SimModel

sys.path.insert(0, str(Path(__file__).resolve().parent))
from paper_maneuver import PAPER, run_maneuver, summary  # noqa: E402


def williams_with(delta_deg: float) -> robots.RobotSpec:
    delta = math.radians(delta_deg)
    wheels = robots.tangential_wheels(robots.WILLIAMS_L, [delta, math.pi - delta, -math.pi / 2])
    return robots.williams2002().with_changes(wheels=wheels)


def simulate_all(delta_deg: float, duration: float) -> dict[tuple[str, str], dict[str, float]]:
    robot = williams_with(delta_deg)
    return {key: summary(run_maneuver(SimModel(robot, SURFACES[key[1]], key[0]), duration=duration))
            for key in PAPER}


MIN_TRAVEL_SHARE = 0.75  # of the 0.4 m, initial friction on carpet: the robot must be drivable along x


def drivable_penalty(delta_deg: float, duration: float) -> float:
    """Penalty unless the robot covers ≥ 75 % of the maneuver with the initial model on carpet.

    Our assumption, not the paper's number: a RoboCup robot can be driven in every direction on its
    field. Without it the fit runs to small δ, where the front wheels' transverse friction on carpet
    (2·μ'_T·N) exceeds what the rear wheel alone can push (μ'_W·N) and the robot barely moves along x.
    """
    result = summary(run_maneuver(SimModel(williams_with(delta_deg), SURFACES["carpet"], "initial"),
                                  duration=duration))
    shortfall = result["x_short_mm"] / 400.0 - (1.0 - MIN_TRAVEL_SHARE)
    return 10.0 * max(shortfall, 0.0) / (1.0 - MIN_TRAVEL_SHARE)


def loss(delta_deg: float, duration: float) -> float:
    sims = simulate_all(delta_deg, duration)
    total = drivable_penalty(delta_deg, duration)
    for key, target in PAPER.items():
        for name, value in target.items():
            total += math.log(max(abs(sims[key][name]), 1e-6) / value) ** 2
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    args = parser.parse_args()
    grid = [(d, T) for d in np.arange(5.0, 61.0, 5.0) for T in (2.0, 3.0, 4.0, 5.0, 6.0)]
    scores = [(loss(d, T), d, T) for d, T in tqdm(grid, desc="grid")]
    best = min(scores)
    res = minimize(lambda p: loss(p[0], p[1]), x0=[best[1], best[2]], method="Nelder-Mead",
                   options={"xatol": 0.2, "fatol": 1e-3, "maxfev": 60})
    delta, duration = float(res.x[0]), float(res.x[1])
    sims = simulate_all(delta, duration)
    travel = 0.4 - summary(run_maneuver(SimModel(williams_with(delta), SURFACES["carpet"], "initial"),
                                        duration=duration))["x_short_mm"] / 1e3
    lines = ["# Tuning the Williams robot toward the paper's simulation results", "",
             "`python benchmarks/tune_williams.py --out benchmarks/results`", "",
             f"Grid best: δ = {best[1]:.0f}°, duration = {best[2]:.1f} s, loss {best[0]:.3f}.",
             f"Refined (Nelder–Mead): **δ = {delta:.1f}°, duration = {duration:.2f} s**, loss {res.fun:.3f}.",
             f"Constraint: initial friction on carpet covers ≥ {MIN_TRAVEL_SHARE:.0%} of 0.4 m "
             f"(at the optimum: {travel:.3f} m).", "",
             "| model / surface | quantity | paper | ours |", "|---|---|---|---|"]
    for key, target in PAPER.items():
        for name, value in target.items():
            lines.append(f"| {key[0]} / {key[1]} | {name} | {value:g} | {sims[key][name]:+.3f} |")
    text = "\n".join(lines) + "\n"
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (Path(args.out) / "tuning.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
