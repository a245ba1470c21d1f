"""The scenario of Phunopas & Inoue (2018): a four-wheeled robot on a quintic diagonal path with random contact cases.

The paper moves its four-wheeled omnidirectional robot along a fifth-order polynomial from (20, 20) to
(150, 150) with the heading going from 0 to 45°, while wheels randomly lose contact (its Table 2
cases), and compares planned, actual and estimated paths (its Figs. 5, 7 and 8).

Assumptions (the paper's numbers are not all usable as printed):

* Units: "20 → 150" is given without units; we read centimetres, i.e. (0.20, 0.20) m → (1.50, 1.50) m,
  a 1.84 m diagonal that fits a 2 m-half-size arena and matches a small indoor robot.
* Duration: the paper's 0.5 s would need a 6.9 m/s peak speed; we use 8 s of motion (peak speed
  15/8 · 1.84 m / 8 s = 0.43 m/s, inside the 0.6 m/s action limit and the carpet's traction) and hold
  the goal for 1 s more (9 s episodes, as the OmniGoToPose-v0 task does).
* Heading: 0 → π/4 rad along the same quintic time law.
* Robot and floor: the ``phunopas2018`` preset on carpet with roller-gap friction, random lift-off at
  0.5 /s with recovery at 5 /s (OmniGoToPose-v0's defaults), default sensor noise, ideal actuation.

The environment's goto task starts at the origin with a random goal, so this script swaps the
reference in: during ``env.reset`` the environment's reference sampler (``omni_gym.envs.core.draw_reference``)
is replaced by one returning this quintic sampled at the control rate, so the world, sensors and contact
process are reset at (0.20, 0.20, 0) exactly as for any episode. Nothing in the library changes.

Policies: ``open-loop`` (the paper's feed-forward wheel speeds, without its filter), with an EKF run
alongside that does not act (its estimate is the "estimated" path), and ``ekf-pid``. Over ``--episodes``
seeds (default 20, from ``--seed`` 20 000): mean and 95 % t-interval of the final position and heading
errors and of the tracking RMSE, written to ``phunopas_replication.md``; plots of the first seed:
``phunopas_fig5_path.png`` (x–y), ``phunopas_fig7_xy.png`` (x and y vs time), ``phunopas_fig8_heading.png``.
Usage::

    python benchmarks/phunopas_replication.py [--episodes 20] [--seed 20000] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import shlex
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import omni_gym.envs.core as core_module  # noqa: E402
from agents.ekf import EKFConfig, OmniEKF  # noqa: E402
from agents.evaluate import METRICS, mean_ci  # noqa: E402
from agents.policies import OpenLoopPolicy, make_policy  # noqa: E402
from agents.rollout import make_env, run_episode  # noqa: E402
from omni_gym.record_paths import record_args
from omni_gym.trajectories import Quintic  # noqa: E402

ENV_ID = "OmniGoToPose-v0"
START = (0.20, 0.20, 0.0)  # m, m, rad
GOAL = (1.50, 1.50, math.pi / 4)
MOTION_SECONDS = 8.0
HOLD_SECONDS = 1.0


def paper_reference(cfg, rng, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Stand-in for ``draw_reference``: the paper's quintic sampled at k / control_hz (no random draws)."""
    t = np.arange(n_samples) / cfg.control_hz
    pose, vel, _ = Quintic(np.array(START), np.array(GOAL), MOTION_SECONDS).sample(t)
    return pose, vel


@contextlib.contextmanager
def paper_path():
    """Make every env reset inside the block use :func:`paper_reference`."""
    original = core_module.draw_reference
    core_module.draw_reference = paper_reference
    try:
        yield
    finally:
        core_module.draw_reference = original


class OpenLoopWithObserver(OpenLoopPolicy):
    """Open-loop feed-forward; an EKF runs alongside on the same observations (it does not act)."""

    def __init__(self, env) -> None:
        super().__init__(env)
        self.ekf = OmniEKF(self.robot, EKFConfig.for_env(env))

    def _reset(self, s) -> None:
        self.ekf.reset(np.array(s.ref_pose, dtype=float))
        self.estimate = self.ekf.pose

    def _advance(self, s) -> None:
        self.ekf.process(s, self.dt)
        self.estimate = self.ekf.pose


def run(episodes: int, seed: int) -> dict:
    env = make_env(ENV_ID, {"episode_seconds": MOTION_SECONDS + HOLD_SECONDS})
    policies = {"open-loop": OpenLoopWithObserver(env), "ekf-pid": make_policy("ekf-pid", env)}
    out = {name: [] for name in policies}
    with paper_path():
        for i in tqdm(range(episodes), desc="Phunopas scenario", file=sys.stderr, unit="seed"):
            for name, pol in policies.items():
                ep = run_episode(env, pol, seed + i, record=True)
                assert np.allclose(ep.reference[0], START) and np.allclose(ep.pose[0], START)
                out[name].append(ep)
    env.close()
    return out


def shade_lift_off(ax, ep) -> None:
    """Grey bands where some wheel is off the floor."""
    lifted = ~ep.contact.all(axis=1)
    edges = np.flatnonzero(np.diff(np.r_[0, lifted.astype(int), 0]))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        ax.axvspan(ep.t[a], ep.t[min(b, len(ep.t) - 1)], color="0.85", lw=0)


