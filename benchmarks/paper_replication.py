"""Replicate the maneuver of Williams et al. (2002): `initial` vs `roller_gap` on `paper` and `carpet`.

    python benchmarks/paper_replication.py [--out benchmarks/results] [--quick]

``make demo`` runs it with ``--out out/demo`` (untracked); the committed ``benchmarks/results`` files
come from the command above. ``--quick`` (tests) runs only the two cases on paper.

Prints a side-by-side table with the paper's reported figures, writes it to
``paper_replication.md`` and saves plots in the style of the paper's Figs. 6 and 9 (displacements
and wheel slip speeds against time) and Figs. 7 and 10 (y against x).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from paper_maneuver import PAPER, PAPER_CARPET_MEASURED, PAPER_DURATION, run_maneuver, summary  # noqa: E402

from omni_gym.physics.model import load_model  # noqa: E402

CASES = [("initial", "paper"), ("roller_gap", "paper"), ("initial", "carpet"), ("roller_gap", "carpet")]


def fmt(value: float | None, spec: str) -> str:
    return "–" if value is None else format(value, spec)


def table(results: dict) -> str:
    lines = [
        "# Paper replication: Williams et al. (2002), 0.4 m along +x",
        "",
        "`python benchmarks/paper_replication.py --out benchmarks/results` (also run by `make demo`)",
        "",
        f"Robot `williams2002` (δ, maneuver duration {PAPER_DURATION} s: fitted, see `tuning.md`), "
        "ideal velocity-source wheels, default physics (0.5 ms substeps). Ours: signed final values "
        "(y > 0 is left, heading > 0 is counter-clockwise); the paper gives magnitudes.",
        "",
        "| friction / surface | x short [mm] ours | paper | y drift [mm] ours | paper | heading [rad] ours | paper |",
        "|---|---|---|---|---|---|---|",
    ]
    for case in (c for c in CASES if c in results):
        s = summary(results[case])
        p = PAPER.get(case, {})
        lines.append(
            f"| {case[0]} / {case[1]} | {s['x_short_mm']:.1f} | {fmt(p.get('x_short_mm'), 'g')} | "
            f"{s['y_drift_mm']:+.1f} | {fmt(p.get('y_drift_mm'), 'g')} | {s['heading_rad']:+.3f} | "
            f"{fmt(p.get('heading_rad'), 'g')} |")
    measured = ", ".join(f"{v:g}" for v in PAPER_CARPET_MEASURED)
    lines += ["", f"Measured on the real robot on carpet (final heading, three trials): {measured} rad; the paper's "
              "roller_gap simulation gave 0.558 rad."]
    return "\n".join(lines) + "\n"


def plot_time_series(results: dict, out: Path) -> None:
    for case in (c for c in CASES if c in results):
        r = results[case]
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        ax1.plot(r["t"], r["pose"][:, 0], label="x [m]")
        ax1.plot(r["t"], r["pose"][:, 1], label="y [m]")
        ax1.plot(r["t"], r["pose"][:, 2], label="θ [rad]")
        ax1.set_ylabel("displacement")
        ax1.legend(loc="upper left")
        ax1.grid(alpha=0.3)
        ax1.set_title(f"{case[0]} friction on {case[1]}: (a) Cartesian displacements")
        for i in range(r["slip"].shape[1]):
            ax2.plot(r["t"], r["slip"][:, i], label=f"v_W{i + 1}")
        ax2.set_ylabel("slip speed [m/s]")
        ax2.set_xlabel("t [s]")
        ax2.set_title("(b) wheel sliding speeds along the drive direction")
        ax2.legend(loc="upper right")
        ax2.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(out / f"paper_{case[0]}_{case[1]}.png", dpi=100)
        plt.close(fig)


def plot_paths(results: dict, out: Path) -> None:
    surfaces = [s for s in ("paper", "carpet") if any(case[1] == s for case in results)]
    fig, axes = plt.subplots(1, len(surfaces), figsize=(5 * len(surfaces), 4), squeeze=False)
    for ax, surface in zip(axes[0], surfaces, strict=True):
        for friction, style in (("initial", "--"), ("roller_gap", "-")):
            pose = results[(friction, surface)]["pose"]
            ax.plot(pose[:, 0], pose[:, 1], style, label=f"{friction} (simulated)")
        ax.plot([0, 0.4], [0, 0], ":", color="grey", label="commanded")
        ax.set_title(f"y against x on {surface} (cf. Figs. 7 and 10)")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "paper_paths.png", dpi=100)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results", help="folder for the table and plots")
    parser.add_argument("--quick", action="store_true", help="only the two cases on paper (tests)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cases = [c for c in CASES if c[1] == "paper"] if args.quick else CASES
    results = {case: run_maneuver(load_model("williams2002", case[1], case[0])) for case in cases}
    text = table(results)
    (out / "paper_replication.md").write_text(text)
    print(text)
    plot_time_series(results, out)
    plot_paths(results, out)
    print(f"plots written to {out}/paper_*.png")


if __name__ == "__main__":
    main()
