"""Maximum force before sliding vs robot orientation, after Williams et al. (2002), Fig. 8.

For the williams2002 robot on every surface of ``omni_gym.physics.friction.SURFACES`` (paper and carpet of
Table I, and the high-friction ``grip`` reference surface), compute the largest force
F_max [N] at the centre of mass along world +x that friction can hold, as the robot's orientation θ
sweeps one symmetry period 2π/3 of a three-wheeled robot. Two contact cases per surface:

* rollers: every wheel touches the floor with a roller (μ'_W along the drive, μ'_T along the axle);
* gap: every wheel touches with the rigid material between rollers (μ'' both ways).

Loads are equal, m·g/3 per wheel, as in the paper. Writes DIR/max_force.md and DIR/max_force.png.

    .venv/bin/python benchmarks/max_force.py [--out benchmarks/results] [--quick]

``make demo`` runs it with ``--out out/demo`` (untracked). ``--quick`` (tests) plots 25 points, not 241.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless: only files are written
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from omni_gym.analysis.max_force import max_force_curve, static_loads  # noqa: E402
from omni_gym.physics.friction import SURFACES  # noqa: E402
from omni_gym.physics.robot import williams2002  # noqa: E402
from omni_gym.record_paths import record_args

PERIOD = 2 * math.pi / 3  # rad, symmetry period of a regular three-wheeled robot
TABLE_POINTS = 13  # every 10°
PLOT_POINTS = 241  # every 0.5°
QUICK_POINTS = 25  # every 5°, --quick


def compute(thetas: np.ndarray, loads: np.ndarray | None = None) -> dict[tuple[str, str], np.ndarray]:
    """F_max [N] at each θ [rad] for (surface, contact) in SURFACES × {rollers, gap}."""
    robot = williams2002()
    all_gap = np.ones(robot.n_wheels, dtype=bool)
    out = {}
    for name, surface in SURFACES.items():
        out[(name, "rollers")] = max_force_curve(robot, surface, thetas, loads=loads)
        out[(name, "gap")] = max_force_curve(robot, surface, thetas, on_gap=all_gap, loads=loads)
    return out


def markdown(command: str, thetas: np.ndarray, curves: dict, extremes: dict, static: dict,
             static_n: np.ndarray) -> str:
    keys = list(curves)
    lines = [
        "# Maximum force before sliding (Williams et al. 2002, Sec. IV-B, Fig. 8)",
        "",
        f"Produced by: `{command}`",
        "",
        "Robot `williams2002` (m = 2 kg, equal loads m·g/3), push at the centre of mass along world +x,",
        "robot orientation θ over one three-wheel period [0, 2π/3]. F_max in N.",
        "*rollers*: every wheel on a roller (μ'_W, μ'_T); *gap*: every wheel on the rigid material (μ'').",
        "",
        "| θ [rad] | θ [deg] | " + " | ".join(f"{s} {c}" for s, c in keys) + " |",
        "|---:|---:|" + "---:|" * len(keys),
    ]
    for i, th in enumerate(thetas):
        cells = " | ".join(f"{curves[k][i]:.3f}" for k in keys)
        lines.append(f"| {th:.3f} | {math.degrees(th):.0f} | {cells} |")
    grid = len(next(iter(extremes.values())))
    lines += ["", f"Min / max over θ ∈ [0, 2π/3] on a {grid}-point grid. The layout is not three-fold",
              "symmetric, but F(θ) = F(−θ) (mirror symmetry about the body y axis) and F(θ) = F(θ + π)",
              "(the friction boxes are symmetric), so [0, π/2] ⊂ [0, 2π/3] already covers a full turn:", ""]
    lines += [f"- {s} {c}: {v.min():.3f} / {v.max():.3f} N" for (s, c), v in extremes.items()]
    loads = ", ".join(f"{n:.2f}" for n in static_n)
    lines += ["", "Equal loads do not balance the weight about the com of this layout (the wheel centroid is",
              f"off the origin). With loads that do (`static_loads`: {loads} N, wheels 1-3), min / max:", ""]
    lines += [f"- {s} {c}: {v.min():.3f} / {v.max():.3f} N" for (s, c), v in static.items()]
    return "\n".join(lines) + "\n"


def surface_colours(names: list[str]) -> dict[str, str]:
    """One colour per surface: paper and carpet keep their historical blue and red, others take the next
    tab10 colours (so a surface added to SURFACES is plotted rather than raising a KeyError)."""
    fixed = {"paper": "tab:blue", "carpet": "tab:red"}
    spare = iter(c for c in ("tab:green", "tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive",
                             "tab:cyan", "tab:gray") if c not in fixed.values())
    return {n: fixed.get(n) or next(spare, "k") for n in names}


def plot(path: Path, thetas: np.ndarray, curves: dict) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    colours = surface_colours(sorted({s for s, _ in curves}))
    for (s, c), v in curves.items():
        ax.plot(thetas, v, color=colours[s], linestyle="-" if c == "rollers" else "--",
                label=f"{s}, {'rollers' if c == 'rollers' else 'all wheels on gap'}")
    ax.set_xlim(0, PERIOD)
    ax.set_ylim(bottom=0)
    ax.set_xticks(np.linspace(0, PERIOD, 5))
    ax.set_xticklabels(["0", "π/6", "π/3", "π/2", "2π/3"])
    ax.set_xlabel("robot orientation θ [rad]")
    ax.set_ylabel("F_max [N]")
    ax.set_title("Maximum force before sliding vs. robot orientation\n(williams2002, push along world x)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results"), help="output directory")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_POINTS} plot points, not {PLOT_POINTS} (tests)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    command = shlex.join([".venv/bin/python", "benchmarks/max_force.py", *record_args(sys.argv[1:])])

    table_thetas = np.linspace(0.0, PERIOD, TABLE_POINTS)
    points = QUICK_POINTS if args.quick else PLOT_POINTS
    plot_thetas = np.linspace(0.0, PERIOD, points)
    fine = compute(plot_thetas)
    static_n = static_loads(williams2002())
    text = markdown(command, table_thetas, compute(table_thetas), fine, compute(plot_thetas, static_n), static_n)
    (args.out / "max_force.md").write_text(text)
    plot(args.out / "max_force.png", plot_thetas, fine)
    print(text)
    print(f"wrote {args.out / 'max_force.md'} and {args.out / 'max_force.png'}")


if __name__ == "__main__":
    main()