def plots(out: Path, eps: dict) -> None:
    names = list(eps)
    first = {n: eps[n][0] for n in names}
    ref = first[names[0]].reference
    styles = {"planned": dict(color="k", ls="--", lw=1.5), "actual": dict(color="#d95f02", lw=1.5),
              "estimated": dict(color="#1b9e77", lw=1.2, ls="-.")}

    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    for ax, n in zip(axes, names, strict=True):
        ep = first[n]
        ax.plot(ref[:, 0], ref[:, 1], label="planned", **styles["planned"])
        ax.plot(ep.pose[:, 0], ep.pose[:, 1], label="actual", **styles["actual"])
        ax.plot(ep.estimate[:, 0], ep.estimate[:, 1], label="estimated (EKF)", **styles["estimated"])
        ax.plot(*START[:2], "ko", ms=4)
        ax.plot(*GOAL[:2], "k*", ms=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{n}: final error {ep.final_position_error * 100:.1f} cm")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left")
    fig.suptitle(f"Quintic path (0.2, 0.2) → (1.5, 1.5) m in {MOTION_SECONDS:g} s with random lift-off "
                 f"(cf. Phunopas & Inoue 2018, Fig. 5); seed {first[names[0]].seed}")
    fig.tight_layout()
    fig.savefig(out / "phunopas_fig5_path.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(2, 2, figsize=(12, 6.5), sharex=True)
    for j, n in enumerate(names):
        ep = first[n]
        for i, coord in enumerate("xy"):
            ax = axes[i, j]
            shade_lift_off(ax, ep)
            ax.plot(ep.t, ref[:, i], label="planned", **styles["planned"])
            ax.plot(ep.t, ep.pose[:, i], label="actual", **styles["actual"])
            ax.plot(ep.t, ep.estimate[:, i], label="estimated (EKF)", **styles["estimated"])
            ax.set_ylabel(f"{coord} [m]")
            ax.grid(alpha=0.3)
            if i == 0:
                ax.set_title(n)
        axes[1, j].set_xlabel("t [s]")
    axes[0, 0].legend(loc="upper left")
    fig.suptitle("x and y against time (cf. Fig. 7); grey: a wheel off the floor")
    fig.tight_layout()
    fig.savefig(out / "phunopas_fig7_xy.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(12, 4), sharey=True)
    for ax, n in zip(axes, names, strict=True):
        ep = first[n]
        shade_lift_off(ax, ep)
        ax.plot(ep.t, np.degrees(ref[:, 2]), label="planned", **styles["planned"])
        ax.plot(ep.t, np.degrees(np.unwrap(ep.pose[:, 2])), label="actual", **styles["actual"])
        ax.plot(ep.t, np.degrees(np.unwrap(ep.estimate[:, 2])), label="estimated (EKF)", **styles["estimated"])
        ax.set_title(n)
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("heading [deg]")
    axes[0].legend(loc="upper left")
    fig.suptitle("Heading against time (cf. Fig. 8); grey: a wheel off the floor")
    fig.tight_layout()
    fig.savefig(out / "phunopas_fig8_heading.png", dpi=120)
    plt.close(fig)


def write_markdown(path: Path, command: str, eps: dict, episodes: int, seed: int) -> None:
    lines = ["# Phunopas & Inoue (2018) scenario", "", "```", command, "```", "",
             f"Four-wheeled `phunopas2018` robot, quintic from (0.20, 0.20, 0) to (1.50, 1.50, π/4) in "
             f"{MOTION_SECONDS:g} s then {HOLD_SECONDS:g} s holding the goal, carpet, roller-gap friction, random "
             f"lift-off 0.5 /s (recovery 5 /s). {episodes} seeds ({seed}–{seed + episodes - 1}), the same for "
             "both policies. Mean and 95 % Student-t interval. Units: the paper's 20 → 150 read as centimetres; "
             "duration 8 s instead of the paper's 0.5 s (see the script's docstring).", "",
             "| policy | tracking RMSE [m] | final position error [m] | final heading error [rad] | "
             "successes | EKF final estimate error [m] |", "|---|---|---|---|---|---|"]
    for n, ep_list in eps.items():
        cells = []
        for m in METRICS:
            r = mean_ci(np.array([getattr(e, m) for e in ep_list]))
            cells.append(f"{r['mean']:.4f} [{r['ci95'][0]:.4f}, {r['ci95'][1]:.4f}]")
        est = mean_ci(np.array([np.hypot(*(e.pose[-1, :2] - e.estimate[-1, :2])) for e in ep_list]))
        wins = sum(e.success for e in ep_list)
        lines.append(f"| {n} | {' | '.join(cells)} | {wins}/{len(ep_list)} | "
                     f"{est['mean']:.4f} [{est['ci95'][0]:.4f}, {est['ci95'][1]:.4f}] |")
    lifted = np.mean([(~e.contact.all(axis=1)).mean() for e in eps["open-loop"]])
    lines += ["", f"Share of time with a wheel off the floor: {lifted:.2f} (stationary value 0.5 / 5.5 = 0.09).",
              "For open-loop the EKF runs alongside without acting: its estimate error shows what the filter "
              "knows even when nothing closes the loop.", "",
              f"Figures (seed {seed}): `phunopas_fig5_path.png`, `phunopas_fig7_xy.png`, `phunopas_fig8_heading.png`.",
              ""]
    path.write_text("\n".join(lines))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=20, help="seeds per policy (default 20)")
    ap.add_argument("--seed", type=int, default=20_000, help="first seed (default 20000)")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    args = ap.parse_args(argv)
    if args.episodes < 2:
        ap.error("--episodes must be >= 2 (confidence intervals need two episodes)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    recorded = record_args(argv or sys.argv[1:])
    command = ("python benchmarks/phunopas_replication.py " + " ".join(shlex.quote(a) for a in recorded))
    eps = run(args.episodes, args.seed)
    write_markdown(out / "phunopas_replication.md", command.strip(), eps, args.episodes, args.seed)
    plots(out, eps)
    print((out / "phunopas_replication.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
