"""Convergence study: world error against the independent reference, as a function of the substep.

    python benchmarks/convergence.py --out benchmarks/results

For three maneuvers of 2 s (step changes of body twist up to 0.4 m/s and 1.5 rad/s, then a stop) on
`williams2002` / carpet, both friction models, the world runs at substeps from 4 ms down to 0.125 ms
and is compared with `omni_gym.analysis.reference` (Radau, rtol 1e-10, exact roller/gap switching). Writes
``convergence.md`` (max position and heading errors) and ``convergence.png`` (log-log).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from omni_gym.analysis.reference import reference_trajectory  # noqa: E402
from omni_gym.physics.model import load_model  # noqa: E402
from omni_gym.physics.world import DEFAULT_DT, World  # noqa: E402

STEPS = [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4]
SAMPLE = 0.02  # s between compared samples (a multiple of every step below)
# Body twists (vx [m/s], vy [m/s], ω [rad/s]) held for 0.5 s each, then a stop.
MANEUVERS = {
    "translate": [(0.4, 0.0, 0.0), (0.0, 0.3, 0.0), (-0.2, 0.2, 0.0), (0.0, 0.0, 0.0)],
    "rotate": [(0.0, 0.0, 1.5), (0.0, 0.0, -1.0), (0.0, 0.0, 0.5), (0.0, 0.0, 0.0)],
    "combined": [(0.3, 0.1, 1.0), (0.1, -0.3, -1.5), (0.25, 0.25, 0.5), (0.0, 0.0, 0.0)],
}
SEGMENT = 0.5  # s


def commands_for(model, twists) -> tuple[np.ndarray, np.ndarray]:
    W = model.robot.wheel_matrix()
    times = np.arange(len(twists)) * SEGMENT
    return times, np.array([W @ np.asarray(tw) for tw in twists])


def run_world(model, times, commands, dt, t_eval) -> np.ndarray:
    world = World(model, dt=dt)
    poses = [world.pose[0]]
    ticks = np.rint(times / dt).astype(int)
    n_sample = int(round(SAMPLE / dt))
    k = 0
    total = int(round(t_eval[-1] / dt))
    seg = 0
    while k < total:
        while seg + 1 < len(ticks) and k >= ticks[seg + 1]:
            seg += 1
        world.set_commands(commands[seg])
        world.substeps(n_sample)
        k += n_sample
        poses.append(world.pose[0])
    return np.array(poses)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_eval = np.arange(0, 2.0 + 1e-9, SAMPLE)
    rows = []
    errors: dict[tuple[str, str], list[tuple[float, float]]] = {}
    jobs = [(f, name) for f in ("initial", "roller_gap") for name in MANEUVERS]
    for friction, name in tqdm(jobs, desc="maneuvers"):
        model = load_model("williams2002", "carpet", friction)
        times, commands = commands_for(model, MANEUVERS[name])
        ref = reference_trajectory(model, times, commands, t_eval)["pose"]
        for dt in STEPS:
            pose = run_world(model, times, commands, dt, t_eval)
            pos_err = np.max(np.hypot(pose[:, 0] - ref[:, 0], pose[:, 1] - ref[:, 1]))
            head_err = np.max(np.abs(pose[:, 2] - ref[:, 2]))
            errors.setdefault((friction, name), []).append((pos_err, head_err))
            rows.append((friction, name, dt, pos_err, head_err))
    lines = ["# Convergence: world against the independent reference (williams2002, carpet, 2 s)", "",
             "`python benchmarks/convergence.py --out benchmarks/results` (also `make bench`)", "",
             f"Default substep: {DEFAULT_DT * 1e3:g} ms. Goal: ≤ 1 mm position, ≤ 2 mrad heading.", "",
             "| friction | maneuver | dt [ms] | max position error [mm] | max heading error [mrad] |",
             "|---|---|---|---|---|"]
    for friction, name, dt, pe, he in rows:
        mark = " **(default)**" if dt == DEFAULT_DT else ""
        lines.append(f"| {friction} | {name} | {dt * 1e3:g}{mark} | {pe * 1e3:.3f} | {he * 1e3:.3f} |")
    text = "\n".join(lines) + "\n"
    (out / "convergence.md").write_text(text)
    print(text)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for (friction, name), errs in errors.items():
        e = np.array(errs)
        style = "-o" if friction == "initial" else "--s"
        ax1.loglog(np.array(STEPS) * 1e3, e[:, 0] * 1e3, style, label=f"{friction} {name}")
        ax2.loglog(np.array(STEPS) * 1e3, e[:, 1] * 1e3, style, label=f"{friction} {name}")
    for ax, goal, label in ((ax1, 1.0, "max position error [mm]"), (ax2, 2.0, "max heading error [mrad]")):
        ax.axhline(goal, color="red", lw=0.8, label="goal")
        ax.axvline(DEFAULT_DT * 1e3, color="grey", ls=":", label="default dt")
        ax.set_xlabel("substep dt [ms]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
    ax1.legend(fontsize=7)
    fig.suptitle("Error against the Radau reference: first-order convergence")
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=100)
    print(f"plot written to {out}/convergence.png")


if __name__ == "__main__":
    main()
